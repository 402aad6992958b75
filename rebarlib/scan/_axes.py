"""Stage 5 of a scanned cloud: the slab frame, each lattice's bar axes and their heights, and
the sign of up from the crossings where nothing else settles it."""

from __future__ import annotations

import dataclasses
import math
import warnings

import numpy as np

from .. import geometry as G
from .._checks import RebarInputError
from .._design import Design
from ._bars import _Bar, _crossing_along, _crossing_free, _robust_line, lattice_bars
from ._datum import Datum, split_lattices
from ._util import _band_side, _dot, _slab_frame


_SURFACE_MEAN = 2.0 / math.pi  # mean height of points spread evenly over a bar's upper half, x radius


def _envelope(design: Design, layer: str, level: str) -> float:
    """Width over the ribs (or a plain bar's diameter) of a lattice level's bars, mm."""
    from ..diameter.barsizes import barset_width_mm

    return barset_width_mm(design.lattice(layer).level(level), design.bar_system)


def _to_axis(b: _Bar, layer: str, level: str, group: int, r: float) -> G.BarAxis:
    """A bar as a :class:`~rebarlib.geometry.BarAxis` (slab frame): its axis lies 2r/π under the
    mean height of its points."""
    axis_h = b.mean_h - _SURFACE_MEAN * r
    se = b.resid_sd / math.sqrt(max(b.n, 1))
    return G.BarAxis(
        layer,
        b.direction,
        b.centre,
        b.slope,
        axis_h,
        0.0,
        b.t0,
        b.t1,
        r,
        b.n,
        b.resid_sd,
        b.idx,
        group,
        level,
        arc_deg=float("nan"),
        axis_se_mm=se,
    )


def _all_axes(q, split, design, datum, min_length_mm, rng):
    """Every lattice's bar axes, and per lattice the noise (plan, height) measured on them."""
    bars, noise = [], {}
    for layer in G.LAYERS:
        axes, noise[layer] = _layer_axes(q, split, layer, design, datum, min_length_mm, rng)
        bars += axes
    # the streak fits' products are small ((N ≈ 2 000, 6) by (6, J ≤ 90)): BLAS threads that wake
    # for each of them spin between them: on 2 cores at a load average of 6 the whole inspection
    # of the benchmark's 1.1 M point cloud took 22 s of CPU against 5.4 s with one thread (the
    # same numbers)
    from threadpoolctl import threadpool_limits

    with threadpool_limits(limits=1, user_api="blas"):
        return _refit_seen_sides(q, split, bars, noise, datum), noise


def _refit_seen_sides(q, split: float, bars: list, noise: dict, datum: Datum) -> list:
    """Each bar's offset again as the axis of the streaks its points form in its cross-section
    (:func:`._sides.seen_sides_centre`), the bars above it that run the same way taken as
    occluders of its surface: the mean of a bar's points lies toward the side it was seen from, by
    up to 0.85 r.

    Applied to a whole set (lattice and level) or not at all: where its bars' median range noise
    along the rays, as fitted, is at least their radius. Below, a one-sided bar's points form a
    roundish cloud whose direction the fit cannot tell (the streak is under twice as long as it is
    wide; on simulated one-sided bars at σ 4-8 mm, r 8 mm, the fit stayed at the points' mean),
    and correcting some bars of a set and not their neighbours made spacings worse (decision 026).

    The axis is a line: its offset and its slope are both taken from the fit, through the centres
    of stretches along the bar (decision 030). The stations' shares of a bar's points change
    along it (a nearer station returns more), so the points' mean drifts across along the bar
    (7.7 mm end to end on one bar of a synthetic scan) and the line the earlier stages drew
    through them took a slope that the bar does not have (4.6 mm off at one end, 0.4 mm at the
    other). The band's points where something else crowds it at one place along (a cover
    block or a chair under the bar: :func:`_along_uniform`) are left out first.

    The range noise along the rays is one for a set (:func:`_set_ray_noise`): each bar is fitted
    with its own noise first, which decides whether the fit applies to the set and measures the
    set's noise on its bars; then each bar of the set is fitted again with the noise held at the
    set's (a bar whose second fit fails keeps its first; decision 045)."""
    from ._sides import seen_sides_centre

    plan, h = q[:, :2], q[:, 2]
    out = []
    fits, calls = {}, {}
    proj = {}  # (layer, direction index) -> the layer's rows and their offsets across
    for b in bars:
        sig_plan = noise[b.layer][0]
        r = b.radius_mm
        same = [x for x in bars if x.layer == b.layer]
        r_max = max(x.radius_mm for x in same)
        half = _band_side(r_max, sig_plan)
        over_fw = datum.found and b.layer == "lower"
        reach = 3 * r + 4 * sig_plan
        lo = -4 * datum.noise_mm if over_fw else b.centre_h_mm - reach
        lo = max(lo, split) if b.layer == "upper" else lo
        hi = min(b.centre_h_mm + reach, split) if b.layer == "lower" else b.centre_h_mm + reach
        key = (b.layer, b.group)
        if key not in proj:
            layer_rows = np.flatnonzero(h >= split) if b.layer == "upper" else np.flatnonzero(h < split)
            proj[key] = (layer_rows, _dot(plan[layer_rows], b.normal2d))
        layer_rows, off_all = proj[key]
        drift = abs(b.slope) * float(max(abs(b.t0_mm), abs(b.t1_mm))) + 1.0
        # one pass over the layer's offsets a bar (sorting them once cost more than 40 passes)
        rows = layer_rows[(off_all >= b.offset_mm - half - drift) & (off_all < b.offset_mm + half + drift)]
        rows = rows[(h[rows] > lo) & (h[rows] < hi)]
        t = _dot(plan[rows], b.direction)
        resid = _dot(plan[rows], b.normal2d) - (b.offset_mm + b.slope * t)
        sel = (np.abs(resid) < half) & (t >= b.t0_mm) & (t <= b.t1_mm)
        cross = [c for c in (_cross_axes(b, x) for x in same if x.level != b.level) if np.isfinite(c)]
        sel[sel] = _crossing_free(t[sel], cross, r_max + 2.0 * sig_plan + 2.0)
        pick = np.flatnonzero(sel)
        if len(pick) >= 50:
            pick = pick[_along_uniform(t[pick], 2 * r)]
        if len(pick) < 50:
            out.append(b)
            continue
        pick = pick[:: max(1, len(pick) // 2000)]
        tm = 0.5 * (b.t0_mm + b.t1_mm)
        half_len = max(0.5 * (b.t1_mm - b.t0_mm), 1.0)
        occ = []
        for x in bars:
            cosd = float(x.direction @ b.direction)
            if x is b or abs(cosd) < 0.9 or x.centre_h_mm < b.centre_h_mm + r:
                continue
            xa = float(x.plan_point(np.sign(cosd) * tm) @ b.normal2d) - (b.offset_mm + b.slope * tm)
            occ.append((xa, x.centre_h_mm - b.centre_h_mm, x.radius_mm))
        call = dict(
            a=resid[pick],
            h=h[rows][pick],
            radius_mm=r,
            centre0=(0.0, b.centre_h_mm),
            sigma0_mm=sig_plan,
            half_mm=half,
            formwork_sd_mm=datum.noise_mm if over_fw else None,
            occluders=occ,
            along=(t[pick] - tm) / half_len,
        )
        fits[id(b)] = _line_fit(seen_sides_centre(**call), tm, half_len)
        calls[id(b)] = (call, tm, half_len)
        out.append(b)
    applied = []
    for key in {(b.layer, b.level) for b in out}:
        group = [b for b in out if (b.layer, b.level) == key and fits.get(id(b)) is not None]
        if not group or np.median([fits[id(b)][2] for b in group]) < np.median([b.radius_mm for b in group]):
            continue
        applied.append(group)
    for group in applied:
        ray_sigma = _set_ray_noise([fits[id(b)] for b in group])
        for b in group:
            call, tm, half_len = calls[id(b)]
            again = _line_fit(seen_sides_centre(**{**call, "sigma0_mm": ray_sigma, "sigma_fixed": True}), tm, half_len)
            shift, slope = (fits[id(b)] if again is None else again)[:2]
            i = next(k for k, x in enumerate(out) if x is b)
            out[i] = dataclasses.replace(b, offset_mm=b.offset_mm + float(shift), slope=b.slope + float(slope))
    return out


def _line_fit(fit, tm: float, half_len: float):
    """(offset at 0 along, slope per mm, range noise, direction weights) of a streak fit whose line
    was fitted about the bar's middle ``tm`` with positions scaled by ``half_len``; None for None."""
    if fit is None:
        return None
    c = fit[0]
    return (c[0] - c[2] * tm / half_len, c[2] / half_len, fit[1], fit[2])


def _set_ray_noise(fits: list) -> float:
    """A set's range noise along the rays in its bars' cross-sections (mm), as the streak fits see
    it: the median of the noise fitted on each of its bars.

    Each bar's fit takes its own noise, but on a bar seen from one side the noise and the axis's
    place along the rays trade against each other: the last bar of a set, seen from its inner side
    over its cover blocks, fitted 7.0 mm where its set's bars fitted 9.4-10.9 mm, and the fit put
    it 2.5 mm further inward than the line through its points (decision 045). The noise in a
    section is the range noise σ of the rays that cross it, times the share of each ray that lies
    in the section, √(1 - (u·d)²) for a ray u and a bar d: the same for a set's parallel bars seen
    from the same stations, not for the other direction (σ 15 mm: the two directions of one
    lattice fitted 9.9 and 13.1 mm; one noise for the scan moved a bar over a formwork 2.5 mm and
    made its pair err 5.5 mm). Measured where many bars agree (the median over the set: a
    one-sided fit on either side of it moves it little) and held there for each bar."""
    return float(np.median([f[2] for f in fits]))


def _along_uniform(t, min_cell_mm: float, z: float = 5.0) -> np.ndarray:
    """Mask of a bar's band points away from what crowds the band at one place along it.

    A straight bar gives the same cross-section all along; what lies in its band at one place
    only (a cover block or a chair under it, a tie) adds returns there. Cells along the bar (at
    least ``min_cell_mm``, and long enough for 10 points at the band's density) holding more than
    ``z`` σ over the median count of the cells about them (±4) are left out, with the cell on each
    side (the object straddles cells); σ is the larger of a cell's counting noise and the robust
    spread of all cells about their references (the formwork beside a bar has shadows of its
    own). The density's slow change along the bar (range, incidence) stays under that."""
    if len(t) < 50:
        return np.ones(len(t), bool)
    t0, t1 = float(t.min()), float(t.max())
    dens = len(t) / max(t1 - t0, 1.0)
    cell = max(min_cell_mm, 10.0 / dens)
    k = np.floor((t - t0) / cell).astype(int)
    counts = np.bincount(k)
    occupied = counts > 0  # cells emptied by the crossings' cut are not part of the reference
    pad = 4
    padded = np.pad(np.where(occupied, counts, np.nan).astype(float), pad, constant_values=np.nan)
    with np.errstate(all="ignore"), warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # a window of empty cells only
        ref = np.nanmedian(np.lib.stride_tricks.sliding_window_view(padded, 2 * pad + 1), axis=1)
    ref = np.nan_to_num(ref)
    # the cells' spread about that reference: their counting noise, or more where the band's
    # density has structure of its own (shadows on the formwork beside the bar)
    excess = (counts - ref)[occupied]
    spread = np.maximum(np.sqrt(np.maximum(ref, 1.0)), 1.4826 * float(np.median(np.abs(excess))))
    crowded = occupied & (counts > ref + z * spread)
    crowded = crowded | np.r_[False, crowded[:-1]] | np.r_[crowded[1:], False]
    return ~crowded[k]


def crossing_lift(q, bars: list, noise: dict) -> float:
    """Height (mm) of the points along the bars at their crossings less that away from them,
    each level's median over its bars, averaged over the levels: positive when the slab frame's up
    is the scanner's side.

    Seen from above, a bar beneath a crossing bar is hidden there, and the band along it holds
    the crossing bar's points, a bar radius or two higher; the bar on top shows its own surface
    either way. Seen from below (up taken upside down) the hidden bar's band holds points lower
    than its own. The band keeps to the bar's height: within a diameter and two height-noise σ
    of its axis (``noise[layer]`` is (plan, height) σ), which holds the crossing bar resting on
    it; with four radii and three *plan* σ it also held the other level's bars well away from
    the crossings, and at σ 15 mm the sign was right in 1 of 4 synthetic scans.

    Either way up, the lower level's band at a crossing holds the other level's points, higher,
    and the upper level's band the lower level's, lower: the bar hidden beneath tells the two
    apart, its band holding the crossing bar's points only (a full lift, or a full drop the wrong
    way up). Each level counts once: weighted by points, a level sampled four times more
    densely along its bars outweighed the other, and the lift of the two ways up came out
    0.0 and -0.7 mm, -0.2 and -0.3 mm on sparse scans without a formwork (the sign wrong on one
    of them), where the levels' medians were +8.6 and -5.0 mm the right way up and +5.1 and
    -7.4 mm the other.

    Parameters
    ----------
    q : (N, 3) float slab-frame points (plan x, y and height above the mesh's plane), mm
    bars : list of :class:`rebarlib.geometry.BarAxis`, the axes found in ``q`` (both lattices;
        a bar's crossings are those of the other level of its own lattice)
    noise : ``{layer: (plan σ, height σ)}`` in mm, as measured on the bars; a layer missing is
        taken as (10, 10)

    Returns
    -------
    float, mm: per bar the points' mean height within a radius of the crossings less that more
    than three radii and two plan σ away from them; its median over each level's bars; their
    mean over the levels; 0.0 where no bar has 20 points in its band with 5 at and 5 away from a
    crossing.
    """
    lifts = {}
    plan, h = q[:, :2], q[:, 2]
    for layer in G.LAYERS:
        sig, sig_h = noise.get(layer, (10.0, 10.0))
        mine = [b for b in bars if b.layer == layer]
        for b in mine:
            n2 = b.normal2d
            t = _dot(plan, b.direction)
            across = np.abs(_dot(plan, n2) - (b.offset_mm + b.slope * t))
            band = (across < b.radius_mm + sig) & (t >= b.t0_mm) & (t <= b.t1_mm)
            band &= np.abs(h - b.axis_height_mm) < 2 * b.radius_mm + 2 * sig_h
            idx = np.flatnonzero(band)
            cross = [_cross_axes(b, x) for x in mine if x.level != b.level]
            cross = np.array([c for c in cross if np.isfinite(c)])
            if len(idx) < 20 or len(cross) == 0:
                continue
            dist = np.min(np.abs(t[idx][:, None] - cross[None, :]), axis=1)
            at = dist < b.radius_mm
            away = dist > 3 * b.radius_mm + 2 * sig
            if at.sum() < 5 or away.sum() < 5:
                continue
            lifts.setdefault((layer, b.level), []).append(float(h[idx][at].mean()) - float(h[idx][away].mean()))
    return float(np.mean([np.median(v) for v in lifts.values()])) if lifts else 0.0


def _cross_axes(b: G.BarAxis, x: G.BarAxis) -> float:
    """Where axis ``x`` crosses axis ``b`` in plan, as a position along ``b``."""
    A = np.vstack([b.normal2d, x.normal2d])
    if abs(np.linalg.det(A)) < 1e-6:
        return float("nan")
    p = np.linalg.solve(A, [b.offset_mm, x.offset_mm])
    return float(p @ b.direction)


def _frame(pts, normal, datum: Datum):
    """The slab frame (the datum's plane, else heights from the cloud's lowest points along
    ``normal``), the slab-frame points and the split between the lattices."""
    if datum.found:
        plane = datum.plane
    else:
        plane = G.Plane(normal, -float(np.percentile(_dot(pts, normal), 0.5)))
    q = _slab_frame(pts, plane)
    h = q[:, 2]
    above = h > (3 * datum.noise_mm + 2 if datum.found else -np.inf)
    split = split_lattices(h[above], noise_mm=datum.noise_mm if datum.found else 10.0)
    if split is None:
        raise RebarInputError(
            "cloud: no gap between two lattices in the heights above the mesh's plane; "
            "is this a two-lattice mesh (or is up wrong)?"
        )
    return plane, q, split


def _layer_points(q, split, layer, datum: Datum) -> np.ndarray:
    """Indices of a lattice's points: above the split, or between the formwork's noise and it."""
    h = q[:, 2]
    if layer == "upper":
        return np.flatnonzero(h >= split)
    floor = 3 * datum.noise_mm + 2 if datum.found else -np.inf
    return np.flatnonzero((h > floor) & (h < split))


def _layer_axes(q, split, layer, design: Design, datum: Datum, min_length_mm, rng) -> tuple[list, tuple]:
    """The bar axes of one lattice, and the noise (plan, height) measured on its bars.

    Two passes: the first with the formwork's noise (or 10 mm) finds the bars; their spread
    across gives the noise in plan, with which the second finds them again."""
    lat = design.lattice(layer)
    radii = {lv: _envelope(design, layer, lv) / 2 for lv in G.LEVELS}
    r = max(radii.values())
    idx = _layer_points(q, split, layer, datum)
    qs = q[idx]
    spacing = min(lat.bottom.spacing_mm, lat.top.spacing_mm)
    guess = max(datum.noise_mm or 10.0, 3.0)
    found = lattice_bars(
        qs, radius_mm={0: r, 1: r}, spacing_mm=spacing, noise_mm=guess, min_length_mm=min_length_mm, rng=rng
    )
    if not found:
        return [], (guess, guess)
    sig_plan = _noise_across(found, r)
    found = lattice_bars(
        qs, radius_mm={0: r, 1: r}, spacing_mm=spacing, noise_mm=sig_plan, min_length_mm=min_length_mm, rng=rng
    )
    if not found:
        return [], (sig_plan, guess)
    found = _refit_off_crossings(qs, found, r, sig_plan)
    if datum.found and layer == "lower":
        found = _refit_over_formwork(q, split, found, r, sig_plan, datum.noise_mm)
    sig_plan = _noise_across(found, r)
    sig_h = (
        datum.noise_mm
        if datum.found
        else float(np.median([math.sqrt(max(b.h_sd**2 - 0.05 * r**2, 0.25)) for _, b in found]))
    )
    level_of = _levels(found)
    axes = []
    band_floor = -np.inf if (layer == "lower") else split
    band_ceiling = split if layer == "lower" else np.inf
    sel = np.flatnonzero((q[:, 2] >= band_floor) & (q[:, 2] < band_ceiling))
    qb = q[sel]
    proj = {}  # direction index -> offsets across and positions along it of qb's points
    for g, b in found:
        lv = level_of[g]
        other = [x for gg, x in found if gg != g]
        half_cross = radii["top" if lv == "bottom" else "bottom"] + 2 * sig_plan + 2
        if g not in proj:
            proj[g] = (_dot(qb[:, :2], b.normal2d), _dot(qb[:, :2], b.direction))
        mean_h, n = _bar_height(
            qb,
            proj[g],
            b,
            other,
            half_cross,
            r + 2 * sig_plan + 2,
            sig_h,
            formwork=datum.found and layer == "lower",
            radius_mm=radii[lv],
        )
        if mean_h is None:
            continue
        b.mean_h, b.n, b.idx = mean_h, n, idx[b.idx]
        axes.append(_to_axis(b, layer, lv, g, radii[lv]))
    min_sep = max(0.45 * spacing, 3 * math.sqrt(sig_plan**2 + r**2 / 2))  # the peaks' separation (lattice_bars)
    return _drop_off_level(_drop_duplicates(axes, min_sep), sig_h, q), (sig_plan, sig_h)


def _refit_off_crossings(qs, found: list, r: float, sig_plan: float) -> list:
    """Each bar's offset again from its band's points away from the bars crossing it (its drift
    kept): there the band holds only this bar and what lies beside it."""
    plan = qs[:, :2]
    half = _band_side(r, sig_plan)
    for g, b in found:
        cross = [c for c in (_crossing_along(b, x) for gg, x in found if gg != g) if np.isfinite(c)]
        if not cross:
            continue
        t = _dot(plan, b.direction)
        resid = _dot(plan, b.normal2d) - (b.centre + b.slope * t)
        sel = (np.abs(resid) < half) & (t >= b.t0) & (t <= b.t1)
        sel[sel] = _crossing_free(t[sel], cross, r + 2.0 * sig_plan + 2.0)
        if sel.sum() < 50:
            continue
        b.centre += _robust_line(np.zeros(int(sel.sum())), resid[sel])[0]
    return found


def _refit_over_formwork(q, split: float, found: list, r: float, sig_plan: float, sig_f: float) -> list:
    """Each lower bar's offset again from its band's points at every height down to the formwork,
    as the across mean of the bar's component of a two-component mixture (:func:`_bar_offset_mixture`).

    The lattice's points start above a floor (three formwork σ) that keeps the formwork out; but
    along an oblique ray the range error moves a point up *and* across, so a floor that cuts a low
    bar's heights keeps the points moved toward the stations and shifts its offset that way (by up
    to 6 mm at σ 15 mm, 18 mm at σ 20 mm on synthetic scans, where the bar's own points lie within
    2.5 mm of its axis). Without the floor the band holds the formwork beside the bar, which the
    mixture models instead of cutting it away."""
    plan, h = q[:, :2], q[:, 2]
    half = _band_side(r, sig_plan)
    rows = np.flatnonzero((h > -4 * sig_f) & (h < split))
    plan_r, h_r = plan[rows], h[rows]
    proj = {}  # direction index -> positions along and offsets across it of the rows
    for g, b in found:
        cross = [c for c in (_crossing_along(b, x) for gg, x in found if gg != g) if np.isfinite(c)]
        if g not in proj:
            proj[g] = (_dot(plan_r, b.direction), _dot(plan_r, b.normal2d))
        t, off = proj[g]
        resid = off - (b.centre + b.slope * t)
        sel = (np.abs(resid) < half) & (t >= b.t0) & (t <= b.t1)
        sel[sel] = _crossing_free(t[sel], cross, r + 2.0 * sig_plan + 2.0)
        if sel.sum() < 50:
            continue
        shift = _bar_offset_mixture(resid[sel], h_r[sel], half, sig_f, b.mean_h, sig_plan)
        if shift is not None:
            b.centre += shift
    return found


def _bar_offset_mixture(a, h, half: float, sig_f: float, h0: float, sig_a: float, iters: int = 60):
    """Across mean of a bar's points in a band that also holds the formwork: EM on (across ``a``,
    height ``h``) with two components, the formwork (heights N(0, ``sig_f``), the formwork's
    measured noise; across uniform over the band's ±``half``) and the bar (a free 2-D Gaussian:
    its covariance takes the correlation that oblique rays give across and height). None when
    the bar's component holds under 20 points or its mean leaves the band or the lattice.

    Every point counts with its probability of being the bar's, and a low point that is the
    bar's is not cut away for lying low: the mean is the mixture's maximum-likelihood one, not a
    mean over the points a height threshold keeps."""
    # the sums run column by column: a matrix product of a tall thin array goes through BLAS
    # threads (see _util._dot)
    ma, mh = 0.0, float(h0)
    caa, chh, cah = sig_a**2, sig_f**2 + sig_a**2, 0.0
    share = 0.5
    log_f = -0.5 * (h / sig_f) ** 2 - math.log(sig_f * math.sqrt(2 * math.pi) * 2 * half)
    for _ in range(iters):
        det = caa * chh - cah**2
        if not det > 0:
            return None
        da, dh = a - ma, h - mh
        m = (chh * da**2 - 2 * cah * da * dh + caa * dh**2) / det
        log_b = -0.5 * m - math.log(2 * math.pi * math.sqrt(det))
        # responsibility of the bar, from the log odds (no underflow far from either component)
        z = np.clip(math.log(share) - math.log1p(-share) + log_b - log_f, -50, 50)
        w = 1.0 / (1.0 + np.exp(-z))
        sw = float(w.sum())
        if sw < 20 or sw > len(w) - 1e-6:
            return None
        na, nh = float((w * a).sum()) / sw, float((w * h).sum()) / sw
        da, dh = a - na, h - nh
        caa = float((w * da * da).sum()) / sw + 1e-3
        chh = float((w * dh * dh).sum()) / sw + 1e-3
        cah = float((w * da * dh).sum()) / sw
        share = sw / len(w)
        done = max(abs(na - ma), abs(nh - mh)) < 0.01
        ma, mh = na, nh
        if done:
            break
    if abs(ma) >= half or mh <= 0:
        return None
    return ma


def _noise_across(found: list, r: float) -> float:
    """Noise in plan: the bars' spread across less what a bar's own width spreads its points."""
    sd = float(np.median([b.resid_sd for _, b in found]))
    return float(math.sqrt(max(sd**2 - r**2 / 3, 1.0)))


def _levels(found: list) -> dict:
    """Direction index -> level: the direction whose bars lie lower is the bottom one."""
    groups = sorted({g for g, _ in found})
    mean_h = {g: float(np.median([b.mean_h for gg, b in found if gg == g])) for g in groups}
    order = sorted(groups, key=lambda g: mean_h[g])
    return {g: G.LEVELS[min(k, 1)] for k, g in enumerate(order)}


def _bar_height(qb, proj, b: _Bar, other: list, half_cross, half, sig_h, *, formwork: bool, radius_mm: float):
    """Mean height of a bar's surface points away from the crossing bars, and their number.

    Over a formwork the band beside a low bar also holds formwork points: the heights are then
    a mixture of the formwork's (mean 0, σ the formwork's noise) and the bar's, and the bar's
    mean is its component's (a few EM steps)."""
    off, t = proj
    inb = (np.abs(off - (b.centre + b.slope * t)) < half) & (t >= b.t0) & (t <= b.t1)
    cross = [_crossing_along(b, x) for x in other]
    pick = np.flatnonzero(inb)
    free = _crossing_free(t[pick], [c for c in cross if np.isfinite(c)], half_cross)
    if free.sum() >= 10:
        pick = pick[free]
    hh = qb[pick, 2]
    if len(hh) < 10:
        return None, 0
    if not formwork:
        return _trimmed_mean(hh), len(hh)
    return _mixture_mean(hh, sig_h, radius_mm)


def _trimmed_mean(x, k: float = 3.0) -> float:
    """Mean of ``x`` within ``k`` robust σ of its median."""
    m = float(np.median(x))
    sd = 1.4826 * float(np.median(np.abs(x - m))) + 1e-6
    return float(np.mean(x[np.abs(x - m) < k * sd]))


def _mixture_mean(h, sig0, radius_mm: float, iters: int = 30):
    """Mean of the bar component of heights mixed with formwork points N(0, sig0).

    The bar's component has the formwork's noise widened by the spread of a bar's upper half
    (0.3 r): left free, its width swallowed the formwork's tail where formwork points outnumber
    the bar's tenfold (sparse synthetic scans: bar heights 12 mm low)."""
    hi = h[h > 2 * sig0]
    mu = float(np.median(hi)) if len(hi) else float(np.median(h))
    s1 = math.sqrt(sig0**2 + (0.3 * radius_mm) ** 2)
    pi1 = 0.5
    for _ in range(iters):
        p0 = (1 - pi1) * np.exp(-0.5 * (h / sig0) ** 2) / sig0
        p1 = pi1 * np.exp(-0.5 * ((h - mu) / s1) ** 2) / s1
        w = p1 / np.maximum(p0 + p1, 1e-300)
        sw = float(w.sum())
        if sw < 5:
            return None, 0
        mu = float((w * h).sum() / sw)
        pi1 = sw / len(h)
    return mu, int(round(sw))


def _drop_duplicates(axes: list, min_sep_mm: float) -> list:
    """Of two bars of one level closer than the offset peaks they were found from may lie
    (``min_sep_mm``), the one with fewer points: its line has moved onto the other's points while
    it was fitted (a bar's points spread by the range noise toward an empty neighbour's side form a
    second, flatter peak; on synthetic scans such a "bar" lay 8-56 mm from the bar it duplicated,
    its points spread 2-4 times as widely across)."""
    out = list(axes)
    while True:
        worst = None
        for i, a in enumerate(out):
            for b in out[i + 1 :]:
                if a.level != b.level or abs(float(a.direction @ b.direction)) < 0.9:
                    continue
                t = 0.5 * (max(a.t0_mm, b.t0_mm) + min(a.t1_mm, b.t1_mm))
                sign = 1.0 if float(a.direction @ b.direction) > 0 else -1.0
                gap = abs(float(a.plan_point(t) @ a.normal2d) - float(b.plan_point(sign * t) @ a.normal2d))
                if gap < min_sep_mm:
                    weak = a if len(a.point_index) < len(b.point_index) else b
                    worst = weak if worst is None else worst
        if worst is None:
            return out
        out = [x for x in out if x is not worst]


_SEEN_ALONG = 0.5  # a "bar" whose returns span under this share of what its set's bars' span


def _drop_off_level(axes: list, sig_h: float, q=None) -> list:
    """A "bar" lying far from the other bars of its direction is a chair, a spacer, a tie: not a
    bar of this level. A bar with at least a quarter of its set's typical points per mm is kept
    unless it lies more than its diameter off its level's height (:func:`_level_heights`, a line
    across the set, so that a tilted frame does not count against the set's outer bars) beyond
    four times the noise of its mean height. Not a radius: the bars of a real level are not
    coplanar to a radius (on a real laser scan of a wall cage, bars lay up to 1.8 r off their
    level's line, and a radius dropped three of its 28 bars; decision 042), and a bar out of its
    level is a defect the cover and layer distance must show, not a phantom to hide. A sparser
    one must *show* that it lies at its level: within its radius even with four times that
    noise added. A few stray points do not make a bar, and their height is too uncertain to
    vouch for them (two "bars" about 110 mm beyond a set's last bar, made of formwork points and
    the crossing bars' points there, were kept on synthetic scans: 1.05 and 1.32 radii off their
    level, with 17 % and 2 % of their set's points per mm, inside the noise allowance).

    So must a "bar" whose returns gather in a short part of its extent (``q``, the points the
    axes' ``point_index`` refer to, given): the middle 80 % of its returns along it span under
    half (``_SEEN_ALONG``) of the share of their extents that its set's bars' span (the median:
    shadows and a density falling with range narrow every bar of a set alike). A bar is seen
    along its length, a chair or a spacer where it stands: on held-out σ 20 mm sparse seed 11, a
    chair's 21 returns and 2 of a crossing bar made a "bar" of 300 mm whose middle returns
    spanned 18 % of it against its set's 80 %, 3.0 r over its level with an allowance of 8.1 mm
    (kept by the diameter). On the 256 training scans the real bars spanned at least 0.555 of
    their set's median (two bars at their level over a formwork; those farther off it than a radius
    less the allowance, at least 0.93), on a real laser scan of a wall cage 0.87 (decision 045). A
    real bar off its level within the diameter is still seen along its length, and kept."""
    out = []
    for lv in G.LEVELS:
        group = [a for a in axes if a.level == lv]
        if len(group) < 3:
            out += group
            continue
        level = _level_heights(group)
        dens = float(np.median([_per_mm(a) for a in group]))
        spans = [1.0] * len(group) if q is None else [_span_along(a, q) for a in group]
        span_set = float(np.median(spans))
        for a, lv_h, span in zip(group, level, spans):
            allow = 4 * sig_h / math.sqrt(max(a.n_points, 1))
            off = abs(a.axis_height_mm - lv_h)
            if _per_mm(a) >= 0.25 * dens and span >= _SEEN_ALONG * span_set:
                keep = off - allow <= 2 * a.radius_mm
            else:
                keep = off + allow <= a.radius_mm
            if keep:
                out.append(a)
    return out


def _span_along(a: G.BarAxis, q) -> float:
    """The share of a bar's extent that the middle 80 % of its returns (``q[a.point_index]``, slab
    frame) span along it: about 0.8 for returns spread evenly over it, less where they gather."""
    if len(a.point_index) < 2:
        return 0.0
    t = q[a.point_index, :2] @ a.direction
    p10, p90 = np.percentile(t, [10.0, 90.0])
    return float(p90 - p10) / max(a.t1_mm - a.t0_mm, 1.0)


def _level_heights(group: list) -> np.ndarray:
    """The height of a level under each of its bars: a line through the bars' axis heights
    against their offsets across (at the middle of each bar), its slope the median of the pairs'
    slopes and its height the median of the bars' heights less it (Theil-Sen: a chair's "bar"
    among a set's bars moves neither). Without a formwork the slab frame's plane comes from the
    cloud's thinnest direction, which may tilt across a set: on synthetic scans without one, real
    bars lay up to 1.2 r off their level's median height, with a formwork at most 0.65 r; off
    this line, at most 0.89 r without one (decision 042)."""
    mid = [0.5 * (a.t0_mm + a.t1_mm) for a in group]
    x = np.array([float(a.plan_point(t) @ a.normal2d) for a, t in zip(group, mid)])
    h = np.array([a.axis_height_mm for a in group])
    i, j = np.triu_indices(len(group), 1)
    dx = x[j] - x[i]
    ok = np.abs(dx) > 1.0
    slope = float(np.median((h[j] - h[i])[ok] / dx[ok])) if ok.any() else 0.0
    base = float(np.median(h - slope * x))
    return base + slope * x


def _per_mm(a: G.BarAxis) -> float:
    """A bar's points per mm along it, the fewer of two counts: the lattice's points that made it
    a bar (``point_index``) and those its height was measured on (``n_points``). Over a formwork
    the latter is the weight of the bar's component of the height mixture, which a "bar" of a few
    dozen stray points fills with formwork points (36 points over 1.1 m counted 972, kept as a
    bottom bar 16 mm under its level on a synthetic scan); the former alone kept four "bars" that
    the latter drops (phantoms on synthetic scans at σ 5-15 mm)."""
    return min(len(a.point_index), a.n_points) / max(a.t1_mm - a.t0_mm, 1.0)
