"""Inspecting a scanned point cloud (laser scanner, mobile LiDAR, photogrammetry): ``inspect_cloud``.

A scan differs from an RGB-D capture in everything the camera pipeline relies on: there is no
camera position (several stations are merged, the origin can be anywhere), no pixels, the noise
is 2–20 mm against bars of 8–20 mm, and the density varies tenfold across the cloud and between
directions. So the stages here are statistical: a bar is where the points pile up across a
direction, and its axis is the mean of many noisy points, not a fitted cross-section.

Stages (each a function):

1. :func:`mesh_up` — the mesh's normal (the formwork's, or the thin direction of the bars' cloud)
   and its sign: the given ``up``, else away from the formwork, else from the file's normals
   (oriented to the scanner), else guessed from the crossings (:func:`crossing_lift`). Never
   from the origin.
2. :func:`find_datum` — the formwork (or ground) plane under the mesh if the scan holds one, with
   the range noise measured on it; cover is measured from it, and without it cover is "not
   measured".
3. :func:`split_lattices` — the valley of the noise-smoothed height histogram between the lattices.
4. :func:`lattice_bars` — per lattice, the two bar directions (angular scan of the plan offsets),
   then the bars of each as peaks of the offset histogram that stand out of their local
   background by more than its counting noise (thresholds from the measured density and noise,
   not fixed ratios), and that run at least ``min_length_mm``.
5. Axes: per bar, a robust line through its band's points; height from the mean height of its
   points away from the crossings (points cover the upper half of a bar: the mean lies 2r/π
   above the axis), over a formwork as one component of a formwork/bar mixture.
6. Spacings (:func:`rebarlib.geometry.measure_spacings`), layer distance, cover, diameters (only
   where the noise allows, see :func:`diameter_resolvable`).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import pandas as pd

from . import geometry as G
from ._checks import RebarInputError
from ._inspect import _top_cover
from ._design import Design
from ._results import InspectionResult, Measurement
from .cloud_io import ScanCloud, read_cloud

__all__ = ["as_scan_cloud", "cloud_manifest", "crossing_lift", "diameter_resolvable", "find_datum",
           "inspect_cloud", "lattice_bars", "mesh_up", "parse_up", "split_lattices"]

METHOD = "cloud"
_SURFACE_MEAN = 2.0 / math.pi  # mean height of points spread evenly over a bar's upper half, x radius


# ----------------------------------------------------------------------------------------------
# Input
# ----------------------------------------------------------------------------------------------

def as_scan_cloud(cloud, *, units: str | None = None) -> ScanCloud:
    """A :class:`ScanCloud` from a file path (``units`` required), a ScanCloud, or an (N, 3)
    array in mm (``units`` "mm" or None) or m (``units="m"``)."""
    if isinstance(cloud, ScanCloud):
        return cloud
    if isinstance(cloud, (str, Path)):
        if units is None:
            raise RebarInputError(f"units: the unit of {Path(cloud).name} must be given ('mm' or 'm')")
        return read_cloud(cloud, units=units)
    pts = np.asarray(cloud, float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise RebarInputError(f"cloud: expected a file, a ScanCloud or a non-empty (N, 3) array, got shape {pts.shape}")
    scale = {"mm": 1.0, None: 1.0, "m": 1000.0}.get(units)
    if scale is None:
        raise RebarInputError(f"units: expected 'mm' or 'm', got {units!r}")
    pts = pts[np.all(np.isfinite(pts), axis=1)] * scale
    off = np.median(pts, axis=0)
    return ScanCloud(pts - off, off, {}, units or "mm", "")


def parse_up(up) -> np.ndarray | None:
    """``"+z"``, ``"-y"``, ... or a 3-vector -> unit vector; None stays None."""
    if up is None:
        return None
    if isinstance(up, str):
        s = up.strip().lower()
        if len(s) == 1:
            s = "+" + s
        if len(s) != 2 or s[0] not in "+-" or s[1] not in "xyz":
            raise RebarInputError(f"up: expected one of +x, -x, +y, -y, +z, -z, got {up!r}")
        v = np.zeros(3)
        v["xyz".index(s[1])] = 1.0 if s[0] == "+" else -1.0
        return v
    v = np.asarray(up, float)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise RebarInputError(f"up: expected an axis name or a non-zero 3-vector, got {up!r}")
    return v / np.linalg.norm(v)


def cloud_manifest(cloud_path, design_path, *, method: str = METHOD, options: dict | None = None) -> dict:
    """The result manifest of a cloud file (as :func:`rebarlib._manifest.make_manifest` writes for
    a capture folder): the cloud's path and SHA-256 digest stand for the capture's."""
    from . import __version__
    from ._manifest import file_digest, make_manifest

    p = Path(cloud_path).resolve()
    man = make_manifest(p.parent, design_path, method=method, options=options)
    man.update({"capture_folder": None, "capture_digest": None, "cloud_file": str(p),
                "cloud_digest": file_digest(p), "rebarlib_version": __version__})
    return man


# ----------------------------------------------------------------------------------------------
# 1-2. Up and datum
# ----------------------------------------------------------------------------------------------

def _dot(a, v) -> np.ndarray:
    """``a @ v`` for (N, k) points and a k-vector, column by column: a matrix product of a tall
    thin array goes through BLAS threads, which on a busy 2-core machine cost 50x more."""
    out = a[:, 0] * float(v[0])
    for j in range(1, len(v)):
        out += a[:, j] * float(v[j])
    return out


def _slab_frame(points, plane: G.Plane) -> np.ndarray:
    """:func:`rebarlib.geometry.to_slab_frame` without a matrix product (see :func:`_dot`)."""
    R = G.plane_frame(plane)
    return np.column_stack([_dot(points, R[0]), _dot(points, R[1]), _dot(points, R[2]) + plane.offset_mm])


def _sample(n: int, k: int, rng) -> np.ndarray:
    return np.arange(n) if n <= k else np.sort(rng.choice(n, k, replace=False))


def _thin_direction(points, rng) -> np.ndarray:
    """The direction in which the cloud is thinnest (smallest principal axis, robust to outliers)."""
    p = points[_sample(len(points), 50_000, rng)]
    p = p - np.median(p, axis=0)
    r = np.linalg.norm(p, axis=1)
    p = p[r <= np.percentile(r, 98)]
    _, v = np.linalg.eigh(p.T @ p)
    return v[:, 0]


def mesh_up(points, *, up=None, rng=None) -> tuple[np.ndarray, str]:
    """The mesh's normal with a sign, and how it was found.

    ``up`` given: the cloud's thin direction if within 30° of it (the mesh's own tilt), else
    ``up`` itself; the sign is always ``up``'s. Without it the sign is settled later (formwork,
    else the denser lattice): this returns the thin direction with a provisional sign.
    """
    rng = np.random.default_rng(rng)
    n = _thin_direction(points, rng)
    u = parse_up(up)
    if u is None:
        return n, "the thin direction of the cloud (its sign settled below)"
    if abs(float(n @ u)) >= math.cos(math.radians(30)):
        return (n if n @ u > 0 else -n), f"up = {up} given; the mesh plane's own tilt from the cloud"
    return u, f"up = {up} given (the cloud's thin direction is more than 30° off it: kept as given)"


@dataclass(frozen=True)
class Datum:
    """The formwork (or ground) plane under the mesh, if found."""

    plane: G.Plane
    found: bool
    noise_mm: float | None
    share: float  # of the points on it
    reason: str = ""


def _smoothed_hist(x, bin_mm: float, sd_mm: float, lo=None, hi=None):
    lo = float(np.min(x)) if lo is None else lo
    hi = float(np.max(x)) if hi is None else hi
    edges = np.arange(lo, hi + bin_mm, bin_mm)
    if len(edges) < 2:
        edges = np.array([lo, lo + bin_mm])
    c, _ = np.histogram(x, edges)
    k = max(sd_mm / bin_mm, 0.5)
    ker = np.exp(-0.5 * (np.arange(-int(4 * k) - 1, int(4 * k) + 2) / k) ** 2)
    s = np.convolve(c.astype(float), ker / ker.sum(), mode="same")
    return 0.5 * (edges[:-1] + edges[1:]), s, c


def _far_side_sigma(s, i: int, *, bin_mm: float, kernel_mm: float) -> float:
    """σ of a histogram peak at bin ``i`` from its half width at half maximum on its low side
    (nothing but the plane lies there), less the smoothing kernel: sparse outliers far off do
    not widen it, as they would a spread of the residuals."""
    j = i
    while j > 0 and s[j] > 0.5 * s[i]:
        j -= 1
    hwhm = (i - j) * bin_mm
    return float(math.sqrt(max((hwhm / 1.1774) ** 2 - kernel_mm ** 2, 0.25)))


def find_datum(points, normal, *, rng=None) -> Datum:
    """The formwork or ground plane under the mesh: a plane holding at least 15 % of the points
    at the low end of their heights along ``normal`` (either sign), with the range noise measured
    on its far side (away from the bars, where nothing else lies).

    The plane's height is the mode of the residuals (not their mean: the lowest bars lie within
    a few noise σ above it) and its noise the half width of that mode on its far side.
    """
    rng = np.random.default_rng(rng)
    n = np.asarray(normal, float)
    h = _dot(points, n)
    sub = _sample(len(h), 100_000, rng)
    best = None
    for sign in (1.0, -1.0):
        hs = sign * h[sub]
        lo = np.percentile(hs, 0.5)
        x, s, _ = _smoothed_hist(hs, 1.0, 3.0, lo - 5, np.percentile(hs, 99.5))
        # the lowest strong peak
        i = int(np.argmax(s[: max(1, len(s) // 2)]))
        mode = x[i]
        sigma = _far_side_sigma(s, i, bin_mm=1.0, kernel_mm=3.0)
        share = float(np.mean(np.abs(hs - mode) < max(2.5 * sigma, 2.0)))
        if best is None or share > best[2]:
            best = (sign, mode, share, sigma)
    sign, mode, share, sigma = best
    if share < 0.15:
        return Datum(G.Plane(n, 0.0), False, None, share,
                     f"no plane under the mesh: at most {100 * share:.0f} % of the points lie on one "
                     "(the formwork or the ground is not in the scan)")
    if _lined_up(points, n, sign * h, mode, sigma, rng):
        return Datum(G.Plane(n, 0.0), False, None, share,
                     "the lowest dense layer of points is made of bars, not a plane (no formwork or "
                     "ground in the scan)")
    # refine the plane's tilt on its own points (a band around the mode, below the bars)
    band = np.abs(sign * h - mode) < max(1.5 * sigma, 1.5)
    q = points[band]
    q = q[_sample(len(q), 200_000, rng)]
    c = q.mean(axis=0)
    w, v = np.linalg.eigh((q - c).T @ (q - c))
    nn = v[:, 0] if v[:, 0] @ (sign * n) > 0 else -v[:, 0]
    if nn @ (sign * n) < math.cos(math.radians(15)):
        nn = sign * n
    hh = _dot(points, nn) - float(c @ nn)
    x, s, _ = _smoothed_hist(hh[np.abs(hh) < 6 * sigma + 10], 0.5, max(sigma / 3, 0.5))
    mode2 = float(x[int(np.argmax(s))])
    below = hh[(hh < mode2) & (hh > mode2 - 8 * sigma - 10)]
    sigma2 = 1.4826 * float(np.median(mode2 - below)) if len(below) > 20 else sigma
    offset = -float(nn @ c) - mode2
    return Datum(G.Plane(nn, offset, int(band.sum()), sigma2), True, sigma2, share)


def _sharpness_ratio(plan, rng) -> float:
    """How much more the plan offsets pile up at the best angle than at a typical one."""
    p = plan[_sample(len(plan), 20_000, rng)]
    if len(p) < 50:
        return 1.0
    s = G.direction_sharpness(p, np.radians(np.arange(0.0, 180.0, 1.0)), 6.0)
    return float(s.max() / np.median(s))


def _lined_up(points, n, h, mode, sigma, rng) -> bool:
    """Whether the layer at ``mode`` is a lattice rather than a plane: its points line up along
    bar directions (their offsets' sharpness at the best angle exceeds the typical one by 40 % or
    more, and by a quarter of what the points above it show). A formwork's points only show the
    bars' shadows: on synthetic scans (σ 5–20 mm) 17–22 % over, a lattice's 100 % and more."""
    R = G.plane_frame(G.Plane(n, 0.0))
    plan = np.column_stack([_dot(points, R[0]), _dot(points, R[1])])
    band = np.abs(h - mode) < max(2.5 * sigma, 2.0)
    above = h > mode + 3 * sigma + 30
    if above.sum() < 100:
        return False
    excess = _sharpness_ratio(plan[band], rng) - 1
    return excess > 0.4 and excess > 0.25 * (_sharpness_ratio(plan[above], rng) - 1)


# ----------------------------------------------------------------------------------------------
# 3. Lattices
# ----------------------------------------------------------------------------------------------

def split_lattices(h, *, noise_mm: float, min_gap_mm: float = 10.0) -> float | None:
    """Height between the two lattices: the deepest valley of the height histogram smoothed by the
    noise, between the two highest modes at least ``min_gap_mm`` + 2 noise σ apart; None when the
    valley is not below half the lower of the two modes (one lattice)."""
    h = np.asarray(h, float)
    if len(h) < 50:
        return None
    lo, hi = np.percentile(h, [1, 99])
    x, s, _ = _smoothed_hist(h[(h >= lo) & (h <= hi)], 1.0, max(noise_mm, 3.0) * 0.7, lo, hi)
    peaks = [i for i in range(1, len(s) - 1) if s[i] >= s[i - 1] and s[i] > s[i + 1]]
    if len(peaks) < 2:
        return None
    order = sorted(peaks, key=lambda i: -s[i])
    sep = min_gap_mm + 2 * noise_mm
    best = None
    for a_i, a in enumerate(order):
        for b in order[a_i + 1:]:
            if abs(x[a] - x[b]) < sep:
                continue
            i0, i1 = sorted((a, b))
            v = i0 + int(np.argmin(s[i0:i1 + 1]))
            depth = s[v] / min(s[i0], s[i1])
            if best is None or depth < best[0]:
                best = (depth, x[v])
        if best is not None and best[0] < 0.5:
            break
    if best is None or best[0] >= 0.5:
        return None
    return float(best[1])


# ----------------------------------------------------------------------------------------------
# 4. Bars of a lattice
# ----------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Candidate:
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
    return sorted((_Candidate(float(x[i]), float(s[i] - bg[i]), float(z[i])) for i in kept),
                  key=lambda cnd: cnd.centre)


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


def _longest_extent(t, *, cell_mm: float, max_gap_mm: float) -> tuple[float, float]:
    """The longest stretch of occupied cells along a bar (gaps up to ``max_gap_mm`` closed)."""
    if len(t) == 0:
        return 0.0, 0.0
    cells = np.unique(np.floor(t / cell_mm).astype(np.int64))
    gaps = np.diff(cells) * cell_mm > max_gap_mm + cell_mm
    starts = np.r_[0, np.flatnonzero(gaps) + 1]
    ends = np.r_[np.flatnonzero(gaps), len(cells) - 1]
    k = int(np.argmax(cells[ends] - cells[starts]))
    return float(cells[starts[k]] * cell_mm), float((cells[ends[k]] + 1) * cell_mm)


@dataclass
class _Bar:
    direction: np.ndarray
    centre: float
    slope: float
    t0: float
    t1: float
    mean_h: float
    n: int
    resid_sd: float  # spread of the points' offsets about the axis
    h_sd: float
    idx: np.ndarray
    z: float

    @property
    def normal2d(self) -> np.ndarray:
        return np.array([-self.direction[1], self.direction[0]])


def _mad(x) -> float:
    """Robust standard deviation (1.4826 × the median absolute value) of residuals ``x``."""
    return 1.4826 * float(np.median(np.abs(x)))


def _bar_points(off, along, centre, slope, half_width, keep):
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


def lattice_bars(q, *, radius_mm: dict, spacing_mm: float, noise_mm: float, min_length_mm: float = 100.0,
                 rng=None) -> list:
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
    """
    rng = np.random.default_rng(rng)
    plan, h = q[:, :2], q[:, 2]
    out = _find_lattice(plan, h, radius_mm, spacing_mm, noise_mm, min_length_mm, rng)
    return _drop_phantoms(plan, out)


def _band(plan, b: "_Bar", half: float) -> np.ndarray:
    d = b.direction
    n2 = np.array([-d[1], d[0]])
    return np.abs(_dot(plan, n2) - (b.centre + b.slope * _dot(plan, d))) < half


def _drop_phantoms(plan, found: list) -> list:
    """Drop a "bar" whose points lie almost all (80 %) where bars of the other direction cross it:
    the crossing bars' points, gathered between their shadows, not a bar."""
    out = []
    for g, b in found:
        other = [x for gg, x in found if gg != g]
        if not other:
            out.append((g, b))
            continue
        t = _dot(plan[b.idx], b.direction)
        cross = [c for c in (_crossing_along(b, x) for x in other) if np.isfinite(c)]
        half = 2 * float(np.median([x.resid_sd for x in other])) + 2.0
        inside = ~_crossing_free(t, cross, half)
        if inside.mean() < 0.8:
            out.append((g, b))
    return out


def _find_lattice(plan, h, radius_mm, spacing_mm, noise_mm, min_length_mm, rng) -> list:
    out = []
    keep = np.ones(len(plan), bool)
    first = None
    for g in (0, 1):
        ang = _direction_scan(plan[keep], rng, exclude_deg=first, bin_mm=max(4.0, noise_mm / 2))
        if ang is None:
            break
        first = ang if first is None else first
        bars, off, along = _bars_along(plan, h, ang, keep, radius_mm=radius_mm.get(g, max(radius_mm.values())),
                                       spacing_mm=spacing_mm, noise_mm=noise_mm, min_length_mm=min_length_mm)
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
    spread = math.sqrt(noise_mm ** 2 + radius_mm ** 2 / 2)
    half = radius_mm + 2.5 * noise_mm + 2.0
    peaks = _offset_peaks(off[keep], kernel_mm=spread, min_sep_mm=max(0.45 * spacing_mm, 3 * spread),
                          background_mm=max(spacing_mm, 6 * spread), z_min=5.0)
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
        t0, t1 = _longest_extent(t, cell_mm=cell, max_gap_mm=max(60.0, 2 * cell))
        if t1 - t0 < min_length_mm - cell:
            continue
        idx = idx[(along[idx] >= t0) & (along[idx] <= t1)]
        if len(idx) < 20:
            continue
        r = off[idx] - (c + slope * along[idx])
        bars.append(_Bar(d, c, slope, t0, t1, float(np.mean(h[idx])), len(idx),
                         _mad(r), _mad(h[idx] - np.median(h[idx])),
                         idx, p.z))
    return bars, off, along


# ----------------------------------------------------------------------------------------------
# 5-6. Axes, heights, measurements
# ----------------------------------------------------------------------------------------------

def diameter_resolvable(noise_mm: float, radius_mm: float, half_gap_mm: float, n_points: int) -> tuple[bool, str]:
    """Whether a bar's size can be read from its points, and why not.

    A circle fitted to noisy points of a bar's upper half is biased by the noise unless the noise
    is well below the radius, and its radius' standard error is about σ·√(8/N) for N points over
    a half circle. The size is read only where σ ≤ radius / 4 and that error is under a quarter
    of the half gap to the nearest other standard size (so the size is told apart at 4 σ).
    """
    if noise_mm > radius_mm / 4:
        return False, (f"range noise σ {noise_mm:.1f} mm exceeds a quarter of the bar's radius "
                       f"({radius_mm:.1f} mm): the scan cannot size it")
    se = noise_mm * math.sqrt(8.0 / max(n_points, 1))
    if se > half_gap_mm / 4:
        return False, (f"{n_points} points at σ {noise_mm:.1f} mm give its radius to ±{se:.2f} mm, more than "
                       f"a quarter of the half gap to the next size ({half_gap_mm:.2f} mm)")
    return True, ""


def _envelope(design: Design, layer: str, level: str) -> float:
    from ._barsizes import barset_width_mm

    return barset_width_mm(design.lattice(layer).level(level), design.bar_system)


def _mean_measure(values, ses, n_points: int) -> Measurement:
    v = np.asarray(values, float)
    if len(v) == 0:
        return Measurement.not_measured("no bar of this level was measured")
    sd = float(np.std(v, ddof=1)) / math.sqrt(len(v)) if len(v) > 1 else float(ses[0])
    return Measurement(float(np.mean(v)), sd, n_points)


def _to_axis(b: _Bar, layer: str, level: str, group: int, r: float) -> G.BarAxis:
    """A bar as a :class:`~rebarlib.geometry.BarAxis` (slab frame): its axis lies 2r/π under the
    mean height of its points."""
    axis_h = b.mean_h - _SURFACE_MEAN * r
    se = b.resid_sd / math.sqrt(max(b.n, 1))
    return G.BarAxis(layer, b.direction, b.centre, b.slope, axis_h, 0.0, b.t0, b.t1, r, b.n, b.resid_sd,
                     b.idx, group, level, arc_deg=float("nan"), axis_se_mm=se)


def inspect_cloud(cloud, design: Design, *, units: str | None = None, up=None, min_length_mm: float = 100.0,
                  diameters: bool = True, rng=0, name: str | None = None) -> InspectionResult:
    """Cover, layer distance, bars, spacings (and diameters where the scan resolves them) of a
    scanned point cloud of a two-lattice mesh.

    Parameters
    ----------
    cloud : a cloud file (any format of :mod:`rebarlib.cloud_io`; ``units`` required), a
        :class:`~rebarlib.cloud_io.ScanCloud`, or an (N, 3) array (mm unless ``units="m"``)
    design : the slab's :class:`~rebarlib.Design`
    units : "mm" or "m" for a file or an array in metres
    up : "+x", "-x", "+y", "-y", "+z", "-z" or a vector: the mesh's up side in the cloud's frame;
        None: found (away from the formwork, else toward the denser lattice; the result's notes
        say which)
    min_length_mm : a bar is reported when at least this much of it is scanned
    diameters : size the bars where the scan's noise allows (:func:`diameter_resolvable`)

    Returns
    -------
    InspectionResult with ``method="cloud"``; bar coordinates are in the cloud's frame re-centred
    (``extras["cloud"]["offset_mm"]`` added gives the file's frame, in mm).
    """
    if not isinstance(design, Design):
        raise RebarInputError("design: expected a rebarlib.Design (use rebarlib.load_design), "
                              f"got {type(design).__name__}")
    t_start = time.perf_counter()
    sc = as_scan_cloud(cloud, units=units)
    pts = sc.points
    if len(pts) < 500:
        raise RebarInputError(f"cloud {sc.source or 'array'}: {len(pts)} points, at least 500 needed for a mesh")
    rng = np.random.default_rng(rng)
    notes = []
    normal, up_how = mesh_up(pts, up=up, rng=rng)
    datum = find_datum(pts, normal, rng=rng)
    if datum.found and up is None:
        normal, up_how = datum.plane.normal, "away from the formwork/ground plane found under the mesh"
    elif datum.found and float(datum.plane.normal @ normal) < 0:
        datum = Datum(G.Plane(normal, 0.0), False, None, datum.share,
                      "the only plane found lies above the mesh (for the up given): no formwork in the scan")
    plane, q, split = _frame(pts, normal, datum)
    result_bars, noise = _all_axes(q, split, design, datum, min_length_mm, rng)
    if not datum.found and up is None:
        # nothing else settles the sign: a scanner looks down on the mesh, so where two bars
        # cross, the one beneath is hidden and the band along it holds the crossing bar's points,
        # which lie higher than its own: heights lift at the crossings only when up is up
        facing = _normals_facing(sc, plane.normal)
        if facing is not None:
            flip = facing < 0
            up_how = (f"the mesh plane from the bars (no formwork in the scan); its sign from the file's normals "
                      f"({100 * abs(facing):.0f} % more of them face that side: the scanner's)")
        else:
            lift = crossing_lift(q, result_bars, noise)
            flip = lift < 0
            up_how = (f"the mesh plane from the bars (no formwork in the scan); its sign GUESSED from the crossings, "
                      f"where the bar on top hides the one beneath (heights {abs(lift):.1f} mm higher there): right "
                      "in every synthetic scan at noise σ 5 mm, not at σ 15 mm: give up= (--up)")
        if flip:
            plane, q, split = _frame(pts, -normal, datum)
            result_bars, noise = _all_axes(q, split, design, datum, min_length_mm, rng)
    notes.append(f"up: {up_how}")
    sig = float(np.median([v[0] for v in noise.values()]))
    notes.append(f"noise σ: {datum.noise_mm or float('nan'):.1f} mm across the formwork, "
                 f"spread {sig:.1f} mm across the bars in plan (noise and what lies beside them)" if datum.found else
                 f"spread σ: {sig:.1f} mm across the bars in plan (noise and what lies beside them; no formwork)")
    return _assemble(sc, design, plane, datum, result_bars, sig, notes, diameters, q,
                     name=name, t_start=t_start, up_how=up_how)


def _normals_facing(sc: ScanCloud, normal) -> float | None:
    """The share of the file's normals on ``normal``'s side less that on the other side, or None
    without normals or when they are unoriented (under 20 % more on one side)."""
    nrm = sc.fields.get("normals")
    if nrm is None or np.ndim(nrm) != 2 or np.shape(nrm)[1] != 3:
        return None
    dots = np.asarray(nrm, float) @ np.asarray(normal, float)
    dots = dots[np.isfinite(dots) & (np.abs(dots) > 0.1)]
    if len(dots) < 100:
        return None
    facing = float(np.mean(dots > 0) - np.mean(dots < 0))
    return facing if abs(facing) >= 0.2 else None


def _all_axes(q, split, design, datum, min_length_mm, rng):
    bars, noise = [], {}
    for layer in G.LAYERS:
        axes, noise[layer] = _layer_axes(q, split, layer, design, datum, min_length_mm, rng)
        bars += axes
    return bars, noise


def crossing_lift(q, bars: list, noise: dict) -> float:
    """Mean height (mm) of the points along the bars at their crossings less that away from them,
    over every bar (weighted by points): positive when the slab frame's up is the scanner's side.

    Seen from above, a bar beneath a crossing bar is hidden there, and the band along it holds
    the crossing bar's points, a bar radius or two higher; the bar on top shows its own surface
    either way. Seen from below (up taken upside down) the hidden bar's band holds points lower
    than its own."""
    total, weight = 0.0, 0
    plan, h = q[:, :2], q[:, 2]
    for layer in G.LAYERS:
        sig = noise.get(layer, (10.0, 10.0))[0]
        mine = [b for b in bars if b.layer == layer]
        for b in mine:
            n2 = b.normal2d
            t = _dot(plan, b.direction)
            across = np.abs(_dot(plan, n2) - (b.offset_mm + b.slope * t))
            band = (across < b.radius_mm + sig) & (t >= b.t0_mm) & (t <= b.t1_mm)
            band &= np.abs(h - b.axis_height_mm) < 4 * b.radius_mm + 3 * sig
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
            total += (float(h[idx][at].mean()) - float(h[idx][away].mean())) * len(idx)
            weight += len(idx)
    return total / weight if weight else 0.0


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
        raise RebarInputError("cloud: no gap between two lattices in the heights above the mesh's plane; "
                              "is this a two-lattice mesh (or is up wrong)?")
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
    found = lattice_bars(qs, radius_mm={0: r, 1: r}, spacing_mm=spacing, noise_mm=guess,
                         min_length_mm=min_length_mm, rng=rng)
    if not found:
        return [], (guess, guess)
    sig_plan = _noise_across(found, r)
    found = lattice_bars(qs, radius_mm={0: r, 1: r}, spacing_mm=spacing, noise_mm=sig_plan,
                         min_length_mm=min_length_mm, rng=rng)
    if not found:
        return [], (sig_plan, guess)
    found = _refit_off_crossings(qs, found, r, sig_plan)
    sig_plan = _noise_across(found, r)
    sig_h = datum.noise_mm if datum.found else float(np.median(
        [math.sqrt(max(b.h_sd ** 2 - 0.05 * r ** 2, 0.25)) for _, b in found]))
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
        mean_h, n = _bar_height(qb, proj[g], b, other, half_cross, r + 2 * sig_plan + 2, sig_h,
                                formwork=datum.found and layer == "lower", radius_mm=radii[lv])
        if mean_h is None:
            continue
        b.mean_h, b.n, b.idx = mean_h, n, idx[b.idx]
        axes.append(_to_axis(b, layer, lv, g, radii[lv]))
    return _drop_off_level(axes, sig_h), (sig_plan, sig_h)


def _refit_off_crossings(qs, found: list, r: float, sig_plan: float) -> list:
    """Each bar's offset again from its band's points away from the bars crossing it (its drift
    kept): there the band holds only this bar and what lies beside it."""
    plan = qs[:, :2]
    half = r + 2.5 * sig_plan + 2.0
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


def _noise_across(found: list, r: float) -> float:
    """Noise in plan: the bars' spread across less what a bar's own width spreads its points."""
    sd = float(np.median([b.resid_sd for _, b in found]))
    return float(math.sqrt(max(sd ** 2 - r ** 2 / 3, 1.0)))


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
    s1 = math.sqrt(sig0 ** 2 + (0.3 * radius_mm) ** 2)
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


def _drop_off_level(axes: list, sig_h: float) -> list:
    """A "bar" lying far from the other bars of its direction is a chair, a spacer, a tie: not a
    bar of this level. Far: beyond four times the noise of its mean height, more than its diameter
    off, or more than its radius off with under a quarter of its set's typical points per mm
    (bars of a real cage lie a radius or so off their level's median; a few stray points do not
    make a bar)."""
    out = []
    for lv in G.LEVELS:
        group = [a for a in axes if a.level == lv]
        if len(group) < 3:
            out += group
            continue
        med = float(np.median([a.axis_height_mm for a in group]))
        dens = float(np.median([_per_mm(a) for a in group]))
        for a in group:
            off = abs(a.axis_height_mm - med) - 4 * sig_h / math.sqrt(max(a.n_points, 1))
            if off <= a.radius_mm or (off <= 2 * a.radius_mm and _per_mm(a) >= 0.25 * dens):
                out.append(a)
    return out


def _per_mm(a: G.BarAxis) -> float:
    return a.n_points / max(a.t1_mm - a.t0_mm, 1.0)


def _crossing_along(b: _Bar, x: _Bar) -> float:
    """Where bar ``x`` crosses bar ``b``, as a position along ``b``."""
    n_b = np.array([-b.direction[1], b.direction[0]])
    n_x = np.array([-x.direction[1], x.direction[0]])
    A = np.vstack([n_b, n_x])
    if abs(np.linalg.det(A)) < 1e-6:
        return float("nan")
    p = np.linalg.solve(A, [b.centre, x.centre])
    return float(p @ b.direction)


def _assemble(sc: ScanCloud, design: Design, plane, datum: Datum, bars: list, noise, notes, diameters, q,
              *, name, t_start, up_how) -> InspectionResult:
    order = sorted(range(len(bars)), key=lambda i: (G.LAYERS.index(bars[i].layer), G.LEVELS.index(bars[i].level),
                                                    bars[i].offset_mm))
    bars = [bars[i] for i in order]
    spacing = {(la, lv): design.lattice(la).level(lv).spacing_mm for la in G.LAYERS for lv in G.LEVELS}
    spacings = G.measure_spacings(bars, design_spacing=spacing)
    table = G.bars_table(bars, plane)
    if diameters:
        table = _add_diameters(table, bars, q, design, noise)
    und = {(la, lv): [b.underside_mm for b in bars if b.layer == la and b.level == lv] for la in G.LAYERS
           for lv in G.LEVELS}
    npts = {(la, lv): sum(b.n_points for b in bars if b.layer == la and b.level == lv) for la in G.LAYERS
            for lv in G.LEVELS}
    ses = {k: [b.axis_se_mm for b in bars if (b.layer, b.level) == k] for k in und}
    lo, hi = und[("lower", "bottom")], und[("upper", "bottom")]
    if lo and hi:
        m_lo, m_hi = _mean_measure(lo, ses[("lower", "bottom")], 0), _mean_measure(hi, ses[("upper", "bottom")], 0)
        layer_distance = Measurement(m_hi.value_mm - m_lo.value_mm,
                                     math.hypot(m_lo.uncertainty_mm, m_hi.uncertainty_mm),
                                     npts[("lower", "bottom")] + npts[("upper", "bottom")])
    else:
        layer_distance = Measurement.not_measured("the bottom bars of both lattices are needed; "
                                                  f"found {len(lo)} lower and {len(hi)} upper")
    if not datum.found:
        cover = Measurement.not_measured(f"{datum.reason}: heights have no datum")
        upper_top = Measurement.not_measured(cover.reason)
    else:
        cover = _mean_measure(lo, ses[("lower", "bottom")], npts[("lower", "bottom")]) if lo else \
            Measurement.not_measured("no bottom bar of the lower lattice found")
        tops = [b.top_mm for b in bars if b.layer == "upper" and b.level == "top"]
        upper_top = Measurement(float(np.mean(tops)), None, npts[("upper", "top")]) if tops else \
            Measurement.not_measured("no top bar of the upper lattice found")
    top_cover = _top_cover(design, upper_top)
    counts = pd.DataFrame([{"layer": la, "level": lv, "found": sum(1 for b in bars if (b.layer, b.level) == (la, lv)),
                            "expected": None, "missing": None, "extra": None}
                           for la in G.LAYERS for lv in G.LEVELS])
    fw = plane.to_dict() | {"found": bool(datum.found)}
    if not datum.found:
        fw["reason"] = datum.reason
    res = InspectionResult(
        capture=name or (Path(sc.source).stem if sc.source else "cloud"), method=METHOD, cover=cover,
        layer_distance=layer_distance, upper_top=upper_top, top_cover=top_cover, bars=table, spacings=spacings,
        counts=counts, formwork=fw, camera={}, timings_s={"total": time.perf_counter() - t_start}, notes=notes,
        extras={"cloud": {"source": sc.source, "units": sc.units, "n_points": int(len(sc)),
                          "offset_mm": [round(float(v), 3) for v in sc.offset_mm],
                          "up": [round(float(v), 6) for v in plane.normal],
                          "up_how": up_how, "noise_mm": round(float(noise), 3), "formwork": bool(datum.found),
                          "frame": "the cloud's frame re-centred: add offset_mm for the file's frame (mm)"}})
    return res


def _add_diameters(table: pd.DataFrame, bars: list, q, design: Design, noise) -> pd.DataFrame:
    """Bar sizes where :func:`diameter_resolvable` allows: a free-radius circle through the bar's
    cross-section points (offset across its axis, height), its width snapped to the design's
    bar system; else "not measured" with the criterion that failed. Columns as the camera's
    diameter stage names them: ``nominal_mm, width_mm, width_sigma_mm, confidence,
    budget_confidence, design_diameter_mm, diameter_status, diameter_reason``."""
    from ._barsizes import bar_system, size_half_gaps_mm, snap_diameter

    system = design.bar_system
    sysm = bar_system(system)
    rows = []
    for b in bars:
        bs = design.lattice(b.layer).level(b.level)
        deformed = getattr(bs, "surface", "deformed") == "deformed"
        i = min(range(len(sysm.sizes_mm)), key=lambda k: abs(sysm.sizes_mm[k] - bs.diameter_mm))
        gap = min(size_half_gaps_mm(sysm.sizes_mm[i], system=system, deformed=deformed))
        cross = [c for c in (_cross_axes(b, x) for x in bars if x.layer == b.layer and x.level != b.level)
                 if np.isfinite(c)]
        fit = _cross_section_width(b, q, noise, cross)
        if fit is not None and not 0.7 < fit[0] / (2 * b.radius_mm) < 1.4:
            rows.append((None, None, None, None, "not measured",
                         f"the circle through its cross-section is {fit[0]:.1f} mm wide against the set's "
                         f"{2 * b.radius_mm:.1f} mm: something else lies in its cross-section"))
            continue
        if fit is None:
            rows.append((None, None, None, None, "not measured", "its cross-section points do not fix a circle"))
            continue
        w, sd, sigma, n = fit
        ok, why = diameter_resolvable(sigma, b.radius_mm, gap, n)
        if not ok:
            rows.append((None, None, None, None, "not measured", why))
            continue
        nominal, conf = snap_diameter(w, system=system, deformed=deformed, sigma_mm=sd)
        rows.append((nominal, w, sd, conf, "measured", ""))
    table = table.copy()
    for k, col in enumerate(("nominal_mm", "width_mm", "width_sigma_mm", "confidence")):
        table[col] = pd.to_numeric(pd.Series([r[k] for r in rows], dtype=object), errors="coerce")
    # the acceptance's decision rule reads the size's confidence here; for a cloud the width's
    # whole uncertainty is the circle fit's standard error
    table["budget_confidence"] = table["confidence"]
    table["design_diameter_mm"] = [design.lattice(b.layer).level(b.level).diameter_mm for b in bars]
    table["diameter_status"] = [r[4] for r in rows]
    table["diameter_reason"] = [r[5] for r in rows]
    return table


def _cross_section_width(b: G.BarAxis, q, noise, crossings=()) -> tuple[float, float, float, int] | None:
    """Width (2 × radius) of the circle through a bar's points in its cross-section, its standard
    error (from three independent thirds of the bar), the noise about the circle (robust σ of the
    residuals) and the points used; None if no circle fits."""
    p = q[b.point_index]
    t = _dot(p[:, :2], b.direction)
    s_ = _dot(p[:, :2], b.normal2d) - (b.offset_mm + b.slope * t)
    h = p[:, 2]
    keep = (np.abs(s_) < b.radius_mm + 3 * noise) & (np.abs(h - b.axis_height_mm) < 2 * b.radius_mm + 3 * noise)
    keep &= _crossing_free(t, list(crossings), 3 * b.radius_mm)  # away from the bars crossing it
    cut = noise
    for _ in range(4):
        if keep.sum() < 30:
            return None
        xc, yc, rad = _circle(s_[keep], h[keep])
        res = np.hypot(s_ - xc, h - yc) - rad
        cut = max(min(cut, 3 * _mad(res[keep])), 0.2)
        keep &= np.abs(res) < 3 * cut
        sigma = _mad(res[keep])
    thirds = [_circle(s_[keep][k::3], h[keep][k::3])[2] for k in range(3)]
    if not np.all(np.isfinite(thirds)):
        return None
    return 2 * rad, 2 * float(np.std(thirds, ddof=1)) / math.sqrt(3), sigma, int(keep.sum())


def _circle(s, h) -> tuple[float, float, float]:
    """Least-squares (Kåsa) circle through cross-section points: centre (s, h) and radius
    (normal equations of the 3-parameter linear problem, centred for conditioning)."""
    ms, mh = float(s.mean()), float(h.mean())
    x, y = s - ms, h - mh
    A = np.column_stack([2 * x, 2 * y, np.ones(len(x))])
    try:
        xc, yc, k = np.linalg.solve(A.T @ A, A.T @ (x ** 2 + y ** 2))
    except np.linalg.LinAlgError:
        return math.nan, math.nan, math.nan
    return float(xc + ms), float(yc + mh), float(math.sqrt(max(k + xc ** 2 + yc ** 2, 0.0)))
