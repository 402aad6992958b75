"""A lot over captures not placed on each other (docs/decisions/039-a-lot-over-captures-not-placed.md):
a share rule is judged under both extreme readings of whether two such captures show the same
spacings, against hand-built results.

The results below have no formwork plane (no plan frame), so no two of them can be placed on each
other: whether they show the same bars is unknown, as in the verdict benchmark's slab 024.
"""

from __future__ import annotations

import pytest

from rebarlib import evaluate
from rebarlib.data import paper_design

LEVEL = ("lower", "bottom")


def _spacing(i, value, u=1.1):
    return {
        "layer": LEVEL[0],
        "level": LEVEL[1],
        "bar_a": i,
        "bar_b": i + 1,
        "spacing_mm": value,
        "design_spacing_mm": 200.0,
        "uncertainty_mm": u,
        "status": "measured",
        "reason": "",
    }


def _result(name, values, u=1.1):
    """A capture of the paper design (GB 50204: spacing 200 ± 10 mm, a lot passes with 80 % of
    its spacings within) measuring ``values`` between the lower bottom bars."""
    return {
        "capture": name,
        "measurements": {
            "cover": {"value_mm": 20.0, "uncertainty_mm": 0.3, "status": "measured"},
            "layer_distance": {"value_mm": 85.0, "uncertainty_mm": 0.3, "status": "measured"},
        },
        "spacings": [_spacing(i, v, u) for i, v in enumerate(values)],
        "formwork": {},
    }


def _item(acc, item="spacing_lower_bottom"):
    return acc.items.set_index("item").loc[item]


# slab 024 of the verdict benchmark after its closer capture, its lower bottom spacings as measured
C0 = [197.33, 194.65, 210.51, 198.46]  # one beyond (210.5 against 200 ± 10)
C1 = [201.75, 197.52, 199.80, 195.73]
Z1 = [210.93]  # the same pair as C0's 210.5 as built (210.75 mm)


def test_one_spacing_in_two_unplaced_captures_leaves_the_lot_incomplete_not_rejected():
    acc = evaluate([_result("C0", C0), _result("C1", C1), _result("Z1", Z1)], paper_design())
    it = _item(acc)
    # counted as they are: 7 of 9 within, under 80 %; were Z1's spacing C0's, 7 of 8 (87.5 %);
    # were three of C1's C0's, 4 of 6: it depends on what no result can tell
    assert (it["passed"], it["measured"]) == (7, 9)
    assert it["verdict"] == "incomplete"
    assert "5/7 to 7/8 depending on which they share" in it["reason"]
    assert "C0 and C1; C0 and Z1" in it["reason"]
    assert "a capture placed on both settles it" in it["reason"]
    assert acc.verdict == "incomplete"


def test_a_duplicated_good_spacing_cannot_lift_a_failing_lot():
    # alone, C0 is 3 of 4 within (75 %); a fifth spacing from an unplaced capture, close to one
    # of C0's, would lift it to 80 % only if it is another spacing
    acc = evaluate([_result("C0", C0), _result("C2", [197.0])], paper_design())
    it = _item(acc)
    assert (it["passed"], it["measured"]) == (4, 5)
    assert it["verdict"] == "incomplete"
    assert "3/4 to 4/5 depending on which they share" in it["reason"]


def test_it_fails_when_no_reading_reaches_the_share():
    # Z1's beyond spacing reads 225 mm: not C0's 210.5 ± 1.1 mm; C0 + Z1: 3/5, with C1 at most 7/9
    acc = evaluate([_result("C0", C0), _result("C1", C1), _result("Z1", [225.0])], paper_design())
    it = _item(acc)
    assert it["verdict"] == "fail"
    assert "below it however many spacings of captures not placed on each other" in it["reason"]


def test_it_passes_when_every_reading_reaches_the_share():
    # one beyond among 9 within in one capture, and an unplaced capture of 4 within: at worst
    # (4 of those are repeats) 9/10 = 90 %
    a = [200.0 + d for d in (1, -2, 3, 0.5, -1, 2, 4, -3, 1)] + [211.0]
    acc = evaluate([_result("A", a), _result("B", [201.0, 198.0, 203.0, 200.5])], paper_design())
    it = _item(acc)
    assert it["verdict"] == "pass"
    assert "at least 80% either way" in it["reason"]


def test_readings_that_cannot_be_the_same_spacing_are_counted_as_they_are():
    # C2's spacings are 5 mm or more from every one of C0's (within 2 combined σ: 3.1 mm): not repeats
    acc = evaluate([_result("C0", C0), _result("C2", [204.0, 204.5, 205.0, 205.5])], paper_design())
    it = _item(acc)
    assert (it["passed"], it["measured"], it["verdict"]) == (7, 8, "pass")
    assert "repeat" not in it["reason"]


def test_one_capture_alone_is_judged_as_before():
    acc = evaluate([_result("C0", C0 + C1 + Z1)], paper_design())
    it = _item(acc)
    assert (it["passed"], it["measured"], it["verdict"]) == (7, 9, "fail")
    # both beyond (210.51 and 210.93 against 210, U = 2.2 mm) are beyond by less than U: the sheet says so
    assert it["reason"] == (
        "7/9 within tolerance, below 80%; 2 of the 2 checkpoints beyond lie beyond their limit by less than their "
        "expanded uncertainty U (not proven: a hand measurement confirms it)"
    )


@pytest.mark.parametrize("second", [[224.5], [220.5]])
def test_a_rule_over_every_spacing_is_unaffected(second):
    # EN 13670 class 1 (every spacing within ± 20 mm): a spacing out of tolerance is out whichever
    # capture saw it, whether the other capture saw it out too (224.5) or just inside (219.5 / 220.5)
    within = [205.0, 195.0, 219.5 if second == [220.5] else 224.8]
    acc = evaluate([_result("A", within), _result("B", second)], paper_design(), "EN13670-class1")
    assert _item(acc)["verdict"] == "fail"


def test_a_run_seen_whole_in_both_captures_passes_as_it_is():
    # both captures show the same five spacings, one of them 210.5 mm; read in the row's order
    # they are the same run or none of it (a repeat of its first four is a repeat of the fifth
    # too): 9/11, 5/6 or (C1 first = C0 last) 8/10, 80 % or more. Without the order, dropping the four
    # within and keeping the fifth (5/7) would leave it incomplete.
    c0 = [195.0, 204.0, 199.0, 210.5, 201.5, 193.0]
    c1 = [195.1, 204.1, 198.9, 210.6, 201.4]
    acc = evaluate([_result("C0", c0), _result("C1", c1)], paper_design())
    it = _item(acc)
    assert it["verdict"] == "pass"
    assert "8/10 to 9/11" in it["reason"]  # C1 first spacing may also be C0 last one


def test_slab_026_a_chance_reversed_overlap_leaves_it_open():
    # slab 026 of the verdict benchmark: the same five spacings in both captures, but C1's first
    # three read backwards also fit C0's first three within 2 combined σ (198.4 / 204.4 / 200.7
    # against 200.8 / 204.4 / 198.4): with no placing, that overlap cannot be ruled out (6/8)
    c0 = [198.38, 204.36, 200.76, 191.18, 210.04, 196.68]
    c1 = [198.44, 204.42, 200.69, 191.21, 210.10]
    it = _item(evaluate([_result("C0", c0), _result("C1", c1)], paper_design()))
    assert it["verdict"] == "incomplete"
    assert "6/8 to 9/11" in it["reason"]


def test_a_run_with_a_spacing_out_fails_whichever_way_it_is_read():
    # slab 079 (150 ± 10 mm): C1 shows C0's last three spacings, one 138 mm; counted once, 3 of 4
    # within; counted twice, 5 of 7; no reading reaches 80 %
    d = paper_design()
    c0 = [159.23, 138.31, 155.60, 147.34]
    c1 = [138.35, 155.54, 147.54]

    def res(name, values):
        r = _result(name, values)
        for s in r["spacings"]:
            s["design_spacing_mm"] = 150.0
        return r

    acc = evaluate([res("C0", c0), res("C1", c1)], d)
    it = _item(acc)
    assert it["verdict"] == "fail"


def test_a_spacing_not_measured_breaks_the_run():
    from rebarlib._verdicts import _runs

    rows = [
        {"what": "bars 1-2", "status": "within", "measured_value": 200.0},
        {"what": "bars 2-3", "status": "beyond", "measured_value": 212.0},
        {"what": "bars 3-4", "status": "not measured", "measured_value": None},
        {"what": "bars 4-5", "status": "within", "measured_value": 199.0},
        {"what": "bars 7-8", "status": "within", "measured_value": 201.0},
    ]
    assert [[r["what"] for r in run] for run in _runs(rows)] == [["bars 1-2", "bars 2-3"], ["bars 4-5"], ["bars 7-8"]]


def test_the_verdict_benchmark_reads_the_pairs_a_lot_asks_a_capture_on_both_for():
    # benchmarks/bench_verdicts.py --follow-advice takes a capture half-way between the first pair
    # this reason names; its pattern must keep reading what the verdict writes
    from benchmarks.bench_verdicts import BOTH

    acc = evaluate([_result("C0", C0), _result("C1", C1), _result("Z1", Z1)], paper_design())
    m = BOTH.search(_item(acc)["reason"])
    assert m is not None
    assert [p.split(" and ") for p in m.group(1).split("; ")] == [["C0", "C1"], ["C0", "Z1"]]


def _result_pairs(name, rows):
    """A capture measuring ``(bar_a, bar_b, value)`` between the lower bottom bars; a value of
    None is a spacing not measured."""
    res = _result(name, [])
    for a, b, v in rows:
        sp = _spacing(0, v)
        sp.update(bar_a=a, bar_b=b)
        if v is None:
            sp.update(spacing_mm=None, uncertainty_mm=None, status="not measured", reason="a bar seen only in parts")
        res["spacings"].append(sp)
    return res


def test_the_unmeasured_can_save_a_share_under_the_reading_that_drops_the_repeats():
    """Held-out verdict slab 161 as guided (two captures not placed on each other, each with one
    spacing not measured): as counted 4 of 6 within (one spacing beyond seen twice); were the
    second capture's run the first's, 2 of 3 measured, and with the two spacings not measured —
    distinct ones under that reading — 4 of 5 (80 %). No reading fails it on evidence: incomplete,
    not fail (decision 062)."""
    c0 = _result_pairs("C0", [(0, 1, 203.56), (1, 2, 187.94), (2, 3, 203.87), (3, 4, None)])
    g0 = _result_pairs("G0", [(9, 4, None), (4, 5, 203.62), (5, 6, 187.74), (6, 7, 204.21)])
    it = _item(evaluate([c0, g0], paper_design()))
    assert (it["passed"], it["measured"], it["not_measured"]) == (4, 6, 2)
    assert it["verdict"] == "incomplete"
    assert (
        "could still reach 4/5, if captures not placed on each other (C0 and G0) show the same spacings" in it["reason"]
    )
    # the same captures with the two spacings measured, one of them beyond: a fail however read
    c0 = _result_pairs("C0", [(0, 1, 203.56), (1, 2, 187.94), (2, 3, 203.87), (3, 4, 212.0)])
    g0 = _result_pairs("G0", [(9, 4, 189.0), (4, 5, 203.62), (5, 6, 187.74), (6, 7, 204.21)])
    assert _item(evaluate([c0, g0], paper_design()))["verdict"] == "fail"
