"""The ONNX segmentation model: run any network that a sidecar JSON describes (the model contract).

:meth:`SegmentationModel.default` loads the model shipped in ``rebarlib/models`` (trained on
synthetic captures by ``training/train_segmentation.py``). The runtime never imports torch.
"""

from __future__ import annotations

import math
import os
import threading
from pathlib import Path

import numpy as np

from .._checks import RebarInputError
from .sidecar import _DTYPES, _bad, read_sidecar

__all__ = ["SegmentationModel", "MODELS_DIR", "DEFAULT_MODEL"]


def _cores() -> int:
    """The cores this process may run on."""
    try:
        return max(1, len(os.sched_getaffinity(0)))
    except AttributeError:  # pragma: no cover - not Linux
        return max(1, os.cpu_count() or 1)


def _rgb(color) -> np.ndarray:
    """``color`` as an array, checked to be an (H, W, 3) uint8 image."""
    img = np.asarray(color)
    if img.ndim != 3 or img.shape[2] != 3 or img.dtype != np.uint8:
        raise RebarInputError(f"color: expected an (H, W, 3) uint8 RGB image, got {img.shape} {img.dtype}")
    return img


def _channel_block() -> int | None:
    """The channel block of onnxruntime's blocked ("NCHWc") convolutions on this CPU: 16 with
    AVX-512, 8 with AVX2; None elsewhere (another architecture, or flags not readable)."""
    import platform

    if platform.machine().lower() not in ("x86_64", "amd64"):
        return None
    try:
        with open("/proc/cpuinfo") as f:
            flags = next((line.split(":", 1)[1].split() for line in f if line.startswith("flags")), [])
    except OSError:
        return None
    return 16 if "avx512f" in flags else 8 if "avx2" in flags else None


MODELS_DIR = Path(__file__).resolve().parent.parent / "models"
DEFAULT_MODEL = "rebar_seg"


def _sigmoid(x):
    """The probability of a logit ``x`` (in ``x``'s float type)."""
    return 1.0 / (1.0 + np.exp(-x))


class SegmentationModel:
    """An ONNX rebar segmentation network and the sidecar JSON that says how to use it.

    Parameters
    ----------
    onnx_path : path of the ``.onnx`` file
    sidecar_json_path : path of the sidecar; default: next to the model, same name, ``.json``
    threads : onnxruntime intra-op threads (default: onnxruntime's choice). By default, the
        several runs of one image or tile (its test-time flips) run at once instead, one per
        core, each on one thread: the same numbers as one run after the other, with less CPU
        time than each run split over the cores (docs/batch.md, "Speed")

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
        self.sidecar_path = (
            Path(sidecar_json_path) if sidecar_json_path is not None else self.onnx_path.with_suffix(".json")
        )
        spec = read_sidecar(self.sidecar_path)
        self.spec = spec
        self._inp, self._out = spec["input"], spec["output"]
        self._lut = None  # the normalisation of each channel's 256 values (float32 models), made at first use

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
        self._graph = str(self.onnx_path)  # what the sessions load: the file, or its blocked variant
        try:
            self._session = ort.InferenceSession(self._graph, so, providers=["CPUExecutionProvider"])
        except Exception as e:  # onnxruntime raises its own exception types for unreadable models
            raise _bad(self.onnx_path, f"not a valid ONNX model ({type(e).__name__}: {str(e)[:200]})") from None
        self._check_io()
        if self.pad_layout:
            self._pad_layout(so)
        # several runs at once (threads=None): a one-thread session and a thread per core, made
        # at the first image with more than one run
        self._parallel = _cores() if threads is None else 1
        self._pool, self._pool_session, self._pool_lock, self._pool_pid = None, None, threading.Lock(), None

    #: Run the graph with its channel concatenations padded to onnxruntime's channel blocks
    #: where that gives the same numbers (:meth:`_pad_layout`); False: the file's graph as it is
    pad_layout = True

    def _pad_layout(self, so):
        """Run the sessions on the model's blocked variant where there is one for this CPU's
        channel block (``<stem>.blocked16.onnx`` beside the model file, written by
        ``training/pad_graph.py``: the graph with its channel concatenations padded to whole blocks
        of onnxruntime's blocked layout, AVX-512: 16) and where it gives the file's numbers to the
        bit on a probe input; otherwise keep the file's graph. About 15 % less CPU time per run of
        the stage-4 network (shipped until decision 051) on an AVX-512 CPU (docs/batch.md, "A
        fourth pass"); the network shipped now is padded in its own file (decision 056) and has no variant."""
        import onnxruntime as ort

        block = _channel_block()
        if block is None:
            return
        variant = self.onnx_path.with_name(f"{self.onnx_path.stem}.blocked{block}.onnx")
        if not variant.is_file():
            return
        try:
            session = ort.InferenceSession(str(variant), so, providers=["CPUExecutionProvider"])
        except Exception:  # the runtime refuses the variant: keep the file's graph
            return
        probe = self._probe_input()
        try:
            ref = self._run(self._session, probe)
            got = self._run(session, probe)
        except Exception:  # a graph that does not take the probe: keep the file's
            return
        if ref.shape == got.shape and ref.dtype == got.dtype and ref.tobytes() == got.tobytes():
            self._graph, self._session = str(variant), session

    @property
    def layout_padded(self) -> bool:
        """Whether the sessions run the model's blocked variant (its concatenations padded to
        whole channel blocks, :meth:`_pad_layout`): the same numbers, in less time."""
        return self._graph != str(self.onnx_path)

    def _probe_input(self):
        """A fixed pseudo-random input of the network's size (for a model without one, about
        256 x 256, a multiple of ``input.pad_to``), in its layout and type."""
        side = -(-256 // self._inp["pad_to"]) * self._inp["pad_to"]
        w, h = self._inp["size"] if self._inp["size"] is not None else (side, side)
        rng = np.random.default_rng(0)
        shape = (1, 3, h, w) if self._inp["layout"] == "NCHW" else (1, h, w, 3)
        if self._np_dtype == np.uint8:
            return rng.integers(0, 256, shape, dtype=np.uint8)
        return rng.standard_normal(shape).astype(self._np_dtype)

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
            raise RebarInputError(
                f"{where}: input.dtype {self._inp['dtype']!r} does not match the model's input type {node.type}"
            )
        shape = node.shape
        if len(shape) != 4:
            raise RebarInputError(
                f"{where}: expected a 4-D image input ({self._inp['layout']}), the model's input has shape {shape}"
            )
        c_axis, h_axis, w_axis = (1, 2, 3) if self._inp["layout"] == "NCHW" else (3, 1, 2)
        if isinstance(shape[c_axis], int) and shape[c_axis] != 3:
            raise RebarInputError(
                f"{where}: input.layout {self._inp['layout']!r} puts the colour "
                f"channels on axis {c_axis}, but the model's input shape is {shape}"
            )
        fixed = [shape[h_axis], shape[w_axis]]
        size = self._inp["size"]
        if all(isinstance(v, int) for v in fixed):
            if size is None:
                raise RebarInputError(
                    f"{where}: the model takes a fixed {fixed[1]} x {fixed[0]} image; "
                    f"set input.size to [{fixed[1]}, {fixed[0]}]"
                )
            if [size[1], size[0]] != fixed:
                raise RebarInputError(
                    f"{where}: input.size {size} (width, height) does not match the model's input shape {shape}"
                )
        if self._inp["resize"] == "scale" and all(isinstance(v, int) for v in fixed):
            raise RebarInputError(
                f"{where}: input.resize 'scale' runs the network on the image at its own scale, "
                f"but the model takes only a fixed {fixed[1]} x {fixed[0]} input"
            )
        if self._inp["full_resolution"] == "whole" and all(isinstance(v, int) for v in fixed):
            raise RebarInputError(
                f"{where}: input.full_resolution 'whole' runs the network on the whole image, "
                f"but the model takes only a fixed {fixed[1]} x {fixed[0]} input"
            )
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
                raise RebarInputError(
                    f"{where}: output.kind 'labels' expects an (N, H, W) label map, "
                    f"the model's output has shape {oshape}"
                )
        else:
            if len(oshape) not in (3, 4):
                raise RebarInputError(
                    f"{where}: output.kind {self._out['kind']!r} expects an "
                    f"(N, C, H, W) or (N, H, W) output, the model's has shape {oshape}"
                )
            n_cls = None
            if len(oshape) == 4:
                ax = 1 if self._out["layout"] == "NCHW" else 3
                n_cls = oshape[ax] if isinstance(oshape[ax], int) else None
            elif len(oshape) == 3:
                n_cls = 1
            if n_cls is not None:
                if self._out["kind"] == "probability" and n_cls != 1:
                    raise RebarInputError(
                        f"{where}: output.kind 'probability' expects one channel, the model's output has shape {oshape}"
                    )
                bad = [c for c in self._out["rebar_classes"] if c >= n_cls]
                if bad:
                    raise RebarInputError(
                        f"{where}: output.rebar_classes {bad} out of range for "
                        f"{n_cls} output channel(s) (shape {oshape})"
                    )

    # ---- inference
    def _prepare(self, color, factor=None):
        import cv2

        img = _rgb(color)
        H, W = img.shape[:2]
        w, h = self._input_size(W, H, factor)
        interp = cv2.INTER_AREA if w < W else cv2.INTER_LINEAR
        x = img if (w, h) == (W, H) else cv2.resize(img, (w, h), interpolation=interp)
        return self._laid_out(self._normalised(x))

    def _normalised(self, x):
        """An (h, w, 3) uint8 RGB image (at the network's scale) in the sidecar's channel order,
        type and normalisation, still (h, w, 3); each pixel on its own, so that a tile of the
        result is the result of the tile."""
        import cv2

        inp = self._inp
        if inp["channel_order"] == "BGR":
            x = x[..., ::-1]
        if self._np_dtype == np.uint8:
            return x
        if self._lut is None:
            # each channel's 256 values, normalised once: (v * value_scale - mean) / std, in
            # float32 as an image would be, so a looked-up pixel is the computed one to the bit
            mean = np.asarray(inp["mean"], np.float32)
            inv = 1.0 / np.asarray(inp["std"], np.float32)
            v = np.arange(256, dtype=np.float32)[:, None]
            self._lut = np.ascontiguousarray(((v * inp["value_scale"] - mean) * inv)[:, None, :], np.float32)
        return cv2.LUT(np.ascontiguousarray(x), self._lut)

    def _laid_out(self, t):
        """The network's input from a :meth:`_normalised` (h, w, 3) image: padded and in the
        sidecar's layout; ``(tensor, (h, w), (padded h, padded w))``."""
        inp = self._inp
        h, w = t.shape[:2]
        # padded bottom / right: to the fixed input where the image's aspect ratio differs
        # from it, then to a multiple of pad_to; the padding is cut off the output
        fw, fh = inp["size"] if inp["size"] is not None and inp["resize"] != "scale" else (w, h)
        p = inp["pad_to"]
        ph, pw = fh - h + (-fh % p), fw - w + (-fw % p)
        if ph or pw:
            t = np.pad(t, ((0, ph), (0, pw), (0, 0)))
        t = t.transpose(2, 0, 1)[None] if inp["layout"] == "NCHW" else t[None]
        return np.ascontiguousarray(t, dtype=self._np_dtype), (h, w), (h + ph, w + pw)

    def _input_size(self, W: int, H: int, factor=None) -> tuple[int, int]:
        """(width, height) the network sees an image of W × H at, before any padding: scaled by
        ``input.scale`` (no ``input.size``, or ``input.resize`` "scale": a photo of any size
        and aspect ratio keeps its pixel scale; ``factor``: another scale, one of
        :meth:`whole_scales`), or, for a fixed ``input.size``, by the largest factor that fits
        it, keeping the aspect ratio (``input.resize`` "keep_aspect", the default: the rest is
        padded), or stretched to it (``input.resize`` "stretch")."""
        inp = self._inp
        if inp["size"] is None or inp["resize"] == "scale":
            f = inp["scale"] if factor is None else factor
            return max(1, round(W * f)), max(1, round(H * f))
        w, h = inp["size"]
        if inp["resize"] == "stretch":
            return w, h
        f = min(w / W, h / H)
        return max(1, min(w, round(W * f))), max(1, min(h, round(H * f)))

    def whole_scales(self, W: int, H: int) -> list[float] | None:
        """The scales a whole W × H image is run at, its score maps averaged: ``input.scale``
        alone, and for ``input.resize`` "scale" also the factor that fits the image into
        ``input.size`` where that is larger (an image smaller than twice the design input).
        None for a model whose fixed input the image is fitted into or stretched to.

        Why two (decision 051): a photo's bars are as wide in pixels as its camera and distance
        make them. Kept at its pixel scale, a capture of a lower-resolution camera shows its bars
        thinner than the network learnt them (a 640 × 400 render: 86.3 % IoU at half its size,
        93.9 % fitted); fitted, a close-up 640 × 480 site photo shows them wider (the `dtu` set:
        recall 75.7 % at half its size, 59.5 % fitted). The mean of both reads 92.5 % and 71.6 %
        there: neither case is served badly, for about twice the network's work on an image
        that is small to begin with."""
        inp = self._inp
        if inp["size"] is None:
            return [inp["scale"]]
        if inp["resize"] != "scale":
            return None
        w, h = inp["size"]
        fit = min(w / W, h / H)
        return [inp["scale"]] if fit <= inp["scale"] else [inp["scale"], fit]

    def _run_all(self, inputs: list) -> list:
        """The network's output for each of ``inputs``, in their order: one after the other, or
        (threads=None, more than one input, more than one core) at once, one per core."""
        if len(inputs) == 1 or self._parallel == 1:
            return [self._run(self._session, x) for x in inputs]
        with self._pool_lock:
            if self._pool is None or self._pool_pid != os.getpid():  # (a forked child has no threads)
                import onnxruntime as ort
                from concurrent.futures import ThreadPoolExecutor

                so = ort.SessionOptions()
                so.intra_op_num_threads, so.inter_op_num_threads = 1, 1
                so.log_severity_level = 3
                self._pool_session = ort.InferenceSession(self._graph, so, providers=["CPUExecutionProvider"])
                self._pool = ThreadPoolExecutor(self._parallel, thread_name_prefix="rebarlib-model")
                self._pool_pid = os.getpid()
        return list(self._pool.map(lambda x: self._run(self._pool_session, x), inputs))

    def _run(self, session, x):
        return np.asarray(session.run([self._output_name], {self._input_name: x})[0])

    def _score(self, color, flips: bool = True, prepared=None):
        """The rebar score map at full resolution and the threshold it is compared with.
        ``prepared``: the network's input for ``color``, if made already (:meth:`_prepare`)."""
        import cv2

        H, W = np.asarray(color).shape[:2]
        if prepared is None:
            scales = self.whole_scales(W, H)
            if scales is not None and len(scales) > 1:
                return self._score_scales(color, flips, scales)
        t, (h, w), (hp, wp) = self._prepare(color) if prepared is None else prepared
        is_logit = False
        out = self._out
        if flips and self._inp["flips"]:
            # test-time flips: the outputs (logits or probabilities) of the mirrored images,
            # mirrored back, are averaged with the plain one (a network's errors at edges differ
            # between an image and its mirror image, so the mean is closer to the truth)
            t_hw = (2, 3) if self._inp["layout"] == "NCHW" else (1, 2)
            axes = lambda hw, f: tuple(a for a, c in zip(hw, "vh") if c in f)  # noqa: E731
            ys = self._run_all([t] + [np.ascontiguousarray(np.flip(t, axes(t_hw, f))) for f in self._inp["flips"]])
            y = ys[0]
            y_hw = (2, 3) if y.ndim == 4 and out["layout"] == "NCHW" else (1, 2)
            acc = y.astype(np.float32)
            for f, yf in zip(self._inp["flips"], ys[1:]):
                acc += np.flip(yf, axes(y_hw, f))
            y = acc / (1 + len(self._inp["flips"]))
        else:
            y = self._run_all([t])[0]
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
            score = score[: max(1, round(oh * h / hp)), : max(1, round(ow * w / wp))]
        if score.shape != (H, W):
            score = cv2.resize(np.ascontiguousarray(score), (W, H), interpolation=interp)
        return score, thr, is_logit

    def _score_scales(self, color, flips, scales):
        """:meth:`_score` of ``color`` run at each of ``scales``, the probabilities averaged
        (as a logit again where the network gives logits)."""
        runs = [self._score(color, flips, self._prepare(color, f)) for f in scales]
        thr, is_logit = runs[0][1], runs[0][2]
        if not is_logit:
            return np.mean([r[0] for r in runs], axis=0).astype(np.float32), thr, is_logit
        p = np.mean([_sigmoid(r[0].astype(np.float64)) for r in runs], axis=0)
        p = np.clip(p, 1e-7, 1 - 1e-7)
        return np.log(p / (1 - p)).astype(np.float32), thr, is_logit

    def _untiled(self, W, H) -> bool:
        """Whether an image of W × H is scored whole rather than in tiles: the model has no
        fixed input size, or the image is no larger than the input or smaller than it in one
        direction; never for a model run at a scale (``input.resize`` "scale") whose full
        resolution is the whole image (``full_resolution`` "whole"): that is run at the tiles'
        scale, as :meth:`tile_scale` gives it for the image's size."""
        size = self._inp["size"]
        if size is not None and self._inp["resize"] == "scale" and self._inp["full_resolution"] == "whole":
            return False  # the whole image at the tiles' scale, whatever its size (not its own scale)
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
        tiles. With the sidecar's ``input.full_resolution`` "whole" (a graph that takes any
        size), the image at that scale is run once instead, padded to ``input.pad_to``.
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
        if self._inp["full_resolution"] == "whole":
            # the network once on the whole image at the tiles' scale (padded to pad_to), not on
            # overlapping tiles: each pixel computed once per run instead of up to four times
            t = self._normalised(_rgb(img))
            p = self._inp["pad_to"]
            ph, pw = -H % p, -W % p
            if ph or pw:
                t = np.pad(t, ((0, ph), (0, pw), (0, 0)))
            t = t.transpose(2, 0, 1)[None] if self._inp["layout"] == "NCHW" else t[None]
            prepared = np.ascontiguousarray(t, dtype=self._np_dtype), (H, W), (H + ph, W + pw)
            score, thr, is_logit = self._score(img, flips, prepared)
            if (W, H) != (W0, H0):
                score = cv2.resize(score, (W0, H0), interpolation=cv2.INTER_LINEAR)
            return score, thr, is_logit
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
        # the tiles are of the input's size (no resize): the image is normalised once, and each
        # tile's input cut from it (the same numbers as normalising each tile: it is per pixel)
        norm = self._normalised(_rgb(img))
        for y0 in starts(H, th):
            for x0 in starts(W, tw):
                tile_img = img[y0 : y0 + th, x0 : x0 + tw]
                prepared = self._laid_out(norm[y0 : y0 + th, x0 : x0 + tw])
                tile, thr, is_logit = self._score(tile_img, flips, prepared)
                wgt = np.outer(ramp(th, y0 > 0, y0 + th < H), ramp(tw, x0 > 0, x0 + tw < W))
                acc[y0 : y0 + th, x0 : x0 + tw] += wgt * tile
                wsum[y0 : y0 + th, x0 : x0 + tw] += wgt
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
        :meth:`_score_tiled`), or, with the sidecar's ``input.full_resolution`` "whole" (the
        shipped model), once on the whole image at that resolution; ``bar_width_px``, the
        widest bar's width in the image, lowers that resolution where the bars would otherwise
        be wider than the model knows, and caps the enlargement (:meth:`tile_scale`).
        ``flips``: the sidecar's test-time flips (``input.flips``), on the whole image or on
        every tile; False runs the network once per image or tile instead of once per flip and
        once more (the shipped model: 4 runs; faster, a less exact mask: docs/benchmarks.md,
        "Full-resolution tiles").
        """
        score, _, is_logit = self._score_tiled(color, bar_width_px, flips) if tiled else self._score(color, flips)
        if is_logit:
            return _sigmoid(score).astype(np.float32)
        return np.clip(score, 0, 1).astype(np.float32)

    def predict_mask(self, color) -> np.ndarray:
        """Binary rebar mask, (H, W) bool at the resolution of ``color`` ((H, W, 3) uint8 RGB)."""
        score, thr, _ = self._score(color)
        return score > thr
