"""Every bar of one lattice (refined method): directions by an angular scan, bars as peaks of the
points' offsets across each direction, each bar's points fitted with a cylinder of its rib
envelope's radius.
"""

from __future__ import annotations

import math
from dataclasses import replace
from typing import NamedTuple

import numpy as np

from .axis import BarAxis, _longest_run
from .fit import _facing_fit, _fit_bar, _refit_along_rays, _rms_on
from .params import GeometryParams
from .partial import _approximate_axes


def direction_sharpness(plan, angles_rad, bin_mm) -> np.ndarray:
    """How concentrated the plan offsets (N, 2) mm across each direction are: the sum of squared
    counts of a ``bin_mm`` histogram of the offsets, for each angle (radians) in ``angles_rad``.

    Examples
    --------
    >>> pts = np.c_[np.arange(100.0), np.zeros(100)]          # a line along x
    >>> s = direction_sharpness(pts, np.radians([0.0, 90.0]), 1.0)
    >>> bool(s[0] > s[1])
    True
    """
    out = np.empty(len(angles_rad))
    for i, a in enumerate(angles_rad):
        o = -plan[:, 0] * math.sin(a) + plan[:, 1] * math.cos(a)
        c = np.bincount(np.floor((o - o.min()) / bin_mm).astype(np.int64))
        out[i] = float(c @ c)
    return out


def bar_directions(plan, *, max_points: int = 5000, min_separation_deg: float = 30.0, rng=None) -> list:
    """The dominant bar directions (plan angles in degrees, [0, 180)) of one lattice's points.

    Bars are long and straight, so offsets across the true direction pile up into narrow peaks:
    scan the angle coarsely (1°, 4 mm bins), then finely (0.05°, 1 mm bins) around the best angle
    and around the best one at least ``min_separation_deg`` away. The second direction is kept
    only if its sharpness stands out of the scan's background.

    Examples
    --------
    >>> t = np.linspace(-300, 300, 400)
    >>> bars = [np.c_[t, np.full_like(t, y)] for y in (-100, 0, 100)]
    >>> bars += [np.c_[np.full_like(t, x), t] for x in (-150, 50)]
    >>> [round(a, 1) for a in bar_directions(np.vstack(bars), rng=0)]
    [0.0, 90.0]
    """
    rng = np.random.default_rng(rng)
    plan = np.asarray(plan, float)
    if len(plan) < 20:
        return []
    sub = plan if len(plan) <= max_points else plan[rng.choice(len(plan), max_points, replace=False)]
    coarse = np.radians(np.arange(0.0, 180.0, 1.0))
    s = direction_sharpness(sub, coarse, 4.0)
    dirs = []
    first = int(np.argmax(s))
    base = float(np.median(s))
    cands = [first]
    dist = np.abs(((np.arange(180) - first) + 90) % 180 - 90)
    far = np.where(dist >= min_separation_deg)[0]
    if len(far):
        second = int(far[np.argmax(s[far])])
        if s[second] > 1.5 * base:
            cands.append(second)
    for c in cands:
        fine = np.radians(c + np.arange(-1.5, 1.5001, 0.05))
        f = direction_sharpness(sub, fine, 1.0)
        dirs.append(float(np.degrees(fine[int(np.argmax(f))]) % 180.0))
    return dirs


def _bar_candidates(
    off, along, *, radius_mm, min_length_mm, cell_mm: float = 5.0, max_gap_mm: float = 10.0, min_cell_points: int = 2
):
    """Offsets (mm) across a direction at which the points run continuously along it.

    The points are rasterised in (offset, along) cells of 1 mm × ``cell_mm``; a cell counts as
    occupied when at least ``min_cell_points`` points lie within ``radius_mm`` across of it (a
    bar's surface is sampled densely, the flying pixels along an edge are not). For every offset row the longest
    occupied stretch (gaps up to ``max_gap_mm`` closed) is measured: a bar gives a stretch as long
    as its visible part, a crossing bar only about its width. Rows with a stretch of at least
    ``min_length_mm`` that are the best within 2.2 radii are bars; each is placed at the densest
    row of its plateau.

    Returns ``(centres, run_mm)``.
    """
    if len(off) == 0:
        return np.array([]), np.array([])
    r = max(1, int(round(radius_mm)))
    o0 = off.min() - 2 * r
    a0 = along.min()
    io = np.floor(off - o0).astype(np.int64)
    ia = np.floor((along - a0) / cell_mm).astype(np.int64)
    n_o, n_a = int(io.max()) + 2 * r + 1, int(ia.max()) + 1
    count = np.bincount(io * n_a + ia, minlength=n_o * n_a).reshape(n_o, n_a).astype(np.int32)
    # occupancy within +-r rows: cumulative sum over rows
    cs = np.cumsum(np.vstack([np.zeros((1, n_a), np.int32), count]), axis=0)
    lo = np.clip(np.arange(n_o) - r, 0, n_o)
    hi = np.clip(np.arange(n_o) + r + 1, 0, n_o)
    occ = (cs[hi] - cs[lo]) >= min_cell_points
    # close gaps of up to max_gap_mm along each row
    g = int(max_gap_mm // cell_mm)
    if g > 0:
        closed = occ.copy()
        for k in range(1, g + 1):
            closed[:, :-k] |= occ[:, k:] & np.maximum.accumulate(occ, axis=1)[:, :-k]
        occ = closed
    # longest run per row: position minus the last empty cell before it
    pos = np.arange(1, n_a + 1)[None, :]
    last_empty = np.maximum.accumulate(np.where(occ, 0, pos), axis=1)
    run = ((pos - last_empty) * occ).max(axis=1) * cell_mm
    dens = count.sum(axis=1).astype(float)
    w = max(1, int(round(2.2 * radius_mm)))
    # greedy: the longest stretch first; its plateau (neighbouring rows with >= 80 % of its
    # length) is one bar, placed at the plateau's point-weighted centre; suppress the plateau
    # and w rows on each side, repeat
    free = run >= min_length_mm
    centres, runs = [], []
    while free.any():
        i = int(np.argmax(np.where(free, run, -1.0)))
        j0 = i
        while j0 - 1 >= 0 and run[j0 - 1] >= 0.8 * run[i] and free[j0 - 1]:
            j0 -= 1
        j1 = i
        while j1 + 1 < n_o and run[j1 + 1] >= 0.8 * run[i] and free[j1 + 1]:
            j1 += 1
        rows_ = np.arange(j0, j1 + 1)
        wts = dens[rows_]
        centre = float((rows_ * wts).sum() / wts.sum()) if wts.sum() > 0 else 0.5 * (j0 + j1)
        centres.append(o0 + centre + 0.5)
        runs.append(float(run[i]))
        free[max(0, j0 - w) : j1 + w + 1] = False
    order = np.argsort(centres)
    return np.array(centres)[order], np.array(runs)[order]


def find_bars(
    points,
    *,
    layer: str,
    radius_mm,
    min_length_mm: float = 50.0,
    min_points: int = 30,
    window_mm: float | None = None,
    min_inlier_fraction: float = 0.6,
    max_rms_ratio: float = 3.0,
    pitch_mm: float | None = None,
    min_arc_deg: float = 90.0,
    max_arc_deg: float = 200.0,
    camera=None,
    skew_check_deg: float = 2.0,
    rng=None,
    params: GeometryParams | None = None,
) -> list:
    """Every bar of one lattice (refined method): directions by angular scan, bars as offset
    peaks, each bar's points fitted with a cylinder of its envelope radius.

    Parameters
    ----------
    points : (N, 3) slab-frame points of one lattice ``(a, b, h)``
    layer : "lower" | "upper" (copied into the bars)
    radius_mm : envelope radius, one number or a dict ``{group index: radius}`` (0 = first
        direction found); the level of each group is decided afterwards from the fitted heights
    min_length_mm, min_points : a peak with less visible length / fewer points is not a bar
    window_mm : half-width of the band of points given to a bar (default radius + 3 mm)
    min_inlier_fraction : a candidate whose robust cylinder fit keeps less than this fraction of
        its points is not a bar
    max_rms_ratio : a candidate whose fit residual (rms) exceeds this multiple of the lattice's
        median bar residual is not a bar (the median is the sensor noise on bars)
    min_arc_deg : a bar whose fitted points span less of its cross-section than this (seen only
        along one edge) and that is sparsely sampled, or that spans less than 2/3 of it, is kept
        with status "not measured"
    max_arc_deg : a camera above a bar sees at most a little more than its upper half; points
        spanning more than this around the fitted axis (two flanks of a bar hidden under a bar
        above it) mean the circle is misplaced: "not measured"
    camera : the camera's position in the slab frame (``to_slab_frame`` of the origin), or None.
        The points of a bar face the camera; a fixed-radius circle through a flank seen alone
        (the top hidden by a bar over it) also fits with its centre on the far side of the
        points, a diameter away, where they would face away from the camera. Given the camera,
        such a fit is refitted from the mirrored centre, and kept only if its points then face
        the camera (else the bar is "not measured").
    skew_check_deg : the bars of a mesh run parallel to within about a degree. A bar fitted more
        skewed than this off its direction is refitted parallel to it, and the parallel axis is
        kept unless the skewed one fits its points more than 10 % better (root-mean-square
        residual over the points the skewed fit keeps): over a short sliver a free fit tilts by
        10° and more, while a bar truly laid askew over a long stretch fits a parallel axis far
        worse and keeps its skew.
    pitch_mm : spacing of the samples on the lattice (depth pixel footprint × stride). A stretch
        of a bar must hold at least 20 % of the points a fully seen bar surface would give
        there; without it, 2 points per cell. The sampled extent of a bar falls short of its
        visible length by about one pitch, so ``min_length_mm`` applies to extent + pitch.
    params : GeometryParams, the search's other tuning (default ``GeometryParams()``)

    Returns
    -------
    list of BarAxis (``group`` = direction index); bars with too few points are kept with
    status "not measured" and the reason.
    """
    prm = params or GeometryParams()
    rng = np.random.default_rng(rng)
    q = np.asarray(points, float)
    if len(q) < min_points:
        return []
    plan, h = q[:, :2], q[:, 2]
    # the extent between a bar's outermost samples falls short of its true visible length by
    # about one sample pitch (half a pitch at each end): a bar of min_length_mm is accepted when
    # its sampled extent reaches min_length_mm - pitch_mm
    min_extent = min_length_mm - (pitch_mm or 0.0)
    dirs = bar_directions(plan, rng=rng)
    radii = radius_mm if isinstance(radius_mm, dict) else {0: float(radius_mm), 1: float(radius_mm)}
    max_r = max(radii.values())
    cand = [
        _direction_band(g, ang, plan, radii.get(g, max_r), min_extent, pitch_mm, window_mm, prm)
        for g, ang in enumerate(dirs)
    ]
    ambiguous = np.zeros(len(q), bool)
    if len(cand) == 2:
        ambiguous = cand[0].member & cand[1].member
    bars = []
    for dn in cand:
        for k, c in enumerate(dn.centres):
            bar = _candidate_bar(
                dn,
                k,
                c,
                h,
                ambiguous,
                layer=layer,
                min_points=min_points,
                min_extent=min_extent,
                min_inlier_fraction=min_inlier_fraction,
                skew_check_deg=skew_check_deg,
                camera=camera,
                prm=prm,
            )
            if bar is not None:
                bars.append(bar)
    # sparse bars: a stretch whose depth is mostly lost (too few points for the density test
    # above) is still a bar if its few points sit at its direction's bar height; it is reported
    # "not measured", never dropped silently and never given a number
    bars += _sparse_bars(bars, cand, ambiguous, h, layer=layer, min_extent_mm=min_extent)
    bars = _off_their_level(bars, radii, max_r, prm)
    bars = _seen_in_parts(bars, min_arc_deg, max_arc_deg, prm)
    # two bars of one direction cannot overlap: of two axes closer than the sum of their radii,
    # keep the one with more points (the other is the first one's edge or shadow fringe)
    bars = _drop_overlaps(bars)
    rms = [b.rms_mm for b in bars if b.status == "measured"]
    if len(rms) >= 3:
        limit = max_rms_ratio * float(np.median(rms))
        bars = [b for b in bars if b.status != "measured" or b.rms_mm <= limit]
    return _approximate_axes(bars, {c[0]: c[3] for c in cand}, h, camera)


class _Direction(NamedTuple):
    """One direction group's candidate bars: the points' offsets across and positions along
    it, the candidates' offsets (``centres``), each point's nearest candidate and whether it
    lies within ``win`` of it."""

    g: int
    d: np.ndarray
    n2: np.ndarray
    off: np.ndarray
    along: np.ndarray
    r: float
    centres: np.ndarray
    near: np.ndarray
    member: np.ndarray
    win: float


def _direction_band(g, ang, plan, r, min_extent, pitch_mm, window_mm, prm) -> _Direction:
    """The candidate bars of direction group ``g`` (plan angle ``ang`` degrees) and the band of
    points around each (:func:`_bar_candidates`)."""
    a = math.radians(ang)
    d = np.array([math.cos(a), math.sin(a)])
    n2 = np.array([-d[1], d[0]])
    off = plan @ n2
    along = plan @ d
    min_cell = 2 if pitch_mm is None else max(2, int(prm.min_cell_share * prm.cell_mm * 2 * r / pitch_mm**2))
    centres, _ = _bar_candidates(
        off, along, radius_mm=r, min_length_mm=min_extent, cell_mm=prm.cell_mm, min_cell_points=min_cell
    )
    win = window_mm if window_mm is not None else r + prm.window_margin_mm
    if len(centres):
        j = np.searchsorted(centres, off)
        j0, j1 = np.clip(j - 1, 0, len(centres) - 1), np.clip(j, 0, len(centres) - 1)
        near = np.where(np.abs(off - centres[j0]) < np.abs(off - centres[j1]), j0, j1)
        member = np.abs(off - centres[near]) < win
    else:
        near = np.zeros(len(off), int)
        member = np.zeros(len(off), bool)
    return _Direction(g, d, n2, off, along, r, centres, near, member, win)


def _candidate_bar(
    dn: _Direction,
    k,
    c,
    h,
    ambiguous,
    *,
    layer,
    min_points,
    min_extent,
    min_inlier_fraction,
    skew_check_deg,
    camera,
    prm,
):
    """The bar at candidate ``k`` (offset ``c``) of a direction: its points' stretch, the
    cylinder fitted to them (:func:`_fitted_bar`), or a "not measured" bar with too few points
    for a fit; None where there is no bar."""
    g, d, r, along = dn.g, dn.d, dn.r, dn.along
    band = dn.member & (dn.near == k)
    # a "run" made mostly of points that also belong to crossing bars is the crossing
    # bars themselves, not a bar of this direction
    if (band & ambiguous).sum() > prm.crossing_share * max(band.sum(), 1):
        return None
    idx = np.where(band & ~ambiguous)[0]
    if len(idx) == 0:
        return None
    t = along[idx]
    # the bar's extent: the longest run of occupied 5 mm cells (a peak can also catch a
    # few stray points far away along the line)
    t0, t1 = _longest_run(t, cell_mm=prm.run_cell_mm, max_gap_mm=max(prm.run_gap_mm, prm.run_gap_radii * r))
    sel = (t >= t0) & (t <= t1)
    idx, t = idx[sel], t[sel]
    length = float(t1 - t0)
    if length < min_extent:
        return None
    if len(idx) < min_points:
        return BarAxis(
            layer,
            d,
            float(c),
            0.0,
            float(np.median(h[idx])) - r,
            0.0,
            float(t0),
            float(t1),
            r,
            len(idx),
            float("nan"),
            idx,
            g,
            status="not measured",
            reason=f"{len(idx)} points, at least {min_points} needed for a cross-section fit",
        )
    return _fitted_bar(
        dn,
        c,
        idx,
        t,
        t0,
        t1,
        h,
        ambiguous,
        layer=layer,
        min_points=min_points,
        min_extent=min_extent,
        min_inlier_fraction=min_inlier_fraction,
        skew_check_deg=skew_check_deg,
        camera=camera,
        prm=prm,
    )


def _fitted_bar(
    dn: _Direction,
    c,
    idx,
    t,
    t0,
    t1,
    h,
    ambiguous,
    *,
    layer,
    min_points,
    min_extent,
    min_inlier_fraction,
    skew_check_deg,
    camera,
    prm,
):
    """A candidate's cylinder, refitted on its band re-centred (:func:`_refit_band`), kept
    parallel unless a skew fits clearly better, on the side facing the camera and with the
    depth noise's bias out; None where most of its points are not on the cylinder."""
    g, d, n2, off, r = dn.g, dn.d, dn.n2, dn.off, dn.r
    fit, idx, t = _refit_band(dn, c, idx, t, t0, t1, h, ambiguous, min_points, prm)
    s_b, h_b = off[idx] - c, h[idx]
    if abs(fit[0][1]) > math.tan(math.radians(skew_check_deg)):
        # more skewed than a mesh's bars are: unless the skew fits the points clearly
        # better, the bar runs parallel to its direction (a short sliver tilts a free fit)
        par = _fit_bar(t, s_b, h_b, r, parallel=True)
        if _rms_on(par, fit, t, s_b, h_b, r) <= prm.skew_gain * fit[2]:
            fit = par
    if camera is not None:
        fit, facing = _facing_fit(fit, t, s_b, h_b, r, camera, c, n2)
        if facing:  # depth noise lies along the lines of sight: take its bias out
            fit = _refit_along_rays(fit, t, s_b, h_b, r, camera, c, d, n2)
    (a0, a1, b0, b1), w, rms, se = fit
    keep = w > 0
    # not a bar: most of the band's points do not lie on a cylinder of the bar's radius
    # (a spacer block, a tie, a chair)
    if keep.mean() < min_inlier_fraction or keep.sum() < min_points:
        return None
    tt = t[keep]
    if tt.max() - tt.min() < min_extent:
        return None
    # how much of the cross-section the points cover: a bar seen only along one edge
    # (the rest hidden by a bar above it) does not fix its axis
    phi = np.degrees(np.arctan2(h[idx][keep] - (b0 + b1 * tt), off[idx][keep] - (c + a0 + a1 * tt)))
    phi = (phi + 90.0) % 360.0 - 90.0  # the seen upper half, [0°, 180°], without a wrap
    arc = float(np.percentile(phi, 95) - np.percentile(phi, 5))
    status, reason = "measured", ""
    if camera is not None and not facing:
        status, reason = (
            "not measured",
            (
                "its points face away from the camera from either side of "
                "them: a flank seen alone, its axis cannot be placed"
            ),
        )
    return BarAxis(
        layer,
        d,
        float(c + a0),
        float(a1),
        float(b0),
        float(b1),
        float(tt.min()),
        float(tt.max()),
        r,
        int(keep.sum()),
        rms,
        idx[keep],
        g,
        status=status,
        reason=reason,
        arc_deg=arc,
        axis_se_mm=float(max(se)),
    )


def _refit_band(dn: _Direction, c, idx, t, t0, t1, h, ambiguous, min_points, prm):
    """``(fit, idx, t)``: the cylinder fitted to a candidate's points, then (twice) to the
    points gathered again around the fitted axis.

    The candidate's centre is only good to a few mm, so the band is re-centred on the bar. It
    also keeps to the bar's height (within a radius of the fitted axis, plus 3 times the fit's
    residual, at least 3 mm): a refit band that moved across picks up points of the crossing
    bars beside the original band (not "ambiguous" there), which lie a bar diameter above this
    bar's surface and would drag the fit off."""
    off, along, r, win = dn.off, dn.along, dn.r, dn.win
    fit = _fit_bar(t, off[idx] - c, h[idx], r)
    for _ in range(prm.refits):
        (a0, a1, b0, b1), w, rms, _ = fit
        pred = c + a0 + a1 * along
        h_axis = b0 + b1 * along
        reach = r + max(prm.refit_reach_mm, prm.refit_reach_rms * rms if np.isfinite(rms) else prm.refit_reach_mm)
        near_axis = (
            (np.abs(off - pred) < win)
            & ~ambiguous
            & (along >= t0 - prm.refit_margin_mm)
            & (along <= t1 + prm.refit_margin_mm)
            & (np.abs(h - h_axis) < reach)
        )
        idx2 = np.where(near_axis)[0]
        if len(idx2) < min_points:
            break
        idx, t = idx2, along[idx2]
        fit = _fit_bar(t, off[idx] - c, h[idx], r)
    return fit, idx, t


def _off_their_level(bars: list, radii: dict, max_r: float, prm) -> list:
    """Something lying well below the other bars of its direction (a spacer block's top, the
    stub of a chair) is not a bar of this lattice level and is left out; a bar fitted well
    above them was fitted on a sliver (seen beside a bar over it) and its axis is not where it
    seems: "not measured"."""
    for g in {b.group for b in bars}:
        hs = [b.axis_height_mm for b in bars if b.group == g and b.status == "measured"]
        if len(hs) >= 2:
            med, tol = float(np.median(hs)), prm.level_tol_radii * radii.get(g, max_r)
            bars = [b for b in bars if b.group != g or b.status != "measured" or b.axis_height_mm >= med - tol]
            bars = [
                replace(
                    b,
                    status="not measured",
                    reason=f"axis {b.axis_height_mm - med:.1f} mm above the other bars of "
                    "its direction: fitted on the sliver of it that is seen, its axis cannot be placed",
                )
                if b.group == g and b.status == "measured" and b.axis_height_mm > med + tol
                else b
                for b in bars
            ]
    return bars


def _seen_in_parts(bars: list, min_arc_deg: float, max_arc_deg: float, prm) -> list:
    """A bar seen only along one edge does not fix its axis: the fixed-radius circle can slide
    along the visible arc. "Not measured": under 2/3 of ``min_arc_deg`` of its cross-section
    seen, or under ``min_arc_deg`` and sparsely sampled (under a quarter of the layer's typical
    points per mm), or over ``max_arc_deg`` (two flanks of a bar under a bar above it)."""
    dens = [b.n_points / max(b.t1_mm - b.t0_mm, 1.0) for b in bars if b.status == "measured"]
    if dens:
        typical = float(np.median(dens))
        bars = [
            replace(
                b,
                status="not measured",
                reason=(
                    f"{b.arc_deg:.0f}° of the bar's cross-section is covered by its points "
                    f"({b.n_points / max(b.t1_mm - b.t0_mm, 1.0):.1f} points/mm against "
                    f"{typical:.1f} typical): it is seen only in parts, its axis cannot be placed"
                ),
            )
            if b.status == "measured"
            and (
                b.arc_deg < prm.arc_min_share * min_arc_deg
                or b.arc_deg > max_arc_deg
                or (
                    b.arc_deg < min_arc_deg
                    and b.n_points / max(b.t1_mm - b.t0_mm, 1.0) < prm.sparse_density_share * typical
                )
            )
            else b
            for b in bars
        ]
    return bars


def _sparse_bars(
    bars: list, cand: list, ambiguous, h, *, layer: str, min_extent_mm: float, min_points: int = 8
) -> list:
    out = []
    # points already fitted as part of a bar (the crossing bars above or below, a neighbour)
    # are not evidence of another bar: without them, what is left along a loose run is the
    # hidden bar's own few points and whatever else lies there (spacers, ties)
    claimed = np.zeros(len(h), bool)
    for b in bars:
        if b.point_index is not None:
            claimed[b.point_index] = True
    for g, d, n2, off, along, r, centres, near, member, win in cand:
        same = [b for b in bars if b.group == g and b.status == "measured"]
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
                    status="not measured",
                    reason=f"only {int(keep.sum())} points over {t1 - t0:.0f} mm (its depth is mostly "
                    "missing): too few to fit its cross-section",
                )
            )
            known = np.append(known, c)
    return out


def _drop_overlaps(bars: list) -> list:
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
