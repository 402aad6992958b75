"""A rebar mask from depth: what stands clearly above the formwork plane.

Shadows, stains and rust cannot fool it; holes in the depth and the sensor's edge fattening
are handled where it is fused with the colour mask (:mod:`~rebarlib.segmentation.fusion`).
"""

from __future__ import annotations

import numpy as np

from .._camera import Intrinsics, _valid_depth, depth_to_points
from .._checks import RebarInputError

__all__ = ["fit_formwork_plane", "height_above_plane", "mask_from_depth"]


def fit_formwork_plane(points_mm, *, distance_mm: float = 4.0, max_points: int = 30_000, rng=None) -> tuple:
    """Fit the formwork plane to camera-frame points with a seeded RANSAC (Open3D).

    Self-contained on purpose (the geometry stage has its own, finer fit): the formwork is the
    farthest large plane in a view of a mesh on formwork. If a plane is found with many points
    clearly *behind* it (it lay on bar tops), it is refitted to those points, up to 3 times.

    Parameters
    ----------
    points_mm : (N, 3) float, camera frame, mm
    distance_mm : RANSAC inlier distance, mm
    max_points : points sampled for the fit (speed)
    rng : seed or Generator

    Returns
    -------
    (normal (3,), offset_mm): the plane ``normal @ x + offset_mm = 0``, with the normal pointing
    towards the camera (so ``offset_mm`` > 0 is the camera's height above the plane).

    Examples
    --------
    >>> g = np.random.default_rng(0)
    >>> xy = g.uniform(-200, 200, (2000, 2))
    >>> pts = np.column_stack([xy, np.full(2000, 500.0)])
    >>> n, d = fit_formwork_plane(pts, rng=0)
    >>> np.round(n, 6).tolist(), round(d, 3)
    ([0.0, 0.0, -1.0], 500.0)
    """
    from .._checks import check_points
    from .._cloud import ransac_plane

    pts = check_points(points_mm, "points_mm", min_count=3)
    rng = np.random.default_rng(rng)
    if len(pts) > max_points:
        pts = pts[rng.choice(len(pts), max_points, replace=False)]
    cand = pts
    normal, offset = None, None
    for _ in range(4):
        if len(cand) < 3:
            break
        (a, b, c, d), _ = ransac_plane(cand, threshold_mm=distance_mm, iterations=300, seed=int(rng.integers(2**31)))
        n = np.array([a, b, c], float)
        s = np.linalg.norm(n)
        n, d = n / s, d / s
        if d < 0:  # orient towards the camera (origin on the positive side)
            n, d = -n, -d
        normal, offset = n, d
        below = pts @ n + d < -3 * distance_mm
        if below.mean() < 0.02:
            break
        cand = pts[below]
    if normal is None:
        raise RebarInputError("points_mm: no plane found")
    return normal, float(offset)


def height_above_plane(depth_mm, intrinsics: Intrinsics, plane) -> np.ndarray:
    """Height of every pixel's point above ``plane`` = (normal, offset_mm), mm; NaN without depth.

    Parameters
    ----------
    depth_mm : (H, W) float depth map, mm; 0 (or beyond 10 m, or not finite) = no depth
    intrinsics : the camera's :class:`~rebarlib.Intrinsics`, of the depth map's size
    plane : ``(normal (3,), offset_mm)``, the plane ``normal @ x + offset_mm = 0`` in the
        camera frame, e.g. from :func:`fit_formwork_plane` (normal of unit length, pointing
        towards the camera)

    Returns
    -------
    (H, W) float, ``normal @ x + offset_mm`` of each pixel's back-projected point ``x``: the
    distance above the plane (mm, negative behind it) for a unit normal; NaN where the pixel
    has no depth.

    Examples
    --------
    >>> K = Intrinsics(100.0, 100.0, 1.0, 1.0, 3, 3)
    >>> h = height_above_plane(np.full((3, 3), 480.0), K, (np.array([0, 0, -1.0]), 500.0))
    >>> float(h[1, 1])
    20.0
    """
    d = np.asarray(depth_mm, float)
    cloud = depth_to_points(d, intrinsics)
    n, off = plane
    h = np.full(d.shape, np.nan)
    # the cloud's points are its valid pixels in row-major order: a boolean mask places them
    h[_valid_depth(d)] = cloud.points @ np.asarray(n, float) + float(off)
    return h


def mask_from_depth(
    capture_or_depth,
    intrinsics: Intrinsics | None = None,
    *,
    min_height_mm: float | None = None,
    max_height_mm: float = 400.0,
    plane=None,
    open_px: int = 1,
    rng=None,
) -> np.ndarray:
    """Rebar pixels known from depth: points clearly above the formwork plane.

    Parameters
    ----------
    capture_or_depth : a :class:`~rebarlib.Capture`, or an (H, W) depth map in mm (0 = none)
    intrinsics : needed with a depth map
    min_height_mm : a pixel is a bar if its point is at least this far above the formwork;
        default ``max(6 mm, 4 sigma)`` with sigma the robust spread of the formwork's points
        (noise grows with distance, so the default adapts to the capture)
    max_height_mm : higher points are not rebar (a boot, a tool)
    plane : tuple, optional
        the formwork's ``(normal, offset_mm)`` if known, else fitted with
        :func:`fit_formwork_plane`
    open_px : radius of a morphological opening that removes isolated (flying) pixels; 0 = none
    rng : seed or Generator of the plane fit

    Returns
    -------
    (H, W) bool; pixels without depth are False (see :func:`fuse_masks` for how holes are used).

    Examples
    --------
    >>> K = Intrinsics(100.0, 100.0, 3.5, 3.5, 8, 8)
    >>> depth = np.full((8, 8), 500.0); depth[:, 3:5] = 480.0   # a 20 mm high "bar"
    >>> mask_from_depth(depth, K, rng=0, open_px=0)[0].astype(int).tolist()
    [0, 0, 0, 1, 1, 0, 0, 0]
    """
    import cv2

    if hasattr(capture_or_depth, "depth_mm"):
        depth, intr = capture_or_depth.depth_mm, capture_or_depth.intrinsics
    else:
        if intrinsics is None:
            raise RebarInputError("intrinsics: required when a depth map is given instead of a Capture")
        depth, intr = np.asarray(capture_or_depth, float), intrinsics
    rng = np.random.default_rng(rng)
    if plane is None:
        cloud = depth_to_points(depth, intr)
        if len(cloud.points) < 3:
            raise RebarInputError("depth: fewer than 3 pixels with depth, no formwork plane to fit")
        plane = fit_formwork_plane(cloud.points, rng=rng)
    h = height_above_plane(depth, intr, plane)
    if min_height_mm is None:
        near = h[np.isfinite(h) & (np.abs(h) < 10)]
        sigma = 1.4826 * np.median(np.abs(near - np.median(near))) if len(near) > 50 else 1.0
        min_height_mm = max(6.0, 4 * sigma)
    with np.errstate(invalid="ignore"):
        mask = (h > min_height_mm) & (h < max_height_mm)
    if open_px > 0:
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * open_px + 1, 2 * open_px + 1))
        mask = cv2.morphologyEx(mask.astype(np.uint8), cv2.MORPH_OPEN, k).astype(bool)
    return mask
