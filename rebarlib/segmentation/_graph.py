"""A layout rewrite of an ONNX graph that onnxruntime runs faster and that computes the same numbers.

onnxruntime's CPU provider runs convolutions in a blocked channel layout ("NCHWc": channels in
blocks of 16 with AVX-512, 8 with AVX2), padding a tensor's channels with zeros to a whole
block. A channel concatenation whose channel count is not a whole number of blocks cannot stay
in that layout: the runtime converts its inputs back to the plain layout, concatenates, and
converts the result again. In the shipped network that happens once, at full-resolution / 2
(48 + 8 = 56 channels before the last decoder block): three copies of a 200 x 320 x 56 tensor
per run, about 15 % of the network's CPU time.

:func:`pad_concat_channels` gives the last input of such a concatenation zero channels up to a
whole block: its convolution gets zero filters (and zero biases), the depthwise convolution that
reads the concatenation zero filters for them, and the convolutions after it zero weights for
them. Each added channel is exactly 0 everywhere (a ReLU of a zero-weight, zero-bias convolution)
and adds exact zeros to the sums that read it, where the runtime added its own zero padding
before; the channels that were there are computed as before. The caller
(:class:`~rebarlib.segmentation.SegmentationModel`) still checks the rewritten graph against the
original on a probe input, to the bit, and keeps the original where they differ.

The graph is read and written with a small protobuf wire-format codec (ONNX files are
protobuf), so the runtime needs no ``onnx`` package; a graph that does not match the pattern
exactly, or keeps its weights outside the file, is left as it is (None).
"""

from __future__ import annotations

import numpy as np

__all__ = ["pad_concat_channels"]

# ---- protobuf wire format: a message is a list of [field number, wire type, value]


def _varint(b: bytes, i: int) -> tuple[int, int]:
    shift = value = 0
    while True:
        c = b[i]
        i += 1
        value |= (c & 0x7F) << shift
        if c < 0x80:
            return value, i
        shift += 7


def _enc_varint(v: int) -> bytes:
    v &= (1 << 64) - 1  # negative int64 as ten bytes, as protobuf writes it
    out = bytearray()
    while True:
        c = v & 0x7F
        v >>= 7
        if v:
            out.append(c | 0x80)
        else:
            out.append(c)
            return bytes(out)


def _parse(b: bytes) -> list:
    fields, i, n = [], 0, len(b)
    while i < n:
        key, i = _varint(b, i)
        num, wt = key >> 3, key & 7
        if wt == 0:
            v, i = _varint(b, i)
        elif wt == 1:
            v, i = b[i : i + 8], i + 8
        elif wt == 2:
            ln, i = _varint(b, i)
            v, i = b[i : i + ln], i + ln
        elif wt == 5:
            v, i = b[i : i + 4], i + 4
        else:
            raise ValueError(f"unsupported protobuf wire type {wt}")
        fields.append([num, wt, v])
    return fields


def _serialize(fields: list) -> bytes:
    out = bytearray()
    for num, wt, v in fields:
        out += _enc_varint((num << 3) | wt)
        if wt == 0:
            out += _enc_varint(v)
        elif wt == 2:
            out += _enc_varint(len(v)) + v
        else:
            out += v
    return bytes(out)


def _get(fields, num):
    return [f[2] for f in fields if f[0] == num]


def _str(fields, num, default=""):
    v = _get(fields, num)
    return v[0].decode() if v else default


# ---- ONNX messages (field numbers of onnx.proto)
_MODEL_GRAPH = 7
_GRAPH_NODE, _GRAPH_INIT, _GRAPH_INPUT, _GRAPH_OUTPUT, _GRAPH_VALUE_INFO = 1, 5, 11, 12, 13
_NODE_IN, _NODE_OUT, _NODE_OP, _NODE_ATTR, _NODE_DOMAIN = 1, 2, 4, 5, 7
_ATTR_NAME, _ATTR_I, _ATTR_INTS = 1, 3, 8
_T_DIMS, _T_TYPE, _T_FLOATS, _T_NAME, _T_RAW, _T_EXTERNAL, _T_LOCATION = 1, 2, 4, 8, 9, 13, 14
_VI_NAME = 1
_FLOAT = 1


class _Node:
    def __init__(self, raw: bytes):
        self.fields = _parse(raw)
        self.inputs = [v.decode() for v in _get(self.fields, _NODE_IN)]
        self.outputs = [v.decode() for v in _get(self.fields, _NODE_OUT)]
        self.op = _str(self.fields, _NODE_OP)
        self.domain = _str(self.fields, _NODE_DOMAIN)

    def attr(self, name):
        """(int value, or list of ints) of attribute ``name``; None if absent."""
        for raw in _get(self.fields, _NODE_ATTR):
            a = _parse(raw)
            if _str(a, _ATTR_NAME) == name:
                i = _get(a, _ATTR_I)
                if i:
                    return i[0] if i[0] < (1 << 63) else i[0] - (1 << 64)
                return _ints(a, _ATTR_INTS)
        return None

    def set_int_attr(self, name, value):
        for f in self.fields:
            if f[0] == _NODE_ATTR and _str(_parse(f[2]), _ATTR_NAME) == name:
                a = [g for g in _parse(f[2]) if g[0] != _ATTR_I]
                a.append([_ATTR_I, 0, int(value)])
                f[2] = _serialize(a)
                return
        raise KeyError(name)

    def is_op(self, op):
        return self.op == op and self.domain in ("", "ai.onnx")


def _ints(fields, num) -> list:
    """A repeated int64 field, packed or not."""
    out = []
    for f in fields:
        if f[0] != num:
            continue
        if f[1] == 0:
            out.append(f[2])
        else:
            i = 0
            while i < len(f[2]):
                v, i = _varint(f[2], i)
                out.append(v)
    return [v - (1 << 64) if v >= (1 << 63) else v for v in out]


def _tensor(raw: bytes):
    """(name, float32 array) of a TensorProto held in the file; None for any other."""
    t = _parse(raw)
    if _get(t, _T_EXTERNAL) or (_get(t, _T_LOCATION) and _get(t, _T_LOCATION)[0] != 0):
        return None
    if (_get(t, _T_TYPE) or [0])[0] != _FLOAT:
        return None
    dims = _ints(t, _T_DIMS)
    data = _get(t, _T_RAW)
    if data:
        arr = np.frombuffer(data[0], dtype="<f4")
    else:
        vals = []
        for f in t:
            if f[0] == _T_FLOATS:
                vals.append(np.frombuffer(f[2], dtype="<f4"))  # packed (wire type 2) or one (5)
        arr = np.concatenate(vals) if vals else np.zeros(0, "<f4")
    if arr.size != int(np.prod(dims, dtype=np.int64)):
        return None
    return _str(t, _T_NAME), arr.astype(np.float32).reshape(dims)


def _tensor_bytes(name: str, arr: np.ndarray) -> bytes:
    fields = [[_T_DIMS, 0, int(d)] for d in arr.shape]
    fields += [[_T_TYPE, 0, _FLOAT], [_T_NAME, 2, name.encode()], [_T_RAW, 2, arr.astype("<f4").tobytes()]]
    return _serialize(fields)


def pad_concat_channels(model: bytes, block: int) -> bytes | None:
    """``model`` (an ONNX file's bytes) with every matching channel concatenation padded to a
    whole number of ``block`` channels, or None where nothing matches.

    The pattern: a ``Concat`` on axis 1 whose only reader is a depthwise ``Conv`` (one filter
    per channel, group = channels); whose inputs before the last one hold a whole number of
    blocks and whose last input does not; that last input made by a ``Conv`` of group 1 (and
    optionally a ``Relu``) read only by the concatenation; and whose depthwise convolution is
    read, directly or through a ``Relu``, only by ``Conv`` nodes of group 1. Every weight and bias
    touched must be an initializer of the file used by that node alone.
    """
    mfields = _parse(model)
    graphs = [f for f in mfields if f[0] == _MODEL_GRAPH]
    if len(graphs) != 1:
        return None
    gfields = _parse(graphs[0][2])
    nodes = [_Node(f[2]) for f in gfields if f[0] == _GRAPH_NODE]
    inits = {}
    for f in gfields:
        if f[0] == _GRAPH_INIT:
            t = _tensor(f[2])
            if t is not None:
                inits[t[0]] = t[1]
    graph_io = {_str(_parse(f[2]), _VI_NAME) for f in gfields if f[0] in (_GRAPH_INPUT, _GRAPH_OUTPUT)}
    producer = {o: n for n in nodes for o in n.outputs}
    readers: dict = {}
    for n in nodes:
        for i in n.inputs:
            readers.setdefault(i, []).append(n)

    def only_reader(name, node):
        return name not in graph_io and readers.get(name, []) == [node]

    def weights(node):
        """(weight name, bias name or None) of a Conv whose weights are private initializers."""
        if len(node.inputs) < 2 or node.inputs[1] not in inits or not only_reader(node.inputs[1], node):
            return None
        bias = node.inputs[2] if len(node.inputs) > 2 and node.inputs[2] else None
        if bias is not None and (bias not in inits or not only_reader(bias, node)):
            return None
        return node.inputs[1], bias

    new = {}  # initializer name -> new array
    regroup = []  # (node, new group)
    changed = set()  # tensors whose shape changes (their value_info, if any, is dropped)
    for cat in nodes:
        if not cat.is_op("Concat") or cat.attr("axis") != 1 or len(cat.inputs) < 2:
            continue
        out = cat.outputs[0]
        if out in graph_io or len(readers.get(out, [])) != 1:
            continue
        dw = readers[out][0]
        if not dw.is_op("Conv") or dw.inputs[0] != out or weights(dw) is None:
            continue
        dw_w, dw_b = weights(dw)
        n = inits[dw_w].shape[0]
        if dw.attr("group") != n or inits[dw_w].shape[1] != 1 or n % block == 0:
            continue
        # the last input: Conv (group 1) [-> Relu], read only by the concatenation
        last = cat.inputs[-1]
        src, relu = producer.get(last), None
        if src is not None and src.is_op("Relu"):
            relu, src = src, producer.get(src.inputs[0])
            if src is None or not only_reader(src.outputs[0], relu):
                continue
        if src is None or not src.is_op("Conv") or (src.attr("group") or 1) != 1 or not only_reader(last, cat):
            continue
        if weights(src) is None:
            continue
        q_w, q_b = weights(src)
        c_last = inits[q_w].shape[0]
        if (n - c_last) % block or c_last >= n:
            continue
        # the depthwise convolution's readers: [Relu ->] Conv nodes of group 1, on their data input
        d_out = dw.outputs[0]
        d_readers = readers.get(d_out, [])
        if len(d_readers) == 1 and d_readers[0].is_op("Relu") and d_out not in graph_io:
            d_out = d_readers[0].outputs[0]
            d_readers = readers.get(d_out, [])
        if d_out in graph_io or not d_readers:
            continue
        if any(
            not p.is_op("Conv")
            or (p.attr("group") or 1) != 1
            or p.inputs[0] != d_out
            or d_out in p.inputs[1:]
            or weights(p) is None
            or inits[weights(p)[0]].shape[1] != n
            for p in d_readers
        ):
            continue
        pad = -n % block
        w = inits[q_w]
        new[q_w] = np.concatenate([w, np.zeros((pad,) + w.shape[1:], np.float32)])
        if q_b is not None:
            new[q_b] = np.concatenate([inits[q_b], np.zeros(pad, np.float32)])
        w = inits[dw_w]
        new[dw_w] = np.concatenate([w, np.zeros((pad,) + w.shape[1:], np.float32)])
        if dw_b is not None:
            new[dw_b] = np.concatenate([inits[dw_b], np.zeros(pad, np.float32)])
        regroup.append((dw, n + pad))
        for p in d_readers:
            w = inits[p.inputs[1]]
            new[p.inputs[1]] = np.concatenate([w, np.zeros((w.shape[0], pad) + w.shape[2:], np.float32)], axis=1)
        changed.update([last, out, dw.outputs[0], d_out] + src.outputs)
    if not new:
        return None
    for node, group in regroup:
        node.set_int_attr("group", group)
    node_iter = iter(nodes)
    out_fields = []
    for f in gfields:
        if f[0] == _GRAPH_NODE:
            out_fields.append([f[0], f[1], _serialize(next(node_iter).fields)])
        elif f[0] == _GRAPH_INIT:
            t = _tensor(f[2])
            name = t[0] if t is not None else None
            out_fields.append([f[0], f[1], _tensor_bytes(name, new[name]) if name in new else f[2]])
        elif f[0] == _GRAPH_VALUE_INFO and _str(_parse(f[2]), _VI_NAME) in changed:
            continue
        else:
            out_fields.append(f)
    graph = _serialize(out_fields)
    return _serialize([[f[0], f[1], graph] if f[0] == _MODEL_GRAPH else f for f in mfields])
