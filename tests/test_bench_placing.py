"""benchmarks/bench_placing.py's truth helpers (docs/decisions/035): the true placing of one
capture's plan frame in another's, and the share of one view's formwork another image shows."""

import json

import numpy as np

from benchmarks.bench_placing import _formwork_share, _true_reg
from rebarlib.geometry.plane import Plane, to_slab_frame
from rebarlib.synth import CameraPose


def _camera(height, tilt, yaw, target):
    pose = CameraPose.looking_down(height, tilt_deg=tilt, yaw_deg=yaw, target_mm=target)
    R, C = np.asarray(pose.rotation, float), np.asarray(pose.centre, float)
    cam = {"rotation_world_to_camera": R.tolist(), "centre_world_mm": C.tolist()}
    # the formwork (world z = 0) in the camera frame: normal up, offset the camera's height
    result = {"formwork": {"normal": (R @ [0.0, 0.0, 1.0]).tolist(), "offset_mm": float(C[2])}}
    return cam, result


def test_true_placing_carries_a_formwork_point_to_where_the_other_capture_sees_it():
    ca, ra = _camera(520.0, 12.0, 30.0, (0.0, 0.0))
    cb, rb = _camera(610.0, 5.0, 200.0, (150.0, -80.0))
    reg = _true_reg(ra, rb, ca, cb, "A", "B")
    world = np.array([[40.0, -25.0, 0.0], [-120.0, 90.0, 0.0], [200.0, 10.0, 0.0]])

    def plan(cam, r):
        c = (world - np.array(cam["centre_world_mm"])) @ np.array(cam["rotation_world_to_camera"]).T
        return to_slab_frame(c, Plane(np.array(r["formwork"]["normal"]), r["formwork"]["offset_mm"]))

    qa, qb = plan(ca, ra), plan(cb, rb)
    assert np.allclose(qa[:, 2], 0.0, atol=1e-6) and np.allclose(qb[:, 2], 0.0, atol=1e-6)
    assert np.allclose(reg.to_b(qa[:, :2]), qb[:, :2], atol=1e-6)


def test_formwork_share_is_whole_for_one_view_and_none_for_views_apart(tmp_path):
    K = [600.0, 0.0, 0.0, 0.0, 600.0, 0.0, 320.0, 240.0, 1.0]
    for name in ("a", "b"):
        (tmp_path / name).mkdir()
        (tmp_path / name / "camera.json").write_text(json.dumps({"width": 640, "height": 480, "intrinsic_matrix": K}))
    ca, _ = _camera(500.0, 0.0, 0.0, (0.0, 0.0))
    far, _ = _camera(500.0, 0.0, 0.0, (3000.0, 0.0))
    half, _ = _camera(500.0, 0.0, 0.0, (0.5 * 640 * 500 / 600, 0.0))  # moved by half the view's width
    assert _formwork_share(tmp_path / "a", tmp_path / "b", ca, ca) == 1.0
    assert _formwork_share(tmp_path / "a", tmp_path / "b", ca, far) == 0.0
    assert abs(_formwork_share(tmp_path / "a", tmp_path / "b", ca, half) - 0.5) < 0.05
