"""The verdicts of a slab's acceptance (:func:`rebarlib.acceptance.evaluate`): each item's from
its checkpoints and lot rule (pass / fail / incomplete / not measured), the slab's from its items,
and each bar's for the plan view; with the design values the items are judged against.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pandas as pd

from ._decision import BEYOND_NP, WITHIN_NP
from ._design import Design
from ._status import (
    ACCEPTED,
    BEYOND,
    BEYOND_MAX,
    EXCLUDED,
    FAIL,
    HIDDEN,
    INCOMPLETE,
    NOT_CHECKED,
    NOT_IN_VIEW,
    SAME_SPACING,
    SIZED_ELSEWHERE,
    SPANS_MISSING,
    NOT_MEASURED,
    PASS,
    REJECTED,
    SLAB_INCOMPLETE,
    WITHIN,
)
from ._tolerances import Tolerances

# Deviations come from results rounded to 0.001 mm; a deviation that equals its limit to within
# this is on the limit (inside), so "exactly 1.5x" is not lost to binary rounding.
_EPS = 1e-6


def _size_text(d, system: str) -> str:
    if d is None:
        return "-"
    return f"Φ{d:g}" if str(system).upper().startswith("GB") else f"{d:g} mm"


def _tol_key(item: str) -> str:
    if item.startswith("bar_size_"):
        return "bar_size"
    if item.startswith("bar_count_"):
        return "bar_count"
    return item


def design_top_cover_mm(design: Design) -> float | None:
    """Design top cover over the ribs: thickness - (cover + layer distance + rib envelopes of the
    upper lattice's two bar sizes); ``None`` without a design thickness.

    Cover and layer distance are measured to the bars' rib envelope (docs/method.md), and so is
    the top of the upper bars; judging it against nominal diameters would read a Φ12 mesh ~4 mm
    high on every slab. The envelope is GB 1499.2's d1 + 2h (``rebarlib.diameter.barsizes.rib_envelope_mm``).

    Examples
    --------
    >>> from rebarlib.data import paper_design
    >>> d = paper_design()
    >>> d.top_cover_mm, design_top_cover_mm(d)
    (51.0, 47.2)
    """
    if design.thickness_mm is None:
        return None
    from .diameter.barsizes import rib_envelope_mm

    upper = design.upper
    top = (
        design.cover_mm
        + design.layer_distance_mm
        + rib_envelope_mm(upper.bottom.diameter_mm)
        + rib_envelope_mm(upper.top.diameter_mm)
    )
    return round(design.thickness_mm - top, 3)


def _design_value(item: str, design: Design):
    if item in ("cover", "layer_distance"):
        return getattr(design, f"{item}_mm")
    if item == "top_cover":
        return design_top_cover_mm(design)
    kind, la, lv = item.rsplit("_", 2)
    bs = design.lattice(la).level(lv)
    return bs.spacing_mm if kind == "spacing" else bs.diameter_mm if kind == "bar_size" else None


#: two readings of one spacing may be the same spacing when they differ by no more than this
#: many combined standard uncertainties (the acceptance's coverage factor, rebarlib.acceptance)
TWIN_K = 2.0


def _may_be_same(a: dict, b: dict) -> bool:
    """Whether two measured checkpoints of one item could be one quantity seen twice: their values
    within ``TWIN_K`` combined standard uncertainties (a reading without an uncertainty cannot be
    told from any other)."""
    ua, ub = a.get("uncertainty"), b.get("uncertainty")
    if ua is None or ub is None or not (np.isfinite(ua) and np.isfinite(ub)):
        return True
    return abs(float(a["measured_value"]) - float(b["measured_value"])) <= TWIN_K * float(np.hypot(ua, ub)) + _EPS


#: the most combinations of alignments weighed for one run of spacings; beyond it the bound of
#: a one-to-one matching without the row's order is used (a wider range of readings)
_MAX_COMBOS = 4096


def _runs(rows: list) -> list:
    """The runs of one capture's checkpoints of one item, in the result's order: consecutive
    counted (measured, not excluded) spacings that share a bar (``bars a-b`` then ``bars b-c``).
    Within a run the bars are neighbours in the row; a spacing not measured or excluded ends it
    (it may span one bar not found or more)."""
    runs, cur, prev = [], [], None
    for r in rows:
        ab = str(r["what"])[5:].split("-", 1) if str(r["what"]).startswith("bars ") else [None, None]
        counted = r["status"] in (WITHIN, BEYOND, BEYOND_MAX) and r.get("measured_value") is not None
        if counted and cur and ab[0] == prev:
            cur.append(r)
        else:
            if cur:
                runs.append(cur)
            cur = [r] if counted else []
        prev = ab[-1]
    if cur:
        runs.append(cur)
    return runs


def _alignments(J: list, prev: list) -> list:
    """Every way run ``J`` of a later capture may show the same bars as run ``prev`` of an earlier one:
    the two runs side by side, in the same or the reverse order, overlapping by at least one
    spacing, every overlapping pair of readings possibly the same spacing (:func:`_may_be_same`).
    Where two runs show the same bar pair, they show their neighbours too as far as both runs go,
    so each alignment pairs the whole overlap. Returns ``[[(k in J, record of prev)], ...]``."""
    L, M, out = len(J), len(prev), []
    for rev in (False, True):
        for o in range(-(L - 1), M) if not rev else range(0, L + M - 1):
            pairs = [(k, (o - k) if rev else (k + o)) for k in range(L)]
            pairs = [(k, m) for k, m in pairs if 0 <= m < M]
            if pairs and all(_may_be_same(J[k], prev[m]) for k, m in pairs):
                out.append([(k, prev[m]) for k, m in pairs])
    return out


def _lot_readings(cp: pd.DataFrame, unplaced: set, order: list, r_min: float) -> tuple:
    """The two extreme readings of an item's lot where captures were not placed on each other
    (docs/decisions/039-a-lot-over-captures-not-placed.md): ``(low, high, pairs)``, each reading
    ``(within, counted)``, ``pairs`` the capture pairs that make them differ from the count as
    taken.

    Whether two captures not placed on each other show the same bars is not known (their results
    share no frame, so their views could overlap). A run of a later capture's spacings
    (:func:`_runs`) may repeat a run of an earlier one where :func:`_alignments` allows; each run
    of the later capture takes any one alignment (or none) with each run of each earlier
    capture not placed on it. A spacing seen twice counts once, out of tolerance if either
    reading is (a spacing out as any capture saw it stays out). Dropping a repeat changes
    ``within - r_min * counted`` by ``r_min - 1`` where one of its readings is within and by
    ``r_min`` where both are beyond; ``low`` is the reading that lowers the share most, ``high``
    the one that raises it most, over every combination (or a looser bound past ``_MAX_COMBOS``)."""
    passed = int((cp["status"] == WITHIN).sum())
    counted = int(cp["status"].isin([WITHIN, BEYOND, BEYOND_MAX]).sum())
    if not unplaced or not counted:
        return (passed, counted), (passed, counted), []
    rows = cp.to_dict(orient="records")
    rank = {c: k for k, c in enumerate(order)}
    runs = {c: _runs([r for r in rows if r["capture"] == c]) for c in order}
    lo, hi, pairs = [0, 0], [0, 0], set()  # (within lost, counted lost)
    for cap in order:
        earlier = [
            (c, run) for c in order if rank[c] < rank[cap] and frozenset((cap, c)) in unplaced for run in runs[c]
        ]
        if not earlier:
            continue
        for J in runs[cap]:
            options = [[None] + _alignments(J, run) for _, run in earlier]
            n_combos = math.prod(len(o) for o in options)
            best = worst = (0.0, 0, 0, ())  # (score, within lost, counted lost, captures)
            if n_combos > _MAX_COMBOS:
                # the matching bound: every reading of J that may repeat something, dropped alike
                twins = [any(_may_be_same(x, y) for _, run in earlier for y in run) for x in J]
                n_w = sum(t and x["status"] == WITHIN for t, x in zip(twins, J))
                n_b = sum(t and x["status"] != WITHIN for t, x in zip(twins, J))
                caps = tuple(sorted({c for c, _ in earlier}))
                best, worst = ((1 - r_min) * n_w, n_w, n_w, caps), (-r_min * n_b, 0, n_b, caps)
            else:
                for combo in itertools.product(*options):
                    twin: dict = {}
                    caps = set()
                    for (c, _), al in zip(earlier, combo):
                        for k, rec in al or ():
                            twin.setdefault(k, rec)
                            caps.add(c)
                    a = sum(J[k]["status"] == WITHIN or rec["status"] == WITHIN for k, rec in twin.items())
                    m = len(twin)
                    score = a - r_min * m
                    if score > best[0] + _EPS:
                        best = (score, a, m, tuple(caps))
                    if score < worst[0] - _EPS:
                        worst = (score, a, m, tuple(caps))
            for acc, (_, a, m, caps) in ((lo, best), (hi, worst)):
                acc[0], acc[1] = acc[0] + a, acc[1] + m
                pairs |= {(c, cap) for c in caps}
    return (
        (passed - lo[0], counted - lo[1]),
        (passed - hi[0], counted - hi[1]),
        sorted(pairs, key=lambda p: (rank.get(p[0], 0), rank.get(p[1], 0))),
    )


def _unproven_text(k: int, n_beyond: int, size: bool = False) -> str:
    """How many of an item's checkpoints beyond lie beyond their limit by less than their U (a bar
    size: read as another size at a confidence below the one that proves it, Φ(2) = 0.977)."""
    if size:
        if k == n_beyond == 1:
            return "the bar of another size is read so at a confidence below 0.977"
        return f"{k} of the {n_beyond} bars of another size are read so at a confidence below 0.977"
    if k == n_beyond == 1:
        return "the checkpoint beyond lies beyond its limit by less than its expanded uncertainty U"
    return f"{k} of the {n_beyond} checkpoints beyond lie beyond their limit by less than their expanded uncertainty U"


def _item_row(
    key: str,
    cp: pd.DataFrame,
    design: Design,
    tol: Tolerances,
    labels: dict,
    unplaced: set = frozenset(),
    order: list = (),
) -> dict:
    """One item's row: its checkpoints counted against its lot rule. ``unplaced``: the pairs of
    captures not placed on each other (``rebarlib._across.unplaced_pairs``), ``order`` the
    captures' order: a share rule is then judged under the two extreme readings of whether they
    show the same spacings (:func:`_lot_readings`)."""
    t = tol.item(_tol_key(key))
    rule = tol.rule(t.lot_rule)
    dv = _design_value(key, design)
    counted = cp[cp["status"] != EXCLUDED]
    measured = counted[counted["status"] != NOT_MEASURED]
    n, n_meas = len(counted), len(measured)
    passed = int((measured["status"] == WITHIN).sum())
    n_beyond_max = int((measured["status"] == BEYOND_MAX).sum())
    n_not_proven = int(measured["decision"].isin([WITHIN_NP, BEYOND_NP]).sum()) if "decision" in measured else 0
    # under the "proven" rule a checkpoint beyond its limit by less than U is not settled: the item
    # fails only where it fails with those counted within (docs/uncertainty.md)
    n_beyond_np = (
        int((measured["status"].isin([BEYOND, BEYOND_MAX]) & (measured["decision"] == BEYOND_NP)).sum())
        if "decision" in measured
        else 0
    )
    n_unsettled = n_beyond_np if tol.decision_rule == "proven" else 0
    n_nm = n - n_meas
    ratio = passed / n_meas if n_meas else None
    worst = None
    if n_meas:
        dev = measured["deviation"].astype(float)
        worst = float(dev.iloc[int(np.argmax(np.abs(dev.to_numpy())))])
    reasons = sorted(set(r for r in counted.loc[counted["status"] == NOT_MEASURED, "reason"] if r))
    if n_meas == 0:
        verdict = NOT_MEASURED
        reason = "; ".join(reasons) or "no checkpoints in the results"
    else:
        r_min = rule.min_pass_ratio
        ok_ratio = passed >= r_min * n_meas - _EPS
        ok_max = rule.max_factor is None or n_beyond_max == 0
        verdict = PASS if ok_ratio and ok_max else FAIL
        why = []
        # the share of a lot whose captures were not all placed on each other: judged under both
        # extreme readings of which of their spacings are the same (decision 039)
        spacing = key.startswith("spacing")
        low, high, pairs = (
            _lot_readings(counted, unplaced, list(order), r_min) if spacing else ((passed, n_meas),) * 2 + ([],)
        )
        low_ok = low[0] >= r_min * low[1] - _EPS
        high_ok = high[0] >= r_min * high[1] - _EPS
        # the share as counted lies between the two readings; they differ from it only where a
        # repeat could be dropped that changes the share
        differs = low[0] * n_meas != passed * low[1] or high[0] * n_meas != passed * high[1]
        names = "; ".join(f"{a} and {b}" for a, b in pairs)
        if differs and low_ok != high_ok and ok_max:
            verdict = INCOMPLETE
            why.append(
                f"{passed}/{n_meas} within tolerance as counted, but captures not placed on each other ({names}) "
                f"may show the same spacings: {low[0]}/{low[1]} to {high[0]}/{high[1]} depending on which they "
                f"share, below {r_min:.0%} under one reading and not under the other; a capture placed on both "
                "settles it"
            )
        elif (
            not ok_ratio and ok_max and n_unsettled and high[0] + n_nm + n_unsettled >= r_min * (high[1] + n_nm) - _EPS
        ):
            # under the "proven" rule: the share fails only with checkpoints whose being beyond is
            # not proven (and, as below, with the checkpoints not measured): not a failure on proof
            verdict = INCOMPLETE
            why.append(
                f"{passed}/{n_meas} within tolerance, below {r_min:.0%}; "
                + _unproven_text(n_unsettled, n_meas - passed, key.startswith("bar_size"))
                + " (not proven"
                + (f"; {n_nm} checkpoint(s) not measured" if n_nm else "")
                + "): measuring by hand settles it"
            )
        elif not ok_ratio and ok_max and n_nm and high[0] + n_nm >= r_min * (high[1] + n_nm) - _EPS:
            # A share below the rule's on the measured checkpoints alone is no failure on
            # evidence while the checkpoints not measured could still lift it to the rule's:
            # the item fails only on a share that no reading of them can save (decision 050) —
            # under the reading of captures not placed on each other that leaves the highest
            # share (their repeats dropped; decision 062)
            verdict = INCOMPLETE
            under = (
                f", if captures not placed on each other ({names}) show the same spacings"
                if (high[0], high[1]) != (passed, n_meas)
                else ""
            )
            why.append(
                f"{passed}/{n_meas} within tolerance, below {r_min:.0%}; with the {n_nm} checkpoint(s) not measured "
                f"it could still reach {high[0] + n_nm}/{high[1] + n_nm}{under}: measuring them settles it"
            )
        elif not ok_ratio:
            why.append(f"{passed}/{n_meas} within tolerance, below {r_min:.0%}")
            if differs:
                why.append(f"below it however many spacings of captures not placed on each other ({names}) repeat")
        elif differs:
            why.append(
                f"{passed}/{n_meas} within tolerance ({low[0]}/{low[1]} to {high[0]}/{high[1]} however many spacings "
                f"of captures not placed on each other ({names}) repeat: at least {r_min:.0%} either way)"
            )
        if not ok_max:
            why.append(f"{n_beyond_max} checkpoint(s) beyond {rule.max_factor:g}× the tolerance")
        if verdict == FAIL and n_beyond_np:
            # the sheet says where a failure rests on values beyond their limit by less than their
            # uncertainty: judged on the measured side of the limit, as the rule says, not proven
            why.append(
                _unproven_text(n_beyond_np, n_meas - passed, key.startswith("bar_size"))
                + " (not proven: a hand measurement confirms it)"
            )
        if n_nm:
            why.append(f"{n_nm} of {n} checkpoints not measured ({'; '.join(reasons)})")
            # A rule that needs every checkpoint to comply cannot pass on a part of them.
            if verdict == PASS and rule.min_pass_ratio >= 1.0:
                verdict = INCOMPLETE
        reason = "; ".join(why)
    if key.startswith("bar_size"):
        design_text = _size_text(dv, design.bar_system)
    elif key.startswith("bar_count"):
        exp = counted["design_value"].dropna()
        # The design value of a count is the number of bars of that direction in each capture's view.
        design_text = f"{exp.sum():g} in view" if len(exp) else "as drawn"
        dv = None
    else:
        design_text = f"{dv:g} mm"
    labels_txt = t.labels
    rule_txt = rule.text or f"≥ {rule.min_pass_ratio:.0%} within tolerance"
    return {
        "item": key,
        "label": labels[key],
        "unit": t.unit,
        "design_value": dv,
        "design_text": design_text,
        "tolerance": t.text(dv, thickness_mm=design.thickness_mm),
        "checkpoints": n,
        "measured": n_meas,
        "passed": passed,
        "pass_ratio": None if ratio is None else round(ratio, 4),
        "worst_deviation": None if worst is None else round(worst, 3),
        "beyond": n_meas - passed,
        "beyond_max": n_beyond_max,
        "not_measured": n_nm,
        "excluded": len(cp) - n,
        "verdict": verdict,
        "reason": reason,
        "not_proven": n_not_proven,
        "rule": rule_txt + (f" ({labels_txt})" if labels_txt else ""),
        "clause": t.clause + (f" — {t.note}" if t.note else ""),
    }


def _slab_verdict(items: pd.DataFrame, missing: tuple, *, n_results: int):
    reasons = []
    failed = items[items["verdict"] == FAIL]
    open_ = items[items["verdict"].isin([NOT_MEASURED, INCOMPLETE])]
    for rec in failed.itertuples():
        reasons.append(f"{rec.label}: fails ({rec.reason})")
    for rec in open_.itertuples():
        reasons.append(f"{rec.label}: {rec.verdict} ({rec.reason})")
    for cap, why in missing:
        reasons.append(f"capture {cap}: {why}")
    if n_results == 0:
        reasons.append("no inspection results")
    if len(failed):
        return REJECTED, reasons
    if len(open_) or missing or n_results == 0:
        return SLAB_INCOMPLETE, reasons
    return ACCEPTED, reasons


def _bar_verdicts(bar_rows: list, cp: pd.DataFrame) -> pd.DataFrame:
    """pass / fail / incomplete / not checked / hidden per bar, from the checkpoints that name it
    (a bar with too little of it in view for its size to be checked: "not checked").

    A bar whose own checkpoint (its size) could not be measured is "incomplete" even where its
    spacings are within tolerance, not "pass": an acceptance sheet must not show a bar as passed
    that was only partly checked. A spacing that could not be measured belongs to the pair (often
    to the gap: a bar between them hidden) and is listed with its reason among the checkpoints; it
    does not mark the two bars incomplete."""
    out = []
    per_bar: dict = {}
    own_open: set = set()  # bars whose own checkpoint was not measured
    for rec in cp.itertuples():
        what = str(rec.what)
        if what.startswith("bar "):
            ids = [what[4:]]
            if rec.status == NOT_MEASURED:
                own_open.add((rec.capture, ids[0]))
        elif what.startswith("bars "):
            ids = what[5:].split("-")
        else:
            continue
        status = rec.status
        if status == EXCLUDED and str(rec.reason).startswith((SAME_SPACING, SPANS_MISSING)):
            continue  # judged elsewhere: in another capture, or as the missing bar it spans
        if status == EXCLUDED and str(rec.reason).startswith((NOT_IN_VIEW, SIZED_ELSEWHERE)):
            status = NOT_IN_VIEW  # its size is checked in another capture
        for b in ids:
            per_bar.setdefault((rec.capture, b), []).append(status)
    for b in bar_rows:
        st = per_bar.get((b["capture"], str(b["bar_id"])), [])
        if any(s in (BEYOND, BEYOND_MAX) for s in st):
            v = FAIL
        elif EXCLUDED in st:
            v = HIDDEN
        elif NOT_IN_VIEW in st:  # its size is for another capture to check
            v = NOT_CHECKED
        elif WITHIN in st:
            v = INCOMPLETE if (b["capture"], str(b["bar_id"])) in own_open else PASS
        else:
            v = NOT_CHECKED
        out.append({**b, "verdict": v})
    return pd.DataFrame(out, columns=["capture", "bar_id", "layer", "level", "verdict"])
