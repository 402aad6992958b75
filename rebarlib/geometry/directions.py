"""The bar directions of one lattice and the bars' places across each (refined method): an
angular scan of the points' plan offsets (:func:`bar_directions`), then the offsets at which the
points run continuously along a direction (:func:`_bar_candidates`).
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["direction_sharpness", "bar_directions"]


def direction_sharpness(plan, angles_rad, bin_mm) -> np.ndarray:
    """How concentrated the plan offsets (N, 2) mm across each direction are: the sum of squared
    counts of a ``bin_mm`` histogram of the offsets, for each angle (radians) in ``angles_rad``.

    Parameters
    ----------
    plan : (N, 2) array
        Plan coordinates of the points (mm).
    angles_rad : array
        The directions to score (radians).
    bin_mm : float
        The histogram's bin across each direction.

    Returns
    -------
    ndarray
        One sharpness per angle: higher where the offsets pile up in fewer bins.

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

    Parameters
    ----------
    plan : (N, 2) array
        Plan coordinates of one lattice's points (mm).
    max_points : int
        The scan reads a random sample of at most this many points.
    min_separation_deg : float
        The second direction lies at least this far from the first.
    rng : int, Generator or None
        Seed of the sample.

    Returns
    -------
    list of float
        One or two plan angles (degrees, [0, 180)), the sharpest first; empty for under 20
        points.

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
