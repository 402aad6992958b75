"""The plane γ of a bar and the paper's diameter-calculation regions (method.md stage 3.3).

Each bar's axis (from the point cloud) defines the imaginary plane γ: it contains the axis and
faces the camera (normal OA, A the foot of the perpendicular from the camera centre O to the
axis). A pixel on the bar's silhouette edge is back-projected as a ray and met with γ, so widths
come out in millimetres without using the (often missing or wrong) depth at the bar's edges.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._camera import Intrinsics, project, ray_directions
from .._checks import RebarInputError


@dataclass(frozen=True)
class BarPlane:
    """The imaginary plane γ of one bar: ``normal · x = offset_mm`` (camera frame, mm).

    Attributes
    ----------
    normal : (3,) float, unit vector from the camera centre O towards A
    offset_mm : float, the length of OA: the distance from O to the axis
    foot_mm : (3,) float, A, the foot of the perpendicular from O to the axis
    direction : (3,) float, unit axis direction v
    across : (3,) float, unit vector in γ perpendicular to the axis (the cross-section direction)
    """

    normal: np.ndarray
    offset_mm: float
    foot_mm: np.ndarray
    direction: np.ndarray
    across: np.ndarray

    def coordinates(self, points) -> tuple[np.ndarray, np.ndarray]:
        """(along, across) coordinates in mm of points in γ, measured from A."""
        d = np.asarray(points, float).reshape(-1, 3) - self.foot_mm
        return d @ self.direction, d @ self.across


def imaginary_plane(start_mm, end_mm) -> BarPlane:
    """Plane γ through the bar axis ``start_mm``-``end_mm`` whose normal is OA (method.md 3.3).

    Parameters
    ----------
    start_mm, end_mm : (3,) float, two points of the axis in the camera frame (mm)

    Returns
    -------
    BarPlane with ``normal · x = offset_mm``, i.e. ``x_A·x + y_A·y + z_A·z − |A|² = 0``
    scaled by ``1/|A|``.

    Examples
    --------
    >>> g = imaginary_plane([-100.0, 50.0, 500.0], [100.0, 50.0, 500.0])
    >>> g.foot_mm.tolist(), round(g.offset_mm, 3)
    ([0.0, 50.0, 500.0], 502.494)
    >>> bool(abs(g.normal @ [1.0, 0.0, 0.0]) < 1e-12)  # the axis lies in γ
    True
    """
    p0 = np.asarray(start_mm, float).reshape(3)
    p1 = np.asarray(end_mm, float).reshape(3)
    if not (np.all(np.isfinite(p0)) and np.all(np.isfinite(p1))):
        raise RebarInputError(f"bar axis: end points must be finite, got {p0.tolist()} and {p1.tolist()}")
    length = np.linalg.norm(p1 - p0)
    if length < 1e-9:
        raise RebarInputError(f"bar axis: start and end points coincide at {p0.tolist()}")
    v = (p1 - p0) / length
    a = p0 - (p0 @ v) * v
    dist = float(np.linalg.norm(a))
    if dist < 1e-6:
        raise RebarInputError("bar axis: passes through the camera centre, plane γ is undefined")
    n = a / dist
    w = np.cross(v, n)
    return BarPlane(n, dist, a, v, w / np.linalg.norm(w))


def intersect_rays_plane(pixels, intrinsics: Intrinsics, plane: BarPlane) -> np.ndarray:
    """Points where the rays through ``pixels`` meet ``plane`` (camera frame, mm).

    Parameters
    ----------
    pixels : (N, 2) float, (u, v) px
    intrinsics : Intrinsics
    plane : BarPlane (or anything with ``normal`` and ``offset_mm``)

    Returns
    -------
    (N, 3) float, mm; NaN for rays parallel to the plane or meeting it behind the camera.

    Examples
    --------
    >>> from rebarlib import Intrinsics
    >>> K = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)
    >>> g = imaginary_plane([-100.0, 0.0, 500.0], [100.0, 0.0, 500.0])
    >>> intersect_rays_plane([[420.0, 240.0]], K, g).tolist()
    [[100.0, 0.0, 500.0]]
    """
    d = ray_directions(intrinsics, np.asarray(pixels, float).reshape(-1, 2))
    den = d @ plane.normal
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = plane.offset_mm / den
    lam = np.where((np.abs(den) > 1e-12) & (lam > 0), lam, np.nan)
    return d * lam[:, None]


def cross_section_direction(point_mm, direction, intrinsics: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Image directions of the cross-section and of the axis at the axis point ``point_mm``.

    The cross-section direction is that of p → q with q = p + (p − O) × v (method.md 3.3, step 4);
    the axis direction that of p → p + v.

    Parameters
    ----------
    point_mm : (3,) a point of the bar's axis, camera frame (mm)
    direction : (3,) the axis's direction, camera frame (any length)
    intrinsics : Intrinsics of the image the directions are taken in

    Returns
    -------
    across_px, along_px : (2,) float, unit vectors in the image (u, v)

    Examples
    --------
    >>> from rebarlib import Intrinsics
    >>> K = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)
    >>> across, along = cross_section_direction([0.0, 0.0, 500.0], [1.0, 0.0, 0.0], K)
    >>> np.abs(across).round(6).tolist(), along.round(6).tolist()
    ([0.0, 1.0], [1.0, 0.0])
    """
    p = np.asarray(point_mm, float).reshape(3)
    v = np.asarray(direction, float).reshape(3)
    v = v / np.linalg.norm(v)
    c = np.cross(p, v)
    # a short step keeps q in front of the camera; only the image direction matters
    step = 0.01 * np.linalg.norm(p)
    uv = project(np.vstack((p, p + c / np.linalg.norm(c) * step, p + v * step)), intrinsics)
    across = uv[1] - uv[0]
    along = uv[2] - uv[0]
    return across / np.linalg.norm(across), along / np.linalg.norm(along)


def diameter_region(center_px, across_px, along_px, *, long_px: float, short_px: float = 6.0) -> np.ndarray:
    """Corners of the parallelogram diameter-calculation region (method.md 3.3, step 5).

    Centred on ``center_px``; two sides of length ``long_px`` run along the cross-section
    direction ``across_px``, the other two (``short_px``) along the projected axis ``along_px``.

    Parameters
    ----------
    center_px : (2,) the region's centre (u, v), on the projected axis
    across_px, along_px : (2,) unit image directions of the cross-section and of the axis
        (:func:`cross_section_direction`)
    long_px : length of the sides across the bar, px
    short_px : length of the sides along the bar, px

    Returns
    -------
    (4, 2) float, corners (u, v) in order around the parallelogram

    Examples
    --------
    >>> diameter_region([10.0, 20.0], [0.0, 1.0], [1.0, 0.0], long_px=8, short_px=6).tolist()
    [[7.0, 16.0], [13.0, 16.0], [13.0, 24.0], [7.0, 24.0]]
    """
    c = np.asarray(center_px, float).reshape(2)
    a = np.asarray(across_px, float).reshape(2)
    b = np.asarray(along_px, float).reshape(2)
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    ha, hb = a * long_px / 2, b * short_px / 2
    return np.array([c - ha - hb, c - ha + hb, c + ha + hb, c + ha - hb])


def pixels_in_region(corners, shape) -> np.ndarray:
    """Integer pixels (u, v) whose centres lie inside the parallelogram ``corners`` (from
    :func:`diameter_region`), clipped to an image of ``shape`` (H, W).

    Parameters
    ----------
    corners : (4, 2) corners (u, v) in order around the parallelogram
    shape : (H, W) of the image

    Returns
    -------
    (N, 2) int, pixels (u, v)

    Examples
    --------
    >>> corners = diameter_region([10.0, 20.0], [0.0, 1.0], [1.0, 0.0], long_px=4, short_px=2)
    >>> pixels_in_region(corners, (40, 40)).tolist()  # doctest: +NORMALIZE_WHITESPACE
    [[9, 18], [10, 18], [11, 18], [9, 19], [10, 19], [11, 19], [9, 20], [10, 20], [11, 20],
     [9, 21], [10, 21], [11, 21], [9, 22], [10, 22], [11, 22]]
    """
    q = np.asarray(corners, float).reshape(4, 2)
    c = q.mean(axis=0)
    e1, e2 = q[1] - q[0], q[3] - q[0]  # along-axis side, cross-section side
    lo = np.floor(q.min(axis=0)).astype(int)
    hi = np.ceil(q.max(axis=0)).astype(int)
    lo = np.maximum(lo, 0)
    hi = np.minimum(hi, [shape[1] - 1, shape[0] - 1])
    if np.any(hi < lo):
        return np.zeros((0, 2), int)
    vv, uu = np.mgrid[lo[1] : hi[1] + 1, lo[0] : hi[0] + 1]
    d = np.column_stack((uu.ravel(), vv.ravel())) - c
    coef = np.linalg.solve(np.column_stack((e1, e2)), d.T).T  # in units of the side lengths
    inside = np.all(np.abs(coef) <= 0.5 + 1e-9, axis=1)
    return np.column_stack((uu.ravel(), vv.ravel()))[inside]


def boundary_pixels(mask) -> np.ndarray:
    """Rebar pixels with at least one background 4-neighbour (image border counts as background).

    Parameters
    ----------
    mask : (H, W) bool rebar mask

    Returns
    -------
    (H, W) bool

    Examples
    --------
    >>> m = np.zeros((5, 5), bool); m[1:4, 1:4] = True
    >>> int(boundary_pixels(m).sum()), bool(boundary_pixels(m)[2, 2])
    (8, False)
    """
    m = np.asarray(mask, bool)
    p = np.pad(m, 1)
    inner = p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]
    return m & ~inner
