"""Acceptance of a slab against its design: tolerance presets as data, checkpoints, lot rules, verdicts.

Pure functions over the result tables of the inspection (``InspectionResult`` or its JSON dict).
Nothing here measures anything: every number judged comes from a result, every limit from a
tolerance file (``rebarlib/presets/*.toml``) or the slab's ``design.toml`` ``[tolerances]`` table.
"""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import pandas as pd

from ._checks import RebarInputError
from ._decision import WITHIN_NP, decide, decide_size, risk_summary
from ._design import Design
from ._results import table_records
from ._status import (
    ACCEPTED,
    AXIS_OUTSIDE,
    BEYOND,
    BEYOND_MAX,
    EXCLUDED,
    HIDDEN,
    MEASURED,
    NOT_IN_VIEW,
    NOT_MEASURED,
    SAME_SPACING,
    SIZED_ELSEWHERE,
    SPANS_MISSING,
    WITHIN,
)

from ._verdicts import _bar_verdicts, _design_value, _item_row, _slab_verdict, _tol_key, design_top_cover_mm

# the tolerances live in their own module; their names stay importable from here
from ._tolerances import (  # noqa: F401
    DEFAULT_PRESET,
    PRESETS_DIR,
    ItemTolerance,
    LotRule,
    Tolerances,
    _tol_text,
    list_presets,
    load_tolerances,
    preset_path,
)

__all__ = [
    "ItemTolerance",
    "LotRule",
    "Tolerances",
    "Acceptance",
    "load_tolerances",
    "list_presets",
    "evaluate",
    "design_top_cover_mm",
    "PRESETS_DIR",
    "CHECKPOINT_COLUMNS",
    "ITEM_COLUMNS",
]

LAYERS, LEVELS = ("lower", "upper"), ("bottom", "top")
#: The flag a Chinese record sheet prints next to a checkpoint beyond its tolerance.
FLAGS = {BEYOND: "*", BEYOND_MAX: "#"}
# Deviations come from results rounded to 0.001 mm; a deviation that equals its limit to within
# this is on the limit (inside), so "exactly 1.5x" is not lost to binary rounding.
_EPS = 1e-6
#: Coverage factor of the expanded uncertainties the decision rules use (rebarlib.uncertainty).
COVERAGE_K = 2.0

CHECKPOINT_COLUMNS = [
    "item",
    "label",
    "capture",
    "layer",
    "level",
    "what",
    "unit",
    "design_value",
    "measured_value",
    "deviation",
    "uncertainty",
    "tolerance",
    "tol_minus",
    "tol_plus",
    "status",
    "flag",
    "reason",
    "expanded_uncertainty",
    "decision",
    "risk",
]
ITEM_COLUMNS = [
    "item",
    "label",
    "unit",
    "design_value",
    "design_text",
    "tolerance",
    "checkpoints",
    "measured",
    "passed",
    "pass_ratio",
    "worst_deviation",
    "beyond",
    "beyond_max",
    "not_measured",
    "excluded",
    "verdict",
    "reason",
    "rule",
    "clause",
    "not_proven",
]

# --------------------------------------------------------------------------------------------
# Evaluation
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Acceptance:
    """The judgement of one slab.

    Attributes
    ----------
    checkpoints : DataFrame, one row per checkpoint (columns ``CHECKPOINT_COLUMNS``)
    items : DataFrame, one row per item (columns ``ITEM_COLUMNS``)
    bars : DataFrame ``capture, bar_id, layer, level, verdict`` (pass / fail / incomplete / not checked /
        hidden; incomplete: its spacings passed but its own size could not be measured)
    verdict : "accepted" | "rejected" | "incomplete"
    reasons : tuple of str, why the verdict is what it is
    """

    checkpoints: pd.DataFrame
    items: pd.DataFrame
    bars: pd.DataFrame
    verdict: str
    reasons: tuple
    tolerances: Tolerances
    results: tuple = field(default=(), repr=False)  # the result dicts judged, in order
    missing_captures: tuple = ()  # (capture, reason)
    notes: tuple = ()

    @property
    def accepted(self) -> bool:
        return self.verdict == ACCEPTED

    def to_dict(self) -> dict:
        return {
            "verdict": self.verdict,
            "reasons": list(self.reasons),
            "standard": self.tolerances.standard,
            "tolerances": self.tolerances.to_dict(),
            "missing_captures": [{"capture": c, "reason": r} for c, r in self.missing_captures],
            "notes": list(self.notes),
            "items": table_records(self.items, digits=None),
            "decision": self.decision_summary(),
            "checkpoints": table_records(self.checkpoints, digits=None),
        }

    def decision_summary(self) -> dict:
        """The decision rule, the checkpoints it left "not proven" and the false accept / false
        reject probabilities it implied (``rebarlib._decision.risk_summary``)."""
        recs = self.checkpoints.to_dict(orient="records") if "decision" in self.checkpoints else []
        return risk_summary(recs, self.tolerances.decision_rule, COVERAGE_K)

    def to_json(self, **kw) -> str:
        return json.dumps(self.to_dict(), indent=kw.pop("indent", 1), ensure_ascii=False, **kw)


def _result_dict(r, i: int) -> dict:
    if hasattr(r, "to_dict") and hasattr(r, "capture"):
        r = r.to_dict()
    if not isinstance(r, dict) or "capture" not in r or "measurements" not in r:
        raise RebarInputError(
            f"results[{i}]: expected an InspectionResult or its to_dict()/result.json "
            "(keys 'capture', 'measurements', 'bars', 'spacings', 'counts')"
        )
    return r


def _table(r: dict, key: str) -> pd.DataFrame:
    recs = r.get(key) or []
    return pd.DataFrame.from_records(recs) if recs else pd.DataFrame()


def _group_records(df: pd.DataFrame, prefix: str, design: Design):
    """``(layer, level, item, design value, record)`` for every row of a result table, grouped by
    lattice and direction in the items' order (item = ``f"{prefix}_{layer}_{level}"``)."""
    for la in LAYERS:
        for lv in LEVELS:
            item = f"{prefix}_{la}_{lv}"
            dv = _design_value(item, design)
            sub = df[(df["layer"] == la) & (df["level"] == lv)] if len(df) else df
            for rec in sub.to_dict(orient="records"):
                yield la, lv, item, dv, rec


def _num(v):
    if v is None or isinstance(v, bool):
        return None
    try:
        v = float(v)
    except (TypeError, ValueError):
        return None
    return v if math.isfinite(v) else None


def is_true(v) -> bool:
    """A table flag that is set: ``True`` / ``np.True_`` / 1, not NaN (an absent column cell).

    Examples
    --------
    >>> is_true(True), is_true(float("nan")), is_true(None)
    (True, False, False)
    """
    return v is not None and not (isinstance(v, float) and math.isnan(v)) and bool(v)


def _judge(deviation, minus, plus, max_factor):
    """Status and flag of one deviation against (minus, plus); limits are inclusive."""
    lo = -math.inf if minus is None else -minus
    hi = math.inf if plus is None else plus
    if lo - _EPS <= deviation <= hi + _EPS:
        return WITHIN, ""
    factor = 1.5 if max_factor is None else max_factor
    # "Beyond 1.5x" only means something for a non-zero limit on the side that was exceeded.
    side = hi if deviation > 0 else -lo
    if side > 0 and abs(deviation) > factor * side + _EPS:
        return BEYOND_MAX, FLAGS[BEYOND_MAX]
    return BEYOND, FLAGS[BEYOND]


def _judge_with_rule(item, deviation, minus, plus, max_factor, U, confidence, rule_name):
    """``(status, flag, decision, risk)`` of a deviation under the decision rule: guarded
    acceptance narrows each limit by U before :func:`_judge` (a bar size: accepted only where its
    confidence proves it); the decision marks what the interval leaves unproven
    (``rebarlib._decision``). Simple acceptance, shared risk and "proven" judge as :func:`_judge`
    does ("proven" leaves unproven checkpoints to the item's row, ``rebarlib._verdicts``), except
    that under "proven" a checkpoint is beyond 1.5× its limit only where it is so by U."""
    status, flag = _judge(deviation, minus, plus, max_factor)
    if item.startswith("bar_size"):
        decision, risk = decide_size(status == WITHIN, status == WITHIN, confidence, COVERAGE_K)
    else:
        decision, risk = decide(status == WITHIN, deviation, minus, plus, U, COVERAGE_K)
    if rule_name == "proven" and status == BEYOND_MAX and U is not None and math.isfinite(U):
        # beyond the limit's max_factor multiple, but not by U: beyond the limit only, as proven
        # (the deviation moved U towards the design value is judged the same way)
        if _judge(math.copysign(max(abs(deviation) - U, 0.0), deviation), minus, plus, max_factor)[0] != BEYOND_MAX:
            status, flag = BEYOND, FLAGS[BEYOND]
    if rule_name == "guarded" and status == WITHIN and decision == WITHIN_NP:
        # inside the limit, not by the guard band: not accepted (ILAC-G8 binary guarded acceptance)
        status = BEYOND
        if item.startswith("bar_size"):
            risk = None if risk is None else round(1.0 - risk, 3)
        else:
            risk = decide(False, deviation, minus, plus, U, COVERAGE_K)[1]
    return status, flag, decision, risk


def _labels(design: Design) -> dict:
    out = {
        "cover": "Cover (formwork to lower bars)",
        "layer_distance": "Layer distance (lower to upper mesh)",
        "top_cover": "Top cover (predicted from thickness)",
    }
    for la in LAYERS:
        for lv in LEVELS:
            out[f"spacing_{la}_{lv}"] = f"Spacing, {la} mesh, {lv} bars"
            out[f"bar_size_{la}_{lv}"] = f"Bar size, {la} mesh, {lv} bars"
            out[f"bar_count_{la}_{lv}"] = f"Bar count, {la} mesh, {lv} bars"
    return out


def _item_order(design: Design) -> list:
    keys = ["cover", "layer_distance"]
    keys += [f"spacing_{la}_{lv}" for la in LAYERS for lv in LEVELS]
    keys += [f"bar_size_{la}_{lv}" for la in LAYERS for lv in LEVELS]
    keys += [f"bar_count_{la}_{lv}" for la in LAYERS for lv in LEVELS]
    if design.thickness_mm is not None:
        keys.append("top_cover")
    return keys


def evaluate(results, design: Design, tolerances=None, *, missing_captures=()) -> Acceptance:
    """Judge every checkpoint of a slab's captures against the design and the lot rules.

    Parameters
    ----------
    results : list of InspectionResult or result dicts (``result.json``), one per capture
    design : Design
    tolerances : Tolerances, preset name or TOML path; default: the preset named by
        ``design.standard``. The design's ``[tolerances]`` overrides are applied on top.
    missing_captures : sequence of str or of str pairs
        the names of captures of the slab that have no result, or ``(name, reason)`` pairs; they
        make the slab verdict "incomplete".

    Returns
    -------
    Acceptance

    Examples
    --------
    >>> from rebarlib.data import paper_design
    >>> r = {"capture": "A", "measurements": {"cover": {"value_mm": 21.0, "status": "measured"},
    ...      "layer_distance": {"value_mm": 91.0, "status": "measured"}}}
    >>> acc = evaluate([r], paper_design())
    >>> acc.items.set_index("item").loc[["cover", "layer_distance"], "verdict"].tolist()
    ['pass', 'fail']
    >>> acc.verdict
    'rejected'
    """
    if not isinstance(design, Design):
        raise RebarInputError(f"design: expected a rebarlib.Design, got {type(design).__name__}")
    if isinstance(results, (dict,)) or hasattr(results, "capture"):
        results = [results]
    res = [_result_dict(r, i) for i, r in enumerate(results)]
    # positions one capture could not judge, judged by another capture of the slab that shows them
    from ._across import resolve_across

    res, across = resolve_across(res)
    tol = load_tolerances(design.standard if tolerances is None else tolerances)
    tol = tol.with_overrides(design.tolerances, source=design.source or "design")
    missing = tuple(
        (m, "no inspection result") if isinstance(m, str) else (str(m[0]), str(m[1])) for m in missing_captures
    )
    sheet = _Sheet(tol, _labels(design), design.thickness_mm)
    # a bar is checked over at least the length a bar position needs to be judged in view
    from ._counts import CountParams

    in_view_mm = CountParams.min_evidence_mm
    bar_rows = []
    for r in res:
        cap = str(r["capture"])
        _length_checkpoints(sheet, r, cap, design)
        bars = _table(r, "bars")
        _size_checkpoints(sheet, bars, cap, design, in_view_mm)
        _count_checkpoints(sheet, r, cap)
        bar_rows += [
            {"capture": cap, "bar_id": rec.get("bar_id"), "layer": rec.get("layer"), "level": rec.get("level")}
            for rec in (bars.to_dict(orient="records") if len(bars) else [])
        ]
    cp = pd.DataFrame(sheet.rows, columns=CHECKPOINT_COLUMNS)
    # captures not placed on each other may show the same spacings: a share rule is judged under
    # both extreme readings (docs/decisions/039-a-lot-over-captures-not-placed.md)
    from ._across import unplaced_pairs

    apart, order = unplaced_pairs(res), [str(r["capture"]) for r in res]
    items = pd.DataFrame(
        [_item_row(k, cp[cp["item"] == k], design, tol, sheet.labels, apart, order) for k in _item_order(design)],
        columns=ITEM_COLUMNS,
    )
    verdict, reasons = _slab_verdict(items, missing, n_results=len(res))
    return Acceptance(
        checkpoints=cp,
        items=items,
        bars=_bar_verdicts(bar_rows, cp),
        verdict=verdict,
        reasons=tuple(reasons),
        tolerances=tol,
        results=tuple(res),
        missing_captures=missing,
        notes=tuple(_notes(cp, design.thickness_mm, in_view_mm) + _pixels_notes(res, cp) + across),
    )


class _Sheet:
    """The checkpoint rows of one slab as they are judged: :meth:`add` judges one value
    against its item's tolerance and lot rule and appends its row."""

    def __init__(self, tol: Tolerances, labels: dict, thickness_mm):
        self.tol, self.labels, self.thickness = tol, labels, thickness_mm
        self.rows: list = []

    def add(
        self,
        item,
        capture,
        layer,
        level,
        what,
        design_value,
        measured,
        uncertainty=None,
        *,
        status=None,
        reason="",
        deviation=None,
        confidence=None,
        flag=None,
    ):
        tol = self.tol
        t = tol.item(_tol_key(item))
        minus, plus = t.limits(design_value, thickness_mm=self.thickness)
        rule = tol.rule(t.lot_rule)
        flag_, decision, risk = "", None, None
        U = None if uncertainty is None or item.startswith("bar_size") else COVERAGE_K * uncertainty
        if status is None:
            if measured is None or design_value is None:
                status = NOT_MEASURED
            else:
                deviation = measured - design_value if deviation is None else deviation
                status, flag_, decision, risk = _judge_with_rule(
                    item, deviation, minus, plus, rule.max_factor, U, confidence, tol.decision_rule
                )
        self.rows.append(
            {
                "item": item,
                "label": self.labels[item],
                "capture": capture,
                "layer": layer,
                "level": level,
                "what": what,
                "unit": t.unit,
                "design_value": design_value,
                "measured_value": measured,
                "deviation": None if deviation is None else round(deviation, 3),
                "uncertainty": uncertainty,
                "tolerance": _tol_text(minus, plus, t.unit),
                "tol_minus": minus,
                "tol_plus": plus,
                "status": status,
                "flag": flag_ if flag is None else flag,
                "reason": reason,
                "expanded_uncertainty": None if U is None else round(U, 3),
                "decision": decision or (status if status in (WITHIN, BEYOND, BEYOND_MAX) else None),
                "risk": risk,
            }
        )


def _length_checkpoints(sheet: _Sheet, r: dict, cap: str, design: Design) -> None:
    """Cover, layer distance and top cover (one checkpoint per capture), and every spacing."""
    meas = r.get("measurements") or {}
    for item in ("cover", "layer_distance") + (("top_cover",) if sheet.thickness is not None else ()):
        m = meas.get(item) or {}
        ok = m.get("status", MEASURED) == MEASURED and _num(m.get("value_mm")) is not None
        sheet.add(
            item,
            cap,
            "",
            "",
            "capture",
            _design_value(item, design),
            _num(m.get("value_mm")) if ok else None,
            _num(m.get("uncertainty_mm")),
            reason="" if ok else (m.get("reason") or "not in the result"),
        )
    from ._across import spans_missing

    gaps = spans_missing(r)
    for la, lv, item, dv, rec in _group_records(_table(r, "spacings"), "spacing", design):
        v = _num(rec.get("spacing_mm"))
        ok = rec.get("status", MEASURED) == MEASURED and v is not None
        at = gaps.get((la, lv, rec.get("bar_a"), rec.get("bar_b")))
        excluded = None
        if ok and at is not None:
            # the gap of a bar evidenced missing: that defect is the bar count's, counted there once
            excluded = f"{SPANS_MISSING} at {at:.0f} mm ({v:.1f} mm): judged under the bar count"
        elif ok and isinstance(rec.get("also_in"), str):
            # the same two bars' spacing, measured in an earlier capture of the slab placed on
            # this one: a lot counts it once (docs/decisions/028-captures-of-one-slab-together.md)
            excluded = f"{SAME_SPACING} {rec['also_in']}, counted there"
        if excluded is not None:
            v, ok = None, False
        sheet.add(
            item,
            cap,
            la,
            lv,
            f"bars {rec.get('bar_a')}-{rec.get('bar_b')}",
            _num(rec.get("design_spacing_mm")) or dv,
            v if ok else None,
            None if excluded else _num(rec.get("uncertainty_mm")),
            status=EXCLUDED if excluded else None,
            reason=excluded or ("" if ok else (rec.get("reason") or "spacing not measured")),
        )


#: the start of a bar-size checkpoint's reason where the bar is excluded for its axis (decision 061)
_AXIS_OUT_OF_VIEW = f"{NOT_IN_VIEW}: its axis lies outside the image"


def _size_checkpoints(sheet: _Sheet, bars: pd.DataFrame, cap: str, design: Design, in_view_mm: float) -> None:
    """One bar-size checkpoint per bar: its snapped size against the design's, or excluded
    (hidden under nearer bars; too little of it in view and not sized), or not measured."""
    has_diam = len(bars) and ("nominal_mm" in bars.columns or "diameter_status" in bars.columns)
    for la, lv, item, dv, rec in _group_records(bars, "bar_size", design):
        what = f"bar {rec.get('bar_id')}"
        ddv = _num(rec.get("design_diameter_mm")) or dv
        nominal = _num(rec.get("nominal_mm"))
        ok = has_diam and rec.get("diameter_status", MEASURED) == MEASURED and nominal is not None
        seen_mm = _num(rec.get("visible_length_mm"))
        excluded = None
        if is_true(rec.get("hidden")) or rec.get("diameter_status") == HIDDEN:
            excluded = rec.get("diameter_reason") or "hidden under crossing bars"
        elif has_diam and not ok and seen_mm is not None and seen_mm < in_view_mm:
            # a bar the capture shows over less than a bar position needs to be judged in view
            # (docs/verdicts.md): outside what this capture inspects, as such a position is
            excluded = (
                f"{NOT_IN_VIEW}: only {seen_mm:.0f} mm of it in the capture (a bar is checked over at least "
                f"{in_view_mm:.0f} mm); " + (rec.get("diameter_reason") or "diameter not measured")
            )
        elif has_diam and not ok and rec.get("diameter_reason") == AXIS_OUTSIDE:
            # less than half of the bar's width in the image: the line it lies on is outside what
            # this capture inspects, as a bar position whose core leaves the image is
            # (docs/decisions/061-a-bar-whose-axis-leaves-the-image-is-not-in-view.md)
            excluded = (
                f"{_AXIS_OUT_OF_VIEW}, less than half its width in the capture "
                "(a bar is sized where its axis is in view)"
            )
        elif has_diam and not ok and isinstance(rec.get("sized_in"), str) and rec["sized_in"]:
            # the same bar, registered in another capture of the slab, was sized there: its size
            # is checked once, there (docs/decisions/028-captures-of-one-slab-together.md). (A bar
            # of a table where another bar has ``sized_in`` reads NaN there: not sized elsewhere.)
            excluded = f"{SIZED_ELSEWHERE} {rec['sized_in']}; here: " + (
                rec.get("diameter_reason") or "diameter not measured"
            )
        if excluded is not None:
            sheet.add(item, cap, la, lv, what, ddv, None, status=EXCLUDED, reason=excluded)
            continue
        reason = (
            ""
            if ok
            else (rec.get("diameter_reason") or ("diameter stage not run" if not has_diam else "diameter not measured"))
        )
        # the width's standard uncertainty (refined); the paper's vote has none: its spread
        # (with the systematic terms where the uncertainty budget gave them)
        u = _num(rec.get("width_uncertainty_mm"))
        u = u if u is not None else _num(rec.get("width_sigma_mm"))
        sheet.add(
            item,
            cap,
            la,
            lv,
            what,
            ddv,
            nominal if ok else None,
            u if u is not None else _num(rec.get("width_spread_mm")),
            reason=reason,
            confidence=_num(rec.get("budget_confidence")),
        )


def _count_checkpoints(sheet: _Sheet, r: dict, cap: str) -> None:
    """One bar-count checkpoint per direction: it fails only on evidenced missing or extra bars
    (docs/verdicts.md); a position that could be neither leaves it not measured."""
    counts = _table(r, "counts")
    for la in LAYERS:
        for lv in LEVELS:
            item = f"bar_count_{la}_{lv}"
            sub = counts[(counts["layer"] == la) & (counts["level"] == lv)] if len(counts) else counts
            if not len(sub):
                sheet.add(
                    item, cap, la, lv, "count", None, None, reason="no bar count for this direction in the result"
                )
                continue
            rec = sub.iloc[0].to_dict()
            found, expected = _num(rec.get("found")), _num(rec.get("expected"))
            if found is None or expected is None:
                why = str(rec.get("evidence") or "").strip()  # "no bar found", "no design spacing"
                if why == "no bar found":
                    why = "no bar of this direction found in this capture"
                reason = f"bar count not measured: {why}" if why else "bar count not measured"
                sheet.add(item, cap, la, lv, "count", expected, None, reason=reason)
                continue
            n_miss = int(_num(rec.get("missing")) or 0)
            n_extra = int(_num(rec.get("extra")) or 0)
            n_open = int(_num(rec.get("not_measured")) or 0)
            seen = str(rec.get("evidence") or "")
            minus, plus = sheet.tol.item("bar_count").limits()
            bad = (minus is not None and n_miss > minus) or (plus is not None and n_extra > plus)
            what = f"{n_miss} missing, {n_extra} extra" + (f" ({seen})" if seen else "")
            if not bad and n_open:
                sheet.add(
                    item,
                    cap,
                    la,
                    lv,
                    what,
                    expected,
                    None,
                    reason=f"{n_open} bar position(s) could not be judged: "
                    + _open_positions(_table(r, "positions"), la, lv),
                )
                continue
            sheet.add(
                item,
                cap,
                la,
                lv,
                what,
                expected,
                found,
                status=BEYOND if bad else WITHIN,
                deviation=found - expected,
                flag="*" if bad else "",
            )


def _notes(cp: pd.DataFrame, thickness_mm, in_view_mm: float) -> list:
    """What the sheet says besides its items: no thickness, bars left out of the size check."""
    notes = []
    if thickness_mm is None:
        notes.append("The design gives no slab thickness: the top cover is not checked.")
    excluded = cp[cp["status"] == EXCLUDED]
    reasons = excluded["reason"].astype(str)
    n_axis = int(reasons.str.startswith(_AXIS_OUT_OF_VIEW).sum())
    n_view = int(reasons.str.startswith(NOT_IN_VIEW).sum()) - n_axis
    n_else = int(reasons.str.startswith(SIZED_ELSEWHERE).sum())
    n_same = int(reasons.str.startswith((SAME_SPACING, SPANS_MISSING)).sum())
    n_hidden = len(excluded) - n_view - n_axis - n_else - n_same
    if n_hidden:
        notes.append(f"{n_hidden} bar(s) hidden under nearer bars are excluded from the bar-size check.")
    if n_view:
        notes.append(
            f"{n_view} bar(s) with less than {in_view_mm:.0f} mm in view are excluded from the "
            "bar-size check (another capture shows them)."
        )
    if n_axis:
        notes.append(
            f"{n_axis} bar(s) whose axis lies outside the image (less than half the bar in view) are excluded "
            "from the bar-size check (another capture shows them)."
        )
    if n_else:
        notes.append(f"{n_else} bar(s) not sized in one capture are checked where another capture sized them.")
    return notes


def _pixels_notes(res: list, cp: pd.DataFrame) -> list:
    """One note for the bars still unsized on the sheet that their captures put down to the
    camera's pixels (``extras["pixels_for_sizes"]``, ``rebarlib.diameter.closer.pixels_for_sizes``):
    how many, in which captures, and from how near a capture (or with how many more pixels) sizes
    them."""
    from .diameter.closer import CloserParams

    open_sizes = cp[cp["item"].astype(str).str.startswith("bar_size") & (cp["status"] == NOT_MEASURED)]
    counts, near, focal, gap = {}, [], [], math.inf
    for r in res:
        adv = (r.get("extras") or {}).get("pixels_for_sizes")
        if not isinstance(adv, dict):
            continue
        cap = str(r["capture"])
        whats = set(open_sizes.loc[open_sizes["capture"] == cap, "what"].astype(str))
        n = sum(f"bar {int(b)}" in whats for b in adv.get("bar_ids") or ())
        if not n:
            continue
        counts[cap] = n
        gap = min(gap, float(adv.get("min_gap_px") or CloserParams.min_gap_px))
        (near if adv.get("reachable") else focal).append(adv)
    if not counts:
        return []
    n = sum(counts.values())
    caps = ", ".join(counts)
    head = (
        f"{n} bar(s) left unsized ({caps}) lie where the camera's pixels put two neighbouring sizes' rib envelopes "
        f"under {gap:g} px apart"
    )
    if near:
        d = min(float(a["needed_mm"]) for a in near)
        head += f": from about {d:.0f} mm or nearer to the bars a capture puts them {gap:g} px apart"
    if focal:
        f = max(float(a["focal_needed_px"]) for a in focal)
        head += (
            f"{'; elsewhere' if near else ':'} the camera cannot stand near enough, and a focal length of about "
            f"{f:.0f} px or more is needed"
        )
    return [head + " (each capture's notes say which bars)."]


def _open_positions(positions: pd.DataFrame, layer: str, level: str) -> str:
    """The reasons of the positions of one direction that were neither found nor judged."""
    if not len(positions) or "status" not in positions:
        return "see the result's positions table"
    sel = positions[
        (positions["layer"] == layer) & (positions["level"] == level) & (positions["status"] == NOT_MEASURED)
    ]
    return "; ".join(f"at {float(o):.0f} mm: {r}" for o, r in zip(sel["offset_mm"], sel["reason"])) or "–"
