"""benchmarks/study_mask_lean.py: a bar is matched to the nearest true bar of its layer, and a
capture's lean (mask width less envelope) is compared with the lean read from its stack heights."""

import json

from benchmarks.study_mask_lean import _nearest_true_bar, study


def _true_bar(y, *, layer="upper", envelope=16.2, diameter=14.0):
    return {
        "layer": layer,
        "diameter_mm": diameter,
        "axis_start_mm": [-300.0, y, 500.0],
        "axis_end_mm": [300.0, y, 500.0],
        "envelope_mm": envelope,
    }


def _bar(y, width, *, layer="upper", stack=None, status="measured", reason="", nominal=14.0):
    return {
        "layer": layer,
        "bar_id": int(y),
        "nominal_mm": nominal,
        "confidence": 0.9,
        **{f"start_{k}_mm": v for k, v in zip("xyz", (-250.0, y, 500.0))},
        **{f"end_{k}_mm": v for k, v in zip("xyz", (250.0, y, 500.0))},
        "width_median_mm": width,
        "cloud_width_mm": 16.0,
        "stack_mm": stack,
        "one_sided_share": 0.0,
        "diameter_status": status,
        "diameter_reason": reason,
    }


def test_a_bar_is_matched_within_8_mm_in_its_own_layer():
    truth = {"bars": [_true_bar(0.0), _true_bar(5.0, layer="lower"), _true_bar(200.0)]}
    assert _nearest_true_bar(_bar(3.0, 16.0), truth) is truth["bars"][0]
    assert _nearest_true_bar(_bar(9.0, 16.0), truth) is None  # 9 mm from the nearest upper bar
    assert _nearest_true_bar(_bar(4.0, 16.0, layer="lower"), truth) is truth["bars"][1]


def test_a_capture_whose_masks_lean_wide_is_read_so(tmp_path, capsys):
    # six bars 200 mm apart, every mask 0.5 mm over the 16.2 mm envelope, their stacks 16.3 mm
    cap = tmp_path / "slab_000" / "C0_500"
    cap.mkdir(parents=True)
    truth = {"bars": [_true_bar(200.0 * i) for i in range(6)]}
    (cap / "truth.json").write_text(json.dumps(truth), encoding="utf-8")
    bars = [_bar(200.0 * i + 1.0, 16.7, stack=16.3, nominal=16.0 if i == 5 else 14.0) for i in range(6)]
    bars.append(_bar(2000.0, 20.0, status="not measured", reason="ambiguous: width 20.0 mm"))  # no true bar
    (cap.parent / "result_C0_500.json").write_text(json.dumps({"bars": bars}), encoding="utf-8")
    study(tmp_path)
    out = capsys.readouterr().out
    assert "| measured | 6 | +0.50 (+0.50, +0.50) | -0.20 |" in out
    assert "ambiguous" not in out
    assert "captures: 1; true lean p50 +0.50 mm" in out
    assert "sized: 5 to their true size, 1 to another" in out
    assert "- slab_000 C0_500 bar 1001: sized Φ16, truly Φ14 (confidence 0.9)" in out
