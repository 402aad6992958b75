"""The tables the bar positions give (:mod:`rebarlib._counts`): the bar count of each lattice
and direction, and the spacing table settled once the positions are known (a spacing to a bar
placed from the colour mask, a wide gap that is one spacing only where its positions were seen
empty).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pandas as pd

from ._evidence import _offset
from ._status import EXTRA, MEASURED, MISSING, NOT_EXTRA, NOT_MEASURED, OUTSIDE, PRESENT, PRESENT_NO_DEPTH
from .geometry import LAYERS, LEVELS

if TYPE_CHECKING:
    from ._counts import CountParams

__all__ = ["count_table", "settle_spacings", "off_the_row"]


def off_the_row(positions: pd.DataFrame, bars: list) -> set:
    """The bars that take no part in the spacings: of each pair of bars on one design position
    judged no extra bar (a lap's two bars, a loose piece, a sliver or a second fit beside the
    bar), the one that does not stand for the position. The bar that stands is the measured one,
    else the one seen over the longer stretch; the spacings of the row are then taken between
    the bars that stand, with no spacing of a few millimetres between the two of a pair
    (docs/verdicts.md, "Laps and pieces")."""
    out = set()
    if not len(positions) or "twin_id" not in positions.columns:
        return out

    def stands(k):  # measured first, then the longer stretch seen
        return (bars[k].status == MEASURED, float(bars[k].t1_mm - bars[k].t0_mm), -k)

    pairs = positions[(positions["kind"] == "pair") & (positions["status"] == NOT_EXTRA)]
    for a, b in zip(pairs["bar_id"], pairs["twin_id"]):
        if not (pd.isna(a) or pd.isna(b)):
            out.add(min((int(a), int(b)), key=stands))
    return out


def count_table(bars: list, positions: pd.DataFrame, design_spacing: dict) -> pd.DataFrame:
    """Per lattice and direction: ``found`` (bars, including those placed from the mask),
    ``expected``, ``missing`` and ``extra`` (evidenced only), ``not_measured`` (positions that
    are neither), ``outside`` (positions beyond the mesh), ``evidence`` (what was seen)."""
    rows = []
    for layer in LAYERS:
        for level in LEVELS:
            found = sum(1 for b in bars if b.layer == layer and b.level == level)
            s = design_spacing.get((layer, level))
            pos = (
                positions[(positions["layer"] == layer) & (positions["level"] == level)]
                if len(positions)
                else positions
            )
            st = pos["status"].value_counts().to_dict() if len(pos) else {}
            if not found or s is None:
                rows.append(
                    {
                        "layer": layer,
                        "level": level,
                        "found": found,
                        "expected": None,
                        "missing": None,
                        "extra": None,
                        "not_measured": None,
                        "outside": None,
                        "evidence": "no bar found" if not found else "no design spacing",
                    }
                )
                continue
            missing, extra = int(st.get(MISSING, 0)), int(st.get(EXTRA, 0))
            nm = int(st.get(NOT_MEASURED, 0))
            parts = [f"{found} found"]
            for key, label in (
                (PRESENT_NO_DEPTH, "placed from the colour mask (no depth)"),
                (PRESENT, "seen but not fitted"),
                (MISSING, "missing (seen empty)"),
                (EXTRA, "extra"),
                (NOT_MEASURED, "not measured"),
                (NOT_EXTRA, "laps/short pieces"),
                (OUTSIDE, "beyond the mesh's edge"),
            ):
                if st.get(key):
                    parts.append(f"{st[key]} {label}")
            rows.append(
                {
                    "layer": layer,
                    "level": level,
                    "found": found,
                    "expected": found - extra + missing,
                    "missing": missing,
                    "extra": extra,
                    "not_measured": nm,
                    "outside": int(st.get(OUTSIDE, 0)),
                    "evidence": ", ".join(parts),
                }
            )
    df = pd.DataFrame(
        rows, columns=["layer", "level", "found", "expected", "missing", "extra", "not_measured", "outside", "evidence"]
    )
    return df


def settle_spacings(
    spacings: pd.DataFrame, bars: list, positions: pd.DataFrame, params: CountParams | None = None
) -> pd.DataFrame:
    """The spacing table once the positions are known.

    - A spacing to a bar placed from the colour mask (no depth) is measured between the two
      axes when the bar's position is known to ``max_position_sigma_mm``; its reason says so.
    - A spacing spanning more than 1.5 design spacings is one real (wide) spacing only where
      every position between the two bars was seen empty (missing); where one of them could not
      be examined it is "not measured", with what was not seen.
    """
    from .geometry import _pair_spacing

    from ._counts import CountParams

    prm = params or CountParams()
    out = spacings.copy()
    placed = {}
    if len(positions):
        for rec in positions.to_dict(orient="records"):
            if (
                rec["status"] in (PRESENT_NO_DEPTH, PRESENT)
                and rec["bar_id"] is not None
                and not pd.isna(rec["bar_id"])
            ):
                placed[int(rec["bar_id"])] = float(rec["position_sigma_mm"])
    for i, s in out.iterrows():
        a, b = int(s["bar_a"]), int(s["bar_b"])
        ds = s["design_spacing_mm"]
        if (a in placed or b in placed) and s["status"] != MEASURED:
            others = [x for x in (a, b) if x not in placed]
            sig = [placed[x] for x in (a, b) if x in placed]
            if all(bars[x].status == MEASURED for x in others) and max(sig) <= prm.max_position_sigma_mm:
                val = _pair_spacing(bars[a], bars[b])
                out.loc[i, "spacing_mm"] = val
                out.loc[i, "deviation_mm"] = val - ds if np.isfinite(ds) else np.nan
                out.loc[i, "status"] = MEASURED
                out.loc[i, "reason"] = (
                    f"bar {', '.join(str(x) for x in (a, b) if x in placed)} placed from "
                    f"the colour mask (± {max(sig):.1f} mm across)"
                )
                s = out.loc[i]
        if s["status"] != MEASURED or not np.isfinite(ds) or s["spacing_mm"] <= 1.5 * ds:
            continue
        pos = (
            positions[
                (positions["layer"] == s["layer"]) & (positions["level"] == s["level"]) & (positions["kind"] == "gap")
            ]
            if len(positions)
            else positions
        )
        n2 = next(x.normal2d for x in bars if x.layer == s["layer"] and x.level == s["level"])
        lo, hi = sorted((_offset(bars[a], n2), _offset(bars[b], n2)))
        # the empty positions between the two (a bar placed there is one of the two, or splits
        # the gap: it is no empty position)
        q = 0.25 * ds
        inner = (
            pos[
                (pos["offset_mm"] > lo + q)
                & (pos["offset_mm"] < hi - q)
                & ~pos["status"].isin([PRESENT, PRESENT_NO_DEPTH])
            ]
            if len(pos)
            else pos
        )
        if len(inner) and (inner["status"] == MISSING).all():
            continue
        why = "; ".join(str(x) for x in inner["reason"]) if len(inner) else "its positions were not examined"
        out.loc[i, ["spacing_mm", "deviation_mm"]] = np.nan
        out.loc[i, "status"] = NOT_MEASURED
        out.loc[i, "reason"] = (
            f"{s['spacing_mm']:.0f} mm gap with a bar position between that could not be "
            f"judged ({why}), so it is not one spacing"
        )
    return out
