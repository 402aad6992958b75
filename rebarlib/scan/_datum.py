"""Stages 1-3 of a scanned cloud: the mesh's up direction, the formwork (or ground) plane under
it, and the split between the two lattices."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import geometry as G
from ._input import parse_up
from ._util import _dot, _sample, _smoothed_hist


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

    Parameters
    ----------
    points : (N, 3) float points of the scan, mm (e.g. :attr:`ScanCloud.points`)
    up : the mesh's up side as given (:func:`parse_up`: "+z", "-y", ... or a 3-vector), or None
    rng : seed or Generator of the sampling (the thin direction is read from at most 50,000
        points; the 2 % farthest from their median are left out)

    Returns
    -------
    (normal, how): the (3,) unit normal of the mesh, and a sentence saying how it was found
    (for the result's notes).

    Examples
    --------
    >>> g = np.random.default_rng(0)
    >>> pts = np.column_stack([g.uniform(-500, 500, (3000, 2)), g.normal(0.0, 5.0, 3000)])
    >>> n, how = mesh_up(pts, up="-z", rng=0)
    >>> round(float(n[2]), 3), how
    (-1.0, "up = -z given; the mesh plane's own tilt from the cloud")
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


def _far_side_sigma(s, i: int, *, bin_mm: float, kernel_mm: float) -> float:
    """σ of a histogram peak at bin ``i`` from its half width at half maximum on its low side
    (nothing but the plane lies there), less the smoothing kernel: sparse outliers far off do
    not widen it, as they would a spread of the residuals."""
    j = i
    while j > 0 and s[j] > 0.5 * s[i]:
        j -= 1
    hwhm = (i - j) * bin_mm
    return float(math.sqrt(max((hwhm / 1.1774) ** 2 - kernel_mm**2, 0.25)))


def _is_peak(s, i: int, *, kernel_bins: float, z_min: float = 5.0) -> bool:
    """Whether bin ``i`` of a smoothed histogram ``s`` stands out of its median level by
    ``z_min`` times that level's counting noise (as bars do in :func:`lattice_bars`). Outliers
    scattered along the rays below the mesh fill one side's histogram with a flat floor, whose
    highest bin has no half width: read as a plane, its "noise" was hundreds of mm and its band
    held every point (10 % outliers: the plane was taken on the wrong side)."""
    bg = max(float(np.median(s)), 1e-9)
    eff = 2 * math.sqrt(math.pi) * kernel_bins
    return (float(s[i]) - bg) / math.sqrt(bg / eff) >= z_min


def find_datum(points, normal, *, rng=None) -> Datum:
    """The formwork or ground plane under the mesh: a plane holding at least 15 % of the points
    at the low end of their heights along ``normal`` (either sign), with the range noise measured
    on its far side (away from the bars, where nothing else lies).

    The plane's height is the mode of the residuals (not their mean: the lowest bars lie within
    a few noise σ above it) and its noise the half width of that mode on its far side.

    Parameters
    ----------
    points : (N, 3) float points of the scan, mm
    normal : (3,) the mesh's normal (:func:`mesh_up`); either sign, the plane is looked for at
        both ends
    rng : seed or Generator of the sampling (at most 100,000 points in the search for the
        plane, 200,000 for its tilt)

    Returns
    -------
    Datum: ``found``; ``plane``, a :class:`rebarlib.geometry.Plane` whose normal points from
    the plane to the mesh (its ``height`` is the height above the formwork) and whose
    ``n_inliers`` and ``noise_mm`` are its points' count and σ; ``noise_mm`` the range noise σ
    (mm); ``share`` the share of the points on it; ``reason`` "". Not found: ``plane`` is
    ``Plane(normal, 0.0)`` (a placeholder), ``noise_mm`` None, and ``reason`` says why (under
    15 % of the points on one plane, or the lowest dense layer is bars).

    Examples
    --------
    >>> g = np.random.default_rng(0)
    >>> formwork = np.column_stack([g.uniform(0, 1000, (6000, 2)), g.normal(0.0, 2.0, 6000)])
    >>> x = g.integers(0, 7, 3000) * 150.0 + 50 + g.normal(0.0, 2.0, 3000)  # bars along y, 40 mm up
    >>> bars = np.column_stack([x, g.uniform(0, 1000, 3000), 40 + g.normal(0.0, 2.0, 3000)])
    >>> d = find_datum(np.vstack([formwork, bars]), [0, 0, -1.0], rng=0)
    >>> d.found, round(float(d.plane.normal[2]), 3), round(d.noise_mm, 1), round(d.share, 2)
    (True, 1.0, 1.8, 0.64)
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
        if not _is_peak(s, i, kernel_bins=3.0):
            share = 0.0  # scattered points only (outliers below the mesh): no plane on this side
        if best is None or share > best[2]:
            best = (sign, mode, share, sigma)
    sign, mode, share, sigma = best
    if share < 0.15:
        return Datum(
            G.Plane(n, 0.0),
            False,
            None,
            share,
            f"no plane under the mesh: at most {100 * share:.0f} % of the points lie on one "
            "(the formwork or the ground is not in the scan)",
        )
    if _lined_up(points, n, sign * h, mode, sigma, rng):
        return Datum(
            G.Plane(n, 0.0),
            False,
            None,
            share,
            "the lowest dense layer of points is made of bars, not a plane (no formwork or ground in the scan)",
        )
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


def _lined_up(points, n, h, mode, sigma, rng, *, max_excess: float = 0.5) -> bool:
    """Whether the layer at ``mode`` is a lattice rather than a plane: its points line up along
    bar directions (their offsets' sharpness at the best angle exceeds the typical one by more than
    ``max_excess``).

    The excess sharpness (sum of squared offset counts at the best angle over that at a typical
    one, less 1) of points spread evenly over a share φ of the offsets and absent elsewhere is
    1/φ − 1. A plane is a surface seen everywhere but in the shadows of the bars above it: its
    excess is f/(1 − f) for a share f of it in shadow, and 0.5 means a third of the formwork
    hidden in stripes of one direction. A lattice's points lie on its bars only (a few bar widths
    in each spacing). On synthetic scans (σ 5-20 mm, dense and sparse, seeds 0, 1, 10, 11) the
    formwork's excess was 0.14-0.31 and a lattice's (no formwork) 0.86-6.2.

    The rule no longer also asks the excess to reach a quarter of what the points above the
    layer show (decision 040): at σ 5 mm without formwork the lowest layer's mode merged both
    levels of the lower lattice (its σ 19 mm), so "above" (3σ + 30 mm over the mode) held only the
    upper lattice's top level, one direction's bars, excess 4-7.6; the lower lattice's 1.8-2.0
    fell under a quarter of that in 2 of 24 scans (seeds 10 and 17, dense), was taken for a
    formwork with a "noise" of 112 mm, and no split between the lattices was left."""
    R = G.plane_frame(G.Plane(n, 0.0))
    plan = np.column_stack([_dot(points, R[0]), _dot(points, R[1])])
    band = np.abs(h - mode) < max(2.5 * sigma, 2.0)
    above = h > mode + 3 * sigma + 30
    if above.sum() < 100:
        return False
    return _sharpness_ratio(plan[band], rng) - 1 > max_excess


def split_lattices(h, *, noise_mm: float, min_gap_mm: float = 10.0) -> float | None:
    """Height between the two lattices: the deepest valley of the height histogram smoothed by the
    noise, between the two highest modes at least ``min_gap_mm`` + 2 noise σ apart; None when the
    valley is not below half the lower of the two modes (one lattice).

    Parameters
    ----------
    h : (N,) float heights of the points above the mesh's plane (slab frame), mm; the 1 % at
        either end are left out
    noise_mm : the height noise σ, mm (the histogram is smoothed by 0.7 of it, at least 2.1 mm)
    min_gap_mm : the two lattices' modes lie at least this (plus two ``noise_mm``) apart

    Returns
    -------
    float, the height of the valley (mm): points above it are the upper lattice's; None with
    fewer than 50 heights or without such a valley.

    Examples
    --------
    >>> g = np.random.default_rng(0)
    >>> h = np.r_[g.normal(40.0, 5.0, 2000), g.normal(75.0, 5.0, 2000)]
    >>> round(split_lattices(h, noise_mm=5.0), 1), split_lattices(h[:2000], noise_mm=5.0)
    (57.4, None)
    """
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
        for b in order[a_i + 1 :]:
            if abs(x[a] - x[b]) < sep:
                continue
            i0, i1 = sorted((a, b))
            v = i0 + int(np.argmin(s[i0 : i1 + 1]))
            depth = s[v] / min(s[i0], s[i1])
            if best is None or depth < best[0]:
                best = (depth, x[v])
        if best is not None and best[0] < 0.5:
            break
    if best is None or best[0] >= 0.5:
        return None
    return float(best[1])
