"""``rebar calibrate`` end to end on synthetic checkerboard captures with known errors: the
renderer's camera reads depth 1.5 % too far plus 2 mm, and its lens's focal length is 0.4 %
longer than the intrinsics written with the captures.

Tolerances: the estimates within 3 of their own standard uncertainties of the truth, and within
fixed bounds (scale 0.15 %, offset 1 mm, focal length 0.2 %) so that a grossly inflated
uncertainty cannot pass either.
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from rebarlib import GEMINI2, RebarInputError, inspect, save_capture
from rebarlib.calibration import apply_calibration, calibrate, load_calibration
from rebarlib.cli import main
from rebarlib.synth import SensorModel, synth_capture
from rebarlib.synth_calib import Checkerboard, board_captures, render_board

SCALE, OFFSET, FOCAL = 0.015, 2.0, 0.004
SENSOR = SensorModel(depth_scale_error=SCALE, depth_offset_mm=OFFSET, focal_error=FOCAL)


@pytest.fixture(scope="module")
def boards():
    return board_captures(SENSOR, n=8, tilt_deg=40, seed=1)


@pytest.fixture(scope="module")
def cal(boards):
    return calibrate(boards, cols=9, rows=6, square_mm=40.0)


@pytest.mark.slow
def test_calibration_recovers_the_known_errors(cal):
    true_fx = GEMINI2.fx * (1 + FOCAL)
    assert abs(cal.depth_scale - SCALE) <= max(3 * cal.u_depth_scale, 2e-4) and abs(cal.depth_scale - SCALE) < 1.5e-3
    assert abs(cal.depth_offset_mm - OFFSET) <= max(3 * cal.u_depth_offset_mm, 0.2)
    assert abs(cal.depth_offset_mm - OFFSET) < 1.0
    for est, true, u in (
        (cal.intrinsics.fx, true_fx, cal.u_intrinsics[0]),
        (cal.intrinsics.fy, true_fx, cal.u_intrinsics[1]),
    ):
        assert abs(est - true) <= 3 * u and abs(est / true - 1) < 2e-3
    assert abs(cal.intrinsics.cx - GEMINI2.cx) <= max(3 * cal.u_intrinsics[2], 1.0)
    assert abs(cal.intrinsics.cy - GEMINI2.cy) <= max(3 * cal.u_intrinsics[3], 1.0)
    assert cal.n_captures == 8 and cal.reprojection_rms_px < 0.5
    # a straight line fits the board's depths to about the sensor's noise
    assert cal.depth_rms_mm < 3.0


@pytest.mark.slow
def test_a_calibrated_capture_reads_true_depths(boards, cal):
    cap = boards[0]
    fixed = apply_calibration(cap, cal)
    on = cap.depth_mm > 0
    assert np.all(fixed.depth_mm[~on] == 0)
    # the depth correction undoes the 1.5 % + 2 mm: the median over the board is within 0.3 %
    # of the depth the pose gives
    raw = cap.depth_mm[on]
    undone = (raw - OFFSET) / (1 + SCALE)
    assert np.median(np.abs(fixed.depth_mm[on] - undone) / undone) < 3e-3
    assert fixed.intrinsics == cal.intrinsics


@pytest.mark.slow
def test_inspect_with_the_calibration_shrinks_the_errors(cal, paper_design):
    cap = synth_capture(paper_design, height_mm=550, tilt_deg=10, sensor=SENSOR, seed=3)
    t = cap.truth
    truth_sp = {(s["bar_a"], s["bar_b"]): s["spacing_mm"] for s in t["spacings"]}
    plain = inspect(cap, paper_design, diameters=False, rng=0)
    fixed = inspect(cap, paper_design, diameters=False, rng=0, calibration=cal)

    def spacing_error(res):
        sp = res.spacings.dropna(subset=["spacing_mm"])
        # the measured spacings against the truth's design spacing ± as-built jitter: the median
        # over a dozen gaps is the scale's footprint (200 mm x 1.9 % = 3.8 mm uncalibrated)
        return float(np.median(sp["spacing_mm"]) - np.median(list(truth_sp.values())))

    e_ld = tuple(r.layer_distance.value_mm - t["layer_distance_mm"] for r in (plain, fixed))
    e_sp = (spacing_error(plain), spacing_error(fixed))
    # uncalibrated: the 1.5 % depth scale shows (85 mm x 1.5 % = 1.3 mm, ~3.8 mm on a spacing)
    assert e_ld[0] > 0.8 and e_sp[0] > 2.5
    # calibrated: the errors shrink to what the fits leave
    assert abs(e_ld[1]) < 0.5 and abs(e_sp[1]) < 1.0
    assert fixed.extras["calibration"]["summary"].startswith("calibrated on")
    assert fixed.extras["uncertainty"]["inputs"]["source"] == "calibration"
    # the calibrated result's uncertainty covers its error (k = 2)
    assert abs(e_ld[1]) <= 2 * fixed.layer_distance.uncertainty_mm


@pytest.mark.slow
def test_calibration_file_round_trip_and_cli(tmp_path, boards, cal):
    folders = []
    for b in boards[:5]:
        folders.append(str(save_capture(b, tmp_path / b.name)))
    out = tmp_path / "cal" / "camera_cal.json"
    assert main(["calibrate", *folders, "--board", "9x6", "--square-mm", "40", "--out", str(out)]) == 0
    back = load_calibration(out)
    assert back.n_captures == 5 and abs(back.depth_scale - SCALE) < 2e-3
    d = json.loads(out.read_text())
    assert d["format"] == "rebarlib calibration 1" and d["board"] == {"cols": 9, "rows": 6, "square_mm": 40.0}
    # the saved file reads back as the object that wrote it
    p = cal.save(tmp_path / "again.json")
    assert load_calibration(p).to_dict() == cal.to_dict()


def test_bad_inputs_are_refused(tmp_path, capsys):
    bad = tmp_path / "bad.json"
    bad.write_text('{"format": "something else"}')
    with pytest.raises(RebarInputError, match="rebar calibrate"):
        load_calibration(bad)
    bad.write_text("not json")
    with pytest.raises(RebarInputError, match="not a readable calibration"):
        load_calibration(bad)
    assert main(["calibrate", str(tmp_path), "--board", "nine", "--square-mm", "40", "--out", "x.json"]) == 2
    assert "COLSxROWS" in capsys.readouterr().err
    with pytest.raises(RebarInputError, match="3 x 3"):
        Checkerboard(cols=2, rows=6)


def test_too_few_boards_found_is_an_error():
    cap = render_board(_pose(), intrinsics=GEMINI2.scaled(0.25), sensor=SensorModel.ideal(), rng=0)
    with pytest.raises(RebarInputError, match="at least 3"):
        calibrate([cap], cols=9, rows=6, square_mm=40.0)


def _pose():
    from rebarlib.synth import CameraPose

    return CameraPose.looking_down(600.0)


def test_focal_error_renders_through_the_true_lens():
    # a corner straight ahead stays put; one off-axis lands (1 + e) further from the centre
    from rebarlib.synth import CameraPose

    s = SensorModel.ideal()
    K = GEMINI2.scaled(0.25)
    assert s.true_intrinsics(K) == K
    e = replace(s, focal_error=0.01).true_intrinsics(K)
    assert e.fx == pytest.approx(K.fx * 1.01) and (e.cx, e.cy) == (K.cx, K.cy)
    cap = render_board(
        CameraPose.looking_down(500.0),
        intrinsics=K,
        sensor=replace(s, depth_scale_error=0.02, depth_offset_mm=3.0),
        rng=0,
    )
    z = cap.depth_mm[cap.depth_mm > 0]
    assert np.allclose(z, 500.0 * 1.02 + 3.0, atol=1e-6) and math.isfinite(z.mean())
