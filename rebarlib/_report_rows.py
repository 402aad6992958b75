"""The rows of the report's tables, as the templates print them: numbers formatted, the
measurements of a capture, the items and their checkpoints, the uncertainty budget, what was not
measured and why, and the design (:func:`rebarlib.report.report_context` assembles them).
"""

from __future__ import annotations

import math

from ._design import DEFAULT_BAR_SYSTEM, Design
from ._results import table_records
from ._status import EXCLUDED, NOT_IN_VIEW, NOT_MEASURED
from .acceptance import COVERAGE_K, Acceptance


def _fmt(v, nd: int = 1, unit: str = "") -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    try:
        v = float(v)
    except (TypeError, ValueError):
        return str(v)
    s = f"{v:.{nd}f}"
    return s + (f" {unit}" if unit else "")


def _signed(v, nd: int = 1) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    s = f"{float(v):+.{nd}f}"
    return s if float(s) != 0 else f"{0:.{nd}f}"  # no "-0.0" / "+0.0"


def _pct(v) -> str:
    return "–" if v is None or (isinstance(v, float) and not math.isfinite(v)) else f"{100 * float(v):.0f} %"


def _spacing_status(cp) -> dict:
    """The status of each spacing checkpoint, by (capture, bar a, bar b, layer, level): the plan
    view marks the spacings beyond tolerance."""
    status_of = {}
    for rec in cp.itertuples():
        if str(rec.what).startswith("bars "):
            a, b = str(rec.what)[5:].split("-", 1)
            status_of[(rec.capture, a, b, rec.layer, rec.level)] = rec.status
    return status_of


def _measurement_rows(r: dict) -> list:
    """Cover, layer distance, top of the upper bars and top cover of one result, as printed."""
    meas = r.get("measurements") or {}
    rows = []
    for key, label in (
        ("cover", "Cover"),
        ("layer_distance", "Layer distance"),
        ("upper_top", "Top of upper bars above formwork"),
        ("top_cover", "Top cover (predicted)"),
    ):
        m = meas.get(key) or {}
        rows.append(
            {
                "label": label,
                "value": _fmt(m.get("value_mm"), 1, "mm"),
                "u": _fmt(m.get("uncertainty_mm"), 1, "mm"),
                "n": m.get("n_points", ""),
                "status": m.get("status", NOT_MEASURED),
                "reason": m.get("reason", ""),
            }
        )
    return rows


def _item_rows(acceptance: Acceptance) -> tuple[list, list]:
    """The items as printed (worst deviation, pass ratio, what was not measured or proven) and
    the numbered lot rules they refer to."""
    items = table_records(acceptance.items, digits=None)
    rules = []
    for it in items:
        key = (it["rule"], it["clause"])
        if key not in [(r["rule"], r["clause"]) for r in rules]:
            rules.append({"no": len(rules) + 1, "rule": it["rule"], "clause": it["clause"]})
        it["rule_no"] = [(r["rule"], r["clause"]) for r in rules].index(key) + 1
        unit = "bars" if it["unit"] == "bars" else "mm"
        w = it["worst_deviation"]
        it["worst_text"] = "–" if w is None else (f"{_signed(w, 0)} bars" if unit == "bars" else f"{_signed(w, 1)} mm")
        it["ratio_text"] = _pct(it["pass_ratio"])
        it["extra_text"] = ", ".join(
            t
            for t in (
                f"+{it['not_measured']} n/m" if it["not_measured"] else "",
                f"+{it['excluded']} hidden" if it["excluded"] else "",
                f"{it['not_proven']} not proven" if it.get("not_proven") else "",
            )
            if t
        )
    return items, rules


def _uncertainty_rows(cp) -> list:
    """The limitations section: per item the uncertainty the results reported (median and
    largest over the checkpoints that have one)."""
    uncertainty = []
    for key in ("cover", "layer_distance", "top_cover"):
        sub = cp[(cp["item"] == key) & cp["uncertainty"].notna()]
        if len(sub):
            u = sub["uncertainty"].astype(float)
            uncertainty.append(
                {
                    "label": sub["label"].iloc[0],
                    "text": f"{u.median():.1f} mm (median over {len(u)} capture(s), max {u.max():.1f} mm)",
                }
            )
    u_sp = cp[cp["item"].str.startswith("spacing") & cp["uncertainty"].notna()]
    if len(u_sp):
        u = u_sp["uncertainty"].astype(float)
        uncertainty.append(
            {
                "label": "Spacing (each gap's standard uncertainty)",
                "text": f"{u.median():.1f} mm (median over {len(u)} gaps, max {u.max():.1f} mm)",
            }
        )
    for row in uncertainty:
        row["text"] += f"; expanded U = {COVERAGE_K:g} u (k = {COVERAGE_K:g})"
    u_bar = cp[cp["item"].str.startswith("bar_size") & cp["uncertainty"].notna()]
    if len(u_bar):
        uncertainty.append(
            {
                "label": "Bar width (each bar's standard uncertainty; its spread along the bar "
                "where the method gives none)",
                "text": f"{u_bar['uncertainty'].astype(float).median():.1f} mm (median over {len(u_bar)} bars)",
            }
        )
    return uncertainty


def _not_measured_rows(checkpoints: list) -> list:
    """What was not measured, one row per (item, reason) with where (so that the section stays
    readable on a large slab)."""
    not_measured = [
        {"label": c["label"], "capture": c["capture"], "what": c["what"], "reason": c["reason"]}
        for c in checkpoints
        if c["status"] == NOT_MEASURED
    ]
    nm_grouped = {}
    for c in not_measured:
        key = (c["label"], c["reason"])
        nm_grouped.setdefault(key, []).append(f"{c['capture']}: {c['what']}")
    return [
        {
            "label": k[0],
            "reason": k[1],
            "where": ", ".join(v[:6]) + (f" … (+{len(v) - 6})" if len(v) > 6 else ""),
            "n": len(v),
        }
        for k, v in nm_grouped.items()
    ]


def _design_context(design: Design) -> dict:
    """The design values the report's identification table prints."""
    return {
        "cover": design.cover_mm,
        "layer_distance": design.layer_distance_mm,
        "thickness": design.thickness_mm,
        "bar_system": design.bar_system,
        "meshes": [
            {
                "layer": la,
                "level": lv,
                "d": design.lattice(la).level(lv).diameter_mm,
                "s": design.lattice(la).level(lv).spacing_mm,
            }
            for la in ("lower", "upper")
            for lv in ("bottom", "top")
        ],
    }


def _checkpoint_rows(items: list, checkpoints: list, bar_system: str) -> list:
    """One row per item and capture with every checkpoint's value and flag, as on a record sheet.

    (A table row per checkpoint would triple the PDF's layout time on a four-capture slab; the
    CSV / JSON exports keep one row per checkpoint.)
    """
    rows = []
    for it in items:
        cps = [c for c in checkpoints if c["item"] == it["item"]]
        caps = []
        for cap in dict.fromkeys(c["capture"] for c in cps):
            vals = []
            for c in (c for c in cps if c["capture"] == cap):
                if c["status"] == EXCLUDED:
                    v = NOT_IN_VIEW if str(c.get("reason", "")).startswith(NOT_IN_VIEW) else "hidden"
                elif c["status"] == NOT_MEASURED:
                    v = "n/m"
                elif it["item"].startswith("bar_size"):
                    v = _size(c["measured_value"], bar_system)
                elif it["item"].startswith("bar_count"):
                    v = f"{c['measured_text']} of {c['design_text']}"
                else:
                    v = c["deviation_text"]
                vals.append(
                    {
                        "text": v,
                        "flag": c["flag"],
                        "bad": bool(c["flag"]),
                        "open": c["status"] in (NOT_MEASURED, EXCLUDED),
                    }
                )
            caps.append({"capture": cap, "vals": vals})
        rows.append(
            {
                "label": it["label"],
                "tolerance": it["tolerance"],
                "caps": caps,
                "kind": (
                    "measured size"
                    if it["item"].startswith("bar_size")
                    else "found of expected"
                    if it["item"].startswith("bar_count")
                    else "deviation, mm"
                ),
            }
        )
    return rows


def _max_factor_text(tol) -> str:
    factors = sorted({r.max_factor for r in tol.lot_rules.values() if r.max_factor is not None})
    return " / ".join(f"{f:g}×" for f in factors) or "1.5×"


def _css_class(v) -> str:
    return "".join(ch if ch.isalnum() else "-" for ch in str(v or "none").lower())


def _size(v, system=DEFAULT_BAR_SYSTEM) -> str:
    if v is None or (isinstance(v, float) and not math.isfinite(v)):
        return "–"
    return f"Φ{float(v):g}" if str(system).upper().startswith("GB") else f"{float(v):g} mm"
