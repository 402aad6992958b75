"""The verdict benchmark's per-lot count of false fails, and its verdict files per decision rule."""

from benchmarks import bench_verdicts as bv


def _rec(failed_lots, truth_passed):
    short = sorted({lot.split("_lower")[0].split("_upper")[0] for lot in failed_lots})
    return {"failed": short, "failed_lots": failed_lots, "truth_passed_lots": truth_passed}


def test_a_lot_failed_beside_a_lot_that_fails_in_truth_is_counted():
    recs = [
        # the truth fails the lower top spacings and passes the upper bottom ones, failed on a misreading
        _rec(["spacing_lower_top", "spacing_upper_bottom"], ["cover", "spacing_upper_bottom"]),
        # right: the lots that fail in truth; the upper top spacings the truth leaves open
        _rec(["cover", "spacing_lower_bottom", "spacing_upper_top"], ["spacing_lower_top"]),
        _rec(["bar_size_upper_top"], ["bar_size_upper_top", "cover"]),
    ]
    assert bv._lot_false_fails(recs, "spacing") == 1
    assert bv._lot_false_fails(recs, "cover") == 0
    assert bv._lot_false_fails(recs, "bar_size") == 1
    # the truth holds no counts; records judged before lots were kept are not counted
    assert bv._lot_false_fails(recs, "bar_count") == "–"
    assert bv._lot_false_fails(recs + [{"failed": [], "truth_failed": []}], "spacing") == "–"


def test_verdicts_under_another_rule_go_beside_the_presets(monkeypatch):
    assert bv._verdict_file(False, 1) == "verdict.json"
    monkeypatch.setitem(bv.JUDGE, "rule", "shared risk")
    assert bv._verdict_file(False, 1) == "verdict_shared_risk.json"
    assert bv._verdict_file(True, 2) == "verdict_follow2_shared_risk.json"
    assert bv._verdict_file(False, 1, guided=True) == "verdict_guided_shared_risk.json"


def test_a_cache_is_not_judged_again_with_captures_rendered_otherwise(tmp_path):
    import json

    import pytest

    slab = tmp_path / "slab_000"
    slab.mkdir()
    (slab / "slab.json").write_text(json.dumps({"render": {"camera": "d435-848"}, "captures": []}))
    # following advice or guiding may render captures: with the options the cache was made with only
    with pytest.raises(SystemExit, match="d435-848"):
        bv._rejudge((str(slab), True, 1, False))
    with pytest.raises(SystemExit, match="--camera"):
        bv._rejudge((str(slab), False, 1, True))


def test_the_extra_bar_set_adds_one_bar_and_aims_a_capture_at_it(tmp_path, monkeypatch):
    import numpy as np

    monkeypatch.setitem(bv.RENDER, "defects", "extra")
    design, scene, defect, _, specs = bv._slab_plan(601, tmp_path)
    assert defect == "extra" and bv.DEFECT_ITEM[defect] == "bar_count"
    extra = [b for b in scene.bars if b.extra]
    assert len(extra) == 1
    # the first capture is aimed at a point on the extra bar's axis (in plan)
    b, target = extra[0], np.asarray(specs[0]["target"])[:2]
    a0, a1 = b.axis[0, :2], b.axis[-1, :2]
    t = np.clip(np.dot(target - a0, a1 - a0) / np.dot(a1 - a0, a1 - a0), 0, 1)
    assert np.linalg.norm(a0 + t * (a1 - a0) - target) < 1.0 and 0.3 < t < 0.7
    # the even slabs stay clean, and the default set's odd slabs keep their defects
    assert bv._slab_plan(600, tmp_path / "c")[2] is None
    monkeypatch.setitem(bv.RENDER, "defects", "default")
    assert bv._slab_plan(601, tmp_path / "d")[2] == bv.DEFECTS[(601 // 2) % len(bv.DEFECTS)]
