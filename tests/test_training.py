"""The training script's data step (``training/train_segmentation.py data``): what it writes is
what the network is trained on. No torch needed: rendering and writing use the runtime's own
packages."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import cv2
import numpy as np
import pytest

from rebarlib.synth_segmentation import DATASET_SEED, synth_segmentation_capture

ROOT = Path(__file__).resolve().parents[1]
INDEX = 301  # a training-only index (300 and up are never validation or test captures)


@pytest.fixture(scope="module")
def t():
    """The training script as a module (it is not in a package)."""
    spec = importlib.util.spec_from_file_location("train_segmentation", ROOT / "training" / "train_segmentation.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _png_bit_depth(path: Path) -> int:
    return path.read_bytes()[24]  # the IHDR chunk's bit depth, after the signature and IHDR header


def test_a_training_capture_is_written_as_the_model_sees_it(t, tmp_path):
    t._render_one((INDEX, tmp_path, 90, "silhouette", True, 85))
    cap = synth_segmentation_capture(INDEX, seed=DATASET_SEED)
    stem = f"{INDEX:04d}"

    # the input: the capture area-resized to the network's input, as SegmentationModel does
    img = cv2.imread(str(tmp_path / f"{stem}.jpg"))[:, :, ::-1].astype(int)
    small = cv2.resize(cap.color, (t.IN_W, t.IN_H), interpolation=cv2.INTER_AREA).astype(int)
    assert img.shape == (t.IN_H, t.IN_W, 3)
    assert np.abs(img - small).mean() < 3  # JPEG quality 90

    # the label: the render's own labels at full resolution, stored with one bit per pixel
    label = tmp_path / f"{stem}.png"
    assert _png_bit_depth(label) == 1
    np.testing.assert_array_equal(cv2.imread(str(label), cv2.IMREAD_GRAYSCALE) > 0, cap.labels > 0)

    # kept at full resolution when asked (``data --full``; relief training captures by default)
    full = cv2.imread(str(tmp_path / f"{stem}.full.jpg"))[:, :, ::-1].astype(int)
    assert full.shape == cap.color.shape
    assert np.abs(full - cap.color.astype(int)).mean() < 4  # JPEG quality 85

    # resumable: a second run finds every file and rewrites none
    stamps = {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()}
    t._render_one((INDEX, tmp_path, 90, "silhouette", True, 85))
    assert {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()} == stamps


def test_a_smooth_capture_keeps_no_full_render_unless_asked(t, tmp_path):
    t._render_one((INDEX, tmp_path, 90, "silhouette", False, 85))
    assert sorted(p.name for p in tmp_path.iterdir()) == [f"{INDEX:04d}.jpg", f"{INDEX:04d}.png"]


def test_full_renders_are_kept_for_training_captures_only(t):
    split = {"train": [1, 2, "10r", "11r", "12r"], "val": [3, "3r"], "test": [4]}
    assert t._full_renders(split) == {"10r", "11r", "12r"}
    assert t._full_renders(split, relief_full=2) == {"10r", "11r"}
    assert t._full_renders(split, relief_full=0, every=True) == {1, 2, "10r", "11r", "12r"}


@pytest.fixture(scope="module")
def dr():
    """The domain-randomised compositor (training/domain_random.py) as a module."""
    spec = importlib.util.spec_from_file_location("domain_random", ROOT / "training" / "domain_random.py")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_randomised_scene_is_seeded_and_its_mask_marks_bars_only(dr):
    rgb, mask = dr.scene(5, size=160)
    again, mask_again = dr.scene(5, size=160)
    assert rgb.shape == (160, 160, 3) and rgb.dtype == np.uint8 and mask.shape == (160, 160)
    assert np.array_equal(rgb, again) and np.array_equal(mask, mask_again)
    assert not np.array_equal(rgb, dr.scene(6, size=160)[0])
    # over a few scenes: bars in most, never the whole image
    shares = [dr.scene(i, size=160)[1].mean() for i in range(8)]
    assert sum(s > 0 for s in shares) >= 4 and max(shares) < 0.9


def test_a_randomised_scene_is_written_as_the_model_sees_it_and_resumes(dr, tmp_path):
    assert dr.write_sample(3, tmp_path, size=160)
    img = cv2.imread(str(tmp_path / "00003.jpg"))[:, :, ::-1].astype(int)
    mask = cv2.imread(str(tmp_path / "00003.png"), cv2.IMREAD_GRAYSCALE) > 0
    rgb, truth = dr.scene(3, size=160)
    small = cv2.resize(rgb, (80, 80), interpolation=cv2.INTER_AREA).astype(int)
    assert img.shape == (80, 80, 3) and np.abs(img - small).mean() < 5  # half size, JPEG 92
    assert _png_bit_depth(tmp_path / "00003.png") == 1
    np.testing.assert_array_equal(mask, truth)
    stamps = {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()}
    assert not dr.write_sample(3, tmp_path, size=160)
    assert {p.name: p.stat().st_mtime_ns for p in tmp_path.iterdir()} == stamps


def test_hard_negatives_mark_no_rebar_and_leave_the_rest_of_the_scene(dr):
    # they draw from a stream of their own: with them no pixel becomes rebar (a person in front
    # of the bars only hides some), and some scenes get some (each kind is drawn by chance)
    changed = 0
    for i in range(6):
        rgb, mask = dr.scene(i, size=160)
        rgb_hard, mask_hard = dr.scene(i, size=160, hard=True)
        assert not (mask_hard & ~mask).any()
        changed += not np.array_equal(rgb, rgb_hard)
    assert changed >= 1


def test_scenes_written_during_training_are_loaded_as_they_appear(t, dr, tmp_path):
    torch = pytest.importorskip("torch")
    for i in range(3):  # scene 0 validates (a multiple of 20), 1 and 2 train
        dr.write_sample(i, tmp_path, size=160)
    grow = t._GrowingDR(tmp_path, 20, 6, torch.device("cpu"))
    assert grow.n == 2 and len(grow.val[0]) == 1
    for i in range(3, 6):
        dr.write_sample(i, tmp_path, size=160)
    assert grow.grow() == 5
    imgs, masks = grow.train()
    assert imgs.shape == (5, 80, 80, 3) and masks.shape == (5, 160, 160)
    np.testing.assert_array_equal(masks[4].numpy(), cv2.imread(str(tmp_path / "00005.png"), cv2.IMREAD_GRAYSCALE) > 0)
    for i in range(6, 10):  # up to its capacity; the validation scenes stay those of the start
        dr.write_sample(i, tmp_path, size=160)
    assert grow.grow() == 6 and len(grow.val[0]) == 1


def test_a_room_behind_the_bars_marks_no_rebar_and_changes_no_other_draw(dr):
    # --indoor draws from its own stream: indoor=0 is the scene as before; a room behind the
    # bars (indoor=1: in every scene) leaves the mask as it was and changes the picture
    for i in range(4):
        rgb, mask = dr.scene(i, size=160, hard=True)
        np.testing.assert_array_equal(dr.scene(i, size=160, hard=True, indoor=0.0)[0], rgb)
        rgb_room, mask_room = dr.scene(i, size=160, hard=True, indoor=1.0)
        np.testing.assert_array_equal(mask_room, mask)
        assert not np.array_equal(rgb, rgb_room)


def test_thick_cables_and_hair_mark_no_rebar_and_change_no_other_draw(dr):
    # --curves draws from its own stream: curves=0 is the scene as before; with thick cables and
    # long hair in every scene the mask only loses pixels (a cable over a bar) and never gains one
    changed = 0
    for i in range(4):
        rgb, mask = dr.scene(i, size=160, hard=True, indoor=0.3)
        np.testing.assert_array_equal(dr.scene(i, size=160, hard=True, indoor=0.3, curves=0.0)[0], rgb)
        rgb_c, mask_c = dr.scene(i, size=160, hard=True, indoor=0.3, curves=1.0)
        assert not np.any(mask_c & ~mask)
        changed += not np.array_equal(rgb, rgb_c)
    assert changed == 4


@pytest.mark.parametrize(
    "base, option, n, changed_at_least",
    [
        # --dof: a scene whose bars stand in front of a room (indoor=1) has its background blurred
        (dict(indoor=1.0), "dof", 4, 4),
        # --near-blur: some bars of a cage (only cages and starter bars: a few of 12 scenes) blurred
        (dict(dof=0.6), "near_blur", 12, 1),
    ],
)
def test_an_out_of_focus_option_changes_the_picture_not_the_mask(dr, base, option, n, changed_at_least):
    # each option draws from its own stream: 0 is the scene as before; 1 keeps the mask as in focus
    changed = 0
    for i in range(n):
        rgb, mask = dr.scene(i, size=160, hard=True, **base)
        np.testing.assert_array_equal(dr.scene(i, size=160, hard=True, **base, **{option: 0.0})[0], rgb)
        rgb_o, mask_o = dr.scene(i, size=160, hard=True, **base, **{option: 1.0})
        np.testing.assert_array_equal(mask_o, mask)
        changed += not np.array_equal(rgb, rgb_o)
    assert changed >= changed_at_least


def test_defocus_takes_the_detail_out_of_a_texture(dr):
    rng = np.random.default_rng(3)
    img = dr.texture(rng, 160, 160, "gravel").astype(np.float32)
    out = dr._defocus(img, np.random.default_rng(5))
    assert out.shape == img.shape and out.dtype == np.float32
    detail = [np.abs(cv2.Laplacian(x.mean(axis=2), cv2.CV_32F)).mean() for x in (img, out)]
    assert detail[1] < 0.5 * detail[0]


def test_bundled_bars_are_parallel_packed_and_labelled_with_gaps_between(dr):
    # --bundles draws from its own stream: 0 is the scene as before
    for i in range(3):
        plain = dr.scene(i, size=160, hard=True)[0]
        np.testing.assert_array_equal(dr.scene(i, size=160, hard=True, bundles=0.0)[0], plain)
    # each added bar lies beside the bar it follows, moved across it (not along it) at both ends
    # by 1.1 to 2.5 of their mean width there (the last bar of its group, or the bar it starts
    # from): parallel in the image where the widths are equal, opening with the perspective
    # where they grow along the bar; drawn in that bar's order
    bar = (np.array([100.0, 50.0]), np.array([500.0, 350.0]), 20.0, 30.0, 1)
    d = (bar[1] - bar[0]) / np.linalg.norm(bar[1] - bar[0])
    n = np.array([-d[1], d[0]])
    for seed in range(20):
        out = dr._bundle([bar], np.random.default_rng(seed))
        assert out[0] is bar and 2 <= len(out) <= 9
        for k, (q0, q1, w0, w1, order) in enumerate(out[1:], start=1):
            assert order == 1 and 0.85 * 20 - 1e-9 <= w0 <= 1.1 * 20 + 1e-9 and abs(w1 / w0 - 1.5) < 1e-9
            ok = False
            for c0, c1, cw0, cw1, _ in {id(b): b for b in (out[k - 1], bar)}.values():
                s0, s1 = q0 - c0, q1 - c1
                if max(abs(float(np.dot(s0, d))), abs(float(np.dot(s1, d)))) > 1e-6:
                    continue  # not moved straight across that bar
                g0, g1 = abs(float(np.dot(s0, n))) / ((cw0 + w0) / 2), abs(float(np.dot(s1, n))) / ((cw1 + w1) / 2)
                ok |= abs(g0 - g1) < 1e-6 and 1.1 - 1e-6 <= g0 <= 2.5 + 1e-6
            assert ok
    # in whole scenes the packed bars are labelled bar by bar: more rebar in most of them
    grew = 0
    for i in range(12):
        _, mask = dr.scene(i, size=160, hard=True)
        _, mask_b = dr.scene(i, size=160, hard=True, bundles=1.0)
        grew += int(mask_b.sum() > mask.sum())
    assert grew >= 6
