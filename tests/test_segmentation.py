"""Segmentation: metrics, the ONNX + sidecar contract, the shipped model, depth mask and fusion."""

from __future__ import annotations

import json
import shutil

import numpy as np
import pytest

from rebarlib import GEMINI2, RebarInputError
from rebarlib._inspect import registered_mask
from rebarlib._masks import widest_bar_px
from rebarlib.synth import SensorModel, misregister, synth_capture
from rebarlib.segmentation import (
    SegmentationModel,
    confusion_counts,
    depth_overreach_px,
    dice,
    estimate_registration,
    fit_formwork_plane,
    fuse_masks,
    iou,
    mask_from_depth,
    pixel_accuracy,
    shift_image,
    soft_mask,
    trim_depth_overreach,
)
from rebarlib.synth_segmentation import DATASET_SEED, split_indices, synth_eval_regions, synth_segmentation_capture

onnx = pytest.importorskip("onnx")
from onnx import TensorProto, helper  # noqa: E402

# The shipped model on fresh captures (a seed outside the data set), at 640 x 400: it measured
# IoU 0.942 on these three together (0.937, 0.956, 0.931); see rebarlib/models/README.md for the
# test-split figures. The model shipped before it scored 0.909 here, an untrained or broken one
# far below (the first checkpoint: 0.78).
SHIPPED_MIN_IOU = 0.92
FRESH_SEED = 99
FRESH_INDICES = (0, 1, 2)
# Depth-only mask on a half-resolution synthetic capture: holes and fattened edges cost IoU,
# but what it marks is nearly always a bar (or a spacer/chair, which the labels call background).
DEPTH_MIN_IOU = 0.70
DEPTH_MIN_PRECISION = 0.93
PLANE_MAX_ANGLE_DEG = 0.2
PLANE_MAX_OFFSET_MM = 1.0
# Fusion on a half-resolution capture (measured: colour 0.85 -> fused 0.93; a perfect colour mask
# loses 3-5 points to the depth mask's fattened edges at this resolution, less at 1280 x 800)
FUSE_MIN_GAIN = 0.05
FUSE_PERFECT_MIN_IOU = 0.93
FUSE_STRIPE_MAX_LEFT = 0.05
FUSE_LOST_MIN_BACK = 0.7
HALF = GEMINI2.scaled(0.5)


# ---------------------------------------------------------------------------------------------
# metrics


def test_confusion_counts_by_hand():
    pred = np.array([[1, 1, 0, 0, 1], [0, 1, 1, 0, 0]], bool)
    truth = np.array([[1, 0, 0, 1, 1], [0, 1, 0, 1, 0]], bool)
    # TP at (0,0) (0,4) (1,1); FP at (0,1) (1,2); FN at (0,3) (1,3); TN at (0,2) (1,0) (1,4)
    c = confusion_counts(pred, truth)
    assert c == {"TP": 3, "FP": 2, "FN": 2, "TN": 3}
    assert pixel_accuracy(pred, truth) == pytest.approx(6 / 10)
    assert iou(pred, truth) == pytest.approx(3 / 7)
    assert dice(pred, truth) == pytest.approx(6 / 10)
    # the same numbers from the counts
    assert iou(c) == pytest.approx(3 / 7) and dice(c) == pytest.approx(0.6)


def test_confusion_counts_region_and_edge_cases():
    pred = np.array([[1, 1, 0, 0]], bool)
    truth = np.array([[1, 0, 1, 0]], bool)
    region = np.array([[1, 1, 0, 0]], bool)
    assert confusion_counts(pred, truth, region=region) == {"TP": 1, "FP": 1, "FN": 0, "TN": 0}
    empty = np.zeros((3, 3), bool)
    assert np.isnan(iou(empty, empty)) and np.isnan(dice(empty, empty))
    assert pixel_accuracy(empty, empty) == 1.0
    assert iou(truth, truth) == 1.0 and dice(truth, truth) == 1.0
    with pytest.raises(RebarInputError, match="pred"):
        confusion_counts(np.zeros((2, 2)), np.zeros((2, 3)))
    with pytest.raises(RebarInputError, match="TP"):
        iou({"TP": 1})


def test_split_is_6_2_2_by_capture_and_seeded():
    s = split_indices(300, seed=DATASET_SEED)
    assert [len(s[k]) for k in ("train", "val", "test")] == [180, 60, 60]
    allidx = np.concatenate([s["train"], s["val"], s["test"]])
    assert sorted(allidx.tolist()) == list(range(300))
    assert np.array_equal(split_indices(300, seed=DATASET_SEED)["test"], s["test"])


# ---------------------------------------------------------------------------------------------
# ONNX models built here with the onnx helper API, run through the same sidecar contract


def _save(tmp_path, name, graph, sidecar):
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 17)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    path = tmp_path / f"{name}.onnx"
    onnx.save(model, str(path))
    if sidecar is not None:
        (tmp_path / f"{name}.json").write_text(json.dumps(sidecar))
    return path


def _red_minus_blue_model(tmp_path, sidecar, name="redblue", fixed=None):
    """A fixed-weights 1x1 conv: logit = (R - B) / 16 on an NCHW float input."""
    h, w = fixed if fixed else ("H", "W")
    weight = helper.make_tensor("w", TensorProto.FLOAT, [1, 3, 1, 1], [1 / 16, 0.0, -1 / 16])
    graph = helper.make_graph(
        [helper.make_node("Conv", ["image", "w"], ["logit"])],
        "red_minus_blue",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, h, w])],
        [helper.make_tensor_value_info("logit", TensorProto.FLOAT, [1, 1, h, w])],
        [weight],
    )
    return _save(tmp_path, name, graph, sidecar)


def _argmax_label_model(tmp_path, sidecar, name="argmax"):
    """NHWC uint8 input -> label map = index of the brightest channel (R 0, G 1, B 2)."""
    graph = helper.make_graph(
        [
            helper.make_node("Cast", ["img"], ["f"], to=TensorProto.FLOAT),
            helper.make_node("ArgMax", ["f"], ["labels"], axis=3, keepdims=0),
        ],
        "argmax_channel",
        [helper.make_tensor_value_info("img", TensorProto.UINT8, [1, "H", "W", 3])],
        [helper.make_tensor_value_info("labels", TensorProto.INT64, [1, "H", "W"])],
    )
    return _save(tmp_path, name, graph, sidecar)


def _red_left_blue_right(h=50, w=80):
    img = np.zeros((h, w, 3), np.uint8)
    img[:, : w // 2, 0] = 200
    img[:, w // 2 :, 2] = 200
    truth = np.zeros((h, w), bool)
    truth[:, : w // 2] = True
    return img, truth


def test_in_test_logit_model_with_scale_and_padding(tmp_path):
    sidecar = {
        "input": {"scale": 0.5, "pad_to": 16, "channel_order": "RGB", "layout": "NCHW", "dtype": "float32"},
        "output": {"kind": "logits", "rebar_classes": [0], "threshold": 0.5},
    }
    path = _red_minus_blue_model(tmp_path, sidecar)
    model = SegmentationModel(path)  # sidecar found next to the model
    img, truth = _red_left_blue_right(50, 80)
    mask = model.predict_mask(img)
    assert mask.shape == truth.shape and mask.dtype == bool
    # away from the colour edge (bilinear resizing blurs 2 px at most) the mask is exact
    inner = np.ones_like(truth)
    inner[:, 38:42] = False
    assert np.array_equal(mask[inner], truth[inner])
    proba = model.predict_proba(img)
    assert proba.dtype == np.float32 and proba[:, :30].min() > 0.99 and proba[:, 50:].max() < 0.01


def test_in_test_model_bgr_swaps_the_answer(tmp_path):
    sidecar = {"input": {"scale": 1.0, "channel_order": "BGR"}, "output": {"kind": "logits", "rebar_classes": [0]}}
    model = SegmentationModel(_red_minus_blue_model(tmp_path, sidecar, name="bgr"))
    img, truth = _red_left_blue_right()
    assert np.array_equal(model.predict_mask(img), ~truth)


def test_in_test_label_map_model_nhwc_uint8(tmp_path):
    sidecar = {"input": {"layout": "NHWC", "dtype": "uint8"}, "output": {"kind": "labels", "rebar_classes": [0]}}
    model = SegmentationModel(_argmax_label_model(tmp_path, sidecar))
    img, truth = _red_left_blue_right()
    assert np.array_equal(model.predict_mask(img), truth)


def test_in_test_model_fixed_size_resizes_to_full_resolution(tmp_path):
    sidecar = {"input": {"size": [40, 25]}, "output": {"kind": "logits", "rebar_classes": [0]}}
    model = SegmentationModel(_red_minus_blue_model(tmp_path, sidecar, name="fixed", fixed=(25, 40)))
    img, truth = _red_left_blue_right(100, 160)
    mask = model.predict_mask(img)
    assert mask.shape == (100, 160)
    assert mask[:, :70].all() and not mask[:, 90:].any()


def test_in_test_model_fixed_size_keeps_the_aspect_ratio_and_pads(tmp_path):
    sidecar = {"input": {"size": [40, 25]}, "output": {"kind": "logits", "rebar_classes": [0]}}
    model = SegmentationModel(_red_minus_blue_model(tmp_path, sidecar, name="fixed", fixed=(25, 40)))
    assert model._input_size(160, 100) == (40, 25)  # the input's own aspect ratio: scaled
    assert model._input_size(160, 120) == (33, 25)  # 4:3 into 16:10: padded on the right
    assert model._input_size(100, 200) == (12, 25)  # portrait
    img, truth = _red_left_blue_right(120, 160)
    mask = model.predict_mask(img)
    assert mask.shape == (120, 160)
    assert mask[:, :70].all() and not mask[:, 90:].any()
    stretch = dict(sidecar, input={"size": [40, 25], "resize": "stretch"})
    model = SegmentationModel(_red_minus_blue_model(tmp_path, stretch, name="st", fixed=(25, 40)))
    assert model._input_size(160, 120) == (40, 25)


def test_in_test_dynamic_model_keeps_the_pixel_scale_at_any_size(tmp_path):
    sidecar = {"input": {"scale": 0.5, "pad_to": 16}, "output": {"kind": "logits", "rebar_classes": [0]}}
    model = SegmentationModel(_red_minus_blue_model(tmp_path, sidecar, name="dyn"))
    for h, w in ((480, 640), (301, 199), (3024, 4032)):
        assert model._input_size(w, h) == (round(w / 2), round(h / 2))
        img, truth = _red_left_blue_right(h, w)
        mask = model.predict_mask(img)
        assert mask.shape == (h, w)
        assert np.array_equal(mask[:, : w // 2 - 3], truth[:, : w // 2 - 3])
        assert not mask[:, w // 2 + 3 :].any()


def test_in_test_model_resize_scale_keeps_the_pixel_scale_and_the_design_input(tmp_path):
    # input.resize "scale": whole images scaled by input.scale and padded to pad_to only (a
    # photo of any aspect ratio keeps its pixel scale), as without a size; the size is the
    # design input that full resolution refers to (tiles enlarged towards twice it)
    out = {"kind": "logits", "rebar_classes": [0]}
    side = {"size": [40, 25], "resize": "scale", "scale": 0.5, "pad_to": 8, "full_resolution": "whole"}
    model = SegmentationModel(_red_minus_blue_model(tmp_path, {"input": side, "output": out}, name="sc"))
    dyn = SegmentationModel(
        _red_minus_blue_model(tmp_path, {"input": {"scale": 0.5, "pad_to": 8}, "output": out}, name="dy")
    )
    for h, w in ((50, 80), (120, 45), (301, 199)):
        assert model._input_size(w, h) == dyn._input_size(w, h) == (round(w / 2), round(h / 2))
        img, _ = _red_left_blue_right(h, w)
        assert np.array_equal(model.predict_proba(img), dyn.predict_proba(img))
    # an image under twice the design input is also run enlarged as far as it fits it, the two
    # maps' probabilities averaged
    assert model.whole_scales(80, 50) == [0.5] and model.whole_scales(45, 120) == [0.5]
    assert model.whole_scales(60, 32) == [0.5, 2 / 3] and model.whole_scales(40, 24) == [0.5, 1.0]
    img, _ = _red_left_blue_right(32, 60)
    img[:, 45] = (200, 0, 0)  # a thin red line in the blue half: each scale sees it otherwise
    runs = [model.predict_proba(img, flips=False)]
    p = [dyn._score(img, False, dyn._prepare(img, f))[0] for f in (0.5, 2 / 3)]
    want = np.mean([1 / (1 + np.exp(-x.astype(float))) for x in p], axis=0)
    assert np.allclose(runs[0], want, atol=1e-5)
    # full resolution: the whole image once, enlarged towards twice the design input (32 x 60 ->
    # 43 x 80) as a fixed-size model's tiles would be
    seen = []
    score = model._score
    model._score = lambda image, flips=True, *rest: seen.append(image.shape) or score(image, flips, *rest)
    img, _ = _red_left_blue_right(32, 60)
    assert model.predict_proba(img, tiled=True).shape == (32, 60) and seen == [(43, 80, 3)]
    # it needs a size, and a graph that takes any size
    with pytest.raises(RebarInputError, match="resize 'scale' needs input.size"):
        SegmentationModel(_red_minus_blue_model(tmp_path, {"input": {"resize": "scale"}, "output": out}, name="nosz"))
    with pytest.raises(RebarInputError, match="resize 'scale'"):
        SegmentationModel(
            _red_minus_blue_model(
                tmp_path, {"input": {"size": [40, 25], "resize": "scale"}, "output": out}, name="fx", fixed=(25, 40)
            )
        )


@pytest.mark.parametrize("flips", [[], ["h", "v", "hv"]])
def test_in_test_model_fixed_size_tiled_runs_at_full_resolution(tmp_path, flips):
    # a pointwise model (logit = (R - B) / 16) on an image 4 x its input each way: run on tiles at
    # the image's own resolution, every pixel gets exactly its own logit whatever tile it lies in
    # and however the overlapping tiles are blended; down-scaled to the input, a one-pixel red
    # line is averaged away with its blue neighbours
    sidecar = {"input": {"size": [40, 25], "flips": flips}, "output": {"kind": "logits", "rebar_classes": [0]}}
    model = SegmentationModel(_red_minus_blue_model(tmp_path, sidecar, name="tiled" + "_".join(flips), fixed=(25, 40)))
    img, _ = _red_left_blue_right(100, 160)
    img[:, 71] = (200, 0, 0)  # the edge one pixel right of the middle
    img[:, 123] = (200, 0, 0)  # a one-pixel red line in the blue half
    img[37, :] = (90, 0, 30)  # and a row of another logit across both
    want = 1 / (1 + np.exp(-(img[..., 0].astype(float) - img[..., 2]) / 16))
    tiled = model.predict_proba(img, tiled=True)
    assert tiled.shape == (100, 160) and tiled.dtype == np.float32
    assert np.allclose(tiled, want, atol=1e-5)
    whole = model.predict_proba(img)
    assert whole[50, 123] < 0.5 < tiled[50, 123]
    # an image of the input's size, or a smaller one, is scored as without tiles
    small = np.ascontiguousarray(img[:25, :40])
    assert np.array_equal(model.predict_proba(small, tiled=True), model.predict_proba(small))


def test_in_test_model_tiles_are_down_scaled_where_bars_would_be_too_wide(tmp_path):
    # the sidecar says the model knows bars up to 10 input pixels wide: a 20 px bar halves the
    # tiles' resolution, a 40 px bar brings the image down to the input (the plain whole-image run)
    sidecar = {"input": {"size": [40, 25], "max_bar_px": 10}, "output": {"kind": "logits", "rebar_classes": [0]}}
    model = SegmentationModel(_red_minus_blue_model(tmp_path, sidecar, name="maxbar", fixed=(25, 40)))
    assert model.tile_scale(None) == 1.0 and model.tile_scale(8) == 1.0
    assert model.tile_scale(20) == pytest.approx(0.5) and model.tile_scale(40) == pytest.approx(0.25)
    img, _ = _red_left_blue_right(100, 160)
    img[:, 123] = (200, 0, 0)
    want = 1 / (1 + np.exp(-(img[..., 0].astype(float) - img[..., 2]) / 16))
    assert np.allclose(model.predict_proba(img, tiled=True, bar_width_px=8), want, atol=1e-5)
    half = model.predict_proba(img, tiled=True, bar_width_px=20)
    assert half.shape == (100, 160) and not np.allclose(half, want, atol=1e-2)
    assert np.array_equal(model.predict_proba(img, tiled=True, bar_width_px=40), model.predict_proba(img))
    bad = {"input": {"size": [40, 25], "max_bar_px": -3}, "output": {"kind": "logits", "rebar_classes": [0]}}
    with pytest.raises(RebarInputError, match="max_bar_px"):
        SegmentationModel(_red_minus_blue_model(tmp_path, bad, name="badmax", fixed=(25, 40)))


def test_in_test_model_tiles_of_an_image_under_twice_the_input_are_enlarged(tmp_path):
    # Input 40 x 25: the tiles are designed for images of 80 x 50. A 60 x 32 image is enlarged by
    # the smaller ratio, 80 / 60 = 4/3, unless that makes its widest bar wider than the sidecar's
    # 10 px (an 8 px bar: 10 / 8 = 1.25); a bar too wide already shrinks it, as before. Images of
    # twice the input or more, and images no larger than the input, keep their scale.
    sidecar = {"input": {"size": [40, 25], "max_bar_px": 10}, "output": {"kind": "logits", "rebar_classes": [0]}}
    model = SegmentationModel(_red_minus_blue_model(tmp_path, sidecar, name="up", fixed=(25, 40)))
    assert model.tile_scale(None, (60, 32)) == pytest.approx(4 / 3)
    assert model.tile_scale(8, (60, 32)) == pytest.approx(1.25)
    assert model.tile_scale(20, (60, 32)) == pytest.approx(0.5)
    assert model.tile_scale(None, (160, 100)) == 1.0 and model.tile_scale(None, (80, 50)) == 1.0
    assert model.tile_scale(None, (40, 25)) == 1.0 and model.tile_scale(None, (30, 20)) == 1.0
    assert model.tile_scale(None) == 1.0  # no size given: as before
    # the enlarged image's tiles come back at the image's own size; this model reads each pixel
    # alone (logit (R - B) / 16), so enlarging and shrinking back leaves a smooth image's scores
    yy, xx = np.mgrid[0:32, 0:60]
    img = np.stack([(4 * xx).clip(0, 255), np.zeros_like(xx), (255 - 4 * xx).clip(0, 255)], -1)
    img = img.astype(np.uint8)
    got = model.predict_proba(img, tiled=True)
    want = 1 / (1 + np.exp(-(img[..., 0].astype(float) - img[..., 2]) / 16))
    assert got.shape == (32, 60) and np.allclose(got[2:-2, 2:-2], want[2:-2, 2:-2], atol=0.02)
    # ... from 9 tiles of the 80 x 43 enlargement (4 at the image's own 60 x 32)
    seen = []
    score = model._score
    model._score = lambda tile, flips=True, *rest: seen.append(tile.shape) or score(tile, flips, *rest)
    model.predict_proba(img, tiled=True)
    assert len(seen) == 9 and set(seen) == {(25, 40, 3)}
    seen.clear()
    model.predict_proba(img, tiled=True, bar_width_px=10)  # a 10 px bar: no room to enlarge
    assert len(seen) == 4


def test_in_test_model_full_resolution_whole_runs_the_network_once_on_the_whole_image(tmp_path):
    # input.full_resolution "whole": predict_proba(tiled=True) runs a graph that takes any size
    # once on the image at the tiles' scale (padded to pad_to) instead of on overlapping tiles;
    # this model reads each pixel alone, so both give the same scores (up to the tiles' blend)
    side = {"size": [40, 25], "max_bar_px": 10, "pad_to": 8}
    out = {"kind": "logits", "rebar_classes": [0]}
    tiles = SegmentationModel(_red_minus_blue_model(tmp_path, {"input": side, "output": out}, name="t"))
    whole = SegmentationModel(
        _red_minus_blue_model(tmp_path, {"input": {**side, "full_resolution": "whole"}, "output": out}, name="w")
    )
    img, _ = _red_left_blue_right(100, 163)  # 163 x 100: padded to 168 x 104
    img[:, 123] = (200, 0, 0)
    want = 1 / (1 + np.exp(-(img[..., 0].astype(float) - img[..., 2]) / 16))
    seen = []
    score = whole._score
    whole._score = lambda image, flips=True, *rest: seen.append(image.shape) or score(image, flips, *rest)
    got = whole.predict_proba(img, tiled=True, bar_width_px=8)
    assert seen == [(100, 163, 3)] and got.shape == (100, 163)
    assert np.allclose(got, want, atol=1e-5)
    assert np.allclose(got, tiles.predict_proba(img, tiled=True, bar_width_px=8), atol=1e-5)
    # the tile scale still applies: an image under twice the input is enlarged, one whose bars
    # are too wide shrunk, both brought back to the image's size
    seen.clear()
    assert whole.predict_proba(img[:32, :60], tiled=True).shape == (32, 60) and seen == [(43, 80, 3)]
    assert whole.predict_proba(img, tiled=True, bar_width_px=20).shape == (100, 163)
    # the untiled run is unchanged: the image scaled to the fixed input
    assert np.array_equal(whole.predict_proba(img), tiles.predict_proba(img))
    # "whole" needs a graph that takes any size, and a size to scale to
    with pytest.raises(RebarInputError, match="full_resolution"):
        SegmentationModel(
            _red_minus_blue_model(
                tmp_path, {"input": {**side, "full_resolution": "whole"}, "output": out}, name="f", fixed=(25, 40)
            )
        )
    for bad, name in (({"full_resolution": "whole"}, "nosize"), ({**side, "full_resolution": "all"}, "badkey")):
        with pytest.raises(RebarInputError, match="full_resolution"):
            SegmentationModel(_red_minus_blue_model(tmp_path, {"input": bad, "output": out}, name=name))


def _left_neighbour_model(tmp_path, sidecar, name="leftnb"):
    """logit(x) = R(x - 1) / 16 - 4: a model that is not mirror-symmetric (it looks one pixel to
    the left), so test-time flips change its answer in a way that can be computed by hand."""
    weight = helper.make_tensor("w", TensorProto.FLOAT, [1, 3, 1, 3], [1 / 16, 0, 0, 0, 0, 0, 0, 0, 0])
    bias = helper.make_tensor("b", TensorProto.FLOAT, [1], [-4.0])
    graph = helper.make_graph(
        [helper.make_node("Conv", ["image", "w", "b"], ["logit"], pads=[0, 1, 0, 1])],
        "left_neighbour",
        [helper.make_tensor_value_info("image", TensorProto.FLOAT, [1, 3, "H", "W"])],
        [helper.make_tensor_value_info("logit", TensorProto.FLOAT, [1, 1, "H", "W"])],
        [weight, bias],
    )
    return _save(tmp_path, name, graph, sidecar)


@pytest.mark.parametrize("flips, columns", [([], [21]), (["v"], [21]), (["h"], [19, 21]), (["h", "v", "hv"], [19, 21])])
def test_in_test_model_with_test_time_flips(tmp_path, flips, columns):
    # one red column at x = 20: the plain model marks x = 21 (logit 200/16 - 4 = 8.5); its mirror
    # image marks x = 19, and the mean of the two logits is 200/32 - 4 = 2.25 > 0 at both
    sidecar = {"input": {"flips": flips}, "output": {"kind": "logits", "rebar_classes": [0]}}
    model = SegmentationModel(_left_neighbour_model(tmp_path, sidecar, name="flips" + "_".join(flips)))
    img = np.zeros((30, 40, 3), np.uint8)
    img[:, 20, 0] = 200
    mask = model.predict_mask(img)
    assert np.array_equal(np.unique(np.nonzero(mask)[1]), columns) and mask[:, columns].all()
    if flips == ["h"]:
        assert np.allclose(model.predict_proba(img)[:, 19], 1 / (1 + np.exp(-2.25)), atol=1e-5)


def test_in_test_model_tiles_get_the_test_time_flips(tmp_path):
    # the left-looking model on tiles: with the sidecar's flip every tile's logits are the mean of
    # the plain and the mirrored run, so the red column at x = 50 marks x = 49 and x = 51 with the
    # mean logit 2.25, as on a whole image (test above); flips=False runs each tile once (x = 51 only, 8.5).
    # x = 49-51 lie inside every 40 px tile that holds them (tiles start every 20 px)
    sidecar = {"input": {"size": [40, 25], "flips": ["h"]}, "output": {"kind": "logits", "rebar_classes": [0]}}
    model = SegmentationModel(_left_neighbour_model(tmp_path, sidecar, name="tileflips"))
    img = np.zeros((100, 160, 3), np.uint8)
    img[:, 50, 0] = 200
    sig = lambda z: 1 / (1 + np.exp(-z))  # noqa: E731
    both = model.predict_proba(img, tiled=True)
    assert both.shape == (100, 160)
    assert np.allclose(both[:, [49, 51]], sig(2.25), atol=1e-5) and np.allclose(both[:, 55:100], sig(-4.0), atol=1e-5)
    once = model.predict_proba(img, tiled=True, flips=False)
    assert np.allclose(once[:, 51], sig(8.5), atol=1e-5) and np.allclose(once[:, 49], sig(-4.0), atol=1e-5)
    # an image of the input's size is scored whole, with its flip or without
    small = np.ascontiguousarray(img[:25, 30:70])
    assert np.allclose(model.predict_proba(small, tiled=True)[:, 19], sig(2.25), atol=1e-5)
    assert np.allclose(model.predict_proba(small, tiled=True, flips=False)[:, 19], sig(-4.0), atol=1e-5)


# ---------------------------------------------------------------------------------------------
# errors name the file and the problem


def test_missing_model_and_sidecar(tmp_path):
    with pytest.raises(RebarInputError, match=r"nope\.onnx: ONNX model file not found"):
        SegmentationModel(tmp_path / "nope.onnx")
    path = _red_minus_blue_model(tmp_path, None, name="nosidecar")
    with pytest.raises(RebarInputError, match=r"nosidecar\.json: sidecar JSON not found"):
        SegmentationModel(path)


def test_corrupt_model_and_sidecar(tmp_path):
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"this is not a protobuf" * 10)
    (tmp_path / "bad.json").write_text(json.dumps({"input": {}, "output": {"kind": "logits"}}))
    with pytest.raises(RebarInputError, match=r"bad\.onnx: not a valid ONNX model"):
        SegmentationModel(bad)
    path = _red_minus_blue_model(tmp_path, None, name="badjson")
    (tmp_path / "badjson.json").write_text("{ not json")
    with pytest.raises(RebarInputError, match=r"badjson\.json: not valid JSON"):
        SegmentationModel(path)
    (tmp_path / "badjson.json").write_text(json.dumps({"input": {}, "output": {"kind": "heatmap"}}))
    with pytest.raises(RebarInputError, match=r"badjson\.json: output.kind"):
        SegmentationModel(path)
    for flips, kind in ((["x"], "logits"), (["h", "h"], "logits"), (["h"], "labels")):
        (tmp_path / "badjson.json").write_text(json.dumps({"input": {"flips": flips}, "output": {"kind": kind}}))
        with pytest.raises(RebarInputError, match=r"badjson\.json: input.flips"):
            SegmentationModel(path)


@pytest.mark.parametrize(
    "sidecar, message",
    [
        ({"input": {"size": [64, 64]}, "output": {"kind": "logits", "rebar_classes": [0]}}, "does not match"),
        ({"input": {}, "output": {"kind": "logits", "rebar_classes": [0]}}, "set input.size"),
        (
            {"input": {"size": [40, 25], "dtype": "uint8"}, "output": {"kind": "logits", "rebar_classes": [0]}},
            "input.dtype",
        ),
        (
            {"input": {"size": [40, 25], "layout": "NHWC"}, "output": {"kind": "logits", "rebar_classes": [0]}},
            "input.layout",
        ),
        ({"input": {"size": [40, 25]}, "output": {"kind": "logits", "rebar_classes": [1]}}, "out of range"),
        ({"input": {"size": [40, 25], "name": "rgb"}, "output": {"kind": "logits"}}, "input.name"),
    ],
)
def test_mismatched_sidecar(tmp_path, sidecar, message):
    path = _red_minus_blue_model(tmp_path, sidecar, name="mismatch", fixed=(25, 40))
    with pytest.raises(RebarInputError, match=message) as e:
        SegmentationModel(path)
    assert "mismatch.onnx" in str(e.value)


def test_bad_color_input(tmp_path):
    model = SegmentationModel(
        _red_minus_blue_model(tmp_path, {"input": {}, "output": {"kind": "logits", "rebar_classes": [0]}})
    )
    with pytest.raises(RebarInputError, match="color"):
        model.predict_mask(np.zeros((10, 10), np.uint8))


# ---------------------------------------------------------------------------------------------
# the shipped model


@pytest.fixture(scope="module")
def fresh_captures():
    return [synth_segmentation_capture(i, seed=FRESH_SEED, intrinsics=HALF) for i in FRESH_INDICES]


@pytest.fixture(scope="module")
def fresh_full_captures():
    return [synth_segmentation_capture(i, seed=FRESH_SEED) for i in FRESH_INDICES]


@pytest.mark.parametrize("which", ["half", "full"])
def test_shipped_model_iou_on_fresh_captures(which, fresh_captures, fresh_full_captures):
    # at half the camera's resolution (640 x 400, enlarged to the design input) and at its own
    # (1280 x 800, run at half its size): rebarlib/models/README.md
    model = SegmentationModel.default()
    assert model.onnx_path.stat().st_size <= 10 * 2**20
    total = {"TP": 0, "FP": 0, "FN": 0, "TN": 0}
    for cap in fresh_captures if which == "half" else fresh_full_captures:
        c = confusion_counts(model.predict_mask(cap.color), cap.labels > 0)
        total = {k: total[k] + c[k] for k in total}
    assert iou(total) >= SHIPPED_MIN_IOU


def test_shipped_model_is_deterministic_and_full_resolution(fresh_captures):
    model = SegmentationModel.default()
    img = fresh_captures[0].color
    a, b = model.predict_proba(img), model.predict_proba(img)
    assert np.array_equal(a, b)
    # the mask thresholds the logit, the probability is its sigmoid: the same pixels
    assert np.mean(model.predict_mask(img) == (a > model.threshold)) > 0.9999
    big = np.ascontiguousarray(np.repeat(np.repeat(img, 2, axis=0), 2, axis=1))  # 1280 x 800
    assert model.predict_mask(big).shape == (800, 1280)


def test_shipped_sidecar_copied_elsewhere_still_loads(tmp_path):
    src = SegmentationModel.default().onnx_path
    shutil.copy(src, tmp_path / "m.onnx")
    shutil.copy(src.with_suffix(".json"), tmp_path / "other.json")
    assert SegmentationModel(tmp_path / "m.onnx", tmp_path / "other.json").predict_mask(
        np.zeros((8, 8, 3), np.uint8)
    ).shape == (8, 8)


# ---------------------------------------------------------------------------------------------
# depth mask and fusion


def _plane_error(plane, truth_plane):
    n, d = plane
    tn = np.asarray(truth_plane["normal"])
    angle = np.degrees(np.arccos(np.clip(abs(n @ tn), -1, 1)))
    return angle, abs(d - truth_plane["offset_mm"])


def test_depth_mask_and_plane_against_labels(fresh_captures):
    from rebarlib.capture import depth_to_points

    cap = fresh_captures[1]
    truth = cap.labels > 0
    angle, doff = _plane_error(
        fit_formwork_plane(depth_to_points(cap.depth_mm, cap.intrinsics).points, rng=0), cap.truth["formwork_plane"]
    )
    assert angle < PLANE_MAX_ANGLE_DEG and doff < PLANE_MAX_OFFSET_MM
    dm = mask_from_depth(cap, rng=0)
    c = confusion_counts(dm, truth)
    assert iou(c) >= DEPTH_MIN_IOU
    assert c["TP"] / (c["TP"] + c["FP"]) >= DEPTH_MIN_PRECISION
    assert np.array_equal(dm, mask_from_depth(cap, rng=0))  # seeded


def test_the_same_seed_gives_the_same_plane_every_run(fresh_captures):
    # Open3D's RANSAC stops early by default, and which of its threads' planes wins then depends
    # on their timing: with these two seeds, these points gave one of two planes from run to run
    # (4 and 6 of 10 runs each, 2 cores), and a few pixels of the depth mask changed with it
    from rebarlib.capture import depth_to_points

    cap = fresh_captures[1]
    pts = depth_to_points(cap.depth_mm, cap.intrinsics).points
    for seed in (5, 37):
        first = fit_formwork_plane(pts, rng=seed)
        for _ in range(9):
            n, d = fit_formwork_plane(pts, rng=seed)
            assert np.array_equal(n, first[0]) and d == first[1], seed


# The registration of colour and depth on half-resolution captures, the true labels standing for
# the colour model's probability: measured within 0.14 px with depth moved by whole pixels; colour
# moved by fractions of a pixel: 0.45 px (the estimate is pulled toward whole pixels where both
# masks are aliased, as on these synthetic images; an optical image's edges are not)
REGISTRATION_MAX_ERR_PX = 0.3
REGISTRATION_FRACTION_MAX_ERR_PX = 0.5


@pytest.mark.parametrize("du, dv", [(0, 0), (2, -1), (-1, 3)])
def test_registration_finds_how_far_depth_lies_from_colour(fresh_captures, du, dv):
    cap = fresh_captures[0]
    depth = misregister(cap, du, dv).depth_mm
    dmask = mask_from_depth(depth, cap.intrinsics, rng=0)
    eu, ev, cc = estimate_registration((cap.labels > 0).astype(np.float32), dmask, depth_valid=depth > 0)
    assert np.hypot(eu - du, ev - dv) <= REGISTRATION_MAX_ERR_PX
    assert cc > 0.8


def test_registration_to_a_fraction_of_a_pixel(fresh_captures):
    cap = fresh_captures[1]
    colour = shift_image((cap.labels > 0).astype(np.float32), -0.6, 1.4)  # colour moved, depth stays
    eu, ev, _ = estimate_registration(colour, mask_from_depth(cap, rng=0), depth_valid=cap.depth_mm > 0)
    assert np.hypot(eu - 0.6, ev + 1.4) <= REGISTRATION_FRACTION_MAX_ERR_PX


def test_registration_without_bars_is_not_estimated_and_bad_shapes_are_errors():
    empty = np.zeros((40, 60), bool)
    assert all(np.isnan(estimate_registration(empty, empty)))
    with pytest.raises(RebarInputError, match="depth_mask"):
        estimate_registration(np.zeros((40, 60)), np.zeros((40, 61), bool))


def test_shift_image_moves_content_and_leaves_the_input():
    img = np.zeros((5, 6, 3), np.uint8)
    img[2, 2] = 200
    out = shift_image(img, 1.0, -1.0)
    assert out[1, 3].tolist() == [200, 200, 200] and out.dtype == np.uint8
    assert img[2, 2].tolist() == [200, 200, 200] and img[1, 3].tolist() == [0, 0, 0]


def test_fuse_removes_flat_false_bars_and_fills_missed_bars(fresh_captures):
    cap = fresh_captures[2]
    truth = cap.labels > 0
    dm = mask_from_depth(cap, rng=0)
    valid = cap.depth_mm > 0
    # a colour mask with the two failure modes of the paper: a shadow line on the formwork that
    # looks like a bar (false stripe), and a bar lost in shadow (a band of true bar removed)
    color = truth.copy()
    stripe = np.zeros_like(truth)
    stripe[100:104, :] = True
    stripe &= ~truth
    color |= stripe
    lost = np.zeros_like(truth)
    lost[:, 260:380] = True
    lost &= truth
    color &= ~lost
    fused = fuse_masks(color, dm, depth_valid=valid)
    assert iou(fused, truth) > iou(color, truth) + FUSE_MIN_GAIN
    assert (fused & stripe & valid).sum() < FUSE_STRIPE_MAX_LEFT * (stripe & valid).sum()
    assert (fused & lost).sum() > FUSE_LOST_MIN_BACK * lost.sum()
    assert iou(fuse_masks(truth, dm, depth_valid=valid), truth) > FUSE_PERFECT_MIN_IOU


def test_fuse_with_probability_takes_unsure_edges_next_to_depth_bars():
    color = np.zeros((5, 10), bool)
    color[:, 4:6] = True
    proba = np.zeros((5, 10), np.float32)
    proba[:, 3:7] = 0.3  # unsure edge pixels ...
    proba[:, 4:6] = 0.9
    proba[:, 8] = 0.3  # ... and an unsure pixel far from any depth bar
    depth = np.zeros((5, 10), bool)
    depth[:, 4:6] = True
    fused = fuse_masks(color, depth, color_proba=proba, support_px=1)
    assert fused[0].astype(int).tolist() == [0, 0, 0, 1, 1, 1, 1, 0, 0, 0]
    assert fuse_masks(color, depth, color_proba=proba, low_proba=0.5, support_px=1)[0].sum() == 2


def test_depth_overreach_is_fattening_on_every_side_not_a_moved_depth_image(paper_design):
    # 3 px of stereo fattening (the benchmark's "fattened" sensor): the depth's bars reach a pixel
    # beyond the truth's on every side seen; left in, it costs the fused mask IoU (measured 0.916
    # against 0.988 without it) and pulls the registration 0.8 px towards the side not in the
    # projector's shadow (0.06 px without it)
    kw = dict(height_mm=500, tilt_deg=5, intrinsics=HALF, seed=4)
    sensor = SensorModel(edge_fatten_px=3, edge_fatten_prob=0.6, edge_hole_prob=0.2)
    fat = synth_capture(paper_design, sensor=sensor, **kw)
    truth, dm, valid = fat.labels > 0, mask_from_depth(fat, rng=0), fat.depth_mm > 0
    k = depth_overreach_px(truth, dm, depth_valid=valid)
    assert k >= 1
    assert (
        iou(fuse_masks(truth, dm, depth_valid=valid), truth)
        > iou(fuse_masks(truth, dm, depth_valid=valid, overreach_px=0), truth) + 0.03
    )
    trimmed = trim_depth_overreach(truth, dm, k)
    assert not (trimmed & ~dm).any()
    eu, ev, _ = estimate_registration(truth.astype(np.float32), trimmed, depth_valid=valid)
    assert np.hypot(eu, ev) <= REGISTRATION_MAX_ERR_PX
    # as inspect's refined method does it, with the shipped model's soft mask at full resolution:
    # the colour is not moved (measured 0.07 px)
    reg = registered_mask(fat, rng=0, soft=True, tiled=True, bar_width_px=widest_bar_px(fat, paper_design))[2]
    assert reg["depth_overreach_px"] >= 1 and not reg["applied"]
    assert np.hypot(*reg["shift_px"]) <= REGISTRATION_MAX_ERR_PX
    # the default sensor's fattening now and then is not an over-reach, nor is a moved depth image
    cap = synth_capture(paper_design, **kw)
    truth, dm, valid = cap.labels > 0, mask_from_depth(cap, rng=0), cap.depth_mm > 0
    assert depth_overreach_px(truth, dm, depth_valid=valid) == 0
    assert depth_overreach_px(truth, np.roll(dm, 2, axis=1), depth_valid=valid) == 0
    assert depth_overreach_px(truth, np.roll(dm, (-2, 2), axis=(0, 1)), depth_valid=valid) == 0


def test_mask_from_depth_needs_intrinsics_with_a_depth_map():
    with pytest.raises(RebarInputError, match="intrinsics"):
        mask_from_depth(np.full((4, 4), 500.0))
    with pytest.raises(RebarInputError, match="depth_mask"):
        fuse_masks(np.zeros((3, 3), bool), np.zeros((3, 4), bool))


def test_runtime_does_not_import_torch():
    import subprocess
    import sys

    code = (
        "import sys, numpy as np; from rebarlib.segmentation import SegmentationModel; "
        "SegmentationModel.default().predict_mask(np.zeros((8, 8, 3), np.uint8)); "
        "print('torch' in sys.modules)"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "False"


def test_soft_mask_keeps_the_binary_decision():
    mask = np.array([[True, True, False, False]])
    proba = np.array([[0.9, 0.3, 0.7, 0.1]])
    # agree: the probability; the mask overrides: 1 (added) or 0 (removed)
    assert np.allclose(soft_mask(mask, proba), [[0.9, 1.0, 0.0, 0.1]])
    # a model threshold of 0.2 is moved to 0.5, piecewise linearly
    out = soft_mask(np.array([[True, True, False]]), np.array([[0.2, 0.6, 0.1]]), threshold=0.2)
    assert np.allclose(out, [[0.5, 0.5 + 0.5 * 0.4 / 0.8, 0.25]])
    rng = np.random.default_rng(0)
    m, p = rng.random((30, 40)) > 0.5, rng.random((30, 40))
    assert np.array_equal(soft_mask(m, p) >= 0.5, m)
    with pytest.raises(RebarInputError, match="proba"):
        soft_mask(m, p[:, :10])
    with pytest.raises(RebarInputError, match="threshold"):
        soft_mask(m, p, threshold=1.0)


def test_eval_regions_separate_cast_from_attached_shadow():
    cap = synth_segmentation_capture(3, intrinsics=GEMINI2.scaled(0.5))
    r = synth_eval_regions(3, cap)
    bars = cap.labels > 0
    # every bar has a side facing away from the sun (attached shadow): many unlit bar pixels are
    # left out of the shadow subset, which starts from bar pixels in a cast shadow
    unlit_bars = r["unlit"] & bars
    assert (r["shadow"] & bars).any()
    assert (unlit_bars & ~r["shadow"]).sum() > 0.2 * unlit_bars.sum()
    # the shadow subset is unlit bar pixels grown by the margin (2 px at 640 wide): nothing else
    import cv2

    near = cv2.dilate(unlit_bars.astype(np.uint8), np.ones((5, 5), np.uint8)).astype(bool)
    assert not (r["shadow"] & ~near).any()


def test_data_set_capture_with_ribs_in_relief_is_the_same_scene():
    # the same index drawn both ways: the same bars in the same places; in relief, each bar's
    # silhouette lies between its core and its rib envelope, so it covers fewer pixels than the
    # smooth envelope does, and only near the bars' edges do the two differ
    quarter = GEMINI2.scaled(0.25)
    smooth = synth_segmentation_capture(5, intrinsics=quarter)
    relief = synth_segmentation_capture(5, intrinsics=quarter, rib_relief=True)

    def axes(c):
        return [(b["id"], b["axis_start_mm"], b["axis_end_mm"], b["diameter_mm"]) for b in c.truth["bars"]]

    assert axes(smooth) == axes(relief)
    a, b = smooth.labels > 0, relief.labels > 0
    assert b.sum() < a.sum() and (b & ~a).sum() < 0.01 * b.sum()
    import cv2

    edge = cv2.morphologyEx(a.astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)).astype(bool)
    assert ((a != b) & ~edge).sum() < 0.05 * (a != b).sum()
