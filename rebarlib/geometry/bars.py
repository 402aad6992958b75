"""Every bar of one lattice (refined method): directions by an angular scan, bars as peaks of the
points' offsets across each direction, each bar's points fitted with a cylinder of its rib
envelope's radius.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from .._checks import RebarInputError
from .._status import MEASURED, NOT_MEASURED
from .axis import BarAxis, _longest_run
from .bar_checks import _drop_overlaps, _laps, _off_their_level, _rms_outliers, _seen_in_parts, _sparse_bars
from .directions import _bar_candidates, bar_directions, direction_sharpness
from .fit import _facing_fit, _fit_bar, _place_along_rays, _refit_along_rays, _rms_on
from .params import GeometryParams
from .partial import _approximate_axes

__all__ = ["find_bars", "bar_directions", "direction_sharpness"]


class _Limits(NamedTuple):
    """What every candidate bar of one :func:`find_bars` call is checked against (its
    arguments, made once and handed down)."""

    layer: str
    min_points: int
    min_extent: float
    min_inlier_fraction: float
    skew_check_deg: float
    camera: object
    prm: GeometryParams
    noise_mm: float | None = None
    edges: tuple | None = None


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
    noise_mm: float | None = None,
    edges=None,
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
    noise_mm : the capture's depth noise (σ, mm), as measured on its formwork plane. Where it
        reaches ``params.ray_check_noise_share`` of a bar's radius, a bar whose circle fit the
        placing along its lines of sight contradicts is "not measured" (docs/decisions/048).
        None: each bar's own range residuals' robust SD is taken instead.
    edges : ``(silhouette, beside_nearer)``, two (N,) bool arrays from the depth image
        (``rebarlib._inspect.edge_flags``): the point is the nearer surface's last pixel at an
        occluding edge, or lies within a few pixels of a nearer surface. Given them, a bar bordered along a
        stretch by a nearer surface on one flank and clear on the other (a lower bar half under
        an upper bar) is fitted there without its clear flank's last pixel, as the cloud has
        none at its covered flank (docs/decisions/055). None: every point as it comes.

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
    if edges is not None:
        edges = tuple(np.asarray(e, bool) for e in edges)
        if len(edges) != 2 or any(e.shape != (len(q),) for e in edges):
            raise RebarInputError(f"edges: expected two ({len(q)},) bool arrays (one flag per point), got {len(edges)}")
    lim = _Limits(layer, min_points, min_extent, min_inlier_fraction, skew_check_deg, camera, prm, noise_mm, edges)
    bars = []
    for dn in cand:
        for k, c in enumerate(dn.centres):
            bar = _candidate_bar(dn, k, c, h, ambiguous, lim)
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
    bars = _rms_outliers(bars, max_rms_ratio)
    # a bar touching a kept one alongside is a lap: its spacings are taken from the lap's middle
    bars = _laps(bars, plan, h, prm.lap_min_diameters, prm.lap_min_share)
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


def _candidate_bar(dn: _Direction, k, c, h, ambiguous, lim: _Limits):
    """The bar at candidate ``k`` (offset ``c``) of a direction: its points' stretch, the
    cylinder fitted to them (:func:`_fitted_bar`), or a "not measured" bar with too few points
    for a fit; None where there is no bar."""
    g, d, r, along = dn.g, dn.d, dn.r, dn.along
    band = dn.member & (dn.near == k)
    # a "run" made mostly of points that also belong to crossing bars is the crossing
    # bars themselves, not a bar of this direction
    if (band & ambiguous).sum() > lim.prm.crossing_share * max(band.sum(), 1):
        return None
    idx = np.where(band & ~ambiguous)[0]
    if len(idx) == 0:
        return None
    t = along[idx]
    # the bar's extent: the longest run of occupied 5 mm cells (a peak can also catch a
    # few stray points far away along the line)
    t0, t1 = _longest_run(t, cell_mm=lim.prm.run_cell_mm, max_gap_mm=max(lim.prm.run_gap_mm, lim.prm.run_gap_radii * r))
    sel = (t >= t0) & (t <= t1)
    idx, t = idx[sel], t[sel]
    length = float(t1 - t0)
    if length < lim.min_extent:
        return None
    if len(idx) < lim.min_points:
        return BarAxis(
            lim.layer,
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
            status=NOT_MEASURED,
            reason=f"{len(idx)} points, at least {lim.min_points} needed for a cross-section fit",
        )
    return _fitted_bar(dn, c, idx, t, t0, t1, h, ambiguous, lim)


def _fitted_bar(dn: _Direction, c, idx, t, t0, t1, h, ambiguous, lim: _Limits):
    """A candidate's cylinder, refitted on its band re-centred (:func:`_refit_band`), kept
    parallel unless a skew fits clearly better, on the side facing the camera and with the
    depth noise's bias out; None where most of its points are not on the cylinder."""
    g, d, n2, off, r = dn.g, dn.d, dn.n2, dn.off, dn.r
    fit, idx, t = _refit_band(dn, c, idx, t, t0, t1, h, ambiguous, lim.min_points, lim.prm)
    if lim.edges is not None:
        fit, idx, t = _without_clear_flank_edge(fit, idx, t, off[idx] - c, h, r, lim)
    s_b, h_b = off[idx] - c, h[idx]
    if abs(fit[0][1]) > math.tan(math.radians(lim.skew_check_deg)):
        # more skewed than a mesh's bars are: unless the skew fits the points clearly
        # better, the bar runs parallel to its direction (a short sliver tilts a free fit)
        par = _fit_bar(t, s_b, h_b, r, parallel=True)
        if _rms_on(par, fit, t, s_b, h_b, r) <= lim.prm.skew_gain * fit[2]:
            fit = par
    apart = None
    if lim.camera is not None:
        fit, facing = _facing_fit(fit, t, s_b, h_b, r, lim.camera, c, n2)
        if facing:  # depth noise lies along the lines of sight: take its bias out
            fit = _refit_along_rays(fit, t, s_b, h_b, r, lim.camera, c, d, n2)
            apart = _apart_along_rays(fit, t, s_b, h_b, r, lim.camera, c, d, n2, lim.prm, lim.noise_mm)
    (a0, a1, b0, b1), w, rms, se = fit
    keep = w > 0
    # not a bar: most of the band's points do not lie on a cylinder of the bar's radius
    # (a spacer block, a tie, a chair)
    if keep.mean() < lim.min_inlier_fraction or keep.sum() < lim.min_points:
        return None
    tt = t[keep]
    if tt.max() - tt.min() < lim.min_extent:
        return None
    # how much of the cross-section the points cover: a bar seen only along one edge
    # (the rest hidden by a bar above it) does not fix its axis
    phi = np.degrees(np.arctan2(h[idx][keep] - (b0 + b1 * tt), off[idx][keep] - (c + a0 + a1 * tt)))
    phi = (phi + 90.0) % 360.0 - 90.0  # the seen upper half, [0°, 180°], without a wrap
    arc = float(np.percentile(phi, 95) - np.percentile(phi, 5))
    status, reason = MEASURED, ""
    if lim.camera is not None and not facing:
        status, reason = (
            NOT_MEASURED,
            (
                "its points face away from the camera from either side of "
                "them: a flank seen alone, its axis cannot be placed"
            ),
        )
    elif apart is not None:
        status, reason = NOT_MEASURED, apart
    return BarAxis(
        lim.layer,
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


def _apart_along_rays(fit, t, s, h, r, camera, c, d, n2, prm: GeometryParams, noise_mm=None) -> str | None:
    """Why the circle fit's axis cannot be stated (docs/decisions/048), or None: where the axis
    placed from the points' ranges along their lines of sight (:func:`_place_along_rays`, free
    of the depth noise's bias) lies higher or lower than the circle fit's by more than twice
    their combined standard uncertainty, the circle fit's taken as the uncertainty budget states
    a bar's height (:data:`~rebarlib.uncertainty.BAR_FIT_SHARE_OF_RMS` times its residual RMS,
    and :data:`~rebarlib.uncertainty.LEVEL_FIT_COMMON_MM`), the placing's from its profile.
    Checked only where the capture's depth noise ``noise_mm`` (its formwork plane's; without
    it, the placing's range residuals' robust SD) reaches ``prm.ray_check_noise_share`` of the
    radius (below it the circle fit's first-order noise correction holds on any arc of 90° or
    more). Under depth noise of half the bar's radius a
    section cut by a bar above (a parallel bar of the other lattice hides half of it) lets the
    circle slide along the arc seen: lifted by up to 6 mm, its stated uncertainty a tenth of
    that."""
    from ..uncertainty import BAR_FIT_SHARE_OF_RMS, LEVEL_FIT_COMMON_MM

    if noise_mm is not None and noise_mm < prm.ray_check_noise_share * r:
        return None
    placed = _place_along_rays(fit, t, s, h, r, camera, c, d, n2)
    if placed is None or (noise_mm is None and placed[4] < prm.ray_check_noise_share * r):
        return None
    (a0, a1, b0, b1), _, rms, _ = fit
    if not np.isfinite(rms):
        return None
    tm = float(np.mean(t))
    dh = placed[1] - (b0 + b1 * tm)
    u_fit = math.hypot(BAR_FIT_SHARE_OF_RMS * rms, LEVEL_FIT_COMMON_MM)
    lim = 2.0 * math.hypot(u_fit, placed[3])
    if abs(dh) <= lim:
        return None
    return (
        f"its circle fit and its points' ranges along the lines of sight place its axis {abs(dh):.1f} mm apart in "
        f"height, more than their uncertainty allows ({lim:.1f} mm): under this depth noise ({rms:.1f} mm "
        "residual) the section seen does not fix it"
    )


def _without_clear_flank_edge(fit, idx, t, s, h, r, lim: _Limits):
    """``(fit, idx, t)`` refitted without the clear flank's last pixel along the stretches where
    the bar's other flank borders a nearer surface (docs/decisions/055).

    The cloud has no points in the fringe just behind an occluding edge (``prepare_cloud``):
    a lower bar half under an upper bar loses its last pixel at the covered flank, while its
    clear flank keeps its own, with whatever the sensor's edge effects add there (fattening,
    mixed depths). The circle then slides towards the clear flank. Leaving that flank's last
    pixel out too makes the two flanks alike again; a bar seen between two clear flanks, or
    with nearer surfaces on both sides (under a crossing bar), keeps every point.
    Cells are one diameter long; a cell is seen from one flank where its points beside a nearer
    surface reach along at least half of it and the bar's own edge pixels all lie across the
    bar beyond every one of them. A bar with ``prm.one_sided_cells`` or more such cells covered
    on the same flank, twice as many as on the other, loses every edge pixel of its own on the
    clear side of its points beside the nearer surface (a cell can miss the test where the
    nearer bar's edge leaves a hole, or the clear flank's last pixel is missing)."""
    silhouette, beside = (e[idx] for e in lim.edges)
    if not beside.any() or not silhouette.any():
        return fit, idx, t
    a0, a1, b0, b1 = fit[0]
    across = s - (a0 + a1 * t)  # from the fitted axis
    cell = np.floor((t - t.min()) / (2.0 * r)).astype(int)
    order = np.argsort(cell, kind="stable")
    sides = []
    for part in np.split(order, np.flatnonzero(np.diff(cell[order])) + 1):
        b, e = part[beside[part]], part[silhouette[part]]
        # a parallel bar's cover runs along the whole cell (a crossing bar's edge runs across
        # it, its points beside the nearer surface within a few pixels along), on one flank:
        # every edge pixel of the bar's own lies across the bar beyond all of those points
        if len(b) and len(e) and t[b].max() - t[b].min() >= r:
            if across[e].min() > across[b].max():
                sides.append(-1)
            elif across[e].max() < across[b].min():
                sides.append(1)
    covered = int(np.sign(sum(sides)))
    n_covered = sides.count(covered)
    if covered == 0 or n_covered < lim.prm.one_sided_cells or n_covered < 2 * sides.count(-covered):
        return fit, idx, t
    # the clear flank's own edge pixels: beyond the middle of the points beside the nearer bar
    mid = float(np.median(across[beside]))
    drop = silhouette & (covered * (across - mid) < 0)
    if not drop.any() or (~drop).sum() < lim.min_points:
        return fit, idx, t
    keep = ~drop
    idx, t, s = idx[keep], t[keep], s[keep]
    tm = float(t.mean())
    refit = _fit_bar(t, s, h[idx], r, start=(a0 + a1 * tm, a1, b0 + b1 * tm, b1))
    return refit, idx, t


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
