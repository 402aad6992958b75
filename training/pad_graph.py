"""Write a segmentation model's graph padded to whole channel blocks: the same numbers, faster on
CPUs whose onnxruntime convolutions run in a blocked layout (decision 027).

onnxruntime's CPU provider keeps convolution tensors in channel blocks ("NCHWc": 16 channels with
AVX-512, 8 with AVX2). A channel concatenation that does not fill whole blocks cannot stay in that
layout: each run converts its inputs back to the plain layout, concatenates and converts again.
The shipped network has one (48 + 8 = 56 channels before the last decoder block, at half
resolution). Giving the concatenation's last input zero channels up to a whole block — zero
filters and biases in the convolution that makes it, zero filters in the depthwise convolution
that reads the concatenation, zero weights for them in the convolutions after that — keeps every
channel that was there computed as before and adds exact zeros where the runtime padded with its
own zeros; the file written is checked against the original on probe inputs, to the bit, and
refused otherwise.

    python training/pad_graph.py rebarlib/models/rebar_seg.onnx --block 16

writes ``rebarlib/models/rebar_seg.blocked16.onnx`` beside it, which
:class:`rebarlib.segmentation.SegmentationModel` runs instead of the file's graph on a CPU with
that block, where a probe input gives the same output bits (the model file itself is unchanged).
Needs the ``onnx`` package (``pip install -e ".[train]"`` or ``.[dev]``); the runtime does not.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np


def _attr(node, name, default=None):
    for a in node.attribute:
        if a.name == name:
            return a.i if a.type == a.INT else list(a.ints)
    return default


def pad_concat_channels(model, block: int):
    """A copy of ``model`` (an ``onnx.ModelProto``) with every matching channel concatenation
    padded to a whole number of ``block`` channels, or None where nothing matches.

    The pattern: a ``Concat`` on axis 1 whose only reader is a depthwise ``Conv`` (one filter per
    channel, group = channels); whose inputs before the last one hold a whole number of blocks and
    whose last input does not; that last input made by a ``Conv`` of group 1 (optionally through a
    ``Relu``) read only by the concatenation; and whose depthwise convolution is read, directly or
    through a ``Relu``, only by ``Conv`` nodes of group 1 on their data input. Every weight and
    bias touched must be an initializer used by that node alone.
    """
    import onnx
    from onnx import numpy_helper

    model = onnx.ModelProto.FromString(model.SerializeToString())  # a copy
    g = model.graph
    inits = {t.name: t for t in g.initializer}
    graph_io = {v.name for v in g.input} | {v.name for v in g.output}
    producer = {o: n for n in g.node for o in n.output}
    readers: dict = {}
    for n in g.node:
        for i in n.input:
            readers.setdefault(i, []).append(n)

    def is_op(n, op):
        return n is not None and n.op_type == op and n.domain in ("", "ai.onnx")

    def only_reader(name, node):
        return name not in graph_io and readers.get(name, []) == [node]

    def weights(node):
        """(weight name, bias name or None) of a Conv whose weights are private float initializers."""
        if len(node.input) < 2 or node.input[1] not in inits or not only_reader(node.input[1], node):
            return None
        if inits[node.input[1]].data_type != onnx.TensorProto.FLOAT:
            return None
        bias = node.input[2] if len(node.input) > 2 and node.input[2] else None
        if bias is not None and (bias not in inits or not only_reader(bias, node)):
            return None
        return node.input[1], bias

    arr = {name: numpy_helper.to_array(t) for name, t in inits.items() if t.data_type == onnx.TensorProto.FLOAT}
    new, regroup, changed = {}, [], set()
    for cat in g.node:
        if not is_op(cat, "Concat") or _attr(cat, "axis") != 1 or len(cat.input) < 2:
            continue
        out = cat.output[0]
        if out in graph_io or len(readers.get(out, [])) != 1:
            continue
        dw = readers[out][0]
        if not is_op(dw, "Conv") or dw.input[0] != out or weights(dw) is None:
            continue
        dw_w, dw_b = weights(dw)
        n = arr[dw_w].shape[0]
        if _attr(dw, "group", 1) != n or arr[dw_w].shape[1] != 1 or n % block == 0:
            continue
        last = cat.input[-1]
        src, relu = producer.get(last), None
        if is_op(src, "Relu"):
            relu, src = src, producer.get(src.input[0])
            if src is None or not only_reader(src.output[0], relu):
                continue
        if not is_op(src, "Conv") or _attr(src, "group", 1) != 1 or not only_reader(last, cat) or weights(src) is None:
            continue
        q_w, q_b = weights(src)
        c_last = arr[q_w].shape[0]
        if (n - c_last) % block or c_last >= n:
            continue
        d_out = dw.output[0]
        d_readers = readers.get(d_out, [])
        if len(d_readers) == 1 and is_op(d_readers[0], "Relu") and d_out not in graph_io:
            d_out = d_readers[0].output[0]
            d_readers = readers.get(d_out, [])
        if d_out in graph_io or not d_readers:
            continue
        if any(
            not is_op(p, "Conv")
            or _attr(p, "group", 1) != 1
            or p.input[0] != d_out
            or d_out in list(p.input[1:])
            or weights(p) is None
            or arr[weights(p)[0]].shape[1] != n
            for p in d_readers
        ):
            continue
        pad = -n % block

        def zeros_after(a, axis=0):
            shape = list(a.shape)
            shape[axis] = pad
            return np.concatenate([a, np.zeros(shape, a.dtype)], axis=axis)

        new[q_w] = zeros_after(arr[q_w])
        if q_b is not None:
            new[q_b] = zeros_after(arr[q_b])
        new[dw_w] = zeros_after(arr[dw_w])
        if dw_b is not None:
            new[dw_b] = zeros_after(arr[dw_b])
        regroup.append((dw, n + pad))
        for p in d_readers:
            new[p.input[1]] = zeros_after(arr[p.input[1]], axis=1)
        changed.update([last, out, dw.output[0], d_out] + list(src.output))
    if not new:
        return None
    for node, group in regroup:
        for a in node.attribute:
            if a.name == "group":
                a.i = int(group)
    for t in g.initializer:
        if t.name in new:
            t.CopyFrom(numpy_helper.from_array(new[t.name].astype(np.float32), t.name))
    keep = [v for v in g.value_info if v.name not in changed]  # shapes that changed are left to inference
    del g.value_info[:]
    g.value_info.extend(keep)
    return model


def same_numbers(original: bytes, padded: bytes, shapes=((400, 640), (96, 160))) -> bool:
    """Whether the two graphs give the same output bits on seeded probe inputs of ``shapes``
    (one thread each)."""
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.log_severity_level = 3
    a = ort.InferenceSession(original, so, providers=["CPUExecutionProvider"])
    b = ort.InferenceSession(padded, so, providers=["CPUExecutionProvider"])
    name = a.get_inputs()[0].name
    for h, w in shapes:
        x = np.random.default_rng(h).standard_normal((1, 3, h, w)).astype(np.float32)
        ya, yb = a.run(None, {name: x})[0], b.run(None, {name: x})[0]
        if ya.shape != yb.shape or ya.tobytes() != yb.tobytes():
            return False
    return True


def main(argv=None) -> int:
    import onnx

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", type=Path, help="an ONNX segmentation model (e.g. rebarlib/models/rebar_seg.onnx)")
    ap.add_argument("--block", type=int, default=16, help="channel block to pad to (16: AVX-512)")
    ap.add_argument("--out", type=Path, help="default: MODEL's folder, <stem>.blocked<BLOCK>.onnx")
    args = ap.parse_args(argv)
    if not args.model.is_file():
        sys.exit(f"{args.model}: no such model file (expected an .onnx file)")
    out = args.out or args.model.with_name(f"{args.model.stem}.blocked{args.block}.onnx")
    if out.resolve() == args.model.resolve():
        sys.exit(f"--out {out}: would overwrite the model itself")
    padded = pad_concat_channels(onnx.load(str(args.model)), args.block)
    if padded is None:
        print(f"{args.model}: no concatenation to pad to {args.block}-channel blocks; nothing written")
        return 0
    onnx.checker.check_model(padded)
    data = padded.SerializeToString()
    if not same_numbers(args.model.read_bytes(), data):
        sys.exit(f"{args.model}: the padded graph does not give the same output bits; nothing written")
    out.write_bytes(data)
    print(f"{out}: {len(data)} bytes, the same output bits as {args.model.name} on the probes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
