"""The verdicts of a slab's acceptance (:func:`rebarlib.acceptance.evaluate`): each item's from
its checkpoints and lot rule (pass / fail / incomplete / not measured), the slab's from its items,
and each bar's for the plan view; with the design values the items are judged against.
"""

from __future__ import annotations

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


def _item_row(key: str, cp: pd.DataFrame, design: Design, tol: Tolerances, labels: dict) -> dict:
    t = tol.item(_tol_key(key))
    rule = tol.rule(t.lot_rule)
    dv = _design_value(key, design)
    counted = cp[cp["status"] != EXCLUDED]
    measured = counted[counted["status"] != NOT_MEASURED]
    n, n_meas = len(counted), len(measured)
    passed = int((measured["status"] == WITHIN).sum())
    n_beyond_max = int((measured["status"] == BEYOND_MAX).sum())
    n_not_proven = int(measured["decision"].isin([WITHIN_NP, BEYOND_NP]).sum()) if "decision" in measured else 0
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
        ok_ratio = passed >= rule.min_pass_ratio * n_meas - _EPS
        ok_max = rule.max_factor is None or n_beyond_max == 0
        verdict = PASS if ok_ratio and ok_max else FAIL
        why = []
        if not ok_ratio:
            why.append(f"{passed}/{n_meas} within tolerance, below {rule.min_pass_ratio:.0%}")
        if not ok_max:
            why.append(f"{n_beyond_max} checkpoint(s) beyond {rule.max_factor:g}× the tolerance")
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
