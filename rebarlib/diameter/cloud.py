"""Widths from the point cloud: twice the distance of a bar's depth points from its axis, and
the circle fitted to its cross-section (which needs no axis at the bar's centre).
"""

from __future__ import annotations

import math

import numpy as np

from .._camera import backproject, project
from ..geometry.fit import _median  # np.median's number without its overhead (30 iterations a fit)
from .plane import BarPlane


def _section_points(depth, intr, plane: BarPlane, stations, centres, widths, f, *, unique=False):
    """Camera-frame points, less the foot A of γ, of the depth pixels at ``f`` (fractions of each
    half-width) across the mask run of every cross-section; pixels without depth are left out,
    and with ``unique`` each pixel is taken once."""
    H, W = depth.shape
    t = centres[:, None] + f[None, :] * widths[:, None] / 2
    uv = np.rint(project((stations[:, None, :] + t[..., None] * plane.across).reshape(-1, 3), intr)).astype(int)
    uv = uv[(uv[:, 0] >= 0) & (uv[:, 0] < W) & (uv[:, 1] >= 0) & (uv[:, 1] < H)]
    if unique:
        # rows sorted by u, then v, as np.unique(uv, axis=0) gives them, on a 1-D key (faster)
        key = np.unique(uv[:, 0] * H + uv[:, 1])
        uv = np.column_stack((key // H, key % H))
    z = depth[uv[:, 1], uv[:, 0]]
    good = z > 0
    return backproject(uv[good], z[good], intr) - plane.foot_mm


def _depth_width(depth, intr, plane: BarPlane, stations, centres, widths, prm, expected_mm, covered=None):
    """Diameter from the point cloud: twice the median distance from the bar's axis of the points
    on the middle of its mask run at the given cross-sections (mm), its robust spread (mm) and
    how many points.

    Independent of the mask's edges (a mask a pixel too wide or narrow does not move it), but it
    depends on the axis lying at the bar's centre: an axis placed with an assumed radius would
    return that radius. A point farther from the axis than ``expected_mm`` (the expected
    diameter) is not on this bar's surface: the bar over it, seen where a one-sided section's
    band runs under it, or a flying pixel. Such points are left out (too few left gives NaN,
    never the distance to another object), and their share of the points is returned last:
    where it is most of them, the mask runs the sections were read on are mostly another object.
    That share is taken over the sections not ``covered`` (a boolean per section: partly under
    a nearer bar), where the band should show this bar only. Where every section is covered (a
    bar seen beside the bar over it, its band running under that bar) the points off the axis
    are expected there: the share is NaN, no verdict, as long as enough of the bar's own points
    are left to give a width; where they are not, it is the share over the covered sections
    (nothing then checks a width from the bar's one edge).
    """
    if len(stations) < prm.min_sections:
        return math.nan, math.nan, 0, math.nan
    f = np.linspace(-prm.depth_core, prm.depth_core, 7)  # across the middle of each run
    covered = np.zeros(len(stations), bool) if covered is None else np.asarray(covered, bool)

    def distances(part):  # twice each point's distance from the axis, on the sections ``part``
        if not part.any():
            return np.zeros(0)
        P = _section_points(depth, intr, plane, stations[part], centres[part], widths[part], f)
        return 2 * np.linalg.norm(P - np.outer(P @ plane.direction, plane.direction), axis=1)

    open_d, covered_d = distances(~covered), distances(covered)
    off_share = float(np.mean(open_d > 2 * expected_mm)) if len(open_d) else math.nan
    d = np.concatenate([open_d, covered_d])
    d = d[d <= 2 * expected_mm]
    if len(d) < prm.min_sections * 3:
        if not len(open_d) and len(covered_d):
            off_share = float(np.mean(covered_d > 2 * expected_mm))
        return math.nan, math.nan, len(d), off_share
    q1, med, q3 = np.percentile(d, [25, 50, 75])
    return float(med), float((q3 - q1) / 1.349), len(d), off_share


def _circle_fit(a, b, r0, *, iters: int = 30):
    """Robust fit of the near half of a circle, b = b0 − √(r² − (a − a0)²), to points (a, b)
    whose noise lies along b (a depth camera's: along the line of sight).

    Least squares on the residuals along b, not on the distances to the circle: with depth noise
    the latter shrink the circle (on an arc of ±53° a σ of 0.6 mm on a 7 mm radius gives about
    6.5 mm); the former is unbiased. Gauss–Newton from the centre (0, 5th percentile of b + r0) with
    radius ``r0``, then Tukey weights at 4.685 robust σ (MAD, at least 0.05 mm). Returns
    (a0, b0, r, σ_r, weights): σ_r is the radius's standard error from the normal matrix and
    the weighted residual variance, the points taken as independent; NaN where the fit fails.
    """
    p = np.array([0.0, float(np.percentile(b, 5)) + r0, float(r0)])  # crest: the nearest points
    w = np.ones(len(a))
    fail = (math.nan, math.nan, math.nan, math.nan, w)
    for k in range(iters):
        da = a - p[0]
        q = np.sqrt(np.maximum(p[2] ** 2 - da**2, 1e-6))
        res = b - (p[1] - q)
        w = (np.abs(da) < 0.98 * p[2]).astype(float)
        if k:  # the first step from the starting guess is unweighted
            mid = _median(res[w > 0]) if w.any() else 0.0
            s = max(1.4826 * _median(np.abs(res - mid)), 0.05)
            u = (res - mid) / (4.685 * s)
            w *= np.where(np.abs(u) < 1, (1 - u**2) ** 2, 0.0)
        J = np.column_stack((-da / q, np.ones_like(q), -p[2] / q))  # d(b0 − q)/d(a0, b0, r)
        JW = J * w[:, None]
        A = J.T @ JW
        try:
            step = np.linalg.solve(A, JW.T @ res)
        except np.linalg.LinAlgError:
            return fail
        p = p + step
        if not np.all(np.isfinite(p)) or p[2] <= 0:
            return fail
        if np.abs(step).max() < 1e-5:
            break
    res = b - (p[1] - np.sqrt(np.maximum(p[2] ** 2 - (a - p[0]) ** 2, 1e-6)))
    var = float((w * res**2).sum()) / max(float(w.sum()) - 3.0, 1.0)
    try:
        cov = np.linalg.inv(A) * var
    except np.linalg.LinAlgError:
        return fail
    return float(p[0]), float(p[1]), float(p[2]), float(math.sqrt(max(cov[2, 2], 0.0))), w


def _cloud_circle(depth, intr, plane: BarPlane, stations, centres, widths, prm):
    """Diameter of the bar from the shape of its point cloud alone: a circle fitted to the depth
    points across the sections' mask runs, in the cross-section plane (across, normal of γ).

    Unlike :func:`_depth_width`, it needs no axis at the bar's centre, only its direction and
    roughly its place: an axis placed with an assumed radius (the geometry stage's fixed-radius
    cylinder) gives the same circle. The points are read over the middle ``prm.circle_core`` of
    each run (the flanks beyond face the camera at a grazing angle, where a stereo camera's
    depth is least reliable). Returns (diameter, σ): σ is the fit's standard error with
    neighbouring points counted as sharing their noise (``prm.depth_correlated_px``); NaN where
    too few points or the fit fails.
    """
    if len(stations) < prm.min_sections:
        return math.nan, math.nan
    px_mm = float(np.median(stations[:, 2])) / intr.fx
    n = int(np.clip(np.ceil(np.nanmedian(widths) * prm.circle_core / px_mm), 5, 41))
    f = np.linspace(-prm.circle_core, prm.circle_core, n)
    P = _section_points(depth, intr, plane, stations, centres, widths, f, unique=True)
    if len(P) < prm.min_sections * 5:
        return math.nan, math.nan
    r0 = float(np.nanmedian(widths)) / 2
    _, _, r, s_r, _ = _circle_fit(P @ plane.across, P @ plane.normal, r0)
    if not (math.isfinite(r) and 0.25 * r0 < r < 4 * r0):
        return math.nan, math.nan
    return 2 * r, 2 * s_r * math.sqrt(prm.depth_correlated_px)
