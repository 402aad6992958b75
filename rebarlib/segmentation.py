"""Rebar segmentation: a binary rebar mask for the colour image (method.md, Stage 3, step 1).

Three sources of a mask, and the metrics to judge them:

* :class:`SegmentationModel` runs any ONNX segmentation network with onnxruntime, described by a
  small sidecar JSON (how to feed it, how to read it); :meth:`SegmentationModel.default` loads the
  model shipped in ``rebarlib/models`` (trained on synthetic captures by
  ``training/train_segmentation.py``).
* :func:`mask_from_depth`: the pixels whose depth lies clearly above the formwork plane, which
  shadows and rust cannot fool; :func:`fuse_masks` keeps the colour mask's edges where depth
  agrees that a bar is there, and fills bars that colour missed.
* :func:`confusion_counts`, :func:`pixel_accuracy`, :func:`iou`, :func:`dice`: the paper's
  formulas (method.md, "Segmentation metrics").

The runtime never imports torch.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np

from ._camera import Intrinsics, depth_to_points
from ._checks import RebarInputError

__all__ = [
    "SegmentationModel", "confusion_counts", "pixel_accuracy", "iou", "dice",
    "fit_formwork_plane", "height_above_plane", "mask_from_depth", "fuse_masks",
    "DATASET_SEED", "DATASET_SIZE", "segmentation_scene_params", "synth_segmentation_capture",
    "split_indices", "synth_eval_regions", "soft_mask", "estimate_registration", "shift_image",
]

MODELS_DIR = Path(__file__).resolve().parent / "models"
DEFAULT_MODEL = "rebar_seg"
SIDECAR_FORMAT = "rebarlib-segmentation/1"


# ---------------------------------------------------------------------------------------------
# Metrics (method.md, "Segmentation metrics", paper §2.3)


def confusion_counts(pred, truth, *, region=None) -> dict:
    """Pixel confusion counts of a predicted rebar mask against the true one.

    Parameters
    ----------
    pred, truth : (H, W) bool (anything non-zero is rebar)
    region : (H, W) bool, optional; count only these pixels (e.g. the shadow subset)

    Returns
    -------
    dict with int ``TP``, ``FP``, ``FN``, ``TN``. Counts of several images add up (sum the dicts
    key by key) to give data-set metrics, as the paper's tables do.

    Examples
    --------
    >>> confusion_counts([[1, 1, 0, 0]], [[1, 0, 1, 0]])
    {'TP': 1, 'FP': 1, 'FN': 1, 'TN': 1}
    """
    p = np.asarray(pred).astype(bool)
    t = np.asarray(truth).astype(bool)
    if p.shape != t.shape:
        raise RebarInputError(f"pred: expected the shape of truth {t.shape}, got {p.shape}")
    if region is not None:
        r = np.asarray(region).astype(bool)
        if r.shape != t.shape:
            raise RebarInputError(f"region: expected the shape of truth {t.shape}, got {r.shape}")
        p, t = p[r], t[r]
    tp = int(np.count_nonzero(p & t))
    fp = int(np.count_nonzero(p & ~t))
    fn = int(np.count_nonzero(~p & t))
    return {"TP": tp, "FP": fp, "FN": fn, "TN": int(p.size) - tp - fp - fn}


def _counts(pred_or_counts, truth):
    if truth is None:
        c = pred_or_counts
        if not isinstance(c, dict) or not {"TP", "FP", "FN", "TN"} <= set(c):
            raise RebarInputError("pred: expected a mask with truth, or a dict with TP, FP, FN, TN")
        return c
    return confusion_counts(pred_or_counts, truth)


def _ratio(num, den) -> float:
    # an empty denominator means the metric is undefined (e.g. no rebar in either mask)
    return float(num) / float(den) if den > 0 else float("nan")


def pixel_accuracy(pred, truth=None) -> float:
    """Pixel Accuracy = (TP + TN) / (TP + TN + FP + FN), in [0, 1].

    ``pred`` is a mask (with ``truth``) or a :func:`confusion_counts` dict (without).

    Examples
    --------
    >>> pixel_accuracy({"TP": 2, "FP": 1, "FN": 1, "TN": 6})
    0.8
    """
    c = _counts(pred, truth)
    return _ratio(c["TP"] + c["TN"], c["TP"] + c["TN"] + c["FP"] + c["FN"])


def iou(pred, truth=None) -> float:
    """IoU of the rebar class = TP / (TP + FP + FN), in [0, 1]; NaN when both masks are empty.

    Examples
    --------
    >>> iou([[1, 1, 0, 0]], [[1, 0, 1, 0]])
    0.3333333333333333
    """
    c = _counts(pred, truth)
    return _ratio(c["TP"], c["TP"] + c["FP"] + c["FN"])


def dice(pred, truth=None) -> float:
    """Dice of the rebar class = 2 TP / (2 TP + FP + FN), in [0, 1]; NaN when both are empty.

    Examples
    --------
    >>> dice({"TP": 2, "FP": 1, "FN": 1, "TN": 6})
    0.6666666666666666
    """
    c = _counts(pred, truth)
    return _ratio(2 * c["TP"], 2 * c["TP"] + c["FP"] + c["FN"])


# ---------------------------------------------------------------------------------------------
# ONNX models described by a sidecar JSON

_LAYOUTS = ("NCHW", "NHWC")
_DTYPES = {"float32": ("tensor(float)", np.float32), "uint8": ("tensor(uint8)", np.uint8),
           "float16": ("tensor(float16)", np.float16)}
_KINDS = ("logits", "probability", "labels")
_FLIPS = ("h", "v", "hv")  # test-time flips: horizontal, vertical, both


def _bad(path, problem):
    return RebarInputError(f"{path}: {problem}")


def _read_sidecar(path: Path) -> dict:
    if not path.is_file():
        raise _bad(path, "sidecar JSON not found (expected next to the ONNX file, same name, .json; "
                         "docs/formats.md lists its keys)")
    try:
        spec = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise _bad(path, f"not valid JSON ({e})") from None
    if not isinstance(spec, dict) or not isinstance(spec.get("input"), dict) \
            or not isinstance(spec.get("output"), dict):
        raise _bad(path, "expected a JSON object with 'input' and 'output' objects")
    inp, out = dict(spec["input"]), dict(spec["output"])
    size = inp.get("size")
    if size is not None:
        if not (isinstance(size, list) and len(size) == 2 and all(isinstance(v, int) and v > 0 for v in size)):
            raise _bad(path, f"input.size: expected [width, height] in pixels, got {size!r}")
    scale = inp.get("scale", 1.0)
    if not isinstance(scale, (int, float)) or not 0 < scale <= 4:
        raise _bad(path, f"input.scale: expected a number in (0, 4], got {scale!r}")
    pad_to = inp.get("pad_to", 1)
    if not isinstance(pad_to, int) or pad_to < 1:
        raise _bad(path, f"input.pad_to: expected a positive integer, got {pad_to!r}")
    order = inp.get("channel_order", "RGB")
    if order not in ("RGB", "BGR"):
        raise _bad(path, f"input.channel_order: expected 'RGB' or 'BGR', got {order!r}")
    layout = inp.get("layout", "NCHW")
    if layout not in _LAYOUTS:
        raise _bad(path, f"input.layout: expected one of {_LAYOUTS}, got {layout!r}")
    dtype = inp.get("dtype", "float32")
    if dtype not in _DTYPES:
        raise _bad(path, f"input.dtype: expected one of {tuple(_DTYPES)}, got {dtype!r}")
    for key, default in (("mean", [0.0, 0.0, 0.0]), ("std", [1.0, 1.0, 1.0])):
        v = inp.get(key, default)
        if not (isinstance(v, list) and len(v) == 3 and all(isinstance(x, (int, float)) for x in v)):
            raise _bad(path, f"input.{key}: expected 3 numbers (0-255 units, in channel_order), got {v!r}")
        if key == "std" and min(v) <= 0:
            raise _bad(path, f"input.std: expected positive numbers, got {v!r}")
        inp[key] = [float(x) for x in v]
    value_scale = inp.get("value_scale", 1.0)
    if not isinstance(value_scale, (int, float)) or value_scale <= 0:
        raise _bad(path, f"input.value_scale: expected a positive number, got {value_scale!r}")
    flips = inp.get("flips", [])
    if not (isinstance(flips, list) and all(f in _FLIPS for f in flips) and len(set(flips)) == len(flips)):
        raise _bad(path, f"input.flips: expected a list of distinct flips from {_FLIPS}, got {flips!r}")
    max_bar_px = inp.get("max_bar_px")
    if max_bar_px is not None and (isinstance(max_bar_px, bool) or not isinstance(max_bar_px, (int, float))
                                   or max_bar_px <= 0):
        raise _bad(path, f"input.max_bar_px: expected a positive number of input pixels, got {max_bar_px!r}")
    inp.update(size=size, scale=float(scale), pad_to=pad_to, channel_order=order, layout=layout,
               dtype=dtype, value_scale=float(value_scale), flips=list(flips),
               max_bar_px=None if max_bar_px is None else float(max_bar_px))
    kind = out.get("kind")
    if kind not in _KINDS:
        raise _bad(path, f"output.kind: expected one of {_KINDS}, got {kind!r}")
    if flips and kind == "labels":
        raise _bad(path, "input.flips: a label-map output cannot be averaged over flips; use logits or probability")
    classes = out.get("rebar_classes", [1] if kind != "probability" else [0])
    if not (isinstance(classes, list) and classes and all(isinstance(c, int) and c >= 0 for c in classes)):
        raise _bad(path, f"output.rebar_classes: expected a non-empty list of class indices, got {classes!r}")
    thr = out.get("threshold", 0.5)
    if not isinstance(thr, (int, float)) or not 0 < thr < 1:
        raise _bad(path, f"output.threshold: expected a probability in (0, 1), got {thr!r}")
    out_layout = out.get("layout", "NCHW")
    if out_layout not in _LAYOUTS:
        raise _bad(path, f"output.layout: expected one of {_LAYOUTS}, got {out_layout!r}")
    out.update(kind=kind, rebar_classes=classes, threshold=float(thr), layout=out_layout)
    return {**spec, "input": inp, "output": out}


class SegmentationModel:
    """An ONNX rebar segmentation network and the sidecar JSON that says how to use it.

    Parameters
    ----------
    onnx_path : path of the ``.onnx`` file
    sidecar_json_path : path of the sidecar; default: next to the model, same name, ``.json``
    threads : onnxruntime intra-op threads (default: onnxruntime's choice)

    Notes
    -----
    The sidecar (docs/formats.md, "Segmentation model sidecar", lists every key)::

        {"input":  {"size": [640, 400], "channel_order": "RGB", "mean": [...], "std": [...],
                    "layout": "NCHW", "dtype": "float32"},
         "output": {"kind": "logits", "rebar_classes": [0], "threshold": 0.5}}

    A missing, unreadable or inconsistent model or sidecar raises
    :class:`~rebarlib.RebarInputError` naming the file and the problem.

    Examples
    --------
    >>> model = SegmentationModel.default()
    >>> model.predict_mask(np.zeros((40, 64, 3), np.uint8)).shape
    (40, 64)
    """

    def __init__(self, onnx_path, sidecar_json_path=None, *, threads: int | None = None):
        self.onnx_path = Path(onnx_path)
        if not self.onnx_path.is_file():
            raise _bad(self.onnx_path, "ONNX model file not found")
        self.sidecar_path = Path(sidecar_json_path) if sidecar_json_path is not None \
            else self.onnx_path.with_suffix(".json")
        spec = _read_sidecar(self.sidecar_path)
        self.spec = spec
        self._inp, self._out = spec["input"], spec["output"]

        import onnxruntime as ort

        so = ort.SessionOptions()
        if threads is not None:
            so.intra_op_num_threads = int(threads)
            so.inter_op_num_threads = 1
        so.log_severity_level = 3
        # the session's threads sleep between runs instead of spinning: spinning threads burn a
        # core while the rest of inspect() runs and, with other processes on the machine (a
        # batch's workers), take it from them; the numbers computed are the same either way
        so.add_session_config_entry("session.intra_op.allow_spinning", "0")
        try:
            self._session = ort.InferenceSession(str(self.onnx_path), so, providers=["CPUExecutionProvider"])
        except Exception as e:  # onnxruntime raises its own exception types for unreadable models
            raise _bad(self.onnx_path, f"not a valid ONNX model ({type(e).__name__}: {str(e)[:200]})") from None
        self._check_io()

    @classmethod
    def default(cls, *, threads: int | None = None) -> "SegmentationModel":
        """The model shipped with rebarlib (``rebarlib/models/rebar_seg.onnx`` + ``.json``)."""
        return cls(MODELS_DIR / f"{DEFAULT_MODEL}.onnx", threads=threads)

    def __repr__(self):
        return f"SegmentationModel({str(self.onnx_path)!r})"

    @property
    def threshold(self) -> float:
        """Probability above which a pixel is rebar (``output.threshold``; 0.5 for label maps)."""
        return 0.5 if self._out["kind"] == "labels" else self._out["threshold"]

    # ---- consistency of the sidecar with the graph
    def _check_io(self):
        where = f"{self.onnx_path} with {self.sidecar_path.name}"
        inputs = self._session.get_inputs()
        names = [i.name for i in inputs]
        name = self._inp.get("name") or names[0]
        if name not in names:
            raise RebarInputError(f"{where}: input.name {name!r} is not an input of the model (it has {names})")
        if len(inputs) != 1:
            raise RebarInputError(f"{where}: expected a model with one image input, it has {names}")
        node = inputs[0]
        want_type, self._np_dtype = _DTYPES[self._inp["dtype"]]
        if node.type != want_type:
            raise RebarInputError(f"{where}: input.dtype {self._inp['dtype']!r} does not match the "
                                  f"model's input type {node.type}")
        shape = node.shape
        if len(shape) != 4:
            raise RebarInputError(f"{where}: expected a 4-D image input ({self._inp['layout']}), "
                                  f"the model's input has shape {shape}")
        c_axis, h_axis, w_axis = (1, 2, 3) if self._inp["layout"] == "NCHW" else (3, 1, 2)
        if isinstance(shape[c_axis], int) and shape[c_axis] != 3:
            raise RebarInputError(f"{where}: input.layout {self._inp['layout']!r} puts the colour "
                                  f"channels on axis {c_axis}, but the model's input shape is {shape}")
        fixed = [shape[h_axis], shape[w_axis]]
        size = self._inp["size"]
        if all(isinstance(v, int) for v in fixed):
            if size is None:
                raise RebarInputError(f"{where}: the model takes a fixed {fixed[1]} x {fixed[0]} image; "
                                      f"set input.size to [{fixed[1]}, {fixed[0]}]")
            if [size[1], size[0]] != fixed:
                raise RebarInputError(f"{where}: input.size {size} (width, height) does not match the "
                                      f"model's input shape {shape}")
        self._input_name = name
        outputs = self._session.get_outputs()
        onames = [o.name for o in outputs]
        oname = self._out.get("name") or onames[0]
        if oname not in onames:
            raise RebarInputError(f"{where}: output.name {oname!r} is not an output of the model (it has {onames})")
        self._output_name = oname
        oshape = next(o.shape for o in outputs if o.name == oname)
        if self._out["kind"] == "labels":
            if len(oshape) not in (3, 4):
                raise RebarInputError(f"{where}: output.kind 'labels' expects an (N, H, W) label map, "
                                      f"the model's output has shape {oshape}")
        else:
            if len(oshape) not in (3, 4):
                raise RebarInputError(f"{where}: output.kind {self._out['kind']!r} expects an "
                                      f"(N, C, H, W) or (N, H, W) output, the model's has shape {oshape}")
            n_cls = None
            if len(oshape) == 4:
                ax = 1 if self._out["layout"] == "NCHW" else 3
                n_cls = oshape[ax] if isinstance(oshape[ax], int) else None
            elif len(oshape) == 3:
                n_cls = 1
            if n_cls is not None:
                if self._out["kind"] == "probability" and n_cls != 1:
                    raise RebarInputError(f"{where}: output.kind 'probability' expects one channel, "
                                          f"the model's output has shape {oshape}")
                bad = [c for c in self._out["rebar_classes"] if c >= n_cls]
                if bad:
                    raise RebarInputError(f"{where}: output.rebar_classes {bad} out of range for "
                                          f"{n_cls} output channel(s) (shape {oshape})")

    # ---- inference
    def _prepare(self, color):
        import cv2

        img = np.asarray(color)
        if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
            raise RebarInputError(f"color: expected an (H, W, 3) uint8 RGB image, got "
                                  f"{img.shape} {img.dtype}")
        H, W = img.shape[:2]
        inp = self._inp
        if inp["size"] is not None:
            w, h = inp["size"]
        else:
            w, h = max(1, round(W * inp["scale"])), max(1, round(H * inp["scale"]))
        interp = cv2.INTER_AREA if w < W else cv2.INTER_LINEAR
        x = img if (w, h) == (W, H) else cv2.resize(img, (w, h), interpolation=interp)
        if inp["channel_order"] == "BGR":
            x = x[..., ::-1]
        p = inp["pad_to"]
        ph, pw = -h % p, -w % p
        if self._np_dtype == np.uint8:
            t = np.ascontiguousarray(x)
        else:
            mean = np.asarray(inp["mean"], np.float32)
            inv = 1.0 / np.asarray(inp["std"], np.float32)
            t = (x.astype(np.float32) * inp["value_scale"] - mean) * inv
        if ph or pw:
            t = np.pad(t, ((0, ph), (0, pw), (0, 0)))
        t = t.transpose(2, 0, 1)[None] if inp["layout"] == "NCHW" else t[None]
        return np.ascontiguousarray(t, dtype=self._np_dtype), (h, w), (h + ph, w + pw)

    def _score(self, color, flips: bool = True):
        """The rebar score map at full resolution and the threshold it is compared with."""
        import cv2

        H, W = np.asarray(color).shape[:2]
        t, (h, w), (hp, wp) = self._prepare(color)
        is_logit = False
        out = self._out
        run = lambda x: np.asarray(self._session.run([self._output_name], {self._input_name: x})[0])  # noqa: E731
        y = run(t)
        if flips and self._inp["flips"]:
            # test-time flips: the outputs (logits or probabilities) of the mirrored images,
            # mirrored back, are averaged with the plain one (a network's errors at edges differ
            # between an image and its mirror image, so the mean is closer to the truth)
            t_hw = (2, 3) if self._inp["layout"] == "NCHW" else (1, 2)
            y_hw = (2, 3) if y.ndim == 4 and out["layout"] == "NCHW" else (1, 2)
            axes = lambda hw, f: tuple(a for a, c in zip(hw, "vh") if c in f)  # noqa: E731
            acc = y.astype(np.float32)
            for f in self._inp["flips"]:
                acc += np.flip(run(np.ascontiguousarray(np.flip(t, axes(t_hw, f)))), axes(y_hw, f))
            y = acc / (1 + len(self._inp["flips"]))
        y = y[0]
        if out["kind"] == "labels":
            if y.ndim == 3:  # (1, H, W) or (H, W, 1)
                y = y.reshape(y.shape[-2:]) if y.shape[0] == 1 else y[..., 0]
            score = np.isin(y, out["rebar_classes"]).astype(np.float32)
            interp = cv2.INTER_NEAREST
            thr = 0.5
        else:
            if y.ndim == 3:
                y = y if out["layout"] == "NCHW" else y.transpose(2, 0, 1)
            else:
                y = y[None]
            y = y.astype(np.float32)
            interp = cv2.INTER_LINEAR
            if out["kind"] == "probability":
                score, thr = y[0], out["threshold"]
            elif y.shape[0] == 1:
                # one logit channel: resize the logit (smoother edges), compare with logit(thr)
                score, thr = y[0], math.log(out["threshold"] / (1 - out["threshold"]))
                is_logit = True
            else:
                e = np.exp(y - y.max(axis=0, keepdims=True))
                score = e[out["rebar_classes"]].sum(axis=0) / e.sum(axis=0)
                thr = out["threshold"]
        oh, ow = score.shape
        if (hp, wp) != (h, w):  # drop the padding, in output pixels
            score = score[:max(1, round(oh * h / hp)), :max(1, round(ow * w / wp))]
        if score.shape != (H, W):
            score = cv2.resize(np.ascontiguousarray(score), (W, H), interpolation=interp)
        return score, thr, is_logit

    def _untiled(self, W, H) -> bool:
        """Whether an image of W × H is scored whole rather than in tiles: the model has no
        fixed input size, or the image is no larger than the input or smaller than it in one
        direction."""
        size = self._inp["size"]
        return size is None or W < size[0] or H < size[1] or (W, H) == tuple(size)

    def tile_scale(self, bar_width_px=None, image_size=None) -> float:
        """The scale at which :meth:`predict_proba` with ``tiled`` runs the network on an image
        whose widest bar is ``bar_width_px`` pixels wide and whose size is ``image_size`` (W, H).

        Down (< 1) where that bar would be wider than the sidecar's ``input.max_bar_px`` (the
        widest bar the model is known to segment, in input pixels; none: no limit): the scale
        that makes it that wide. Up (> 1) where the image, larger than the network's fixed
        input, is smaller than twice that input in either direction: the tiles were designed
        and measured at twice the input (a 1280 × 800 image into a 640 × 400 input; the shipped
        network was trained on images at the input's size with crops enlarged up to twice), so
        a smaller image (an 848 × 480 camera's) is enlarged towards it, by the smaller of the
        two ratios, and never so far that the widest bar exceeds ``input.max_bar_px``: its bars'
        edges are then placed on a finer grid (docs/benchmarks.md, "Full-resolution tiles"). 1
        otherwise.
        """
        limit = self._inp["max_bar_px"]
        known = bar_width_px is not None and bool(np.isfinite(bar_width_px)) and bar_width_px > 0
        if known and limit is not None and bar_width_px > limit:
            return float(limit / bar_width_px)
        if image_size is None or self._untiled(*image_size):
            return 1.0
        (W, H), size = image_size, self._inp["size"]
        up = min(2 * size[0] / W, 2 * size[1] / H)
        if known and limit is not None:
            up = min(up, limit / bar_width_px)
        return float(max(up, 1.0))

    def _score_tiled(self, color, bar_width_px=None, flips: bool = True):
        """The score map of an image larger than the model's fixed input, from the network run
        on input-sized tiles of the image at full resolution, or at :meth:`tile_scale`: lower
        where its bars would be too wide for the model there (``bar_width_px``: the widest bar's
        width), higher where the image is smaller than twice the input.

        Tiles overlap by half a tile; where they overlap the scores are blended with weights
        that fall linearly to near 0 over the outer eighth of a tile on its sides inside the
        image (a network sees less context near a tile's border). Each tile gets the sidecar's
        test-time flips, as a whole image does (``flips``: False runs each tile once). Models
        without a fixed input size, and images that at that scale are no larger than the input
        or smaller than it in one direction, are scored as by :meth:`predict_proba` without
        tiles.
        """
        import cv2

        img = np.asarray(color)
        if img.ndim != 3:
            return self._score(color, flips)
        H0, W0 = img.shape[:2]
        scale = self.tile_scale(bar_width_px, (W0, H0))
        W, H = (W0, H0) if scale == 1.0 else (max(1, round(W0 * scale)), max(1, round(H0 * scale)))
        if self._untiled(W, H):
            return self._score(color, flips)
        if (W, H) != (W0, H0):
            # area averaging to shrink, bilinear to enlarge
            interp = cv2.INTER_AREA if scale < 1 else cv2.INTER_LINEAR
            img = cv2.resize(img, (W, H), interpolation=interp)
        tw, th = self._inp["size"]

        def starts(n, t):
            return sorted(set(range(0, n - t + 1, max(t // 2, 1))) | {n - t})

        def ramp(n, lo, hi):
            x = np.arange(n) + 0.5
            m = max(n / 8, 1.0)
            r = np.ones(n)
            if lo:
                r = np.minimum(r, x / m)
            if hi:
                r = np.minimum(r, (n - x) / m)
            return r

        acc = np.zeros((H, W), np.float64)
        wsum = np.zeros((H, W), np.float64)
        thr, is_logit = 0.5, False
        for y0 in starts(H, th):
            for x0 in starts(W, tw):
                tile, thr, is_logit = self._score(np.ascontiguousarray(img[y0:y0 + th, x0:x0 + tw]), flips)
                wgt = np.outer(ramp(th, y0 > 0, y0 + th < H), ramp(tw, x0 > 0, x0 + tw < W))
                acc[y0:y0 + th, x0:x0 + tw] += wgt * tile
                wsum[y0:y0 + th, x0:x0 + tw] += wgt
        score = (acc / wsum).astype(np.float32)
        if (W, H) != (W0, H0):
            score = cv2.resize(score, (W0, H0), interpolation=cv2.INTER_LINEAR)
        return score, thr, is_logit

    def predict_proba(self, color, *, tiled: bool = False, bar_width_px=None, flips: bool = True) -> np.ndarray:
        """Rebar probability per pixel, (H, W) float32 in [0, 1] at the image's resolution.

        Label-map models give 0 or 1. ``tiled``: for an image larger than the model's fixed
        input, run the network on input-sized tiles of the image at full resolution instead of
        on the whole image down-scaled to the input (finer edges, 9 tiles for a 1280 × 800 image
        into a 640 × 400 input; an 848 × 480 one is first enlarged 1.51 times, to 9 tiles: see
        :meth:`_score_tiled`); ``bar_width_px``, the widest bar's width in the image, lowers that
        resolution where the bars would otherwise be wider than the model knows, and caps the
        enlargement (:meth:`tile_scale`). ``flips``: the sidecar's test-time flips
        (``input.flips``), on the whole image or on every tile; False runs the network once per
        image or tile instead of once per flip and once more (the shipped model: 4 runs; faster,
        a less exact mask: docs/benchmarks.md, "Full-resolution tiles").
        """
        score, _, is_logit = (self._score_tiled(color, bar_width_px, flips) if tiled
                              else self._score(color, flips))
        if is_logit:
            return (1.0 / (1.0 + np.exp(-score))).astype(np.float32)
        return np.clip(score, 0, 1).astype(np.float32)

    def predict_mask(self, color) -> np.ndarray:
        """Binary rebar mask, (H, W) bool at the resolution of ``color`` ((H, W, 3) uint8 RGB)."""
        score, thr, _ = self._score(color)
        return score > thr


# ---------------------------------------------------------------------------------------------
# A mask from depth: what stands clearly above the formwork


def fit_formwork_plane(points_mm, *, distance_mm: float = 4.0, max_points: int = 30_000,
                       rng=None) -> tuple:
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
    from ._checks import check_points
    from ._cloud import ransac_plane

    pts = check_points(points_mm, "points_mm", min_count=3)
    rng = np.random.default_rng(rng)
    if len(pts) > max_points:
        pts = pts[rng.choice(len(pts), max_points, replace=False)]
    cand = pts
    normal, offset = None, None
    for _ in range(4):
        if len(cand) < 3:
            break
        (a, b, c, d), _ = ransac_plane(cand, threshold_mm=distance_mm, iterations=300,
                                       seed=int(rng.integers(2**31)))
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
    h[cloud.pixels[:, 1], cloud.pixels[:, 0]] = cloud.points @ np.asarray(n, float) + float(off)
    return h


def mask_from_depth(capture_or_depth, intrinsics: Intrinsics | None = None, *,
                    min_height_mm: float | None = None, max_height_mm: float = 400.0,
                    plane=None, open_px: int = 1, rng=None) -> np.ndarray:
    """Rebar pixels known from depth: points clearly above the formwork plane.

    Parameters
    ----------
    capture_or_depth : a :class:`~rebarlib.Capture`, or an (H, W) depth map in mm (0 = none)
    intrinsics : needed with a depth map
    min_height_mm : a pixel is a bar if its point is at least this far above the formwork;
        default ``max(6 mm, 4 sigma)`` with sigma the robust spread of the formwork's points
        (noise grows with distance, so the default adapts to the capture)
    max_height_mm : higher points are not rebar (a boot, a tool)
    plane : (normal, offset_mm) of the formwork if known, else fitted with
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


def estimate_registration(color_proba, depth_mask, *, depth_valid=None,
                          blur_px=(4.0, 2.0, 1.0)) -> tuple[float, float, float]:
    """How far the depth image's content lies from the colour image's, in pixels: (du, dv, cc)
    with ``depth(x + (du, dv)) ≈ colour(x)``, and the correlation coefficient reached.

    A camera's "aligned" depth is the depth re-projected into the colour camera with its factory
    calibration; what that leaves (a pixel or more, more after a knock or a re-mount) moves every
    bar's mask off the axes fitted to its depth: widths taken from one edge and the axis, the
    point cloud read across the mask's runs and the fused mask (which keeps colour pixels next to
    depth ones) all suffer. The bars' pixels seen by colour (the segmentation model's
    probability) and by depth (:func:`mask_from_depth`) are the same objects, so their
    translation is the misregistration: found by maximising their correlation coefficient
    (OpenCV's ECC, translation only), coarse to fine over Gaussian blurs of ``blur_px`` (the
    coarsest reaches a few pixels). Pixels without depth are left out.

    Measured on synthetic captures of two cameras (docs/benchmarks.md, "Colour-depth
    registration"): within
    0.3 px (0.7 px with three times the flying pixels) for whole-pixel shifts up to 4 px; within
    0.6 px where the colour is also moved by a fraction of a pixel (both masks aliased, as on
    synthetic images, pull the estimate toward whole pixels).

    Parameters
    ----------
    color_proba : (H, W) float rebar probability (or bool mask) from the colour image
    depth_mask : (H, W) bool, rebar pixels from depth
    depth_valid : (H, W) bool, where depth exists; default all
    blur_px : Gaussian σ (px) of each pass, coarse to fine

    Returns
    -------
    (du, dv, cc); NaN, NaN, NaN where the search fails (no bars, too little overlap).

    Examples
    --------
    >>> colour = np.zeros((60, 80)); colour[:, 20:30] = 1; colour[40:48, :] = 1
    >>> depth = np.roll(np.roll(colour, 2, axis=1), -1, axis=0) > 0.5  # 2 px right, 1 px up
    >>> du, dv, cc = estimate_registration(colour, depth)
    >>> round(du, 1), round(dv, 1)
    (2.0, -1.0)
    """
    import cv2

    a0 = np.asarray(color_proba, np.float32)
    b0 = np.asarray(depth_mask, np.float32)
    if a0.ndim != 2 or a0.shape != b0.shape:
        raise RebarInputError(f"depth_mask: expected the shape of color_proba {a0.shape}, got {b0.shape}")
    valid = np.ones(a0.shape, np.uint8) if depth_valid is None else np.asarray(depth_valid).astype(np.uint8)
    if valid.shape != a0.shape:
        raise RebarInputError(f"depth_valid: expected the shape of color_proba {a0.shape}, got {valid.shape}")
    fail = (math.nan, math.nan, math.nan)
    if not (b0.any() and (a0 > 0.5).any()):
        return fail
    warp = np.eye(2, 3, dtype=np.float32)
    cc = math.nan
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    for s in blur_px:
        a = cv2.GaussianBlur(a0, (0, 0), s)
        b = cv2.GaussianBlur(b0, (0, 0), s)
        try:
            cc, warp = cv2.findTransformECC(a, b, warp, cv2.MOTION_TRANSLATION, crit, valid, 1)
        except cv2.error:  # did not converge: the masks share too little
            return fail
    return float(warp[0, 2]), float(warp[1, 2]), float(cc)


def shift_image(image, du: float, dv: float) -> np.ndarray:
    """``image`` moved ``du`` pixels right and ``dv`` down (bilinear; the border's pixels repeat
    into what comes in from outside): ``out(x) = image(x − (du, dv))``. The input is not changed.

    Examples
    --------
    >>> shift_image(np.arange(5, dtype=np.float32)[None, :], 1.0, 0.0).tolist()
    [[0.0, 0.0, 1.0, 2.0, 3.0]]
    """
    import cv2

    img = np.asarray(image)
    h, w = img.shape[:2]
    m = np.float32([[1, 0, du], [0, 1, dv]])
    return cv2.warpAffine(img, m, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)


def _two_masks(color_mask, depth_mask):
    """(colour, depth) as bool arrays of one (H, W) shape, else an input error naming it."""
    c = np.asarray(color_mask).astype(bool)
    d = np.asarray(depth_mask).astype(bool)
    if c.shape != d.shape or c.ndim != 2:
        raise RebarInputError(f"depth_mask: expected the shape of color_mask {c.shape}, "
                              f"got {d.shape}")
    return c, d


def depth_overreach_px(color_mask, depth_mask, *, color_proba=None, low_proba: float = 0.2,
                       depth_valid=None, max_px: int = 6, min_pixels: int = 100) -> int:
    """How many pixels the depth's bars reach beyond the colour's, on most rows of every side.

    A stereo camera's matching window straddles a bar's edge and gives the background beside it
    the bar's depth (edge fattening, docs/sensors.md: "a few pixels"); flying pixels do so now
    and then. Ring ``j`` is the pixels ``j`` px (± 0.5) outside the colour mask that the colour
    calls background (probability under ``low_proba`` where ``color_proba`` is given), split by
    the side of the bar they lie on (left, right, above, below: the direction away from the
    colour mask). A side is read where at least ``min_pixels`` of its ring have depth and its
    share with depth is at least half the best side's (a side in the projector's shadow has
    few, and those few lie beside the shadow, where no fattening is). The over-reach is the
    largest ``j`` at which the depth marks at least half of the ring's pixels with depth as bar
    on every side read: beyond that, more than half of a bar's rows would be widened by the
    depth, and the median of its widths with them. Fattening widens a bar on every side; a
    depth image moved against the colour one (misregistration, :func:`estimate_registration`)
    reaches beyond some sides and falls short of the others. With three or four sides read,
    that shows in the rings. With two (one across each direction, the others in the shadow),
    a diagonal move would look the same, so the depth must also mark as bar at least half of
    the pixels 1 px inside the colour mask that have depth (where the colour is sure) on every
    side: a depth image moved away from a side leaves them to the formwork or the shadow. 0
    where half of ring 1 is not reached on a side read, or too few sides are read (a fattening
    now and then leaves a median where the colour puts it). Measured at 500 mm (ring 1, all
    sides together): 0.22 with the benchmark's default sensor (0), 0.63 with 3 px of stereo
    fattening (1), 0.43 with three times the flying pixels (0), 0.03 without edge effects (0).

    Examples
    --------
    >>> color = np.zeros((60, 60), bool); color[:, 25:35] = True; color[25:35, :] = True
    >>> depth = np.zeros((60, 60), bool); depth[:, 23:37] = True; depth[23:37, :] = True
    >>> depth_overreach_px(color, depth, min_pixels=10)   # 2 px wider on every side
    2
    >>> depth_overreach_px(color, np.roll(depth, 2, axis=1), min_pixels=10)   # moved, not wider
    0
    """
    import cv2

    c, d = _two_masks(color_mask, depth_mask)
    valid = np.ones_like(c) if depth_valid is None else np.asarray(depth_valid).astype(bool)
    p = np.where(c, 1.0, 0.0) if color_proba is None else np.asarray(color_proba, dtype=np.float32)
    if p.shape != c.shape or valid.shape != c.shape:
        raise RebarInputError(f"color_proba, depth_valid: expected the shape of color_mask "
                              f"{c.shape}, got {p.shape}, {valid.shape}")
    outside = cv2.distanceTransform((~c).astype(np.uint8), cv2.DIST_L2, 5)
    inside = cv2.distanceTransform(c.astype(np.uint8), cv2.DIST_L2, 5)
    signed = outside - inside  # grows away from the colour mask, across its edges too
    gx = cv2.Sobel(signed, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(signed, cv2.CV_32F, 0, 1, ksize=3)
    horiz = np.abs(gx) >= np.abs(gy)
    sides = (horiz & (gx > 0), horiz & (gx < 0), ~horiz & (gy > 0), ~horiz & (gy < 0))
    rim = (inside > 0.5) & (inside <= 1.5) & (p > 1 - low_proba) & valid
    rim_n = [int((rim & s).sum()) for s in sides]
    rim_held = all(n < min_pixels or 2 * int((rim & s & d).sum()) >= n
                   for s, n in zip(sides, rim_n))
    reach = 0
    for j in range(1, max_px + 1):
        ring = (outside > j - 0.5) & (outside <= j + 0.5) & (p < low_proba)
        with_depth = [ring & s & valid for s in sides]
        n = np.array([int((ring & s).sum()) for s in sides])
        nv = np.array([int(w.sum()) for w in with_depth])
        share = nv / np.maximum(n, 1)
        read = (nv >= min_pixels) & (share >= 0.5 * share.max())
        # one side read across each direction at least (so two or more)
        if not (read[:2].any() and read[2:].any()) or (read.sum() == 2 and not rim_held):
            break
        if min(float(d[w].mean()) for w, r in zip(with_depth, read) if r) < 0.5:
            break
        reach = j
    return reach


def trim_depth_overreach(color_mask, depth_mask, overreach_px: int) -> np.ndarray:
    """The depth mask without its over-reach (:func:`depth_overreach_px`): its parts outside the
    colour mask thinner than ``2 * overreach_px + 1`` px (a morphological opening) are left out,
    the fattening along edges the colour places; parts as thick as a bar (one the colour missed)
    stay. ``overreach_px`` 0: the depth mask as it is (a copy).

    Examples
    --------
    >>> color = np.zeros((1, 12), bool); color[0, 4:7] = True
    >>> depth = np.zeros((1, 12), bool); depth[0, 3:8] = True
    >>> trim_depth_overreach(color[[0] * 5], depth[[0] * 5], 1)[2].astype(int).tolist()
    [0, 0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0]
    """
    import cv2

    c, d = _two_masks(color_mask, depth_mask)
    if overreach_px <= 0:
        return d.copy()
    k = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * overreach_px + 1, 2 * overreach_px + 1))
    return (d & c) | cv2.morphologyEx((d & ~c).astype(np.uint8), cv2.MORPH_OPEN, k).astype(bool)


def fuse_masks(color_mask, depth_mask, *, color_proba=None, low_proba: float = 0.2,
               depth_valid=None, support_px: int | None = None,
               min_fill_px: int | None = None, overreach_px: int | None = None) -> np.ndarray:
    """Combine a colour mask (sharp edges) with a depth mask (presence that light cannot fool).

    1. A colour pixel is kept if depth marks a bar within ``support_px`` of it, or if the pixel
       has no depth (holes, projector shadow: no evidence against it). This removes shadow
       lines, stains and marks on flat formwork that look like bars.
    2. With ``color_proba``, a pixel next to depth-confirmed bar is also taken at the lower
       threshold ``low_proba`` (hysteresis): bar edges in shadow or under rust, where the network
       is unsure, come back with the network's edge position.
    3. Depth regions the colour missed are added (components of at least ``min_fill_px``
       pixels): bars in deep shadow, dark rust on dark board.

    Parameters
    ----------
    color_mask, depth_mask : (H, W) bool
    color_proba : (H, W) float rebar probability of the colour model, optional
    low_proba : probability enough for a pixel that depth supports
    depth_valid : (H, W) bool, where depth exists (e.g. ``capture.depth_mm > 0``); default all
    support_px : how far depth evidence reaches, px; default 1 px per 1280 px of width
        (measured best on the validation captures; more lets shadows next to bars back in)
    min_fill_px : smallest depth-only region added, px; default 1 (every depth pixel: on the
        validation captures any larger value lost IoU; raise it for a sensor with specks)
    overreach_px : how far the depth's bars reach beyond the colour's edges on most rows
        (edge fattening); default :func:`depth_overreach_px` of the two masks. Where it is
        above 0 the depth mask loses that over-reach first (:func:`trim_depth_overreach`): the
        depth's fattening along edges the colour places would widen every bar by it.

    Returns
    -------
    (H, W) bool

    Examples
    --------
    >>> color = np.zeros((6, 12), bool); color[:, 2:4] = True; color[:, 8] = True  # 8: a shadow line
    >>> depth = np.zeros((6, 12), bool); depth[:, 2:4] = True; depth[:, 10:12] = True  # 10-11: missed
    >>> fuse_masks(color, depth, min_fill_px=4)[0].astype(int).tolist()
    [0, 0, 1, 1, 0, 0, 0, 0, 0, 0, 1, 1]
    """
    import cv2

    c, d = _two_masks(color_mask, depth_mask)
    H, W = c.shape
    scale = W / 1280.0
    if support_px is None:
        support_px = max(1, round(scale))
    if min_fill_px is None:
        min_fill_px = 1
    valid = np.ones_like(c) if depth_valid is None else np.asarray(depth_valid).astype(bool)
    if valid.shape != c.shape:
        raise RebarInputError(f"depth_valid: expected the shape of color_mask {c.shape}, got {valid.shape}")
    if color_proba is not None and np.shape(color_proba) != c.shape:
        raise RebarInputError(f"color_proba: expected the shape of color_mask {c.shape}, "
                              f"got {np.shape(color_proba)}")
    if overreach_px is None:
        overreach_px = depth_overreach_px(c, d, color_proba=color_proba, low_proba=low_proba,
                                          depth_valid=valid)
    d = trim_depth_overreach(c, d, overreach_px)
    if support_px > 0:
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * support_px + 1, 2 * support_px + 1))
        near_bar = cv2.dilate(d.astype(np.uint8), k).astype(bool)
    else:
        near_bar = d
    kept = c & (near_bar | ~valid)
    if color_proba is not None:
        kept |= (np.asarray(color_proba, dtype=np.float32) > low_proba) & near_bar
    missed = d & ~kept
    n, lab, stats, _ = cv2.connectedComponentsWithStats(missed.astype(np.uint8), connectivity=8)
    big = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] >= min_fill_px)
    big = big[big > 0]
    if len(big):
        kept |= np.isin(lab, big)
    return kept


def soft_mask(mask, proba, *, threshold: float = 0.5) -> np.ndarray:
    """A binary mask made soft again: the model's probability where the two agree, 1 / 0 where
    the mask overrides the model (pixels ``fuse_masks`` added from depth or hysteresis, or
    removed as shadow lines).

    The diameter stage finds a bar's edges where its profile crosses 0.5: on a binary mask that
    is always half-way between two pixel centres, on the probability it is sub-pixel, so widths
    of bars lying along the pixel grid lose the half-pixel rounding of each edge.

    Parameters
    ----------
    mask : (H, W) bool, e.g. from :func:`fuse_masks`
    proba : (H, W) float rebar probability of the colour model (``predict_proba``)
    threshold : the model's threshold (``SegmentationModel.threshold``): the probability is
        rescaled piecewise-linearly so that it lies at 0.5

    Returns
    -------
    (H, W) float32 in 0..1, ``>= 0.5`` exactly where ``mask`` is True

    Examples
    --------
    >>> soft_mask(np.array([[True, True, False, False]]), np.array([[0.9, 0.3, 0.7, 0.1]])).tolist()
    [[0.8999999761581421, 1.0, 0.0, 0.10000000149011612]]
    """
    m = np.asarray(mask).astype(bool)
    p = np.asarray(proba, dtype=np.float32)
    if p.shape != m.shape or m.ndim != 2:
        raise RebarInputError(f"proba: expected the shape of mask {m.shape}, got {p.shape}")
    if not 0 < threshold < 1:
        raise RebarInputError(f"threshold: expected a probability strictly between 0 and 1, got {threshold!r}")
    p = np.nan_to_num(np.clip(p, 0, 1), nan=0.0)
    if threshold != 0.5:
        p = np.where(p < threshold, 0.5 * p / threshold, 0.5 + 0.5 * (p - threshold) / (1 - threshold))
    return np.where(m, np.where(p >= 0.5, p, 1.0), np.where(p >= 0.5, 0.0, p)).astype(np.float32)


# ---------------------------------------------------------------------------------------------
# Synthetic data for training and evaluating segmentation models

#: The recipe of the shipped model's data set: capture ``i`` of the set is
#: ``synth_segmentation_capture(i, seed=DATASET_SEED)``; the 6:2:2 split is ``split_indices``.
DATASET_SEED = 20240611
DATASET_SIZE = 300


def segmentation_scene_params(index: int, *, seed: int = DATASET_SEED) -> dict:
    """The randomised design, pose, deviations and appearance of capture ``index`` of a data set.

    Everything is drawn from ``numpy.random.default_rng([seed, index])``, so a data set is
    regenerated exactly from ``(seed, index)`` at any resolution.

    Examples
    --------
    >>> p = segmentation_scene_params(3)
    >>> 350 <= p["height_mm"] <= 700 and 0 <= p["tilt_deg"] <= 20
    True
    """
    from .synth import rib_envelope_mm

    rng = np.random.default_rng([int(seed), int(index)])
    sizes = (8, 10, 12, 14, 16, 18, 20)
    d_lo, d_up = (int(rng.choice(sizes)) for _ in range(2))
    s_lo, s_up = (float(10 * round(rng.uniform(100, 250) / 10)) for _ in range(2))
    cover = float(round(rng.uniform(15, 50)))
    layer = float(round(2 * rib_envelope_mm(d_lo) + rng.uniform(10, 90)))
    design = {"slab": {"id": f"SEG-{seed}-{index}"},
              "design": {"cover_mm": cover, "layer_distance_mm": layer,
                         "lower": {"diameter_mm": d_lo, "spacing_mm": s_lo},
                         "upper": {"diameter_mm": d_up, "spacing_mm": s_up}}}
    deviations = dict(position_sigma_mm=float(rng.uniform(0, 6)), height_sigma_mm=float(rng.uniform(0, 2)),
                      bow_mm=float(rng.uniform(0, 10)), mesh_yaw_deg=float(rng.uniform(-45, 45)),
                      missing=int(rng.integers(0, 3)), wrong_size=int(rng.integers(0, 2)))
    rusty = rng.random() < 0.5
    appearance = dict(
        formwork=str(rng.choice(["plywood", "film", "plastic"])),
        rust_fraction=float(rng.uniform(0.3, 1.0)) if rusty else 0.0,
        sun_elevation_deg=float(rng.uniform(20, 85)), sun_azimuth_deg=float(rng.uniform(0, 360)),
        ambient=float(rng.uniform(0.15, 0.6)), exposure=float(rng.uniform(0.6, 1.4)),
        noise_sigma=float(rng.uniform(1.0, 6.0)),
        blur_px=float(rng.uniform(0.0, 1.2)) if rng.random() < 0.5 else 0.0,
        jpeg_quality=int(rng.integers(50, 96)) if rng.random() < 0.5 else None)
    return {"design": design, "height_mm": float(rng.uniform(350, 700)),
            "tilt_deg": float(rng.uniform(0, 20)), "yaw_deg": float(rng.uniform(0, 360)),
            "target_mm": (float(rng.uniform(-300, 300)), float(rng.uniform(-300, 300))),
            "deviations": deviations, "appearance": appearance,
            "render_seed": int(rng.integers(2**31))}


def synth_segmentation_capture(index: int, *, seed: int = DATASET_SEED, intrinsics=None,
                               sensor=None, rib_relief: bool = False):
    """Render capture ``index`` of the segmentation data set (see :func:`segmentation_scene_params`).

    Parameters
    ----------
    index : which capture of the set
    seed : the data set's seed
    intrinsics : camera (default GEMINI2, 1280 x 800); ``GEMINI2.scaled(0.5)`` renders the same
        scene at 640 x 400
    sensor : depth sensor model (default: the realistic ``SensorModel()``)
    rib_relief : draw the bars' ribs in relief (core, longitudinal and crescent transverse ribs,
        ``synth.Deviations.rib_relief``) instead of as their smooth envelope: the same scene
        otherwise, so a capture can be had both ways

    Returns
    -------
    Capture with ``labels`` (rebar = ``labels > 0``) and ``metadata["truth"]``.
    """
    from ._camera import GEMINI2
    from ._design import design_from_dict
    from .synth import Appearance, Deviations, synth_capture

    p = segmentation_scene_params(index, seed=seed)
    return synth_capture(design_from_dict(p["design"], source="segmentation data set"),
                         height_mm=p["height_mm"], tilt_deg=p["tilt_deg"], yaw_deg=p["yaw_deg"],
                         target_mm=p["target_mm"],
                         deviations=Deviations(**p["deviations"], rib_relief=bool(rib_relief)),
                         sensor=sensor, appearance=Appearance(**p["appearance"]),
                         intrinsics=intrinsics or GEMINI2, seed=p["render_seed"],
                         name=f"seg-{seed}-{index}" + ("-relief" if rib_relief else ""))


def split_indices(n: int = DATASET_SIZE, *, seed: int = DATASET_SEED) -> dict:
    """Split capture indices ``0..n-1`` 6:2:2 into train / val / test, by capture, seeded.

    Examples
    --------
    >>> s = split_indices(10, seed=1)
    >>> [len(s[k]) for k in ("train", "val", "test")]
    [6, 2, 2]
    """
    perm = np.random.default_rng([int(seed), 622]).permutation(int(n))
    n_train, n_val = int(round(0.6 * n)), int(round(0.2 * n))
    return {"train": np.sort(perm[:n_train]), "val": np.sort(perm[n_train:n_train + n_val]),
            "test": np.sort(perm[n_train + n_val:])}


def synth_eval_regions(index: int, capture, *, seed: int = DATASET_SEED, margin_px: int | None = None,
                       rib_relief: bool = False) -> dict:
    """The hard-case subsets of a data-set capture, for the shadow / rust breakdown.

    * ``shadow`` (bars in shadow, the paper's hard case): bar pixels that lie in a *cast* shadow
      (sunlight blocked by another bar, a chair or a spacer), grown by ``margin_px`` so that
      false positives around them count too.
    * ``unlit``: every pixel that receives no direct sunlight, bar and formwork alike: cast
      shadows plus the *attached* shadow of every bar (its half facing away from the sun). A
      harder, edge-dominated subset: the dark side of every bar lies along its edge (about twice
      the edge share of the bar pixels overall, ``benchmarks/edge_sensitivity.py``), so it scores
      the edge placement on the dark side rather than bars in shadow. Reported beside ``shadow``.
    * ``rust``: pixels of bars with ``truth rust > 0``, grown by ``margin_px``.

    ``margin_px`` defaults to 3 px per 1280 px of width. Unlit pixels are found by rendering the
    same scene again with no ambient light and no noise (they come out exactly black); attached
    shadow by rendering it once more without cast shadows. Metrics on a subset count only its
    pixels (``confusion_counts(..., region=...)``).

    Parameters
    ----------
    index, seed : the capture of the data set (see :func:`synth_segmentation_capture`)
    capture : that capture, as rendered (gives the resolution and the bar ids)
    rib_relief : as the capture was rendered (:func:`synth_segmentation_capture`)
    """
    import cv2
    from dataclasses import replace

    from ._design import design_from_dict
    from .synth import Appearance, Deviations, SensorModel, synth_capture

    p = segmentation_scene_params(index, seed=seed)
    app = Appearance(**p["appearance"])

    def black(cast_shadows):
        dark = replace(app, ambient=0.0, exposure=1.0, noise_sigma=0.0, blur_px=0.0, jpeg_quality=None,
                       cast_shadows=cast_shadows)
        ref = synth_capture(design_from_dict(p["design"], source="segmentation data set"),
                            height_mm=p["height_mm"], tilt_deg=p["tilt_deg"], yaw_deg=p["yaw_deg"],
                            target_mm=p["target_mm"],
                            deviations=Deviations(**p["deviations"], rib_relief=bool(rib_relief)),
                            sensor=SensorModel.ideal(), appearance=dark, intrinsics=capture.intrinsics,
                            seed=p["render_seed"])
        return ref.color.max(axis=2) == 0

    margin = margin_px if margin_px is not None else max(1, round(3 * capture.intrinsics.width / 1280))
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * margin + 1, 2 * margin + 1))

    def grow(mask):
        return cv2.dilate(mask.astype(np.uint8), kernel).astype(bool) if margin > 0 and mask.any() else mask

    unlit = black(True)
    cast = unlit & ~black(False)
    rusty = [b["id"] + 1 for b in capture.truth["bars"] if b["rust"] > 0]
    return {"shadow": grow(cast & (capture.bar_ids > 0)), "unlit": unlit,
            "rust": grow(np.isin(capture.bar_ids, rusty))}
