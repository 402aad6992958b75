"""The model contract: the sidecar JSON that says how to feed an ONNX network and read its output.

docs/formats.md, "Segmentation model sidecar", lists every key. :func:`read_sidecar` checks a
sidecar and fills in the defaults; :class:`~rebarlib.segmentation.SegmentationModel` then checks
it against the graph.
"""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np

from .._checks import RebarInputError

__all__ = ["SIDECAR_FORMAT", "read_sidecar"]

SIDECAR_FORMAT = "rebarlib-segmentation/1"
_LAYOUTS = ("NCHW", "NHWC")
_DTYPES = {
    "float32": ("tensor(float)", np.float32),
    "uint8": ("tensor(uint8)", np.uint8),
    "float16": ("tensor(float16)", np.float16),
}
_KINDS = ("logits", "probability", "labels")
# with input.size: the image fitted into it and padded, stretched to it, or (a graph that takes
# any size) scaled by input.scale and padded to input.pad_to only, the size then only the design
# input that full resolution refers to
_RESIZE = ("keep_aspect", "stretch", "scale")
_FLIPS = ("h", "v", "hv")  # test-time flips: horizontal, vertical, both
# how predict_proba(tiled=True) runs the network at full resolution: on overlapping tiles of
# the input's size, or once on the whole image (a graph that takes any size)
_FULL_RESOLUTION = ("tiles", "whole")


def _bad(path, problem):
    return RebarInputError(f"{path}: {problem}")


def read_sidecar(path: Path) -> dict:
    """The sidecar at ``path``, checked, with every optional key filled in with its default.

    Parameters
    ----------
    path : Path
        The sidecar JSON (next to the ONNX file, same name; ``docs/formats.md`` lists its keys).

    Returns
    -------
    dict
        The sidecar's object, its ``input`` and ``output`` objects checked and completed.

    Raises
    ------
    RebarInputError
        Naming the file and the key, for a missing file, invalid JSON or a value out of range.

    Examples
    --------
    >>> import json, tempfile
    >>> from pathlib import Path
    >>> with tempfile.TemporaryDirectory() as d:
    ...     p = Path(d) / "model.json"
    ...     _ = p.write_text(json.dumps({"input": {}, "output": {"kind": "logits"}}))
    ...     spec = read_sidecar(p)
    >>> spec["input"]["layout"], spec["output"]["rebar_classes"], spec["output"]["threshold"]
    ('NCHW', [1], 0.5)
    """
    spec = _load_json(path)
    inp = _input_section(path, dict(spec["input"]))
    out = _output_section(path, dict(spec["output"]), inp["flips"])
    return {**spec, "input": inp, "output": out}


def _load_json(path: Path) -> dict:
    """The sidecar's JSON object, with ``input`` and ``output`` objects.

    Parameters
    ----------
    path : Path

    Returns
    -------
    dict

    Raises
    ------
    RebarInputError
        For a missing file, invalid JSON, or an object without the two objects.
    """
    if not path.is_file():
        raise _bad(
            path,
            "sidecar JSON not found (expected next to the ONNX file, same name, .json; docs/formats.md lists its keys)",
        )
    try:
        spec = json.loads(path.read_text(encoding="utf-8"))
    except (UnicodeDecodeError, json.JSONDecodeError) as e:
        raise _bad(path, f"not valid JSON ({e})") from None
    if (
        not isinstance(spec, dict)
        or not isinstance(spec.get("input"), dict)
        or not isinstance(spec.get("output"), dict)
    ):
        raise _bad(path, "expected a JSON object with 'input' and 'output' objects")
    return spec


def _input_section(path: Path, inp: dict) -> dict:
    """The sidecar's ``input`` object checked, its defaults filled in.

    Parameters
    ----------
    path : Path
        The sidecar (named in the errors).
    inp : dict
        A copy of its ``input`` object (completed in place).

    Returns
    -------
    dict
        ``inp``, with ``size``, ``resize``, ``scale``, ``pad_to``, ``channel_order``, ``layout``,
        ``dtype``, ``mean``, ``std``, ``value_scale``, ``flips``, ``full_resolution`` and
        ``max_bar_px`` set.
    """
    size = inp.get("size")
    if size is not None:
        if not (isinstance(size, list) and len(size) == 2 and all(isinstance(v, int) and v > 0 for v in size)):
            raise _bad(path, f"input.size: expected [width, height] in pixels, got {size!r}")
    resize = inp.get("resize", "keep_aspect")
    if resize not in _RESIZE:
        raise _bad(path, f"input.resize: expected one of {_RESIZE}, got {resize!r}")
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
    full_res = inp.get("full_resolution", "tiles")
    if full_res not in _FULL_RESOLUTION:
        raise _bad(path, f"input.full_resolution: expected one of {_FULL_RESOLUTION}, got {full_res!r}")
    if resize == "scale" and size is None:
        raise _bad(path, "input.resize 'scale' needs input.size (the design input full resolution refers to)")
    if full_res == "whole" and size is None:
        raise _bad(path, "input.full_resolution 'whole' needs input.size (the scale the tiles are run at)")
    max_bar_px = inp.get("max_bar_px")
    if max_bar_px is not None and (
        isinstance(max_bar_px, bool) or not isinstance(max_bar_px, (int, float)) or max_bar_px <= 0
    ):
        raise _bad(path, f"input.max_bar_px: expected a positive number of input pixels, got {max_bar_px!r}")
    inp.update(
        size=size,
        resize=resize,
        scale=float(scale),
        pad_to=pad_to,
        channel_order=order,
        layout=layout,
        dtype=dtype,
        value_scale=float(value_scale),
        flips=list(flips),
        full_resolution=full_res,
        max_bar_px=None if max_bar_px is None else float(max_bar_px),
    )
    return inp


def _output_section(path: Path, out: dict, flips: list) -> dict:
    """The sidecar's ``output`` object checked, its defaults filled in.

    Parameters
    ----------
    path : Path
        The sidecar (named in the errors).
    out : dict
        A copy of its ``output`` object (completed in place).
    flips : list
        The input's flips (a label map cannot be averaged over them).

    Returns
    -------
    dict
        ``out``, with ``kind``, ``rebar_classes``, ``threshold`` and ``layout`` set.
    """
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
    return out
