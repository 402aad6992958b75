"""benchmarks/study_hidden_by_view.py on a hand-built verdict cache: tilt from the camera's
rotation, hidden positions counted from the results' reasons."""

import json
import math

from benchmarks.study_hidden_by_view import _rows


def _capture(slab, name, tilt_deg, height, reasons):
    t = math.radians(tilt_deg)
    # a camera looking down (z axis (0, 0, -1)) turned about the world x axis by the tilt
    rot = [[1, 0, 0], [0, -math.cos(t), -math.sin(t)], [0, math.sin(t), -math.cos(t)]]
    (slab / name).mkdir()
    truth = {"camera": {"height_mm": height, "rotation_world_to_camera": rot}}
    (slab / name / "truth.json").write_text(json.dumps(truth), encoding="utf-8")
    positions = [{"status": "not measured" if r else "present", "reason": r} for r in reasons]
    (slab / f"result_{name}.json").write_text(json.dumps({"positions": positions}), encoding="utf-8")


def test_rows_read_tilt_height_and_hidden_positions(tmp_path):
    slab = tmp_path / "slab_000"
    slab.mkdir()
    _capture(slab, "C0", 0.0, 500.0, ["hidden under another bar along 600 mm", None, "no depth there"])
    _capture(slab, "C1", 15.0, 620.0, [None, None])
    (slab / "slab.json").write_text(json.dumps({"captures": ["C0", "C1", "C2"]}), encoding="utf-8")
    rows = list(_rows(tmp_path))  # C2 has no saved result: skipped
    assert len(rows) == 2
    (t0, h0, n0), (t1, h1, n1) = rows
    assert abs(t0) < 1e-9 and h0 == 500.0 and n0 == 1
    assert abs(t1 - 15.0) < 1e-9 and h1 == 620.0 and n1 == 0
