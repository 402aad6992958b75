"""Point-cloud clean-up keeps the pixel links and removes planted outliers."""

import numpy as np

from rebarlib.capture import Cloud, remove_outliers, voxel_downsample


def _plane_cloud(n=4000, seed=0):
    rng = np.random.default_rng(seed)
    pts = np.column_stack((rng.uniform(0, 200, n), rng.uniform(0, 200, n), np.full(n, 500.0)))
    pix = rng.integers(0, 1000, (n, 2)).astype(np.int32)
    return Cloud(pts, pix)


def test_voxel_downsample_keeps_real_points_and_their_pixels():
    c = _plane_cloud()
    d = voxel_downsample(c, 10.0)
    assert 300 < len(d) <= 400  # 20 x 20 voxels on the plane
    # every kept point is one of the originals, with its own pixel
    lookup = {tuple(p): tuple(q) for p, q in zip(c.points, c.pixels)}
    assert all(lookup[tuple(p)] == tuple(q) for p, q in zip(d.points, d.pixels))
    keys = np.floor(d.points / 10.0).astype(int)
    assert len(np.unique(keys, axis=0)) == len(d)


def test_remove_outliers_drops_planted_outliers_only():
    c = _plane_cloud()
    rng = np.random.default_rng(1)
    out = np.column_stack((rng.uniform(0, 200, 20), rng.uniform(0, 200, 20), rng.uniform(300, 450, 20)))
    both = Cloud(np.vstack((c.points, out)), np.vstack((c.pixels, np.zeros((20, 2), np.int32))))
    kept = remove_outliers(both, nb_neighbors=16, std_ratio=2.0)
    assert not np.any(kept.points[:, 2] < 499)
    assert len(kept) > 0.97 * len(c)
