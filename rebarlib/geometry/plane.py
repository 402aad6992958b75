"""The formwork plane and the slab frame (method.md stage 1).

Everything starts in the camera frame (OpenCV, mm). ``plane_frame(plane)`` gives a rotation whose
third row is the formwork normal pointing at the camera; in that *slab frame* a point is
``(a, b, h)``: two plan coordinates and the height above the formwork.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .._checks import RebarInputError


@dataclass(frozen=True)
class Plane:
    """A plane ``normal · p + offset_mm = 0`` in the camera frame; ``normal`` is a unit vector
    pointing toward the camera, so ``normal · p + offset_mm`` is the height above the plane.

    Attributes
    ----------
    normal : (3,) float, unit normal towards the camera
    offset_mm : float, the camera centre's height above the plane (mm)
    n_inliers : int, points the plane was fitted to
    noise_mm : float or None, robust standard deviation of the inliers' heights

    Examples
    --------
    >>> Plane(np.array([0.0, 0.0, -1.0]), 500.0).height([[0.0, 0.0, 480.0]]).tolist()
    [20.0]
    """

    normal: np.ndarray
    offset_mm: float
    n_inliers: int = 0
    noise_mm: float | None = None  # robust std of the inliers' heights

    def height(self, points) -> np.ndarray:
        """Signed height (mm) of (N, 3) camera-frame points above the plane."""
        return np.asarray(points, float) @ self.normal + self.offset_mm

    def to_dict(self) -> dict:
        return {
            "normal": [round(float(x), 8) for x in self.normal],
            "offset_mm": round(float(self.offset_mm), 3),
            "n_inliers": int(self.n_inliers),
            "noise_mm": None if self.noise_mm is None else round(float(self.noise_mm), 3),
        }


def _oriented(normal, offset) -> tuple[np.ndarray, float]:
    n = np.asarray(normal, float)
    s = np.linalg.norm(n)
    n, offset = n / s, float(offset) / s
    # the camera centre (origin) must be on the positive side: height(0) = offset > 0
    if offset < 0:
        n, offset = -n, -offset
    return n, offset


def _lsq_plane(points) -> tuple[np.ndarray, float]:
    c = points.mean(axis=0)
    x = points - c
    # smallest eigenvector of the 3x3 scatter matrix (an SVD of the N x 3 matrix costs 10x more)
    w, v = np.linalg.eigh(x.T @ x)
    n = v[:, 0]
    return _oriented(n, -float(n @ c))


def paper_fit_formwork(points, *, threshold_mm: float, max_trials: int = 170, rng=None) -> tuple[Plane, np.ndarray]:
    """The paper's plane: Open3D RANSAC, inliers within ``threshold_mm`` (t₁ = 0.8 × design
    cover), ``max_trials`` hypotheses (k = 170).

    Parameters
    ----------
    points : (N, 3) array
        Camera-frame points (mm).
    threshold_mm : float
        Inlier distance t₁.
    max_trials : int
        RANSAC hypotheses k.
    rng : int, Generator or None
        Seed of the hypotheses.

    Returns
    -------
    plane : Plane
        Its normal oriented so that the camera lies on the positive side.
    inliers : ndarray of bool
        (N,) the points within ``threshold_mm``.

    Examples
    --------
    >>> rng = np.random.default_rng(0)
    >>> p = np.c_[rng.uniform(-100, 100, (500, 2)), np.full(500, 500.0)]
    >>> plane, inl = paper_fit_formwork(p, threshold_mm=2, rng=0)
    >>> np.round(plane.normal, 6).tolist(), round(float(plane.offset_mm), 3), int(inl.sum())
    ([0.0, 0.0, -1.0], 500.0, 500)
    """
    from .._cloud import ransac_plane

    pts = np.asarray(points, float)
    if len(pts) < 3:
        raise RebarInputError(f"points: need at least 3 points to fit the formwork plane, got {len(pts)}")
    rng = np.random.default_rng(rng)
    model, idx = ransac_plane(
        pts, threshold_mm=threshold_mm, iterations=max_trials, seed=int(rng.integers(0, 2**31 - 1))
    )
    n, d = _oriented(model[:3], model[3])
    mask = np.zeros(len(pts), bool)
    mask[idx] = True
    return Plane(n, float(d), int(mask.sum())), mask


def fit_formwork(
    points, *, threshold_mm: float, max_trials: int = 170, sample: int = 30_000, rng=None
) -> tuple[Plane, np.ndarray]:
    """Formwork plane: RANSAC on a sample, then least squares on inliers re-selected at 4 robust
    standard deviations of the residuals (twice), so that the plane's accuracy is the sensor's.

    Parameters
    ----------
    points : (N, 3) camera-frame points, mm
    threshold_mm : RANSAC inlier distance; anything well below the design cover works (the final
        inliers do not depend on it).
    max_trials : RANSAC hypotheses
    sample : points given to RANSAC (the refit uses all points)

    Returns
    -------
    plane : Plane (``noise_mm`` = robust std of the inliers' heights)
    inliers : (N,) bool

    Examples
    --------
    >>> rng = np.random.default_rng(1)
    >>> p = np.c_[rng.uniform(-200, 200, (4000, 2)), 600 + rng.normal(0, 0.5, 4000)]
    >>> plane, inl = fit_formwork(p, threshold_mm=5, rng=0)
    >>> abs(plane.offset_mm - 600) < 0.1, 0.4 < plane.noise_mm < 0.6
    (True, True)
    """
    pts = np.asarray(points, float)
    if len(pts) < 3:
        raise RebarInputError(f"points: need at least 3 points to fit the formwork plane, got {len(pts)}")
    rng = np.random.default_rng(rng)
    sub = pts if len(pts) <= sample else pts[rng.choice(len(pts), sample, replace=False)]
    plane, _ = paper_fit_formwork(sub, threshold_mm=threshold_mm, max_trials=max_trials, rng=rng)
    n, d = plane.normal, plane.offset_mm
    h = pts @ n + d
    inl = np.abs(h) < threshold_mm
    sigma = None
    for _ in range(3):
        if inl.sum() < 3:
            break
        n, d = _lsq_plane(pts[inl])
        h = pts @ n + d
        sigma = 1.4826 * float(np.median(np.abs(h[inl])))
        inl = np.abs(h) < max(4 * sigma, 0.5)
    return Plane(n, float(d), int(inl.sum()), sigma), inl


def plane_frame(plane: Plane) -> np.ndarray:
    """Rotation R (3, 3) taking camera-frame vectors to the slab frame: rows are two in-plane axes
    and the normal (a single Rodrigues-like choice; method.md allows any rotation taking n to z).

    Parameters
    ----------
    plane : Plane

    Returns
    -------
    ndarray
        (3, 3) orthonormal rows: the camera's x axis projected into the plane, the second
        in-plane axis, the normal.

    Examples
    --------
    >>> R = plane_frame(Plane(np.array([0.0, 0.0, -1.0]), 500.0))
    >>> np.allclose(R @ R.T, np.eye(3)), R[2].tolist()
    (True, [0.0, 0.0, -1.0])
    """
    n = np.asarray(plane.normal, float)
    # first in-plane axis: the camera x axis with its normal component removed (keeps plan views
    # oriented like the image)
    e1 = np.array([1.0, 0.0, 0.0]) - n[0] * n
    if np.linalg.norm(e1) < 1e-6:
        e1 = np.array([0.0, 1.0, 0.0]) - n[1] * n
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    return np.vstack([e1, e2, n])


def to_slab_frame(points, plane: Plane) -> np.ndarray:
    """Camera-frame points in the slab frame of ``plane``.

    Parameters
    ----------
    points : (N, 3) camera-frame points (mm)
    plane : the formwork Plane

    Returns
    -------
    (N, 3) float: ``(a, b, h)``, two plan coordinates (:func:`plane_frame`) and the height above
    the plane

    Examples
    --------
    >>> plane = Plane(np.array([0.0, 0.0, -1.0]), 500.0)
    >>> to_slab_frame([[10.0, 0.0, 480.0]], plane).round(6).tolist()
    [[10.0, 0.0, 20.0]]
    """
    R = plane_frame(plane)
    q = np.asarray(points, float) @ R.T
    q[:, 2] += plane.offset_mm
    return q


def from_slab_frame(q, plane: Plane) -> np.ndarray:
    """Slab-frame points ``(a, b, h)`` back in the camera frame: the inverse of
    :func:`to_slab_frame`.

    Parameters
    ----------
    q : (..., 3) slab-frame points (mm)
    plane : the formwork Plane

    Returns
    -------
    (..., 3) float, camera-frame points (mm)

    Examples
    --------
    >>> plane = Plane(np.array([0.0, 0.0, -1.0]), 500.0)
    >>> from_slab_frame([[10.0, 0.0, 20.0]], plane).round(6).tolist()
    [[10.0, 0.0, 480.0]]
    """
    R = plane_frame(plane)
    q = np.array(q, float, copy=True)
    q[..., 2] -= plane.offset_mm
    return q @ R
