"""benchmarks/study_pixels_for_sizes.py on a hand-built verdict cache: each bar's envelopes' gap
in pixels from its capture's focal length, its design size and its depth; hidden bars left out."""

import json

import pytest

from benchmarks.study_pixels_for_sizes import _rows, main


def _bar(status, reason, z, d=14.0):
    return {
        "diameter_status": status,
        "diameter_reason": reason,
        "design_diameter_mm": d,
        "start_z_mm": z - 20.0,
        "end_z_mm": z + 20.0,
    }


def test_rows_read_the_gap_and_why_a_bar_is_unsized(tmp_path, capsys):
    slab = tmp_path / "slab_000"
    (slab / "C0").mkdir(parents=True)
    (slab / "design.toml").write_text(
        '[slab]\nid = "S"\n\n[design]\ncover_mm = 20\nlayer_distance_mm = 85\n\n'
        "[design.lower]\ndiameter_mm = 14\nspacing_mm = 200\n\n[design.upper]\ndiameter_mm = 12\nspacing_mm = 200\n",
        encoding="utf-8",
    )
    k = [400.0, 0, 0, 0, 400.0, 0, 320, 240, 1]  # f 400 px
    (slab / "C0" / "camera.json").write_text(json.dumps({"intrinsic_matrix": k}), encoding="utf-8")
    bars = [
        _bar("measured", "", 400.0),  # Φ14 (gap 2.2 mm) at 400 mm: 2.2 px
        _bar("not measured", "ambiguous: width 15.1 mm (mask) lies between Φ12 and Φ14", 550.0),  # 1.6 px
        _bar("not measured", "too few clean cross-sections (4 of 46; most lost in shadow)", 300.0),  # 2.93 px
        _bar("hidden", "hidden: 100% of its cross-sections lie under nearer bars", 500.0),  # left out
    ]
    (slab / "result_C0.json").write_text(json.dumps({"bars": bars}), encoding="utf-8")
    (slab / "result_C9.json").write_text(json.dumps({"bars": bars}), encoding="utf-8")  # no camera.json: skipped
    rows = list(_rows(tmp_path))
    assert [k for _, k in rows] == ["sized", "width", "other"]
    assert [g for g, _ in rows] == pytest.approx([400 * 2.2 / 400, 400 * 2.2 / 550, 400 * 2.2 / 300])
    assert main(["--cache", str(tmp_path)]) == 0
    out = capsys.readouterr().out
    assert "| 1.50–1.75 | 1 | 0.0% | 100.0% | 0.0% |" in out and "| 2.00–2.25 | 1 | 100.0% | 0.0% | 0.0% |" in out
