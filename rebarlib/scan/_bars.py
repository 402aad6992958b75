"""Stage 4 of a scanned cloud: the bars of a lattice, as peaks of the plan offsets across each
of its two directions, and a robust line through each."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import geometry as G
from ._util import _band_side, _dot, _mad, _sample, _smoothed_hist


@dataclass(frozen=True)
class _Candidate:
    """A peak of the offset histogram: a would-be bar."""

    centre: float
    excess: float  # counts above the background at the peak (smoothed)
    z: float  # excess over its counting noise


def _offset_peaks(off, *, kernel_mm: float, min_sep_mm: float, background_mm: float, z_min: float) -> list:
    """Peaks of the smoothed offset histogram standing out of a running background (the lower
    envelope over ``background_mm``) by ``z_min`` times its counting noise."""
    if len(off) < 20:
        return []
    lo, hi = float(off.min()) - 3 * kernel_mm, float(off.max()) + 3 * kernel_mm
    x, s, c = _smoothed_hist(off, 1.0, kernel_mm, lo, hi)
    w = max(3, int(background_mm))
    bg = _running_mean(_running_min(s, w), w)
    # counting noise of the smoothed count: a Gaussian kernel of sd k averages ~2√π k bins
    eff = 2 * math.sqrt(math.pi) * max(kernel_mm, 0.5)
    noise = np.sqrt(np.maximum(bg, 1.0 / eff) / eff)
    z = (s - bg) / noise
    cand = [i for i in range(1, len(s) - 1) if s[i] >= s[i - 1] and s[i] > s[i + 1] and z[i] >= z_min]
    cand.sort(key=lambda i: -(s[i] - bg[i]))
    kept = []
    for i in cand:
        if all(abs(x[i] - x[j]) >= min_sep_mm for j in kept):
            kept.append(i)
    return sorted((_Candidate(float(x[i]), float(s[i] - bg[i]), float(z[i])) for i in kept), key=lambda cnd: cnd.centre)


def _running_min(x, w: int) -> np.ndarray:
    """Minimum over a centred window of ``w`` bins (edges padded with the end values)."""
    pad = np.pad(x, (w // 2, w - 1 - w // 2), mode="edge")
    return np.lib.stride_tricks.sliding_window_view(pad, w).min(axis=1)


def _running_mean(x, w: int) -> np.ndarray:
    """Mean over a centred window of ``w`` bins (edges padded with the end values)."""
    pad = np.pad(x, (w // 2, w - 1 - w // 2), mode="edge")
    c = np.concatenate([[0.0], np.cumsum(pad)])
    return (c[w:] - c[:-w]) / w


def _direction_scan(plan, rng, *, exclude_deg=None, bin_mm: float = 6.0) -> float | None:
    """Plan angle (deg) at which the offsets are sharpest; with ``exclude_deg``, only angles at
    least 30° from it."""
    sub = plan[_sample(len(plan), 20_000, rng)]
    if len(sub) < 50:
        return None
    coarse = np.arange(0.0, 180.0, 1.0)
    if exclude_deg is not None:
        coarse = coarse[np.abs(((coarse - exclude_deg) + 90) % 180 - 90) >= 30]
    s = G.direction_sharpness(sub, np.radians(coarse), bin_mm)
    best = float(coarse[int(np.argmax(s))])
    fine = best + np.arange(-1.5, 1.5001, 0.05)
    f = G.direction_sharpness(sub, np.radians(fine), max(bin_mm / 3, 1.0))
    return float(fine[int(np.argmax(f))] % 180.0)


def _longest_extent(t, *, cell_mm: float, max_gap_mm: float) -> tuple[float, float, float]:
    """The longest stretch of occupied cells along a bar (gaps up to ``max_gap_mm`` closed): its
    ends, and the length of the bar its returns cover in it (:func:`_seen_length`)."""
    if len(t) == 0:
        return 0.0, 0.0, 0.0
    cells = np.unique(np.floor(t / cell_mm).astype(np.int64))
    gaps = np.diff(cells) * cell_mm > max_gap_mm + cell_mm
    starts = np.r_[0, np.flatnonzero(gaps) + 1]
    ends = np.r_[np.flatnonzero(gaps), len(cells) - 1]
    k = int(np.argmax(cells[ends] - cells[starts]))
    t0, t1 = float(cells[starts[k]] * cell_mm), float((cells[ends[k]] + 1) * cell_mm)
    return t0, t1, _seen_length(t[(t >= t0) & (t < t1)], cell_mm)


def _seen_length(t, cell_mm: float) -> float:
    """Length of a bar that returns at positions ``t`` along it cover, each the ``cell_mm`` about
    it (the cell sized to hold a few of the band's returns): the union of those stretches. A
    stretch without returns (a shadow, the gap between a chair and a crossing bar) is not seen;
    nor is the slack of a grid of cells, whose first and last cells reach up to a cell beyond the
    returns they hold."""
    if len(t) == 0:
        return 0.0
    gaps = np.diff(np.sort(t))
    return float(cell_mm + np.minimum(gaps, cell_mm).sum())


@dataclass
class _Bar:
    """A bar found in a lattice (slab frame): its line across, extent along, points and spreads."""

    direction: np.ndarray
    centre: float
    slope: float
    t0: float
    t1: float
    mean_h: float  # first the median height of its points (orders the levels), then its surface's
    n: int
    resid_sd: float  # spread of the points' offsets about the axis
    h_sd: float
    idx: np.ndarray
    z: float

    @property
    def normal2d(self) -> np.ndarray:
        return np.array([-self.direction[1], self.direction[0]])


def _bar_points(off, along, centre, slope, half_width, keep):
    """Indices of the ``keep`` points within ``half_width`` of the line ``centre + slope * along``."""
    return np.flatnonzero(keep & (np.abs(off - (centre + slope * along)) < half_width))


_MAX_SLOPE = 0.05  # a bar's drift across per mm along: the bars of a mesh run parallel


def _fit_line(off, along, centre, half_width, keep, iters: int = 3):
    """Robust line ``off = c + slope * along`` through a bar's points (re-selected each pass;
    Tukey-weighted least squares, the scale a robust σ of the residuals)."""
    reach = half_width + _MAX_SLOPE * float(np.max(np.abs(along))) + 20.0
    cand = np.flatnonzero(keep & (np.abs(off - centre) < reach))
    o_all, t_all = off[cand], along[cand]
    c, slope = centre, 0.0
    sel = np.abs(o_all - c) < half_width
    for _ in range(iters):
        if sel.sum() < 10:
            break
        t, o = t_all[sel], o_all[sel]
        tm = float(np.median(t))
        b0, b1 = _robust_line(t - tm, o)
        slope = float(np.clip(b1, -_MAX_SLOPE, _MAX_SLOPE))
        c = float(b0 - slope * tm)
        sel = np.abs(o_all - (c + slope * t_all)) < half_width
    return c, slope, cand[sel]


def _robust_line(x, y, iters: int = 3) -> tuple[float, float]:
    """Intercept and slope of ``y`` on ``x``, Tukey-weighted (4.685 robust σ)."""
    w = np.ones(len(x))
    b0 = b1 = 0.0
    for _ in range(iters):
        sw = float(w.sum())
        if sw <= 0:
            break
        mx, my = float((w * x).sum()) / sw, float((w * y).sum()) / sw
        sxx = float((w * (x - mx) ** 2).sum())
        b1 = float((w * (x - mx) * (y - my)).sum()) / sxx if sxx > 0 else 0.0
        b0 = my - b1 * mx
        r = y - (b0 + b1 * x)
        sd = _mad(r[:: max(1, len(r) // 4000)]) + 1e-6
        w = np.clip(1 - (r / (4.685 * sd)) ** 2, 0, None) ** 2
    return b0, b1


def _crossing_free(along, crossings, half_width):
    """Points along a bar away from the bands of the crossing bars."""
    if len(crossings) == 0:
        return np.ones(len(along), bool)
    cr = np.sort(np.asarray(crossings))
    j = np.clip(np.searchsorted(cr, along), 1, len(cr) - 1) if len(cr) > 1 else np.zeros(len(along), int)
    d = np.abs(along - cr[j])
    if len(cr) > 1:
        d = np.minimum(d, np.abs(along - cr[j - 1]))
    return d > half_width


def lattice_bars(
    q, *, radius_mm: dict, spacing_mm: float, noise_mm: float, min_length_mm: float = 100.0, rng=None
) -> list:
    """The bars of one lattice: ``[(direction index, _Bar), ...]`` from its slab-frame points.

    Directions: the sharpest plan angle, then the sharpest at least 30° from it once the first
    direction's bars are taken out. Bars: offset peaks standing 5 counting-noise σ over their
    local background, the histogram smoothed by the bar's own spread (noise and radius), at
    least 0.45 design spacing (and three spreads) apart, running ``min_length_mm`` or more
    (cells sized by the density along). Phantoms made of crossing bars' points are dropped.

    Parameters
    ----------
    q : (N, 3) slab-frame points of the lattice, mm
    radius_mm : ``{direction index: radius}`` of the bars (0 and 1)
    spacing_mm : the design spacing of the lattice (the smaller of its two levels')
    noise_mm : noise of the points across the bars, mm (sets the bands and the smoothing)
    min_length_mm : a bar runs at least this far
    rng : seed or Generator of the sampling in the angular scan

    Returns
    -------
    list of (int, bar)
        ``(g, bar)`` pairs, ``g`` the direction index (0: the sharper direction, found first;
        1: the other): direction 0's bars in the order of their offsets, then direction 1's;
        empty where no bar is found. ``bar`` is a record of one bar in the slab frame:

        ==========  ======================================================================
        field       meaning
        ==========  ======================================================================
        direction   (2,) unit plan vector along the bar
        centre      offset across (along ``normal2d``, the direction turned 90°) at 0 along
        slope       the offset's drift per mm along: the line is ``centre + slope * along``
        t0, t1      the bar's extent along its direction, mm
        mean_h      the median height of its points, mm
        n           its points
        resid_sd    robust σ of its points' offsets about the line, mm
        h_sd        robust σ of its points' heights, mm
        idx         (n,) indices of its points into ``q``
        z           its offset peak's excess over the counting noise
        ==========  ======================================================================
    """
    rng = np.random.default_rng(rng)
    plan, h = q[:, :2], q[:, 2]
    out = _find_lattice(plan, h, radius_mm, spacing_mm, noise_mm, min_length_mm, rng)
    return _drop_phantoms(plan, out, radius_mm, noise_mm)


def _band(plan, b: "_Bar", half: float) -> np.ndarray:
    """Mask of the plan points within ``half`` of bar ``b``'s line."""
    d = b.direction
    n2 = np.array([-d[1], d[0]])
    return np.abs(_dot(plan, n2) - (b.centre + b.slope * _dot(plan, d))) < half


_CROSSING_SHARE = 0.8  # a "bar" with this share of its points within the crossing bars' bands
_OWN_DENSITY = 0.25  # ... and under this share of its set's points per mm between them
_OWN_COVER = 0.5  # or whose returns cover under this share of what its set's cover between them


def _drop_phantoms(plan, found: list, radius_mm: dict, noise_mm: float) -> list:
    """Drop a "bar" made of what lies where the other direction's bars cross it: the crossing bars'
    points, with what sits at a crossing (a cover block under the bar beneath).

    Such a "bar" holds 80 % (``_CROSSING_SHARE``) of its points within the crossing bars' bands,
    each as wide as the band that gathers a bar's points (radius + 2.5 σ + 2 mm about its axis:
    the crossing bar's points lie there), and shows under a quarter (``_OWN_DENSITY``, the share
    the level test of :mod:`._axes` also asks of a bar) of its set's points per mm between them.
    A bar shows its own surface between the crossings; a bar of a direction scanned much more
    sparsely than the crossing one also holds most of its points at the crossings (about 64 % at
    4×, 80 % at 10×, for bands of 26.5 mm every 200 mm), but between them it has about the points
    per mm of its set. On synthetic scans at σ 20 mm without a formwork, sampled 4× more finely in
    one direction (22 training seeds; decision 036), the "bars" made of crossing bars' points and
    cover blocks held 91-100 % of their points in those bands and 0-12 % of their set's points
    per mm between them; the 1 760 real bars held at most 61 % in the bands and at least 35 % of
    their set's points per mm. With the half width taken before, twice the crossing bars' spread
    about their lines (18 mm at σ 20 mm, narrower than where the crossing bars' points and a
    50 mm cover block lie), the four phantoms left held 72-78 %.

    A "bar" is also dropped where its returns between the crossing bands cover under half
    (``_OWN_COVER``) of those stretches' length, against what its set's bars cover (the median):
    a bar is seen along its stretches between the crossings but for shadows, which its set's
    bars share; a line through two crossings and a chair or a cover block between them is seen
    only where the object stands. Each return covers the cell about it (sized to hold three of
    the bar's returns, as the cells that measure a bar's length: :func:`_seen_length`). On the
    synthetic scans (decision 042: training seeds, σ 5-20 mm without a formwork, 5-10 mm with
    one) such lines held 68-79 % of their points in the crossing bands, under the 80 % above, and
    covered 19-34 % of what their sets' bars cover; the real bars, at least 75 %."""
    stats = _crossing_stats(plan, found, radius_mm, noise_mm)
    out = []
    for (g, b), st in zip(found, stats):
        if st is None:
            out.append((g, b))
            continue
        own = float(np.median([x[1] for (gg, _), x in zip(found, stats) if gg == g and x is not None]))
        cover = float(np.median([x[2] for (gg, _), x in zip(found, stats) if gg == g and x is not None]))
        crossing_points = st[0] >= _CROSSING_SHARE and st[1] < _OWN_DENSITY * own
        if not (crossing_points or st[2] < _OWN_COVER * cover):
            out.append((g, b))
    return out


def _crossing_stats(plan, found: list, radius_mm: dict, noise_mm: float) -> list:
    """Per bar of ``found``: (the share of its points within the bands of the other direction's
    bars, its points per mm of its extent outside them, the share of that extent its returns there
    cover), or None where the other direction has no bar."""
    stats = []
    for g, b in found:
        other = [(gg, x) for gg, x in found if gg != g]
        if not other:
            stats.append(None)
            continue
        half = _band_side(radius_mm.get(other[0][0], max(radius_mm.values())), noise_mm)
        cross = np.array([c for c in (_crossing_along(b, x) for _, x in other) if np.isfinite(c)])
        t = _dot(plan[b.idx], b.direction)
        free = _crossing_free(t, cross, half)
        # the length of the bar's extent outside the crossing bands
        cr = np.sort(cross)
        covered, end = 0.0, b.t0
        for z0, z1 in np.clip(np.c_[cr - half, cr + half], b.t0, b.t1):
            covered += max(z1 - max(z0, end), 0.0)
            end = max(end, z1)
        free_len = (b.t1 - b.t0) - covered
        cell = float(np.clip(3.0 * (b.t1 - b.t0) / max(len(t), 1), 5.0, 40.0))
        stats.append(
            (
                1.0 - float(free.mean()),
                float(free.sum()) / free_len if free_len > 1.0 else 0.0,
                _cover_between(t[free], cr, half, b.t0, b.t1, cell),
            )
        )
    return stats


def _cover_between(t_free, crossings, half: float, t0: float, t1: float, cell_mm: float) -> float:
    """Share of a bar's extent ``t0``-``t1`` outside the crossing bands (``half`` about each of
    ``crossings``) that its returns there (``t_free``) cover, each the ``cell_mm`` about it; 1.0
    where the bands cover the whole extent (nothing to show)."""
    grid = np.arange(t0, t1, 1.0) + 0.5
    free = _crossing_free(grid, crossings, half)
    if free.sum() < 1:
        return 1.0
    if len(t_free) == 0:
        return 0.0
    ts = np.sort(t_free)
    j = np.searchsorted(ts, grid)  # the nearest return is the one after or the one before
    d = np.minimum(np.abs(grid - ts[np.minimum(j, len(ts) - 1)]), np.abs(grid - ts[np.maximum(j - 1, 0)]))
    return float((free & (d <= 0.5 * cell_mm)).sum() / free.sum())


def _find_lattice(plan, h, radius_mm, spacing_mm, noise_mm, min_length_mm, rng) -> list:
    """The bars of both directions of a lattice, the second found once the first's are taken out."""
    out = []
    keep = np.ones(len(plan), bool)
    first = None
    for g in (0, 1):
        ang = _direction_scan(plan[keep], rng, exclude_deg=first, bin_mm=max(4.0, noise_mm / 2))
        if ang is None:
            break
        first = ang if first is None else first
        bars, off, along = _bars_along(
            plan,
            h,
            ang,
            keep,
            radius_mm=radius_mm.get(g, max(radius_mm.values())),
            spacing_mm=spacing_mm,
            noise_mm=noise_mm,
            min_length_mm=min_length_mm,
        )
        out += [(g, b) for b in bars]
        for b in bars:
            keep[b.idx] = False
            # the whole band, not only the fitted points
            keep &= np.abs(off - (b.centre + b.slope * along)) >= b.resid_sd * 2 + 2
    return out


def _bars_along(plan, h, ang, keep, *, radius_mm, spacing_mm, noise_mm, min_length_mm):
    """The bars of one direction (plan angle ``ang``, degrees) among the ``keep`` points, and every
    point's offset across and position along that direction."""
    a = math.radians(ang)
    d = np.array([math.cos(a), math.sin(a)])
    n2 = np.array([-d[1], d[0]])
    off, along = _dot(plan, n2), _dot(plan, d)
    spread = math.sqrt(noise_mm**2 + radius_mm**2 / 2)
    half = _band_side(radius_mm, noise_mm)
    peaks = _offset_peaks(
        off[keep],
        kernel_mm=spread,
        min_sep_mm=max(0.45 * spacing_mm, 3 * spread),
        background_mm=max(spacing_mm, 6 * spread),
        z_min=5.0,
    )
    bars = []
    for p in peaks:
        c, slope, idx = _fit_line(off, along, p.centre, half, keep)
        if len(idx) < 20:
            continue
        # the extent from every point of the band: the points taken out with the bars crossing
        # this one would cut it into short stretches between them
        t = along[np.abs(off - (c + slope * along)) < half]
        dens = len(t) / max(float(np.ptp(t)), 1.0)
        cell = float(np.clip(3.0 / dens, 5.0, 40.0))
        t0, t1, seen = _longest_extent(t, cell_mm=cell, max_gap_mm=max(60.0, 2 * cell))
        # the length scanned is what the returns cover (the union of the cells about them), not
        # the run's ends: a gap closed as a shadow is not seen, and a run's ends lie up to a cell
        # beyond its returns (decision 042: a chair and a crossing bar's points 100 mm apart,
        # joined by one stray return, and a run of two 38 mm cells counted as bars)
        if seen < min_length_mm:
            continue
        idx = idx[(along[idx] >= t0) & (along[idx] <= t1)]
        if len(idx) < 20:
            continue
        r = off[idx] - (c + slope * along[idx])
        # the median height: outliers scattered along the rays above the mesh pulled a mean
        # height up by more than a diameter and swapped the levels (5 % outliers)
        bars.append(
            _Bar(
                d,
                c,
                slope,
                t0,
                t1,
                float(np.median(h[idx])),
                len(idx),
                _mad(r),
                _mad(h[idx] - np.median(h[idx])),
                idx,
                p.z,
            )
        )
    return bars, off, along


def _crossing_along(b: _Bar, x: _Bar) -> float:
    """Where bar ``x`` crosses bar ``b``, as a position along ``b``."""
    n_b = np.array([-b.direction[1], b.direction[0]])
    n_x = np.array([-x.direction[1], x.direction[0]])
    A = np.vstack([n_b, n_x])
    if abs(np.linalg.det(A)) < 1e-6:
        return float("nan")
    p = np.linalg.solve(A, [b.centre, x.centre])
    return float(p @ b.direction)
