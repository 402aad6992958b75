"""Capture folders: exact round trip, Open3D compatibility, and a clear error for each bad input."""

import json
import warnings

import cv2
import numpy as np
import pytest

from rebarlib import Capture, GEMINI2, RebarInputError, load_capture, load_cloud, save_capture
from rebarlib.synth import synth_capture

SMALL = GEMINI2.scaled(0.25)


@pytest.fixture(scope="module")
def capture(paper_design):
    return synth_capture(paper_design, height_mm=500, tilt_deg=8, intrinsics=SMALL, seed=3, name="c1")


@pytest.fixture()
def saved(capture, tmp_path):
    return save_capture(capture, tmp_path / "c1")


def test_round_trip_is_exact(capture, saved):
    back = load_capture(saved)
    assert np.array_equal(back.color, capture.color)
    assert np.array_equal(back.depth_mm, capture.depth_mm)
    assert np.array_equal(back.labels, capture.labels)
    assert np.array_equal(back.bar_ids, capture.bar_ids)
    assert back.intrinsics == capture.intrinsics
    assert back.truth == json.loads(json.dumps(capture.truth))
    assert back.name == "c1" and back.depth_scale_mm == capture.depth_scale_mm


def test_open3d_reads_our_camera_json(saved):
    import open3d as o3d

    intr = o3d.io.read_pinhole_camera_intrinsic(str(saved / "camera.json"))
    assert (intr.width, intr.height) == (SMALL.width, SMALL.height)
    assert np.allclose(intr.intrinsic_matrix, SMALL.matrix)


def test_depth_scale_is_applied(capture, tmp_path):
    cap = Capture(capture.color, capture.depth_mm, capture.intrinsics, {"depth_scale_mm": 0.1})
    folder = save_capture(cap, tmp_path / "s")
    raw = cv2.imread(str(folder / "depth.png"), cv2.IMREAD_UNCHANGED)
    assert raw.max() == pytest.approx(capture.depth_mm.max() / 0.1, abs=0.5)
    assert np.allclose(load_capture(folder).depth_mm, capture.depth_mm, atol=0.05 + 1e-9)


def test_save_never_overwrites(capture, saved):
    before = (saved / "depth.png").read_bytes()
    with pytest.raises(RebarInputError, match="not empty"):
        save_capture(capture, saved)
    assert (saved / "depth.png").read_bytes() == before


def test_jpeg_colour_loads(capture, tmp_path):
    folder = save_capture(capture, tmp_path / "j", color_format="jpg")
    back = load_capture(folder)
    assert back.color.shape == capture.color.shape
    assert np.abs(back.color.astype(int) - capture.color).mean() < 6


# ---- bad input: each names the file and what was wrong


def test_missing_folder(tmp_path):
    with pytest.raises(RebarInputError, match="capture folder not found"):
        load_capture(tmp_path / "nope")


@pytest.mark.parametrize(
    "name, match",
    [
        ("depth.png", "depth.png: file not found"),
        ("camera.json", "camera.json: file not found"),
        ("color.png", "no color.png"),
    ],
)
def test_missing_file(saved, name, match):
    (saved / name).unlink()
    with pytest.raises(RebarInputError, match=match):
        load_capture(saved)


def test_depth_not_16_bit(saved):
    img = cv2.imread(str(saved / "depth.png"), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(saved / "depth.png"), (img // 256).astype(np.uint8))
    with pytest.raises(RebarInputError, match="depth.png: expected a single-channel 16-bit"):
        load_capture(saved)


def test_colour_and_depth_sizes_differ(saved):
    img = cv2.imread(str(saved / "color.png"))
    cv2.imwrite(str(saved / "color.png"), img[:-2])
    with pytest.raises(RebarInputError, match="differ in size"):
        load_capture(saved)


def test_depth_all_zero(saved):
    img = cv2.imread(str(saved / "depth.png"), cv2.IMREAD_UNCHANGED)
    cv2.imwrite(str(saved / "depth.png"), np.zeros_like(img))
    with pytest.raises(RebarInputError, match="every pixel is 0"):
        load_capture(saved)


@pytest.mark.parametrize(
    "edit, match",
    [
        (lambda d: d.pop("intrinsic_matrix"), "missing key 'intrinsic_matrix'"),
        (lambda d: d.update(intrinsic_matrix=[0, 0, 0, 0, 100, 0, 10, 10, 1]), "fx"),
        (lambda d: d.update(intrinsic_matrix=[100, 5, 0, 0, 100, 0, 10, 10, 1]), "not a pinhole matrix"),
        (lambda d: d.update(depth_scale_mm=-1), "depth_scale_mm"),
        (lambda d: d.update(width=999), "says 999x"),
    ],
)
def test_bad_intrinsics(saved, edit, match):
    path = saved / "camera.json"
    data = json.loads(path.read_text())
    edit(data)
    path.write_text(json.dumps(data))
    with pytest.raises(RebarInputError, match=match):
        load_capture(saved)


def test_broken_json(saved):
    (saved / "camera.json").write_text("{ not json")
    with pytest.raises(RebarInputError, match="camera.json: not valid JSON"):
        load_capture(saved)


# ---- bare clouds


def test_load_cloud_units_and_formats(tmp_path):
    pts_m = np.random.default_rng(0).uniform(-1, 1, (500, 3)) + [0, 0, 2]
    np.savez(tmp_path / "c.npz", xyz=pts_m)
    np.savetxt(tmp_path / "c.csv", pts_m, delimiter=",", header="x,y,z")
    import open3d as o3d

    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts_m))
    o3d.io.write_point_cloud(str(tmp_path / "c.ply"), pcd)
    for name in ("c.npz", "c.csv", "c.ply"):
        assert np.allclose(load_cloud(tmp_path / name, units="m"), pts_m * 1000, atol=1e-3)


def test_load_cloud_warns_on_the_other_unit(tmp_path):
    np.savez(tmp_path / "c.npz", xyz=np.random.default_rng(0).uniform(-1, 1, (100, 3)))
    with pytest.warns(UserWarning, match="are these metres"):
        load_cloud(tmp_path / "c.npz", units="mm")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        load_cloud(tmp_path / "c.npz", units="m")


@pytest.mark.parametrize("units", ["cm", None, "metres"])
def test_load_cloud_unknown_units(tmp_path, units):
    with pytest.raises(RebarInputError, match="units"):
        load_cloud(tmp_path / "c.npz", units=units)
