"""The paper's procedure for bars and spacings: sequential RANSAC lines, K-means directions, and
the spacing as the mean distance of one bar's points to its neighbour's axis.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pandas as pd

from .._status import MEASURED
from .axis import BarAxis
from .spacing import _adjacent_pairs, _spacing_frame


def _line_distances(points, p0, dirs):
    """Distances (H, N) of N points to H lines (p0 (H, 3), unit dirs (H, 3))."""
    v = points[None, :, :] - p0[:, None, :]
    proj = np.einsum("hnk,hk->hn", v, dirs)
    d2 = np.einsum("hnk,hnk->hn", v, v) - proj**2
    return np.sqrt(np.maximum(d2, 0))


def paper_find_bars(
    points,
    *,
    layer: str,
    threshold_mm: float,
    max_trials: int = 460,
    stop_fraction: float = 0.06,
    min_count_ratio: float = 0.4,
    max_bars: int = 80,
    chunk: int = 40,
    score_points: int = 4000,
    rng=None,
) -> list:
    """The paper's sequential RANSAC lines in one lattice (slab-frame points).

    Hypotheses (pairs of points) are evaluated in vectorised chunks. Each accepted line is refitted
    by least squares (principal axis) on its inliers, which are then removed; stop when fewer than
    ``stop_fraction`` of the lattice's points remain; drop lines with fewer than
    ``min_count_ratio`` × the mean inlier count. The axis height is the inliers' mean height (the
    paper has no cross-section model).

    Parameters
    ----------
    points : (N, 3) slab-frame points of one lattice
    layer : "lower" or "upper" (copied into the bars)
    threshold_mm : a point within this distance of a line is its inlier
    max_trials : line hypotheses per line found (the paper's k)
    stop_fraction, min_count_ratio, max_bars : when to stop and which lines to keep (above)
    chunk : hypotheses evaluated at once
    score_points : hypotheses are scored on at most this many random points (the chosen line's
        inliers are then taken from all points)
    rng : seed or Generator

    Returns
    -------
    list of BarAxis (no radius, ``group`` unset: :func:`group_directions` sets it)
    """
    rng = np.random.default_rng(rng)
    q = np.asarray(points, float)
    n_total = len(q)
    remaining = np.arange(n_total)
    found = []
    while len(remaining) > stop_fraction * n_total and len(found) < max_bars and len(remaining) >= 2:
        pts_all = q[remaining]
        # hypotheses are scored on a random subset (the count ranks hypotheses the same way up
        # to sampling noise); the chosen line's inliers are then taken from all points
        pts = (
            pts_all if len(pts_all) <= score_points else pts_all[rng.choice(len(pts_all), score_points, replace=False)]
        )
        best_n, best = -1, None
        for s in range(0, max_trials, chunk):
            k = min(chunk, max_trials - s)
            i = rng.integers(0, len(pts), (k, 2))
            p0, p1 = pts[i[:, 0]], pts[i[:, 1]]
            dv = p1 - p0
            ln = np.linalg.norm(dv, axis=1)
            ok = ln > 1e-6
            if not ok.any():
                continue
            dist = _line_distances(pts, p0[ok], dv[ok] / ln[ok, None])
            cnt = (dist < threshold_mm).sum(axis=1)
            j = int(np.argmax(cnt))
            if cnt[j] > best_n:
                best_n, best = int(cnt[j]), (p0[ok][j], (dv[ok] / ln[ok, None])[j])
        if best is None or best_n < 2:
            break
        pts = pts_all
        dist = _line_distances(pts, best[0][None], best[1][None])[0]
        inl = dist < threshold_mm
        if inl.sum() < 2:
            break
        c = pts[inl].mean(axis=0)
        _, _, vt = np.linalg.svd(pts[inl] - c, full_matrices=False)
        found.append((c, vt[0], remaining[inl]))
        remaining = remaining[~inl]
    if not found:
        return []
    mean_count = np.mean([len(f[2]) for f in found])
    bars = []
    for c, v, idx in found:
        if len(idx) < min_count_ratio * mean_count:
            continue
        d2 = v[:2] / (np.linalg.norm(v[:2]) + 1e-12)
        n2 = np.array([-d2[1], d2[0]])
        t = q[idx, :2] @ d2
        off = float(c[:2] @ n2)
        bars.append(
            BarAxis(
                layer,
                d2,
                off,
                0.0,
                float(q[idx, 2].mean()),
                0.0,
                float(t.min()),
                float(t.max()),
                0.0,
                len(idx),
                float("nan"),
                idx,
            )
        )
    return bars


def group_directions(bars: list, *, rng=None) -> list:
    """The paper's K-means (k = 2) on bar directions; angles are doubled so θ and θ + 180° agree.

    Parameters
    ----------
    bars : list of BarAxis of one lattice
    rng : seed or Generator of the K-means initialisation

    Returns
    -------
    list of BarAxis, the same bars with ``group`` set (0 or 1)
    """
    if not bars:
        return []
    ang = np.radians([b.plan_angle_deg for b in bars])
    X = np.c_[np.cos(2 * ang), np.sin(2 * ang)]
    if len(bars) < 2:
        return [replace(bars[0], group=0)]
    from sklearn.cluster import KMeans

    rng = np.random.default_rng(rng)
    km = KMeans(n_clusters=2, n_init=10, random_state=int(rng.integers(0, 2**31 - 1))).fit(X)
    labels = km.labels_
    out = []
    for g in (0, 1):
        members = [i for i in range(len(bars)) if labels[i] == g]
        if not members:
            continue
        # common direction of the group, so offsets are comparable
        mean_ang = 0.5 * math.atan2(np.sin(2 * ang[members]).mean(), np.cos(2 * ang[members]).mean())
        d = np.array([math.cos(mean_ang), math.sin(mean_ang)])
        for i in members:
            b = bars[i]
            # re-express the bar in the group direction (sign of its own direction aligned)
            bd = b.direction if b.direction @ d >= 0 else -b.direction
            p = b.plan_point(np.array([b.t0_mm, b.t1_mm]))
            n2 = np.array([-bd[1], bd[0]])
            t = p @ bd
            out.append(
                replace(
                    b, direction=bd, offset_mm=float(p[0] @ n2), t0_mm=float(t.min()), t1_mm=float(t.max()), group=g
                )
            )
    return out


def paper_spacings(
    bars: list, points_by_layer: dict, *, design_spacing: dict | None = None, n_sample: int = 1000, rng=None
) -> pd.DataFrame:
    """The paper's spacing: mean distance of ``n_sample`` random points of one bar to the fitted
    axis of its neighbour (3-D, slab frame).

    Parameters
    ----------
    bars : list of BarAxis with ``layer``, ``level`` and ``point_index`` set
    points_by_layer : ``{layer: (N, 3) slab-frame points}`` the bars' indices refer to
    design_spacing : ``{(layer, level): spacing_mm}``, adds the design value and deviation
    n_sample : points of each bar sampled
    rng : seed or Generator for the sampling

    Returns
    -------
    pandas.DataFrame with the columns of :func:`~rebarlib.geometry.measure_spacings`
    """
    rng = np.random.default_rng(rng)
    rows = []
    ids = {id(b): i for i, b in enumerate(bars)}
    for layer, level, a, b in _adjacent_pairs(bars):
        p = points_by_layer.get(layer)[a.point_index]
        if len(p) > n_sample:
            p = p[rng.choice(len(p), n_sample, replace=False)]
        p0 = b.axis_points(np.array([b.t_mid]))
        d3 = np.r_[b.direction, 0.0]
        s = float(_line_distances(p, p0, d3[None])[0].mean())
        ds = (design_spacing or {}).get((layer, level))
        rows.append(
            {
                "layer": layer,
                "level": level,
                "bar_a": ids[id(a)],
                "bar_b": ids[id(b)],
                "spacing_mm": s,
                "design_spacing_mm": ds,
                "deviation_mm": None if ds is None else s - ds,
                "status": MEASURED,
                "reason": "",
            }
        )
    return _spacing_frame(rows)
