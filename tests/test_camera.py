"""Camera model: projection round trip, pixel-centre convention, depth to points."""

import numpy as np
import pytest

from rebarlib import GEMINI2, Intrinsics, RebarInputError
from rebarlib.capture import backproject, depth_to_points, project
from rebarlib._camera import ray_directions

ROUND_TRIP_TOL_MM = 1e-9


def test_project_backproject_round_trip():
    rng = np.random.default_rng(0)
    pts = np.column_stack((rng.uniform(-400, 400, 500), rng.uniform(-300, 300, 500), rng.uniform(200, 1500, 500)))
    uv = project(pts, GEMINI2)
    back = backproject(uv, pts[:, 2], GEMINI2)
    assert np.abs(back - pts).max() < ROUND_TRIP_TOL_MM


def test_principal_point_projects_to_cx_cy():
    uv = project([[0.0, 0.0, 700.0]], GEMINI2)
    assert uv[0] == pytest.approx([GEMINI2.cx, GEMINI2.cy])


def test_pixel_centres_are_at_integer_coordinates():
    K = Intrinsics(100.0, 100.0, 2.0, 1.0, 5, 3)
    d = ray_directions(K)
    assert d.shape == (15, 3)
    # pixel (u=2, v=1) is the principal point: its ray is the optical axis
    assert np.allclose(d[1 * 5 + 2], [0, 0, 1])
    assert np.allclose(project(d, K), np.column_stack((np.tile(np.arange(5), 3), np.repeat(np.arange(3), 5))))


def test_depth_to_points_keeps_pixel_links_and_drops_missing():
    K = Intrinsics(500.0, 500.0, 10.0, 8.0, 20, 16)
    depth = np.full((16, 20), 800.0)
    depth[3, 4] = 0
    depth[5, 6] = 20000  # beyond max_depth_mm
    cloud = depth_to_points(depth, K, max_depth_mm=10000)
    assert len(cloud) == 20 * 16 - 2
    uv = project(cloud.points, K)
    assert np.allclose(uv, cloud.pixels)
    assert not np.any((cloud.pixels == [4, 3]).all(axis=1))


def test_scaled_intrinsics_keep_the_pixel_centre_convention():
    half = GEMINI2.scaled(0.5)
    assert (half.width, half.height) == (640, 400)
    p = np.array([[123.0, -45.0, 600.0]])
    assert np.allclose((project(p, GEMINI2) + 0.5) * 0.5 - 0.5, project(p, half))


@pytest.mark.parametrize(
    "kwargs, what",
    [(dict(fx=0.0), "fx"), (dict(fy=-5.0), "fy"), (dict(width=0), "width"), (dict(cx=1e6), "principal point")],
)
def test_impossible_intrinsics_are_refused(kwargs, what):
    args = dict(fx=600.0, fy=600.0, cx=320.0, cy=240.0, width=640, height=480) | kwargs
    with pytest.raises(RebarInputError, match=what):
        Intrinsics(**args)


def test_depth_of_wrong_shape_is_refused():
    with pytest.raises(RebarInputError, match="depth"):
        depth_to_points(np.ones((10, 10)), GEMINI2)
