"""Laps and pieces of bars on one design position (docs/verdicts.md, "Laps and pieces"): two bars
of a row judged no extra bar take no part in the spacings as two; the bar that stands for the
position does. The generator's laps (``Deviations.laps``) and their truth."""

from __future__ import annotations

import numpy as np
import pandas as pd
import pytest

import rebarlib as R
from rebarlib import synth as S
from rebarlib._count_tables import off_the_row
from rebarlib._status import EXTRA, MEASURED, NOT_EXTRA
from rebarlib.data import paper_design
from rebarlib.geometry import BarAxis, measure_spacings


def _axis(offset, t0, t1, status=MEASURED):
    return BarAxis(
        "lower", np.array([1.0, 0.0]), offset, 0.0, 30.0, 0.0, t0, t1, 7.0, 100, 0.3, level="bottom", status=status
    )


def _pair(bar_id, twin_id, status=NOT_EXTRA):
    return {"layer": "lower", "level": "bottom", "kind": "pair", "status": status, "bar_id": bar_id, "twin_id": twin_id}


def test_the_shorter_of_a_lap_takes_no_part_in_the_spacings():
    # a lap: bar 1 runs 0-600 mm, bar 2 (15 mm beside it) 450-1000 mm; neighbours at 0 and 400
    bars = [_axis(0.0, 0, 1000), _axis(200.0, 0, 600), _axis(215.0, 450, 1000), _axis(400.0, 0, 1000)]
    before = measure_spacings(bars, design_spacing={("lower", "bottom"): 200.0})
    assert before["spacing_mm"].round(1).tolist() == [200.0, 15.0, 185.0]  # 15 mm: no spacing at all
    skip = off_the_row(pd.DataFrame([_pair(2, 1)]), bars)
    assert skip == {2}  # both measured: bar 1, seen over 600 mm, stands; bar 2 over 550 mm does not
    after = measure_spacings(bars, design_spacing={("lower", "bottom"): 200.0}, skip=skip)
    assert after[["bar_a", "bar_b"]].values.tolist() == [[0, 1], [1, 3]]
    assert after["spacing_mm"].round(1).tolist() == [200.0, 200.0]


def test_the_measured_bar_of_a_pair_stands():
    bars = [_axis(0.0, 0, 1000), _axis(200.0, 0, 300), _axis(212.0, 0, 1000, status="not measured")]
    assert off_the_row(pd.DataFrame([_pair(1, 2)]), bars) == {2}


@pytest.mark.parametrize("status", [EXTRA, "not measured"])
def test_an_extra_bar_or_an_open_pair_keeps_its_spacings(status):
    bars = [_axis(0.0, 0, 1000), _axis(100.0, 0, 1000), _axis(200.0, 0, 1000)]
    assert off_the_row(pd.DataFrame([_pair(1, 2, status)]), bars) == set()
    # results from before the twin was recorded
    assert off_the_row(pd.DataFrame([_pair(1, 2)]).drop(columns="twin_id"), bars) == set()


def test_the_generator_laps_a_bar_and_its_truth_has_no_spacing_inside_the_lap():
    design = paper_design()
    scene = S.make_scene(design, S.Deviations(laps=2, end_overhang_mm=50.0, mesh_yaw_deg=20.0), rng=7)
    assert len(scene.laps) == 2
    for a, b, mid in scene.laps:
        A, B = scene.bars[a], scene.bars[b]
        assert (A.lap_partner, B.lap_partner) == (b, a)
        assert (A.layer, A.level, A.index) == (B.layer, B.level, B.index)
        assert abs(abs(B.offset_mm - A.offset_mm) - A.envelope_mm) < 1e-6  # side by side, touching
        # the two pieces overlap by the lap (40 diameters, at least 300 mm) around its middle
        s = [(x.axis[:, :2] - mid[:2]) @ A.direction[:2] for x in (A, B)]
        overlap = min(s[0].max(), s[1].max()) - max(s[0].min(), s[1].min())
        assert overlap == pytest.approx(max(40 * A.nominal_mm, 300.0))
    # a scene without laps draws what it drew before the option existed
    plain = S.make_scene(design, S.Deviations(end_overhang_mm=50.0, mesh_yaw_deg=20.0), rng=7)
    assert all(b.lap_partner == -1 for b in plain.bars) and plain.laps == ()


@pytest.mark.slow
def test_a_lap_in_view_is_neither_an_extra_bar_nor_a_spacing():
    design = paper_design()
    scene = S.make_scene(design, S.Deviations(laps=1, end_overhang_mm=50.0, mesh_yaw_deg=20.0), rng=7)
    a, b, mid = scene.laps[0]
    pose = S.CameraPose.looking_down(520.0, tilt_deg=6.0, yaw_deg=30.0, target_mm=tuple(mid[:2]))
    cap = S.render_capture(scene, pose, rng=1, name="lap")
    truth = {x["id"]: x for x in cap.truth["bars"]}
    assert truth[a]["visible"] and truth[b]["visible"] and truth[a]["lap_partner"] == b
    assert not any({s["bar_a"], s["bar_b"]} == {a, b} for s in cap.truth["spacings"])
    res = R.inspect(cap, design, rng=0)
    counts = res.counts.set_index(["layer", "level"])
    assert (counts["extra"].fillna(0) == 0).all()
    sp = res.spacings[res.spacings["status"] == MEASURED]
    row = sp[(sp["layer"] == scene.bars[a].layer) & (sp["level"] == scene.bars[a].level)]
    # every measured spacing of the lapped row is a spacing between positions, none inside the lap
    assert (row["spacing_mm"] > 0.5 * 200.0).all()
    assert R.evaluate([res.to_dict()], design).verdict != "rejected"


@pytest.mark.parametrize("field, value", [("laps", -1), ("missing", -2), ("extra", 1.5), ("wrong_size", True)])
def test_a_count_of_bars_must_be_a_whole_number_not_below_zero(field, value):
    with pytest.raises(ValueError, match=f"{field}: expected a whole number of bars >= 0"):
        S.Deviations(**{field: value})
    with pytest.raises(ValueError, match="lap_length_mm: expected a length > 0 mm"):
        S.Deviations(laps=1, lap_length_mm=0.0)
