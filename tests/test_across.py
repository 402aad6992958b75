"""Judging a slab's captures together: registration from the bars and positions judged across
captures (rebarlib/_across.py, docs/decisions/028-captures-of-one-slab-together.md)."""

from __future__ import annotations

import copy
import math

import numpy as np
import pytest

from rebarlib._across import register, resolve_across, unplaced_pairs

SPACING = 200.0


def _bar(bar_id, layer, level, a, b, plane_h=500.0):
    """A bar record with camera-frame ends for a camera looking straight down from ``plane_h``
    (slab frame = camera x, y; height 30 mm)."""
    z = plane_h - 30.0
    return {
        "bar_id": bar_id,
        "layer": layer,
        "level": level,
        "start_x_mm": a[0],
        "start_y_mm": a[1],
        "start_z_mm": z,
        "end_x_mm": b[0],
        "end_y_mm": b[1],
        "end_z_mm": z,
    }


def _capture(name, offsets_x, offsets_y, view, *, turn=0.0, shift=(0.0, 0.0), positions=()):
    """A result dict of a capture seeing the mesh over ``view`` ((x0, x1), (y0, y1) in mesh
    coordinates), its own frame turned by ``turn`` and shifted by ``shift`` from the mesh's. The
    'bottom' bars run along x at offsets_y[layer], the 'top' bars along y at offsets_x[layer]."""
    c, s = math.cos(turn), math.sin(turn)
    R = np.array([[c, -s], [s, c]])

    def cam(p):
        q = R @ np.asarray(p, float) + np.asarray(shift)
        # slab frame (a, b) of a plane with normal -z is (x, -y) in the camera: see plane_frame
        return (q[0], -q[1])

    (x0, x1), (y0, y1) = view
    bars = []
    for layer in ("lower", "upper"):
        for y in offsets_y[layer]:
            if y0 <= y <= y1:
                bars.append(_bar(len(bars), layer, "bottom", cam((x0, y)), cam((x1, y))))
        for x in offsets_x[layer]:
            if x0 <= x <= x1:
                bars.append(_bar(len(bars), layer, "top", cam((x, y0)), cam((x, y1))))
    pos = []
    for layer, level, off in positions:
        if level == "bottom":
            a, b = cam((x0, off)), cam((x1, off))
        else:
            a, b = cam((off, y0)), cam((off, y1))
        pos.append(
            {
                "layer": layer,
                "level": level,
                "kind": "gap",
                "offset_mm": off,
                "status": "not measured",
                "reason": "hidden under another bar along 400 mm",
                "start_x_mm": a[0],
                "start_y_mm": a[1],
                "start_z_mm": 470.0,
                "end_x_mm": b[0],
                "end_y_mm": b[1],
                "end_z_mm": 470.0,
            }
        )
    counts = [
        {"layer": la, "level": lv, "found": 3, "expected": 3, "missing": 0, "extra": 0, "not_measured": 0}
        for la in ("lower", "upper")
        for lv in ("bottom", "top")
    ]
    for p in pos:
        for c_ in counts:
            if (c_["layer"], c_["level"]) == (p["layer"], p["level"]):
                c_["not_measured"] += 1
    spacings = [
        {"layer": la, "level": lv, "design_spacing_mm": SPACING}
        for la in ("lower", "upper")
        for lv in ("bottom", "top")
    ]
    return {
        "capture": name,
        "measurements": {},
        "formwork": {"normal": [0.0, 0.0, -1.0], "offset_mm": 500.0, "found": True},
        "bars": bars,
        "positions": pos,
        "counts": counts,
        "spacings": spacings,
    }


def _without_lower_bottom(bars, y):
    """``bars`` less the lower bottom bar at mesh offset ``y`` (a capture that did not find it)."""
    return [
        b for b in bars if not (b["layer"] == "lower" and b["level"] == "bottom" and abs(-b["start_y_mm"] - y) < 1e-6)
    ]


def _irregular(n, rng, jitter):
    """Offsets of both lattices' bars of one direction: the design spacing, the upper bars 60 mm
    aside, each bar off its place by a normal draw of ``jitter`` (mm)."""
    base = np.arange(n) * SPACING - (n - 1) * SPACING / 2
    return {"lower": base + rng.normal(0, jitter, n), "upper": base + 60.0 + rng.normal(0, jitter, n)}


def test_two_overlapping_captures_are_registered_to_their_true_placing():
    rng = np.random.default_rng(3)
    xs, ys = _irregular(9, rng, 4.0), _irregular(9, rng, 4.0)
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)))
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)), turn=0.4, shift=(35.0, -12.0))
    reg, why = register(a, b, 0.25 * SPACING)
    assert reg is not None, why
    # a point of the mesh in A's plan frame (the mesh's own here) lands where B sees it
    c, s = math.cos(0.4), math.sin(0.4)
    for p in ([0.0, 0.0], [150.0, -80.0]):
        want = np.array([[c, -s], [s, c]]) @ np.array(p) + np.array([35.0, -12.0])
        assert np.allclose(reg.to_b(np.array(p)), want, atol=0.5)


def test_a_mesh_placed_as_regularly_as_it_is_measured_is_not_registered():
    rng = np.random.default_rng(4)
    xs, ys = _irregular(9, rng, 0.05), _irregular(9, rng, 0.05)
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)))
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)), shift=(20.0, 0.0))
    reg, why = register(a, b, 0.25 * SPACING)
    assert reg is None
    assert "too regular" in why or "no placing" in why


def test_captures_that_do_not_overlap_are_not_registered():
    rng = np.random.default_rng(5)
    xs, ys = _irregular(15, rng, 4.0), _irregular(15, rng, 4.0)
    a = _capture("A", xs, ys, ((-1400, -700), (-300, 250)))
    b = _capture("B", xs, ys, ((600, 1400), (-250, 300)))
    reg, _ = register(a, b, 0.25 * SPACING)
    assert reg is None


@pytest.mark.parametrize("placed", ["colour mask", "one side", "fitted"])
def test_a_bar_placed_otherwise_than_by_a_fit_to_both_sides_does_not_blur_the_placing(placed):
    """Decision 029: a bar placed from the colour mask, or fitted to the one side it shows, lies
    millimetres off its place by an error of its own; the pairs it makes are weighed with their
    own scatter, not the fitted bars'. A fitted bar 3 mm off is a real misfit and still refuses."""
    rng = np.random.default_rng(0)
    xs, ys = _irregular(9, rng, 2.0), _irregular(9, rng, 2.0)
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)))
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)), shift=(100.0, 0.0))
    for lv, keys in (("bottom", ("start_y_mm", "end_y_mm")), ("top", ("start_x_mm", "end_x_mm"))):
        bar = next(x for x in b["bars"] if x["layer"] == "lower" and x["level"] == lv)
        for k in keys:
            bar[k] += 3.0
        if placed == "colour mask":
            bar["status"] = "not measured"
        elif placed == "one side":
            bar["one_sided_share"] = 1.0
    reg, why = register(a, b, 0.25 * SPACING)
    if placed == "fitted":
        assert reg is None and "too regular" in why
        return
    assert reg is not None, why
    for p in ([0.0, 0.0], [150.0, -80.0]):
        assert np.allclose(reg.to_b(np.array(p)), np.array(p) + np.array([100.0, 0.0]), atol=0.5)


def test_bars_fitted_to_one_side_do_not_pull_the_shift_of_the_placing():
    """Decision 029: the shift across each direction is refined on the pairs of fitted axes. Two
    lower bars of each direction fitted to the one side they show, 6 mm off their places, no
    longer pull the shift (and with it every fitted pair) off the true placing."""
    rng = np.random.default_rng(0)
    xs, ys = _irregular(9, rng, 2.0), _irregular(9, rng, 2.0)
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)))
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)), shift=(100.0, 0.0))
    for lv, keys in (("bottom", ("start_y_mm", "end_y_mm")), ("top", ("start_x_mm", "end_x_mm"))):
        for bar in [x for x in b["bars"] if x["layer"] == "lower" and x["level"] == lv][:2]:
            for k in keys:
                bar[k] += 6.0
            bar["one_sided_share"] = 1.0
    reg, why = register(a, b, 0.25 * SPACING)
    assert reg is not None, why
    for p in ([0.0, 0.0], [150.0, -80.0]):
        assert np.allclose(reg.to_b(np.array(p)), np.array(p) + np.array([100.0, 0.0]), atol=0.5)


@pytest.mark.parametrize("present", [True, False])
def test_a_hidden_position_is_judged_by_the_capture_that_shows_it(present):
    rng = np.random.default_rng(6)
    xs, ys = _irregular(9, rng, 4.0), _irregular(9, rng, 4.0)
    hidden = ys["lower"][4]
    view_a, view_b = ((-500, 300), (-450, 400)), ((-400, 420), (-350, 480))
    a = _capture("A", xs, ys, view_a, positions=[("lower", "bottom", hidden)])
    # A found no bar at the hidden place: drop its lower bottom bar there
    a["bars"] = _without_lower_bottom(a["bars"], hidden)
    if present:
        b = _capture("B", xs, ys, view_b, shift=(30.0, 0.0))
    else:
        b = _capture("B", xs, ys, view_b, shift=(30.0, 0.0))
        b["bars"] = _without_lower_bottom(b["bars"], hidden)
        miss = copy.deepcopy(_capture("B", xs, ys, view_b, shift=(30.0, 0.0), positions=[("lower", "bottom", hidden)]))
        p = miss["positions"][0]
        p["status"], p["reason"] = "missing", "seen empty along 400 mm"
        b["positions"] = [p]
    before = copy.deepcopy(a)
    out, notes = resolve_across([a, b])
    assert a == before  # the results given are not changed
    pos = out[0]["positions"][0]
    assert pos["status"] == ("present" if present else "missing")
    assert pos["judged_in"] == "B"
    count = next(c for c in out[0]["counts"] if (c["layer"], c["level"]) == ("lower", "bottom"))
    assert count["not_measured"] == 0
    assert count["missing"] == (0 if present else 1)
    assert any("is present in capture B" in n or "is missing in capture B" in n for n in notes)


def _two_sized_captures():
    """The paper design and two overlapping captures A and B of one irregular mesh, every bar
    sized at its design size."""
    from rebarlib.data import paper_design

    design = paper_design()
    rng = np.random.default_rng(8)
    xs, ys = _irregular(9, rng, 4.0), _irregular(9, rng, 4.0)
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)))
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)), shift=(30.0, 0.0))
    for r in (a, b):
        for bar in r["bars"]:
            dd = design.lattice(bar["layer"]).level(bar["level"]).diameter_mm
            bar.update(
                design_diameter_mm=dd,
                nominal_mm=dd,
                diameter_status="measured",
                diameter_reason="",
                visible_length_mm=600.0,
                hidden=False,
            )
    return design, a, b


def test_a_bar_not_sized_in_one_capture_is_checked_where_another_sized_it():
    from rebarlib import evaluate

    design, a, b = _two_sized_captures()
    # a lower bottom bar of A near the middle, which B shows too, could not be sized in A
    k = next(
        i
        for i, bar in enumerate(a["bars"])
        if (bar["layer"], bar["level"]) == ("lower", "bottom") and abs(bar["start_y_mm"]) < 120
    )
    a["bars"][k].update(
        nominal_mm=None, diameter_status="not measured", diameter_reason="ambiguous between Φ12 and Φ14"
    )
    acc = evaluate([a, b], design)
    cp = acc.checkpoints
    row = cp[(cp["capture"] == "A") & (cp["what"] == f"bar {k}") & cp["item"].str.startswith("bar_size")].iloc[0]
    assert row["status"] == "excluded"
    assert row["reason"].startswith("sized in capture B")
    assert acc.items.set_index("item").loc["bar_size_lower_bottom", "verdict"] == "pass"
    # alone, capture A leaves that item incomplete
    alone = evaluate([a], design)
    assert alone.items.set_index("item").loc["bar_size_lower_bottom", "verdict"] not in ("pass", "fail")


@pytest.mark.parametrize("gap", [100.0, 350.0])
def test_a_bar_seen_over_another_stretch_in_a_placed_capture_is_the_same_bar(gap):
    """Two placed captures that see different stretches of one bar (a capture taken from closer,
    aimed at the bar, shows its middle; the first one end): across a gap shorter than the
    shortest lap (200 mm, decision 041) it is the same bar, so the size read in one checks it
    in the other; across a longer gap another bar, lapped to it there, could be the one seen, and
    nothing is passed."""
    from rebarlib import evaluate

    design, a, b = _two_sized_captures()
    k = next(
        i
        for i, bar in enumerate(a["bars"])
        if (bar["layer"], bar["level"]) == ("lower", "bottom") and abs(bar["start_y_mm"]) < 120
    )
    y = a["bars"][k]["start_y_mm"]
    a["bars"][k].update(
        start_x_mm=-500.0,
        end_x_mm=-350.0,
        nominal_mm=None,
        diameter_status="not measured",
        diameter_reason="ambiguous between Φ12 and Φ14",
    )
    twin = next(
        bar
        for bar in b["bars"]
        if (bar["layer"], bar["level"]) == ("lower", "bottom") and abs(bar["start_y_mm"] - y) < 1e-6
    )
    twin["start_x_mm"] = -350.0 + gap + 30.0  # (B's frame is shifted by 30 mm)
    acc = evaluate([a, b], design)
    cp = acc.checkpoints
    row = cp[(cp["capture"] == "A") & (cp["what"] == f"bar {k}") & cp["item"].str.startswith("bar_size")].iloc[0]
    if gap < 200.0:
        assert row["status"] == "excluded" and row["reason"].startswith("sized in capture B")
    else:
        assert row["status"] == "not measured"


def test_a_bar_sized_nowhere_stays_not_measured_beside_one_sized_elsewhere():
    """One bar of capture A sized in B gives A's bars table a ``sized_in`` column; another bar of
    A that no capture sized reads NaN there and must stay not measured (a NaN is truthy: it once
    excluded the bar, and the benchmark's wrong-size bar of slab 041 with it, as if sized elsewhere)."""
    from rebarlib import evaluate

    design, a, b = _two_sized_captures()
    lower_bottom = [i for i, bar in enumerate(a["bars"]) if (bar["layer"], bar["level"]) == ("lower", "bottom")]
    k = min(lower_bottom, key=lambda i: abs(a["bars"][i]["start_y_mm"]))  # B sizes it
    k2 = max(lower_bottom, key=lambda i: abs(a["bars"][i]["start_y_mm"] - a["bars"][k]["start_y_mm"]))
    for i in (k, k2):
        a["bars"][i].update(nominal_mm=None, diameter_status="not measured", diameter_reason="possible wrong size")
    # B did not size the bar k2 is either (or does not show it)
    at = a["bars"][k2]["start_y_mm"]
    for bar in b["bars"]:
        if (bar["layer"], bar["level"]) == ("lower", "bottom") and abs(bar["start_y_mm"] - at) < 60:
            bar.update(nominal_mm=None, diameter_status="not measured", diameter_reason="possible wrong size")
    acc = evaluate([a, b], design)
    cp = acc.checkpoints.set_index(["capture", "what"])
    assert cp.loc[("A", f"bar {k}")]["status"] == "excluded"
    assert cp.loc[("A", f"bar {k2}")]["status"] == "not measured"
    assert acc.items.set_index("item").loc["bar_size_lower_bottom", "verdict"] not in ("pass", "fail")
    assert acc.verdict != "accepted"


def _with_spacings(r):
    """Add the measured spacings of every set (consecutive bars across) to a result dict."""
    from rebarlib._across import plan_sets

    r["spacings"] = []
    for (la, lv), st in plan_sets(r).items():
        n = np.array([-st.direction[1], st.direction[0]])
        offs = st.mids @ n
        order = np.argsort(offs)
        for i, j in zip(order[:-1], order[1:]):
            r["spacings"].append(
                {
                    "layer": la,
                    "level": lv,
                    "bar_a": st.bar_ids[i],
                    "bar_b": st.bar_ids[j],
                    "spacing_mm": float(offs[j] - offs[i]),
                    "design_spacing_mm": SPACING,
                    "status": "measured",
                }
            )
    return r


def test_a_spacing_two_captures_measured_counts_once():
    from rebarlib import evaluate
    from rebarlib.data import paper_design

    rng = np.random.default_rng(9)
    xs, ys = _irregular(9, rng, 4.0), _irregular(9, rng, 4.0)
    a = _with_spacings(_capture("A", xs, ys, ((-500, 300), (-450, 400))))
    b = _with_spacings(_capture("B", xs, ys, ((-400, 420), (-350, 480)), shift=(30.0, 0.0)))
    acc = evaluate([a, b], paper_design())
    cp = acc.checkpoints
    sp = cp[cp["item"] == "spacing_lower_bottom"]
    # lower bottom bars: A sees y in (-450, 400), B in (-350, 480): the spacings between bars both
    # see are B's duplicates
    both = [y for y in ys["lower"] if -350 <= y <= 400]
    dup = sp[(sp["capture"] == "B") & (sp["status"] == "excluded")]
    assert len(dup) == len(both) - 1
    assert dup["reason"].str.startswith("the same spacing as in capture A").all()
    assert (sp[sp["capture"] == "A"]["status"] != "excluded").all()
    alone = evaluate([b], paper_design()).checkpoints
    assert (alone["status"] != "excluded").all()


def test_the_gap_of_a_missing_bar_is_judged_under_the_count_not_the_spacing():
    from rebarlib import evaluate
    from rebarlib.data import paper_design

    rng = np.random.default_rng(10)
    xs, ys = _irregular(9, rng, 2.0), _irregular(9, rng, 2.0)
    gone = ys["lower"][4]
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)), positions=[("lower", "bottom", gone)])
    a["bars"] = _without_lower_bottom(a["bars"], gone)
    a["positions"][0].update(status="missing", reason="empty: the support is seen along 700 mm")
    a = _with_spacings(a)
    acc = evaluate([a], paper_design())
    cp = acc.checkpoints
    sp = cp[cp["item"] == "spacing_lower_bottom"]
    gap = sp[sp["status"] == "excluded"]
    assert len(gap) == 1 and gap["reason"].iloc[0].startswith("the gap of the missing bar")
    assert (sp[sp["status"] != "excluded"]["status"] == "within").all()


def _regular_across_bottom(rng):
    """Offsets of a mesh whose bottom bars lie at their design places to a tenth of a millimetre
    (two placings a spacing apart across them fit alike) and whose top bars are irregular."""
    return _irregular(9, rng, 4.0), _irregular(9, rng, 0.05)


def _aimed(b, at, bar_id):
    b.setdefault("extras", {})["aimed_at"] = {"capture": at, "bar_id": bar_id}
    return b


def _lower_bottom_id(r, y):
    """The id of the lower bottom bar of capture ``r`` (unturned, ``shift`` (sx, sy)) at mesh offset ``y``."""
    return next(
        b["bar_id"]
        for b in r["bars"]
        if (b["layer"], b["level"]) == ("lower", "bottom") and abs(-b["start_y_mm"] - (y + r["_sy"])) < 1e-6
    )


def _pair_regular_across_bottom(b_shift):
    rng = np.random.default_rng(11)
    xs, ys = _regular_across_bottom(rng)
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)))
    a["_sy"] = 0.0
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)), shift=b_shift)
    return xs, ys, a, b


def test_a_capture_aimed_at_a_bar_is_placed_where_it_was_aimed():
    # B's optical axis (its plan origin: a camera looking straight down) meets the mesh at
    # -shift: 12 mm beside the lower bottom bar at ys["lower"][4] (about 0), a hand's aim
    shift = (20.0, -12.0)
    xs, ys, a, b = _pair_regular_across_bottom(shift)
    reg, why = register(a, b, 0.25 * SPACING)
    assert reg is None and "too regular" in why  # the bars alone cannot tell
    k = _lower_bottom_id(a, ys["lower"][4])
    out, notes = resolve_across([a, _aimed(copy.deepcopy(b), "A", k)])
    placed = [n for n in notes if n.startswith("Captures A and B overlap")]
    assert placed and "chosen by the aim of capture B" in placed[0], notes
    assert "not_placed_on" not in (out[0].get("extras") or {})
    reg, why = register(a, _aimed(copy.deepcopy(b), "A", k), 0.25 * SPACING)
    assert reg is not None, why
    for p in ([0.0, 0.0], [150.0, -80.0]):  # the true placing, not one a spacing off
        assert np.allclose(reg.to_b(np.array(p)), np.array(p) + np.array(shift), atol=0.5)


@pytest.mark.parametrize("aim_y", [-100.0, -60.0])
def test_an_ambiguous_aim_leaves_the_captures_unplaced(aim_y):
    # the optical axis midway between two bars, or farther from the nearest than a quarter spacing
    xs, ys, a, b = _pair_regular_across_bottom((20.0, aim_y))
    k = _lower_bottom_id(a, ys["lower"][4])
    out, notes = resolve_across([a, _aimed(b, "A", k)])
    assert not any(n.startswith("Captures A and B overlap") for n in notes)
    assert out[0]["extras"]["not_placed_on"] == ["B"]
    why = next(n for n in notes if n.startswith("Captures A and B are not placed"))
    assert "too regular" in why and "aimed at bar" in why and "hand's aim error" in why


def test_an_aim_never_overrides_a_placing_the_bars_make():
    rng = np.random.default_rng(3)
    xs, ys = _irregular(9, rng, 4.0), _irregular(9, rng, 4.0)
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)))
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)), shift=(35.0, -12.0))
    # aimed (wrongly) at the bar a spacing away: the bars' own placing stands
    a["_sy"] = 0.0
    k = _lower_bottom_id(a, ys["lower"][5])
    out, notes = resolve_across([a, _aimed(b, "A", k)])
    placed = [n for n in notes if n.startswith("Captures A and B overlap")]
    assert placed and "chosen by the aim" not in placed[0]


def _pair_regular(b_shift):
    rng = np.random.default_rng(12)
    xs, ys = _irregular(9, rng, 0.05), _irregular(9, rng, 0.05)
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)))
    a["_sy"] = 0.0
    return xs, ys, a, _capture("B", xs, ys, ((-400, 420), (-350, 480)), shift=b_shift)


@pytest.mark.parametrize("aim_x, placed", [(-100.0, True), (-40.0, True), (0.0, False)])
def test_on_a_mesh_regular_both_ways_the_aim_along_the_bar_chooses_too(aim_x, placed):
    # the lower bottom bar at y about 0 runs along x; A saw it over x -500..300 (its middle -100);
    # B's optical axis meets the mesh at -shift: 0 or 60 mm along from that middle (within a
    # hand's 3/8 of the 200 mm crossing spacing), or 100 mm (not)
    shift = (-aim_x, -12.0)
    xs, ys, a, b = _pair_regular(shift)
    assert register(a, b, 0.25 * SPACING)[0] is None
    k = _lower_bottom_id(a, ys["lower"][4])
    reg, why = register(a, _aimed(b, "A", k), 0.25 * SPACING)
    if not placed:
        assert reg is None and "along the bar" in why and "more than 75 mm" in why
        return
    assert reg is not None and "across and along it" in reg.aimed, why
    for p in ([0.0, 0.0], [150.0, -80.0]):
        assert np.allclose(reg.to_b(np.array(p)), np.array(p) + np.array(shift), atol=0.5)


def _rot2(a):
    c, s = math.cos(a), math.sin(a)
    return np.array([[c, -s], [s, c]])


def _three_in_a_row(order):
    """Captures A and B of an irregular mesh that do not overlap (their bars alone cannot place
    them), and C overlapping both; turned and shifted apart; in the ``order`` given."""
    rng = np.random.default_rng(21)
    xs, ys = _irregular(15, rng, 4.0), _irregular(15, rng, 4.0)
    pose = {"A": (0.1, (15.0, -8.0)), "B": (-0.3, (40.0, 25.0)), "C": (0.5, (-20.0, 10.0))}
    view = {"A": ((-1400, -300), (-300, 250)), "B": ((300, 1400), (-250, 300)), "C": ((-800, 800), (-300, 300))}
    caps = {n: _capture(n, xs, ys, view[n], turn=pose[n][0], shift=pose[n][1]) for n in "ABC"}
    return [caps[n] for n in order], pose


@pytest.mark.parametrize("order", ["ABC", "CAB", "BCA"])
def test_two_captures_are_placed_through_a_third_placed_on_both(order):
    results, pose = _three_in_a_row(order)
    a, b = (next(r for r in results if r["capture"] == n) for n in "AB")
    reg, why = register(a, b, 0.25 * SPACING)
    assert reg is None and "no placing fits" in why  # their bars alone cannot place them
    out, notes = resolve_across(results)
    first, second = sorted("AB", key=order.index)
    placed = [n for n in notes if n.startswith(f"Captures {first} and {second} are placed on each other through")]
    assert placed and "capture C" in placed[0] and "they show different bars" in placed[0], notes
    # placed: a lot rule counts their spacings as the placings say (decision 039 settled)
    assert all("not_placed_on" not in (r.get("extras") or {}) for r in out)
    assert not unplaced_pairs(out)


def test_the_placing_through_a_third_is_the_true_one():
    from rebarlib import _across

    for order in ("ABC", "CAB", "BCA"):
        results, pose = _three_in_a_row(order)
        sets = [_across.plan_sets(r) for r in results]
        names = [r["capture"] for r in results]
        regs, refused, notes = {}, {}, []
        for i in range(3):
            for j in range(i + 1, 3):
                reg, why = _across._register(sets[i], sets[j], 0.25 * SPACING, names[i], names[j])
                if reg is not None:
                    regs[(i, j)] = reg
                else:
                    refused[(i, j)] = why
        assert len(regs) == 2 and len(refused) == 1
        _across._through_a_third(regs, refused, sets, names, 0.25 * SPACING, notes)
        ((i, j),) = refused
        reg = regs[(i, j)]
        assert reg.through == "C"
        (ta, sa), (tb, sb) = pose[names[i]], pose[names[j]]
        for p in ([0.0, 0.0], [600.0, -80.0], [-900.0, 120.0]):  # mesh points, seen in i's plan frame
            x_i = _rot2(ta) @ np.array(p) + np.array(sa)
            assert np.allclose(reg.to_b(x_i), _rot2(tb) @ np.array(p) + np.array(sb), atol=1.0)


def test_a_placing_through_a_third_that_contradicts_the_pair_own_bars_is_refused(monkeypatch):
    from rebarlib import _across

    # A and B overlap but (stood in) their bars alone are refused as too regular; C's placings
    # compose to a placing half a spacing off: A's bars land between B's, in B's view
    rng = np.random.default_rng(3)
    xs, ys = _irregular(9, rng, 4.0), _irregular(9, rng, 4.0)
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)))
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)))
    c = _capture("C", xs, ys, ((-450, 350), (-400, 450)))
    off = 0.5 * SPACING
    legs = {
        ("A", "C"): _across.Registration("A", "C", np.eye(2), np.array([off, off]), 9, 0.1, 20.0),
        ("B", "C"): _across.Registration("B", "C", np.eye(2), np.zeros(2), 9, 0.1, 20.0),
    }

    def stand_in(sa, sb, g, na, nb, aim=None):
        got = legs.get((na, nb))
        return (got, "") if got is not None else (None, _across._TOO_REGULAR)

    monkeypatch.setattr(_across, "_register", stand_in)
    out, notes = resolve_across([a, b, c])
    assert any(n.startswith("Captures A and B are not placed through capture C") for n in notes), notes
    assert out[0]["extras"]["not_placed_on"] == ["B"]
    # composed right, the same pair is placed through C, its own bars matched under the placing
    legs[("A", "C")] = _across.Registration("A", "C", np.eye(2), np.zeros(2), 9, 0.1, 20.0)
    out, notes = resolve_across([a, b, c])
    placed = next(n for n in notes if n.startswith("Captures A and B are placed on each other through capture C"))
    assert "of their own bars matched under it" in placed and "too regular" in placed
    assert not unplaced_pairs(out)

    # a pair refused for what its bars contradict is never chained
    def contradicted(sa, sb, g, na, nb, aim=None):
        got = legs.get((na, nb))
        return (got, "") if got is not None else (None, "the bars' directions turn by different angles (3.0° apart)")

    monkeypatch.setattr(_across, "_register", contradicted)
    out, notes = resolve_across([a, b, c])
    assert out[0]["extras"]["not_placed_on"] == ["B"]
    assert not any("through capture C" in n for n in notes)


def _nearest_by_search(seg, other, d, n):
    """The bar of ``other`` nearest ``seg`` across ``d`` by a search over every bar, one at a time,
    as the placing once paired them: ``(offset, j)``, or ``(None, -1)`` where none may pair."""
    from rebarlib._across import MAX_GAP_MM, _offset_at

    best, jb = None, -1
    lo, hi = sorted(seg @ d)
    for j, o in enumerate(other):
        olo, ohi = sorted(o @ d)
        a0, a1 = max(lo, olo), min(hi, ohi)
        if a1 - a0 < -MAX_GAP_MM:
            continue
        sm = 0.5 * (a0 + a1)
        r = _offset_at(o, sm, d, n) - _offset_at(seg, sm, d, n)
        if best is None or abs(r) < abs(best):
            best, jb = r, j
    return best, jb


def test_each_bar_pairs_with_the_bar_a_full_search_finds():
    """The pairing of a bar with the other capture's bars (``_pairs``, all of them at once) gives
    the pair a search over every bar, one at a time, gives, to the bit: the same partner and the
    same offset, ties included (bars at the same offset, segments along the direction and across
    it, gaps and overlaps)."""
    from rebarlib._across import _pairs

    rng = np.random.default_rng(5)
    for angle in (0.3, 1.2, 2.9):
        d = np.array([math.cos(angle), math.sin(angle)])
        n = np.array([-d[1], d[0]])
        for _ in range(40):

            def segs(k):
                s0 = rng.uniform(-400, 400, k)
                s1 = s0 + rng.uniform(-600, 600, k) * rng.choice([1.0, 1.0, 1e-9], k)  # some across d
                off = np.round(rng.uniform(-300, 300, k) / 50) * 50 + rng.choice([0.0, 0.4], k)  # ties
                tilt = rng.choice([0.0, 1e-3, 0.05], k)
                a = s0[:, None] * d + off[:, None] * n
                b = s1[:, None] * d + (off + tilt * (s1 - s0))[:, None] * n
                return np.stack([a, b], axis=1)

            mine, other = segs(rng.integers(1, 9)), segs(rng.integers(1, 9))
            got_r, got_j = _pairs(mine, other, d, n)
            for i, seg in enumerate(mine):
                full_best, full_j = _nearest_by_search(seg, other, d, n)
                if full_best is None:
                    assert got_j[i] == -1 and math.isnan(got_r[i])
                else:
                    assert (float(got_r[i]), int(got_j[i])) == (full_best, full_j)


def test_shift_candidates_match_a_bar_by_bar_search():
    """``_fit_shift`` (each shift's bars matched all at once) gives the shifts, counts and RMS that
    matching one bar at a time gives, to the bit, and ``_conflicts`` the same count."""
    from rebarlib._across import _conflicts, _fit_shift

    def conflicts_ref(pairs, tau, gate):
        n = 0
        for u, uo, o, oo in pairs:
            for mine, mine_open, other in ((o, oo, u + tau), (u + tau, uo + tau, o)):
                allx = np.concatenate([mine, mine_open])
                if not len(allx):
                    continue
                lo, hi = allx.min() - gate, allx.max() + gate
                n += sum(1 for x in other[(other > lo) & (other < hi)] if not np.any(np.abs(allx - x) < gate))
        return n

    def fit_shift_ref(pairs, gate, fitted):
        cands = np.unique(np.round(np.concatenate([(o[None, :] - u[:, None]).ravel() for u, _, o, _ in pairs]), 1))
        seen = []
        for tau in cands:
            if any(abs(tau - t2) < gate for _, _, t2 in seen):
                continue
            for _ in range(2):
                res, res_f = [], []
                for (u, _, o, _), (fu, fo) in zip(pairs, fitted):
                    for i, x in enumerate(u + tau):
                        j = np.argmin(np.abs(o - x))
                        if abs(o[j] - x) < gate:
                            res.append(o[j] - x)
                            if fu[i] and fo[j]:
                                res_f.append(o[j] - x)
                if not res:
                    break
                tau = tau + float(np.mean(res_f or res))
            if not res or any(abs(tau - t2) < gate for _, _, t2 in seen) or conflicts_ref(pairs, tau, gate):
                continue
            r = np.asarray(res_f or res)
            seen.append((float(np.sqrt(np.mean(r**2))), len(res), float(tau)))
        seen.sort(key=lambda x: (-x[1], x[0]))
        return seen

    rng = np.random.default_rng(11)
    for _ in range(40):
        pairs, fitted = [], []
        for _set in range(rng.integers(1, 3)):
            sp = rng.uniform(100, 250)
            row = np.arange(12) * sp + rng.normal(0, 3, 12)
            a, b = rng.integers(0, 6), rng.integers(6, 12)
            shift = rng.uniform(-300, 300)
            u, o = row[a:b] - shift, row[rng.integers(0, 4) : rng.integers(8, 13)]
            u, o = np.delete(u, rng.integers(0, len(u), rng.integers(0, 2))), o
            uo, oo = row[:0] + rng.uniform(-500, 500, rng.integers(0, 2)), row[:0]
            pairs.append((u, uo, o, oo))
            fitted.append((rng.random(len(u)) > 0.2, rng.random(len(o)) > 0.2))
        gate = 0.25 * 100
        assert _fit_shift(pairs, gate, fitted) == fit_shift_ref(pairs, gate, fitted)
        for tau in rng.uniform(-300, 300, 5):
            assert _conflicts(pairs, tau, gate) == conflicts_ref(pairs, tau, gate)


def test_placings_tried_together_fit_as_one_at_a_time():
    """``_joint_fits`` (every placing of a rotation at once) gives, for each placing, the fit that
    pairing one bar at a time with every bar of the other capture gives, to the bit: the same RMS
    and counts of both kinds of pairs, and None for the same placings (a bar of one capture in the
    other's view with nothing there)."""
    from rebarlib._across import MIN_CONFLICT_MM, _inside, _joint_fits, _layer_hulls, _perp, _rot, _Set

    def ref_fit(sa, sb, groups, R, t, hull_a, hull_b, gate):
        rms, cnt, unfitted = [], [], []
        for d, ks in groups:
            n = _perp(d)
            res, res_u = [], []
            for k in ks:
                A, B = sa[k].segs @ R.T + t, sb[k].segs
                open_b, open_a = sb[k].open_mids @ n, (sa[k].open_mids @ R.T + t) @ n
                h_b, h_a = hull_b.get(k[0]), hull_a.get(k[0])
                h_a = None if h_a is None else h_a @ R.T + t
                fa, fb = sa[k].fitted, sb[k].fitted
                for mine, other, hull, opens, f_mine, f_other in (
                    (A, B, h_b, open_b, fa, fb),
                    (B, A, h_a, open_a, fb, fa),
                ):
                    for i, seg in enumerate(mine):
                        best, jb = _nearest_by_search(seg, other, d, n)
                        if best is not None and abs(best) < gate:
                            if mine is A:
                                (res if f_mine[i] and f_other[jb] else res_u).append(best)
                            continue
                        if hull is None:
                            continue
                        pts = seg[0] + np.linspace(0, 1, 41)[:, None] * (seg[1] - seg[0])
                        seen = _inside(pts, hull).mean() * np.linalg.norm(seg[1] - seg[0])
                        if seen >= MIN_CONFLICT_MM and not np.any(np.abs(opens - float(seg.mean(axis=0) @ n)) < gate):
                            return None
            rms.append(float(np.sqrt(np.mean(np.square(res)))) if res else math.inf)
            cnt.append(len(res))
            unfitted.append((float(np.sqrt(np.mean(np.square(res_u)))) if res_u else math.inf, len(res_u)))
        return rms, cnt, unfitted

    rng = np.random.default_rng(23)

    def window(offs, x0, y0, w, h, to_frame):
        """The upper lattice's two sets of bars seen over a w x h window (slab frame), in a
        capture's plan frame (``to_frame``), with a tenth of the bars unfound and some open
        positions."""
        out = {}
        for key, d, o in (
            (("upper", "top"), np.array([1.0, 0.0]), offs[0]),
            (("upper", "bottom"), np.array([0.0, 1.0]), offs[1]),
        ):
            n = _perp(d)
            lo, hi = (x0, x0 + w) if d[0] else (y0, y0 + h)
            o = o[(o > (y0 if d[0] else x0)) & (o < (y0 + h if d[0] else x0 + w))]
            segs = to_frame(np.stack([np.outer(o, n) + lo * d, np.outer(o, n) + hi * d], axis=1))
            segs = segs + rng.normal(0, 0.3, segs.shape)
            keep = rng.random(len(segs)) > 0.1
            fitted = rng.random(int(keep.sum())) > 0.2
            out[key] = _Set(
                key,
                d,
                segs[keep].mean(axis=1),
                list(range(int(keep.sum()))),
                segs[keep],
                segs[~keep].mean(axis=1),
                fitted,
            )
        return out

    checked = nones = 0
    for _ in range(12):
        sp = rng.uniform(120, 220)
        offs = [np.arange(-8, 9) * sp + rng.normal(0, 4, 17) for _ in range(2)]
        R = _rot(rng.normal(0, 0.01))
        t_true = rng.uniform(-150, 150, 2)
        sb = window(offs, -450, -300, 900, 600, lambda p: p)
        sa = window(offs, t_true[0] - 400, t_true[1] - 250, 800, 500, lambda p: (p - t_true) @ R)
        keys = list(sb)
        groups = [(sb[keys[0]].direction, [keys[0]]), (sb[keys[1]].direction, [keys[1]])]
        ha, hb = _layer_hulls(sa), _layer_hulls(sb)
        steps = np.array([[i, j] for i in (-1, 0, 1) for j in (-1, 0, 1)]) * sp
        ts = np.vstack([t_true + steps + rng.normal(0, 1, steps.shape), rng.uniform(-300, 300, (6, 2))])
        got = _joint_fits(sa, sb, groups, R, ts, ha, hb, 0.25 * sp)
        for t, fit in zip(ts, got):
            want = ref_fit(sa, sb, groups, R, t, ha, hb, 0.25 * sp)
            assert fit == want
            checked += 1
            nones += want is None
    assert nones and nones < checked  # both kinds of placing were compared


@pytest.mark.parametrize(
    "gap, length, judged", [(100.0, 250.0, True), (-80.0, 250.0, True), (350.0, 250.0, False), (100.0, 100.0, False)]
)
def test_a_hidden_position_is_present_where_a_placed_capture_sees_its_bar_further_along(gap, length, judged):
    """A position hidden in capture A, whose bar capture B sees only beyond A's stretch of it (or
    overlapping it by less than a position's verdict needs): on the same line across a gap
    shorter than the shortest lap (200 mm) it is the same bar, so the position is present, where
    B sees that bar over a verdict's length (150 mm); across a longer gap, or on a shorter stretch,
    it stays not measured (decision 059)."""
    rng = np.random.default_rng(6)
    xs, ys = _irregular(9, rng, 4.0), _irregular(9, rng, 4.0)
    hidden = ys["lower"][4]
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)), positions=[("lower", "bottom", hidden)])
    a["bars"] = _without_lower_bottom(a["bars"], hidden)
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)), shift=(30.0, 0.0))
    twin = next(
        bar
        for bar in b["bars"]
        if (bar["layer"], bar["level"]) == ("lower", "bottom") and abs(-bar["start_y_mm"] - hidden) < 1e-6
    )
    # A's position runs to x = 300 (mesh); B's frame is shifted by 30 mm
    twin["start_x_mm"] = 300.0 + gap + 30.0
    twin["end_x_mm"] = twin["start_x_mm"] + length
    out, _ = resolve_across([a, b])
    pos = out[0]["positions"][0]
    if judged:
        assert pos["status"] == "present" and pos["judged_in"] == "B"
        assert pos["reason"].startswith("judged in capture B: bar")
    else:
        assert pos["status"] == "not measured" and "judged_in" not in pos


def test_a_place_seen_empty_only_further_along_does_not_make_a_hidden_position_missing():
    """Evidence of an empty place is taken only where it overlaps the hidden stretch by a
    verdict's length: a bar may begin just beyond an empty stretch (decision 059)."""
    rng = np.random.default_rng(6)
    xs, ys = _irregular(9, rng, 4.0), _irregular(9, rng, 4.0)
    hidden = ys["lower"][4]
    a = _capture("A", xs, ys, ((-500, 0), (-450, 400)), positions=[("lower", "bottom", hidden)])
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)), shift=(30.0, 0.0))
    for r in (a, b):
        r["bars"] = _without_lower_bottom(r["bars"], hidden)
    miss = _capture("B", xs, ys, ((100, 420), (-350, 480)), shift=(30.0, 0.0), positions=[("lower", "bottom", hidden)])
    p = miss["positions"][0]
    p["status"], p["reason"] = "missing", "seen empty along 320 mm"
    b["positions"] = [p]
    out, _ = resolve_across([a, b])
    assert out[0]["positions"][0]["status"] == "not measured"


@pytest.mark.parametrize("status, placed", [("not in view", True), ("outside the mesh", False)])
def test_a_bar_where_the_other_capture_saw_no_position_in_view_does_not_veto_the_placing(status, placed):
    # A's lower bottom bar at y = -250 lies along A's image border: A found no bar there and its
    # position reads "not in view", though A's other bars reach past it (its view's hull). B
    # shows that bar: it is no conflict (docs/decisions/069). Where A saw the mesh end there
    # instead ("outside the mesh"), a bar of B there contradicts the placing, as before.
    rng = np.random.default_rng(3)
    xs, ys = _irregular(9, rng, 4.0), _irregular(9, rng, 4.0)
    y = float(ys["lower"][np.argmin(np.abs(ys["lower"] + 250.0))])
    a = _capture("A", xs, ys, ((-500, 300), (-450, 400)), positions=[("lower", "bottom", y)])
    a["bars"] = _without_lower_bottom(a["bars"], y)
    a["positions"][0]["status"] = status
    b = _capture("B", xs, ys, ((-400, 420), (-350, 480)), turn=0.4, shift=(35.0, -12.0))
    reg, why = register(a, b, 0.25 * SPACING)
    assert (reg is not None) == placed, why
    if placed:
        c, s = math.cos(0.4), math.sin(0.4)
        want = np.array([[c, -s], [s, c]]) @ np.array([150.0, -80.0]) + np.array([35.0, -12.0])
        assert np.allclose(reg.to_b(np.array([150.0, -80.0])), want, atol=0.5)
