"""Spacings between adjacent bars, the paper's counts from the gaps, and the bars table."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pandas as pd

from .._status import MEASURED, NOT_MEASURED
from .axis import BarAxis
from .layers import LAYERS, LEVELS
from .levels import _MIN_CROSSINGS, _crest_lines, _stacks, _tops
from .plane import Plane, from_slab_frame, to_slab_frame


def _order_across(group_bars: list) -> list:
    if not group_bars:
        return []
    ref = group_bars[0].direction
    n2 = np.array([-ref[1], ref[0]])
    return sorted(group_bars, key=lambda b: float(b.plan_point(b.t_mid) @ n2))


def _pair_spacing(a: BarAxis, b: BarAxis) -> float:
    """Perpendicular plan distance between two fitted axes at the middle of their common stretch
    (each way, averaged); a lapped bar's axis is taken at the lap's middle (:func:`_lap_middle`)."""
    a, b = _lap_middle(a), _lap_middle(b)
    ta0, ta1 = a.t0_mm, a.t1_mm
    pb = b.plan_point(np.array([b.t0_mm, b.t1_mm]))
    tb_on_a = pb @ a.direction
    lo, hi = max(ta0, tb_on_a.min()), min(ta1, tb_on_a.max())
    tm = 0.5 * (lo + hi) if hi > lo else 0.5 * (a.t_mid + float(tb_on_a.mean()))
    pa = a.plan_point(tm)
    # distance from a's point to b's line, and back
    tb = float(pa @ b.direction)
    d1 = abs(float((pa - b.plan_point(tb)) @ b.normal2d))
    pbm = b.plan_point(tb)
    ta = float(pbm @ a.direction)
    d2 = abs(float((pbm - a.plan_point(ta)) @ a.normal2d))
    return 0.5 * (d1 + d2)


def measure_spacings(bars: list, *, design_spacing: dict | None = None, skip=()) -> pd.DataFrame:
    """Spacing of every pair of adjacent bars of each layer and level, in order across the bars.

    Parameters
    ----------
    bars : list of BarAxis with ``layer`` and ``level`` set; the table names each bar by its
        position in the list
    design_spacing : ``{(layer, level): spacing_mm}``, adds the design value and the deviation
    skip : positions in ``bars`` of bars that take no part in the spacings: the second bar of
        a lap, or a loose piece, beside the bar that stands for its design position
        (``_count_tables.off_the_row``); its neighbours' spacings are taken to that bar

    Returns
    -------
    pandas.DataFrame
        One row per pair of neighbours:

        ==================  ==========================================================
        column              meaning
        ==================  ==========================================================
        layer, level        the pair's lattice and direction group
        bar_a, bar_b        the two bars (positions in ``bars``), in order across
        spacing_mm          axis to axis at the middle of their common stretch (NaN
                            where a bar is not measured); a lapped bar's axis is
                            the lap's middle (``BarAxis.lap_shift_mm``)
        design_spacing_mm   the design's spacing (NaN without one)
        deviation_mm        spacing less design spacing
        status, reason      "measured", or "not measured" and which bar; a
                            measured one names its lapped bars
        ==================  ==========================================================

    Examples
    --------
    >>> from rebarlib.geometry import BarAxis
    >>> bars = [BarAxis("lower", np.array([1.0, 0.0]), y, 0.0, 30.0, 0.0, 0.0, 500.0, 7.0, 100,
    ...                 0.3, level="bottom") for y in (0.0, 203.0)]
    >>> t = measure_spacings(bars, design_spacing={("lower", "bottom"): 200.0})
    >>> t.loc[0, ["bar_a", "bar_b"]].tolist(), t.loc[0, ["spacing_mm", "deviation_mm"]].tolist()
    ([0, 1], [203.0, 3.0])
    """
    rows = []
    ids = {id(b): i for i, b in enumerate(bars)}
    # every bar found takes part in the order, so a bar whose axis could not be placed gives two
    # "not measured" spacings instead of one spacing twice the real one
    skip = {int(k) for k in skip}
    for layer, level, a, b in _adjacent_pairs([x for k, x in enumerate(bars) if k not in skip]):
        ds = (design_spacing or {}).get((layer, level))
        row = {"layer": layer, "level": level, "bar_a": ids[id(a)], "bar_b": ids[id(b)], "design_spacing_mm": ds}
        bad = [x for x in (a, b) if x.status != MEASURED]
        if bad:
            rows.append(
                {
                    **row,
                    "spacing_mm": None,
                    "deviation_mm": None,
                    "status": NOT_MEASURED,
                    "reason": f"bar {ids[id(bad[0])]} not measured: {bad[0].reason}",
                }
            )
            continue
        s = _pair_spacing(a, b)
        lapped = [ids[id(x)] for x in (a, b) if x.lap_shift_mm]
        reason = " and ".join(f"bar {k}" for k in lapped) + " lapped: taken at the middle of the lap" if lapped else ""
        dev = None if ds is None else s - ds
        rows.append({**row, "spacing_mm": s, "deviation_mm": dev, "status": MEASURED, "reason": reason})
    return _spacing_frame(rows)


def _lap_middle(b: BarAxis) -> BarAxis:
    """``b``, or where a bar touching it alongside was seen (``lap_shift_mm``, a lap), the line
    through the lap's middle: the two bars stand for one design position together, and a
    spacing to either bar would be off by a radius (docs/decisions/071)."""
    return replace(b, offset_mm=b.offset_mm + b.lap_shift_mm) if b.lap_shift_mm else b


def _adjacent_pairs(bars: list):
    """``(layer, level, bar, next bar)`` for every pair of neighbours across each direction group."""
    for layer in LAYERS:
        for level in LEVELS:
            ordered = _order_across([b for b in bars if b.layer == layer and b.level == level])
            for a, b in zip(ordered[:-1], ordered[1:]):
                yield layer, level, a, b


def _spacing_frame(rows) -> pd.DataFrame:
    cols = ["layer", "level", "bar_a", "bar_b", "spacing_mm", "design_spacing_mm", "deviation_mm", "status", "reason"]
    df = pd.DataFrame(rows, columns=cols)
    for c in ("spacing_mm", "design_spacing_mm", "deviation_mm"):
        df[c] = pd.to_numeric(df[c], errors="coerce").astype(float)
    return df


def count_bars(bars: list, *, design_spacing: dict) -> pd.DataFrame:
    """Found, expected, missing and extra bars per layer and level, from the gaps alone.

    The paper's method has no evidence for an empty position: a gap of ``k`` design spacings
    (rounded) between two found bars holds ``k - 1`` missing bars, and adjacent bars closer than
    half a spacing make one extra bar. The refined method counts on evidence instead
    (``rebarlib._counts``, docs/verdicts.md).

    Parameters
    ----------
    bars : list of BarAxis with ``layer`` and ``level`` set
    design_spacing : ``{(layer, level): spacing_mm}``

    Returns
    -------
    pandas.DataFrame
        One row per layer and level:

        ============  ===============================================================
        column        meaning
        ============  ===============================================================
        layer, level  the lattice and direction group
        found         bars found
        expected      found − extra + missing (None without a design spacing)
        missing       bars the gaps of two or more spacings leave out
        extra         neighbours closer than half a spacing
        ============  ===============================================================
    """
    rows = []
    for layer in LAYERS:
        for level in LEVELS:
            grp = _order_across([b for b in bars if b.layer == layer and b.level == level])
            s = design_spacing.get((layer, level))
            found = len(grp)
            if not grp or s is None:
                rows.append(
                    {"layer": layer, "level": level, "found": found, "expected": None, "missing": None, "extra": None}
                )
                continue
            n2 = np.array([-grp[0].direction[1], grp[0].direction[0]])
            offs = np.array([float(b.plan_point(b.t_mid) @ n2) for b in grp])
            gaps = np.diff(offs)
            extra = int(np.sum(gaps < 0.5 * s))
            missing = int(sum(max(0, int(round(g / s)) - 1) for g in gaps if g > 1.5 * s))
            rows.append(
                {
                    "layer": layer,
                    "level": level,
                    "found": found,
                    "expected": found - extra + missing,
                    "missing": missing,
                    "extra": extra,
                }
            )
    return pd.DataFrame(rows, columns=["layer", "level", "found", "expected", "missing", "extra"])


def bars_table(bars: list, plane: Plane, points: list | None = None) -> pd.DataFrame:
    """The bars table of an inspection.

    Parameters
    ----------
    bars : list of BarAxis (slab frame)
    plane : the formwork Plane of the slab frame
    points : per bar, its camera-frame points (or None): the tops are read off them
        (:func:`top_heights`, :func:`stack_heights`); without them, off the fitted circles

    Returns
    -------
    pandas.DataFrame
        One row per bar (mm, camera frame for the ends):

        =======================  ===========================================================
        column                   meaning
        =======================  ===========================================================
        bar_id                   the bar's position in ``bars``
        layer, level             "lower"/"upper", "bottom"/"top"
        plan_angle_deg           its direction in plan, [0, 180)
        ``start_{x,y,z}_mm``     the axis's ends over the visible extent
        ``end_{x,y,z}_mm``
        visible_length_mm        the visible extent's length
        n_points                 points fitted
        axis_height_mm           the axis's height over the formwork, mid-extent
        underside_mm, radius_mm  the axis height less the radius, the radius (NaN: none)
        fit_rms_mm               the cylinder fit's residual
        arc_deg                  the span of its cross-section the points cover
        axis_se_mm               the axis position's standard error
        stack_mm                 its top above the bars it rests on (:func:`stack_heights`)
        top_mm                   its top above the formwork (:func:`top_heights`)
        status, reason           "measured", or "not measured" and why
        =======================  ===========================================================
    """
    rows = []
    slab_points = None if points is None else [None if p is None else to_slab_frame(p, plane) for p in points]
    crest = _crest_lines(bars, slab_points)  # read once: the stack and top heights both use them
    stack, top = _stacks(bars, crest, _MIN_CROSSINGS), _tops(bars, crest)
    for i, b in enumerate(bars):
        ends = from_slab_frame(b.axis_points(np.array([b.t0_mm, b.t1_mm])), plane)
        rows.append(
            {
                "bar_id": i,
                "layer": b.layer,
                "level": b.level,
                "plan_angle_deg": b.plan_angle_deg,
                "start_x_mm": ends[0, 0],
                "start_y_mm": ends[0, 1],
                "start_z_mm": ends[0, 2],
                "end_x_mm": ends[1, 0],
                "end_y_mm": ends[1, 1],
                "end_z_mm": ends[1, 2],
                "visible_length_mm": b.t1_mm - b.t0_mm,
                "n_points": int(b.n_points),
                "axis_height_mm": b.axis_height_mm,
                "underside_mm": b.underside_mm if b.radius_mm > 0 else float("nan"),
                "radius_mm": b.radius_mm if b.radius_mm > 0 else float("nan"),
                "fit_rms_mm": b.rms_mm,
                "arc_deg": b.arc_deg,
                "axis_se_mm": b.axis_se_mm,
                "stack_mm": stack[i],
                "top_mm": top[i],
                "status": b.status,
                "reason": b.reason,
            }
        )
    cols = [
        "bar_id",
        "layer",
        "level",
        "plan_angle_deg",
        "start_x_mm",
        "start_y_mm",
        "start_z_mm",
        "end_x_mm",
        "end_y_mm",
        "end_z_mm",
        "visible_length_mm",
        "n_points",
        "axis_height_mm",
        "underside_mm",
        "radius_mm",
        "fit_rms_mm",
        "arc_deg",
        "axis_se_mm",
        "stack_mm",
        "top_mm",
        "status",
        "reason",
    ]
    return pd.DataFrame(rows, columns=cols)
