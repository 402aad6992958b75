"""The checks on the bars fitted in one lattice (refined method, :func:`~rebarlib.geometry.find_bars`):
bars found from a few points where the depth is mostly lost, things off their direction's level,
bars seen only in parts, overlapping axes, and fits far worse than the lattice's typical one.
A bar that fails a check is kept "not measured" with the reason, or left out where it is not a
bar of the lattice at all.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from .._status import MEASURED, NOT_MEASURED
from .axis import BarAxis, _longest_run, _runs
from .directions import _bar_candidates

__all__: list = []


def _weighted_median(values, weights) -> float:
    """The value at which half the total weight lies on either side (the lower one on a tie)."""
    order = np.argsort(values)
    v = np.asarray(values, float)[order]
    c = np.cumsum(np.asarray(weights, float)[order])
    return float(v[int(np.searchsorted(c, 0.5 * c[-1]))])


def _level(bars: list) -> float:
    """The level of a direction's bars: their axis heights' median weighted by the length each
    is seen over (docs/decisions/064)."""
    return _weighted_median([b.axis_height_mm for b in bars], [max(b.t1_mm - b.t0_mm, 1.0) for b in bars])


def _density(b: BarAxis) -> float:
    """A bar's fitted points per mm of its extent."""
    return b.n_points / max(b.t1_mm - b.t0_mm, 1.0)


def _off_their_level(bars: list, radii: dict, max_r: float, prm) -> list:
    """Something lying well below the other bars of its direction (a spacer block's top, the
    stub of a chair, the mixed pixels along a bar's silhouette fitted as a short bar) is not a
    bar of this lattice level and is left out; a bar fitted well above them was fitted on a
    sliver (seen beside a bar over it) and its axis is not where it seems: "not measured".

    The direction's level is the median of its bars' axis heights weighted by the length each
    is seen over: a bar's height rests on its whole stretch, and with two bars the plain median
    lies half-way between them, so a 55 mm stretch fitted 19 mm low would pass beside a 460 mm
    bar at its true height (docs/decisions/064)."""
    for g in {b.group for b in bars}:
        mine = [b for b in bars if b.group == g and b.status == MEASURED]
        if len(mine) >= 2:
            med = _level(mine)
            tol = prm.level_tol_radii * radii.get(g, max_r)
            bars = [b for b in bars if b.group != g or b.status != MEASURED or b.axis_height_mm >= med - tol]
            bars = [
                replace(
                    b,
                    status=NOT_MEASURED,
                    reason=f"axis {b.axis_height_mm - med:.1f} mm above the other bars of "
                    "its direction: fitted on the sliver of it that is seen, its axis cannot be placed",
                )
                if b.group == g and b.status == MEASURED and b.axis_height_mm > med + tol
                else b
                for b in bars
            ]
    return bars


def _seen_in_parts(bars: list, min_arc_deg: float, max_arc_deg: float, prm) -> list:
    """A bar seen only along one edge does not fix its axis: the fixed-radius circle can slide
    along the visible arc. "Not measured": under 2/3 of ``min_arc_deg`` of its cross-section
    seen, or under ``min_arc_deg`` and sparsely sampled (under a quarter of the layer's typical
    points per mm), or over ``max_arc_deg`` (two flanks of a bar under a bar above it).

    A sparsely sampled bar whose circle sits more than ``prm.sliver_level_radii`` radii off the
    other bars of its direction (their length-weighted median axis height) is "not measured"
    whatever arc its points cover: the nearer bar beside it leaves only a strip of its section,
    and a circle slid down along that strip covers it with a wide arc while its axis lies a
    centimetre or more off the bar's (docs/decisions/072). The bars of one level rest on the
    same supports; a bar seen whole that far off them is a finding and stays measured, as a bar
    the image border cuts does (:func:`~rebarlib.geometry.flag_border_cut`)."""
    measured = [b for b in bars if b.status == MEASURED]
    if not measured:
        return bars
    typical = float(np.median([_density(b) for b in measured]))

    def level_of(b):
        others = [o for o in measured if o.group == b.group and o is not b]
        return _level(others) if len(others) >= 2 else None

    def reason(b) -> str | None:
        density = _density(b)
        seen = f"({density:.1f} points/mm against {typical:.1f} typical)"
        sparse = density < prm.sparse_density_share * typical
        if (
            b.arc_deg < prm.arc_min_share * min_arc_deg
            or b.arc_deg > max_arc_deg
            or (b.arc_deg < min_arc_deg and sparse)
        ):
            return (
                f"{b.arc_deg:.0f}° of the bar's cross-section is covered by its points {seen}: "
                "it is seen only in parts, its axis cannot be placed"
            )
        level = level_of(b) if sparse else None
        if level is not None and abs(b.axis_height_mm - level) > prm.sliver_level_radii * b.radius_mm:
            return (
                f"only a strip of the bar is seen {seen}, and the circle fitted to it sits "
                f"{b.axis_height_mm - level:+.1f} mm off the other bars of its direction: "
                "its axis cannot be placed"
            )
        return None

    out = []
    for b in bars:
        why = reason(b) if b.status == MEASURED else None
        out.append(b if why is None else replace(b, status=NOT_MEASURED, reason=why))
    return out


def _sparse_bars(
    bars: list, cand: list, ambiguous, h, *, layer: str, min_extent_mm: float, min_points: int = 8
) -> list:
    """Bars whose depth is mostly lost: a stretch along a direction with too few points for the
    density test of the candidates, whose few points (not already fitted to a bar) sit at the
    direction's bar height over at least 80 % of its 5 mm cells. Each is reported "not
    measured", never dropped silently and never given a number.

    Parameters
    ----------
    bars : list of BarAxis
        The bars fitted so far (their points are not evidence of another bar).
    cand : list of _Direction
        Each direction's band of points (:func:`rebarlib.geometry.bars._direction_band`).
    ambiguous : ndarray of bool
        Points in both directions' bands (left out).
    h : ndarray
        The points' heights (mm).
    layer : str
    min_extent_mm : float
        The least sampled extent of a bar.
    min_points : int
        The least points at the bar's height.

    Returns
    -------
    list of BarAxis
        The bars found this way (status "not measured", no fit: ``rms_mm`` NaN).
    """
    out = []
    # points already fitted as part of a bar (the crossing bars above or below, a neighbour)
    # are not evidence of another bar: without them, what is left along a loose run is the
    # hidden bar's own few points and whatever else lies there (spacers, ties)
    claimed = np.zeros(len(h), bool)
    for b in bars:
        if b.point_index is not None:
            claimed[b.point_index] = True
    for g, d, n2, off, along, r, centres, near, member, win in cand:
        same = [b for b in bars if b.group == g and b.status == MEASURED]
        if len(same) < 2:
            continue
        axis_h = float(np.median([b.axis_height_mm for b in same]))
        top = axis_h + r
        known = np.array([float(b.plan_point(b.t_mid) @ n2) for b in bars if b.group == g])
        loose, _ = _bar_candidates(off, along, radius_mm=r, min_length_mm=min_extent_mm, min_cell_points=1)
        for c in loose:
            if len(known) and np.min(np.abs(known - c)) < 2.5 * r:
                continue
            sel = (np.abs(off - c) < r) & ~ambiguous & ~claimed
            hs = h[sel]
            # the points of a bar seen from above lie on its upper half: between the axis and the top
            on_bar = (hs > axis_h - 0.5 * r) & (hs < top + 0.5 * r)
            if on_bar.sum() < min_points:
                continue
            idx = np.where(sel)[0][on_bar]
            t = along[idx]
            t0, t1 = _longest_run(t, cell_mm=5.0, max_gap_mm=max(60.0, 8 * r))
            if t1 - t0 < min_extent_mm:
                continue
            # along that stretch, what lies at the position must be at the bar's height: at least
            # 80 % of the 5 mm cells holding points there hold points at the bar's height. Counted
            # in cells, not points: a spacer block under the bar is sampled far more densely than
            # the hidden bar's few specks, yet covers only a few cm of it
            ta = along[sel]
            inside = (ta >= t0) & (ta <= t1)
            n_cells = len(np.unique(np.floor(ta[inside] / 5.0)))
            if len(np.unique(np.floor(ta[inside & on_bar] / 5.0))) < 0.8 * n_cells:
                continue
            keep = (t >= t0) & (t <= t1)
            out.append(
                BarAxis(
                    layer,
                    d,
                    float(np.median(off[idx][keep])),
                    0.0,
                    axis_h,
                    0.0,
                    float(t0),
                    float(t1),
                    r,
                    int(keep.sum()),
                    float("nan"),
                    idx[keep],
                    g,
                    status=NOT_MEASURED,
                    reason=f"only {int(keep.sum())} points over {t1 - t0:.0f} mm (its depth is mostly "
                    "missing): too few to fit its cross-section",
                )
            )
            known = np.append(known, c)
    return out


def _drop_overlaps(bars: list) -> list:
    """Two bars of one direction cannot overlap: of two axes closer than the sum of their radii
    along a common stretch, the one with more points is kept (the other is its edge or shadow
    fringe).

    Parameters
    ----------
    bars : list of BarAxis

    Returns
    -------
    list of BarAxis
        The bars kept, in their order.
    """
    keep = sorted(bars, key=lambda b: -b.n_points)
    out = []
    for b in keep:
        clash = False
        for o in out:
            if o.group != b.group:
                continue
            p = b.plan_point(np.array([b.t_mid]))[0]
            d = abs(float((p - o.plan_point(np.array([float(p @ o.direction)]))[0]) @ o.normal2d))
            overlap_t = min(b.t1_mm, o.t1_mm) - max(b.t0_mm, o.t0_mm)
            if d < b.radius_mm + o.radius_mm and overlap_t > 0:
                clash = True
                break
        if not clash:
            out.append(b)
    order = {id(b): i for i, b in enumerate(bars)}
    return sorted(out, key=lambda b: order[id(b)])


def _laps(bars: list, plan: np.ndarray, h: np.ndarray, min_diameters: float, min_share: float = 0.25) -> list:
    """The bars with ``lap_shift_mm`` set where a bar touching them alongside is seen: a lap.

    A lap's two bars lie side by side, touching, over 30 diameters or more, and stand together
    for one design position; its middle, not either bar, is where that position's spacings are
    measured from. The fit often keeps one of the two: their bands overlap, and the second is
    either never a candidate of its own or dropped as overlapping (:func:`_drop_overlaps`). Its
    points are still there, beside the kept bar's. Along the bar, in stations one diameter long,
    the points at the bar's height whose offset across lies between 1.5 and 3 radii on one side
    (a bar touching it has its axis 2 radii away; the bar's own points lie within one) are
    counted against the bar's own; a station is occupied where they number at least
    ``min_share`` of the bar's own there (the band takes the outer three quarters of a touching
    bar, whose far flank the camera sees edge-on or not at all). Where the points beside in a
    run of occupied stations on one side span ``min_diameters`` diameters, and those points lie
    at the height of the bar's own (within half a radius, median against median: a bar of the
    same level, not the fringe of flying pixels at a bar's edge, whose heights fall towards the
    ground), the bar is lapped on that side, and its ``lap_shift_mm`` is one radius towards it:
    the middle of two touching axes. (The median offset of those points is no better: it leans
    outwards where the band cuts the other bar's near flank off, and with the side the camera
    sees it from.)
    Lapped on both sides, the line was fitted through both pieces of the lap (one alone at each
    end, the two side by side between) and lies at its middle already: no shift
    (docs/decisions/073).

    Parameters
    ----------
    bars : list of BarAxis (only measured ones are examined)
    plan, h : (N, 2) plan positions and (N,) heights of the lattice's points
    min_diameters : float, the shortest span of the points beside in a run of occupied stations,
        in diameters
    min_share : float, the least share of the bar's own points beside it in an occupied station

    Returns
    -------
    list of BarAxis
        The bars, in their order; a lapped bar is a copy with its ``lap_shift_mm``.
    """
    out = []
    for b in bars:
        shift = _lap_shift(b, plan, h, min_diameters, min_share) if b.status == MEASURED and b.radius_mm > 0 else 0.0
        out.append(replace(b, lap_shift_mm=shift) if shift else b)
    return out


def _lap_shift(b: BarAxis, plan: np.ndarray, h: np.ndarray, min_diameters: float, min_share: float = 0.25) -> float:
    """``lap_shift_mm`` of one bar (:func:`_laps`): 0.0 where no lap is seen."""
    r = b.radius_mm
    t = plan @ b.direction
    near = (t >= b.t0_mm) & (t <= b.t1_mm)
    t = t[near]
    across = plan[near] @ b.normal2d - (b.offset_mm + b.slope * t)
    dh = h[near] - (b.centre_h_mm + b.h_slope * t)
    at_height = (dh > -0.5 * r) & (dh < 1.5 * r)
    own = at_height & (np.abs(across) <= r)
    if not own.any():
        return 0.0
    n_st = int(np.ceil((b.t1_mm - b.t0_mm) / (2 * r))) + 1
    st = np.minimum(((t - b.t0_mm) / (2 * r)).astype(int), n_st - 1)
    n_own = np.bincount(st[own], minlength=n_st)
    own_h = float(np.median(dh[own]))
    lapped = []
    for side in (1, -1):
        beside = at_height & (side * across > 1.5 * r) & (side * across < 3.0 * r)
        occupied = (np.bincount(st[beside], minlength=n_st) >= min_share * n_own) & (n_own > 0)
        # the run's length is what its points span: a station its piece only enters counts
        # as occupied at a quarter, but adds none of its length
        run = 0.0
        for start, stop in _runs(occupied):
            tb = t[beside & (st >= start) & (st < stop)]
            run = max(run, float(tb.max() - tb.min()))
        if run >= min_diameters * 2 * r and abs(float(np.median(dh[beside])) - own_h) <= 0.5 * r:
            lapped.append(side)
    # a touching bar on both sides: the line was fitted through both pieces of the lap (one
    # alone at each end, side by side between), and lies at its middle already
    return float(lapped[0] * r) if len(lapped) == 1 else 0.0


def _rms_outliers(bars: list, max_rms_ratio: float) -> list:
    """The bars without the measured ones whose fit residual exceeds ``max_rms_ratio`` times the
    lattice's median (the median is the sensor noise on bars; a far worse fit is not a bar).

    Parameters
    ----------
    bars : list of BarAxis
    max_rms_ratio : float

    Returns
    -------
    list of BarAxis
        The bars kept, in their order; all of them where fewer than 3 are measured.
    """
    rms = [b.rms_mm for b in bars if b.status == MEASURED]
    if len(rms) >= 3:
        limit = max_rms_ratio * float(np.median(rms))
        bars = [b for b in bars if b.status != MEASURED or b.rms_mm <= limit]
    return bars
