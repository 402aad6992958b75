"""Point-cloud clean-up that keeps the link from every point to its pixel."""

from __future__ import annotations

import numpy as np

from ._camera import Cloud  # noqa: F401 (the doctests build one)
from ._checks import RebarInputError, check_positive

__all__ = ["voxel_downsample", "remove_outliers", "to_open3d", "ransac_plane"]


def to_open3d(points):
    """An ``open3d.geometry.PointCloud`` of (N, 3) points (imported lazily: Open3D is heavy)."""
    import open3d as o3d

    pcd = o3d.geometry.PointCloud()
    pcd.points = o3d.utility.Vector3dVector(np.ascontiguousarray(points, dtype=np.float64))
    return pcd


def _points_of(cloud):
    """The (N, 3) points of a :class:`Cloud` (points linked to pixels), a
    :class:`~rebarlib.cloud_io.ScanCloud` or a bare array (as ``load_cloud`` returns), and a
    function taking indices to the same kind of object (pixel links and fields kept)."""
    if hasattr(cloud, "points") and hasattr(cloud, "subset"):
        return np.asarray(cloud.points, float), cloud.subset
    pts = np.asarray(cloud, float)
    if pts.ndim != 2 or pts.shape[1] != 3:
        raise RebarInputError(f"cloud: expected a Cloud, a ScanCloud or an (N, 3) array, got shape {pts.shape}")
    return pts, lambda idx: pts[idx]


def voxel_downsample(cloud, voxel_mm: float):
    """Keep, per occupied voxel, the original point nearest the voxel centre.

    Open3D's ``voxel_down_sample`` averages points (the average has no pixel) and its
    ``_and_trace`` variant returns Python lists per voxel, which is slow for 10^5 voxels; a
    lexsort over voxel keys does the same job vectorised and keeps one real point per voxel.

    Parameters
    ----------
    cloud : Cloud, ScanCloud or (N, 3) array; the result is of the same kind (a Cloud keeps
        each kept point's pixel, a ScanCloud its fields)
    voxel_mm : edge of the cubic voxel, mm

    Examples
    --------
    >>> c = Cloud(np.array([[0.1, 0, 0], [0.9, 0, 0], [0.6, 0, 0], [5.0, 0, 0]]),
    ...           np.zeros((4, 2), np.int32))
    >>> voxel_downsample(c, 1.0).points[:, 0].tolist()
    [0.6, 5.0]
    """
    voxel = check_positive(voxel_mm, "voxel_mm")
    pts, subset = _points_of(cloud)
    if len(pts) == 0:
        return cloud
    keys = np.floor(pts / voxel).astype(np.int64)
    centre = (keys + 0.5) * voxel
    d2 = ((pts - centre) ** 2).sum(axis=1)
    order = np.lexsort((d2, keys[:, 2], keys[:, 1], keys[:, 0]))
    k = keys[order]
    first = np.ones(len(k), dtype=bool)
    first[1:] = np.any(k[1:] != k[:-1], axis=1)
    keep = np.sort(order[first])
    return subset(keep)


def remove_outliers(cloud, *, nb_neighbors: int = 20, std_ratio: float = 2.0):
    """Statistical outlier removal (Open3D): drop points whose mean distance to their
    ``nb_neighbors`` nearest neighbours exceeds the global mean by ``std_ratio`` std devs.

    ``cloud`` is a Cloud, a ScanCloud or an (N, 3) array; the result is of the same kind."""
    if nb_neighbors < 1:
        raise RebarInputError(f"nb_neighbors: expected a positive integer, got {nb_neighbors!r}")
    check_positive(std_ratio, "std_ratio", unit="")
    pts, subset = _points_of(cloud)
    if len(pts) <= nb_neighbors:
        return cloud
    _, index = to_open3d(pts).remove_statistical_outlier(nb_neighbors=nb_neighbors, std_ratio=std_ratio)
    return subset(np.sort(np.asarray(index, dtype=np.int64)))


def ransac_plane(points, *, threshold_mm: float, iterations: int, seed: int):
    """Open3D's RANSAC plane (``segment_plane``) over exactly ``iterations`` hypotheses, seeded:
    ``(a, b, c, d)`` with ``a x + b y + c z + d = 0`` and the inlier indices.

    Every hypothesis is tried (``probability=1``): Open3D's default stops early once its threads
    think the best plane is found, and which thread's plane that is depends on their timing, so
    the same points and seed gave either of two planes (20 799 or 20 801 inliers of 30 000,
    Open3D 0.20, 2 cores) and a few mask pixels changed between runs. With every hypothesis the
    best of a fixed set wins, the same every run; it is also the paper's k hypotheses.

    Examples
    --------
    >>> g = np.random.default_rng(0)
    >>> pts = np.c_[g.uniform(-100, 100, (500, 2)), np.full(500, 400.0)]
    >>> model, idx = ransac_plane(pts, threshold_mm=1.0, iterations=50, seed=3)
    >>> np.round(np.abs(model[:3]), 6).tolist(), len(idx)
    ([0.0, 0.0, 1.0], 500)
    """
    import open3d as o3d

    o3d.utility.random.seed(int(seed))
    model, idx = to_open3d(points).segment_plane(
        distance_threshold=float(threshold_mm), ransac_n=3, num_iterations=int(iterations), probability=1.0
    )
    return np.asarray(model, float), np.asarray(idx, np.int64)
