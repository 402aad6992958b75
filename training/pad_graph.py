"""Rewrite a segmentation model's graph for onnxruntime's blocked layout: padded to whole channel
blocks with the same numbers (decision 027), or with its resizes at constant scales too, a new
graph whose numbers are measured as a new model's (decision 056).

onnxruntime's CPU provider keeps convolution tensors in channel blocks ("NCHWc": 16 channels with
AVX-512, 8 with AVX2). A channel concatenation that does not fill whole blocks cannot stay in that
layout: each run converts its inputs back to the plain layout, concatenates and converts again
(the stage-4 network: 48 + 8 = 56 channels before the last decoder block). Giving each input that
does not fill whole blocks zero channels up to one — zero filters and biases in the convolution
that makes it, zero filters in the depthwise convolution that reads the concatenation, zero
weights for them in the convolutions after that — keeps every channel that was there computed as
before and adds exact zeros where the runtime padded with its own zeros; the file written is
checked against the original on probe inputs, to the bit, and refused otherwise.

    python training/pad_graph.py rebarlib/models/rebar_seg.onnx --block 16

writes ``rebarlib/models/rebar_seg.blocked16.onnx`` beside it, which
:class:`rebarlib.segmentation.SegmentationModel` runs instead of the file's graph on a CPU with
that block, where a probe input gives the same output bits (the model file itself is unchanged).

A resize given its output size computed in the graph (torch's export of an upsampling to a skip
connection's size) runs in the plain layout, and the tensors around it leave the blocked one.
``--resize-scales`` also gives such resizes their constant scale, and pads the concatenations
after them: onnxruntime's blocked resize rounds otherwise than its plain one (logits about 1e-6
apart), so the result is a new model file, written to ``--out`` and accepted only within
``--max-diff`` of the original on probes; its numbers are measured as a new model's. The shipped
model was made so from its trained export (training/README.md).

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
    channel, group = channels) of a channel count that is not a whole number of blocks; each of
    its inputs that does not fill whole blocks made by a ``Conv`` of group 1, directly or through
    ``Relu`` and ``Resize`` nodes with constant scales (channel by channel, a zero channel stays
    zero), each tensor on the way read only by the next node; and whose depthwise convolution is
    read, directly or through a ``Relu``, only by ``Conv`` nodes of group 1 on their data input.
    Every weight and bias touched must be an initializer used by that node alone. Each such input
    gets zero channels after its own up to a whole block: zero filters and biases in the
    convolution that makes it, zero filters in the depthwise convolution at the same places, zero
    weights for them in the convolutions after it.
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
    channels = {}
    for v in list(onnx.shape_inference.infer_shapes(model).graph.value_info) + list(g.input):
        dims = v.type.tensor_type.shape.dim
        if len(dims) == 4 and dims[1].HasField("dim_value"):
            channels[v.name] = dims[1].dim_value

    def source(name):
        """(conv, nodes between it and ``name``) where ``name`` is made by a group-1 ``Conv``
        through any ``Relu`` and ``Resize`` with constant scales (each a channel-wise map that keeps
        a zero channel zero), every tensor on the way read only by the next node; else None."""
        between, cur = [], name
        while True:
            n = producer.get(cur)
            if n is None:
                return None
            if is_op(n, "Conv"):
                if _attr(n, "group", 1) != 1 or weights(n) is None:
                    return None
                return n, between
            if is_op(n, "Relu") or (is_op(n, "Resize") and len(n.input) == 3 and n.input[2] in inits):
                if not only_reader(n.input[0], n):
                    return None
                between.append(n)
                cur = n.input[0]
                continue
            return None

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
        if _attr(dw, "group", 1) != n or arr[dw_w].shape[1] != 1:
            continue
        # each input's channels (from the convolution that makes it, else from shape inference);
        # an input that does not fill whole blocks must come from a convolution that can be padded
        parts = []
        for x in cat.input:
            src = source(x) if list(cat.input).count(x) == 1 and only_reader(x, cat) else None
            c = arr[weights(src[0])[0]].shape[0] if src is not None else channels.get(x)
            if c is None or (c % block and src is None):
                parts = None
                break
            parts.append((src, c))
        if parts is None or sum(c for _, c in parts) != n or all(c % block == 0 for _, c in parts):
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

        def spread(a, axis=0):
            """``a`` with zeros after each input's channels along ``axis``, up to a whole block."""
            pieces, off = [], 0
            for _, c in parts:
                pieces.append(np.take(a, range(off, off + c), axis=axis))
                shape = list(a.shape)
                shape[axis] = -c % block
                pieces.append(np.zeros(shape, a.dtype))
                off += c
            return np.concatenate(pieces, axis=axis)

        for src, c in parts:
            if c % block:
                conv, between = src
                q_w, q_b = weights(conv)
                shape = list(arr[q_w].shape)
                shape[0] = -c % block
                new[q_w] = np.concatenate([arr[q_w], np.zeros(shape, arr[q_w].dtype)])
                if q_b is not None:
                    new[q_b] = np.concatenate([arr[q_b], np.zeros(-c % block, arr[q_b].dtype)])
                changed.update(list(conv.output) + [o for b in between for o in b.output])
        padded = sum(c + (-c % block) for _, c in parts)
        new[dw_w] = spread(arr[dw_w])
        if dw_b is not None:
            new[dw_b] = spread(arr[dw_b])
        regroup.append((dw, padded))
        for p in d_readers:
            new[p.input[1]] = spread(arr[p.input[1]], axis=1)
        changed.update([out, dw.output[0], d_out])
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


def prune(g, *, initializers: bool = True) -> None:
    """Remove from graph ``g`` the nodes whose outputs nothing reads (over and over, as removing
    one may leave another unread) and, with ``initializers``, the initializers nothing reads."""
    outputs = {o.name for o in g.output}
    while True:
        read = {i for n in g.node for i in n.input} | outputs
        dead = [n for n in g.node if not any(o in read for o in n.output)]
        if not dead:
            break
        for n in dead:
            g.node.remove(n)
    if initializers:
        read = {i for n in g.node for i in n.input}
        for t in [t for t in g.initializer if t.name not in read]:
            g.initializer.remove(t)


def resize_scales(model, block: int, probes=((400, 640), (208, 320))):
    """A copy of ``model`` whose ``Resize`` nodes given output sizes (computed in the graph from
    other tensors' shapes, as torch exports an upsampling to a skip connection's size) take the
    constant whole scale those sizes stand for instead, where their input has at least ``block``
    channels; or None where there is none.

    onnxruntime runs a resize with constant scales in its blocked layout, so the tensors around it
    stay blocked; one of fewer channels than a block is left as it is (the blocked kernel would
    pad it to a whole block). The scale of each resize is read from the output and input sizes
    on the ``probes`` (H, W; multiples of the network's stride) and must be a whole number, the
    same on each probe and 1 on the batch and channel axes. The graph then takes inputs whose
    sides are multiples of its stride, as the sidecar's ``input.pad_to`` gives it.
    """
    import onnx
    from onnx import numpy_helper

    model = onnx.ModelProto.FromString(model.SerializeToString())  # a copy
    g = model.graph
    inits = {t.name for t in g.initializer}
    candidates = [
        n for n in g.node if n.op_type == "Resize" and len(n.input) == 4 and n.input[3] and n.input[3] not in inits
    ]
    if not candidates:
        return None
    probe = onnx.ModelProto.FromString(model.SerializeToString())
    known = {o.name for o in probe.graph.output}
    for n in candidates:
        for t in (n.input[0], n.output[0]):
            if t not in known:
                probe.graph.output.append(onnx.helper.make_empty_tensor_value_info(t))
                known.add(t)
    session = _session(probe.SerializeToString())
    names = [o.name for o in session.get_outputs()]
    # per resize, what each probe shows: (output size / input size per axis, input channels)
    seen = {n.name: set() for n in candidates}
    for h, w in probes:
        x = np.zeros((1, 3, h, w), np.float32)
        shapes = dict(zip(names, (y.shape for y in session.run(None, {session.get_inputs()[0].name: x}))))
        for n in candidates:
            a, b = shapes[n.input[0]], shapes[n.output[0]]
            seen[n.name].add((tuple(bo / ai for ai, bo in zip(a, b)), a[1]))
    changed = False
    for n in candidates:
        if len(seen[n.name]) != 1:  # another scale at another input size: not a constant scale
            continue
        ((factors, channels),) = seen[n.name]
        if factors[:2] != (1, 1) or not all(float(f).is_integer() for f in factors[2:]) or channels < block:
            continue
        name = f"{n.output[0].strip('/').replace('/', '_')}_scales"
        g.initializer.append(numpy_helper.from_array(np.array(factors, np.float32), name))
        x = n.input[0]
        del n.input[:]
        n.input.extend([x, "", name])
        changed = True
    if not changed:
        return None
    prune(g)
    del g.value_info[:]
    return model


def _session(model: bytes):
    """An onnxruntime CPU session of a serialised model, on one thread."""
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.log_severity_level = 3
    return ort.InferenceSession(model, so, providers=["CPUExecutionProvider"])


def _probe_outputs(original: bytes, other: bytes, shapes):
    """The two graphs' outputs ``(ya, yb)`` on a seeded probe input of each of ``shapes``."""
    a, b = _session(original), _session(other)
    name = a.get_inputs()[0].name
    for h, w in shapes:
        x = np.random.default_rng(h).standard_normal((1, 3, h, w)).astype(np.float32)
        yield a.run(None, {name: x})[0], b.run(None, {name: x})[0]


def max_difference(original: bytes, rewritten: bytes, shapes=((400, 640), (96, 160))) -> float:
    """The largest absolute difference between the two graphs' outputs on seeded probe inputs of
    ``shapes`` (one thread each); inf where their shapes differ."""
    worst = 0.0
    for ya, yb in _probe_outputs(original, rewritten, shapes):
        if ya.shape != yb.shape:
            return float("inf")
        worst = max(worst, float(np.max(np.abs(ya.astype(np.float64) - yb))))
    return worst


def same_numbers(original: bytes, padded: bytes, shapes=((400, 640), (96, 160))) -> bool:
    """Whether the two graphs give the same output bits on seeded probe inputs of ``shapes``
    (one thread each)."""
    return all(
        ya.shape == yb.shape and ya.tobytes() == yb.tobytes() for ya, yb in _probe_outputs(original, padded, shapes)
    )


def main(argv=None) -> int:
    import onnx

    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("model", type=Path, help="an ONNX segmentation model (e.g. rebarlib/models/rebar_seg.onnx)")
    ap.add_argument("--block", type=int, default=16, help="channel block to pad to (16: AVX-512)")
    ap.add_argument(
        "--out",
        type=Path,
        help="default: MODEL's folder, <stem>.blocked<BLOCK>.onnx (with --resize-scales: <stem>.layout<BLOCK>.onnx)",
    )
    ap.add_argument(
        "--resize-scales",
        action="store_true",
        help="also give resizes to a computed size their constant scale, so that they run in the blocked "
        "layout: other output bits (a new model, to be measured as one); refused beyond --max-diff",
    )
    ap.add_argument(
        "--max-diff",
        type=float,
        default=1e-4,
        help="with --resize-scales: the largest output difference accepted on the probes (default 1e-4)",
    )
    args = ap.parse_args(argv)
    if not args.model.is_file():
        sys.exit(f"{args.model}: no such model file (expected an .onnx file)")
    kind = "layout" if args.resize_scales else "blocked"
    out = args.out or args.model.with_name(f"{args.model.stem}.{kind}{args.block}.onnx")
    if out.resolve() == args.model.resolve():
        sys.exit(f"--out {out}: would overwrite the model itself")
    model = onnx.load(str(args.model))
    scaled = resize_scales(model, args.block) if args.resize_scales else None
    padded = pad_concat_channels(scaled if scaled is not None else model, args.block)
    if padded is None and scaled is None:
        print(f"{args.model}: nothing to rewrite for {args.block}-channel blocks; nothing written")
        return 0
    result = padded if padded is not None else scaled
    onnx.checker.check_model(result)
    data = result.SerializeToString()
    if not args.resize_scales:
        if not same_numbers(args.model.read_bytes(), data):
            sys.exit(f"{args.model}: the padded graph does not give the same output bits; nothing written")
        out.write_bytes(data)
        print(f"{out}: {len(data)} bytes, the same output bits as {args.model.name} on the probes")
        return 0
    diff = max_difference(args.model.read_bytes(), data)
    if not diff <= args.max_diff:
        sys.exit(
            f"{args.model}: the rewritten graph's output is {diff:.3g} from the original's "
            "(over --max-diff); nothing written"
        )
    out.write_bytes(data)
    print(
        f"{out}: {len(data)} bytes; resizes to constant scales: {'yes' if scaled is not None else 'none'}, "
        f"concatenations padded: {'yes' if padded is not None else 'none'}; "
        f"output at most {diff:.3g} from {args.model.name}'s on the probes"
    )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
