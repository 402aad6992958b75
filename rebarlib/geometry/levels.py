"""Levels within a lattice: each direction group's height, each bar's top, how far a top bar
stands above the bars it rests on, and which group is "bottom" and which "top".
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .._status import MEASURED
from .axis import BarAxis


def level_heights(bars: list) -> dict:
    """Median axis height of each direction group's measured bars.

    Parameters
    ----------
    bars : list of BarAxis

    Returns
    -------
    dict ``{group: height_mm}`` (groups without a measured bar left out)
    """
    out = {}
    for g in sorted({b.group for b in bars}):
        hs = [b.axis_height_mm for b in bars if b.group == g and b.status == MEASURED]
        if hs:
            out[g] = float(np.median(hs))
    return out


def _crest_line(b: BarAxis, q) -> tuple[float, float] | None:
    """Height of a bar's top along it, ``h = c0 + c1 · t``, from its own points (slab frame): those
    within 0.35 radius of the axis across, each raised by the circle's sag there (s² / 2r, under
    0.07 r), fitted by a line with outliers beyond 2.5 robust σ left out. None with under 10
    such points."""
    q = np.asarray(q, float)
    if len(q) < 10 or not b.radius_mm > 0:
        return None
    t = q[:, :2] @ b.direction
    s = q[:, :2] @ b.normal2d - (b.offset_mm + b.slope * t)
    near = np.abs(s) < 0.35 * b.radius_mm
    if near.sum() < 10:
        return None
    t, hc = t[near], q[near, 2] + s[near] ** 2 / (2 * b.radius_mm)
    keep = np.ones(len(t), bool)
    for _ in range(2):
        A = np.column_stack((np.ones(keep.sum()), t[keep]))
        c = np.linalg.lstsq(A, hc[keep], rcond=None)[0]
        res = hc - (c[0] + c[1] * t)
        mad = 1.4826 * float(np.median(np.abs(res[keep] - np.median(res[keep]))))
        keep = np.abs(res) <= max(2.5 * mad, 0.1)
        if keep.sum() < 10:
            return None
    return float(c[0]), float(c[1])


def _crest_lines(bars: list, points: list | None) -> list:
    """Per bar, its top's height along it ``(c0, c1)`` (:func:`_crest_line` from its slab-frame
    ``points``; from the fitted circle without them); None for a bar not measured."""

    def top_line(i, b):
        if b.status != MEASURED:
            return None
        if points is None:
            return b.centre_h_mm + b.radius_mm, b.h_slope
        return None if points[i] is None else _crest_line(b, points[i])

    return [top_line(i, b) for i, b in enumerate(bars)]


def top_heights(bars: list, points: list | None = None) -> np.ndarray:
    """Per bar, the height of its top above the formwork at the middle of its visible extent, read
    off its own points near its axis (:func:`_crest_line`: not off the fixed-radius circle, whose
    top a bar of another size pulls); without ``points`` (slab frame), the fitted circle's. NaN
    for a bar not measured. The bars of one level rest on the same supports, so their tops differ
    by their diameters (the diameter stage compares a bar's top with its level's).

    Parameters
    ----------
    bars : list of BarAxis
    points : per bar, its slab-frame points (or None), or None for all

    Returns
    -------
    (len(bars),) float, mm above the formwork
    """
    return _tops(bars, _crest_lines(bars, points))


def _tops(bars: list, crest: list) -> np.ndarray:
    return np.array([np.nan if c is None else c[0] + c[1] * b.t_mid for b, c in zip(bars, crest)])


_MIN_CROSSINGS = 2  # stack_heights: crossings with measured bottom bars a top bar's stack height needs


def stack_heights(bars: list, points: list | None = None, *, min_crossings: int = _MIN_CROSSINGS) -> np.ndarray:
    """Per bar, how far its top stands above the tops of the bars it rests on: the top-level bars
    of a lattice lie on its bottom-level bars, so at each crossing the top bar's top is one
    diameter (its rib envelope) above the bottom bar's top. Measured at the crossings of the
    fitted axes in plan, with each bar's own top height there (a tilted or sagging mesh is
    followed); the median over the crossings within both bars' visible extents. NaN for a
    bottom-level bar, a bar not measured, or under ``min_crossings`` crossings with measured
    bottom bars.

    ``points``: per bar, its points in the slab frame (or None): the tops are then read off the
    points near the axis (:func:`_crest_line`), which does not depend on the radius the axis
    was fitted with; without them, the fitted circles' tops are used, which a bar of another size
    than the fit's radius pulls by up to a millimetre or two. It assumes the two bars touch: a gap
    between them (a bar lifted by a tie or bent) adds to it.

    Parameters
    ----------
    bars : list of BarAxis with ``layer`` and ``level`` set
    points : per bar, its slab-frame points (or None), or None for all
    min_crossings : crossings with measured bottom bars a top bar needs

    Returns
    -------
    (len(bars),) float, mm (NaN where not measured, above)
    """
    return _stacks(bars, _crest_lines(bars, points), min_crossings)


def _stacks(bars: list, crest: list, min_crossings: int) -> np.ndarray:
    out = np.full(len(bars), np.nan)
    for i, b in enumerate(bars):
        if b.level != "top" or crest[i] is None:
            continue
        diffs = []
        for j, c in enumerate(bars):
            if c.layer != b.layer or c.level != "bottom" or crest[j] is None:
                continue
            # crossing in plan: b.plan_point(t) = c.plan_point(s), both linear in their argument
            A = np.column_stack((b.direction + b.slope * b.normal2d, -(c.direction + c.slope * c.normal2d)))
            if abs(np.linalg.det(A)) < 1e-6:
                continue
            t, s = np.linalg.solve(A, c.offset_mm * c.normal2d - b.offset_mm * b.normal2d)
            if b.t0_mm <= t <= b.t1_mm and c.t0_mm <= s <= c.t1_mm:
                diffs.append((crest[i][0] + crest[i][1] * t) - (crest[j][0] + crest[j][1] * s))
        if len(diffs) >= min_crossings:
            out[i] = float(np.median(diffs))
    return out


def assign_levels(bars: list) -> list:
    """Name each direction group "bottom" (lower axes) or "top" (resting on the bottom bars).

    A group is placed by its measured bars' median axis height (:func:`level_heights`); a group
    with none measured, by the median of its bars' approximate heights (a bar "not measured" still
    carries the height its direction's band was found at). Two groups always get two names: with
    both named "bottom", a lattice's two directions would be counted, spaced and judged as one
    row.

    Parameters
    ----------
    bars : list of BarAxis of one lattice, ``group`` set

    Returns
    -------
    list of BarAxis with ``level`` set (one group alone is "bottom")

    Examples
    --------
    >>> from rebarlib.geometry.axis import BarAxis
    >>> def bar(g, h, status="measured"):
    ...     d = np.array([1.0, 0.0]) if g == 0 else np.array([0.0, 1.0])
    ...     return BarAxis("lower", d, 0.0, 0.0, h, 0.0, 0.0, 500.0, 7.0, 100, 0.3, group=g, status=status)
    >>> [b.level for b in assign_levels([bar(0, 48.0, "not measured"), bar(1, 36.0, "not measured")])]
    ['top', 'bottom']
    """
    hs = level_heights(bars)
    for g in sorted({b.group for b in bars} - set(hs)):
        rough = [b.axis_height_mm for b in bars if b.group == g and np.isfinite(b.axis_height_mm)]
        if rough:
            hs[g] = float(np.median(rough))
    order = sorted(hs, key=hs.get)
    names = {g: ("bottom" if i == 0 else "top") for i, g in enumerate(order)}
    if len(order) == 1:
        names = {order[0]: "bottom"}
    return [replace(b, level=names.get(b.group, "bottom")) for b in bars]
