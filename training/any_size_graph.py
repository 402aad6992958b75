"""Make an exported ``deeplab_fine`` graph take any input whose sides are multiples of 16.

torch's export fixes three sizes in the graph at the export's 640 x 400: the image-pooling
branch's ``Expand`` to the 1/16 feature map (25 x 40) and the output sizes of the three bilinear
``Resize`` (to 1/4, 1/2 and the input). This rewrites them: the ``Expand`` takes the feature
map's size from the graph, and each ``Resize`` the constant scale the fixed sizes stood for
(4, 2, 2; the same output sizes at 640 x 400, and the same coordinates: half-pixel). The weights
are not touched. The result is checked to give the same logits, bit for bit, as the graph it was
made from on random 640 x 400 inputs, then written.

    python training/any_size_graph.py rebarlib/models/rebar_seg.onnx OUT.onnx

The shipped ``rebarlib/models/rebar_seg.onnx`` was made so from the stage-4 export, so that a
sidecar may set ``input.full_resolution`` to "whole": the network run once on the whole
1280 x 800 image instead of on 9 overlapping 640 x 400 tiles (docs/formats.md; measured in
docs/batch.md, "Speed"). The shipped sidecar keeps "tiles".
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from pad_graph import prune  # (training/, beside this script)


def any_size(model):
    """The graph of ``model`` (an ``onnx.ModelProto``, changed in place) with its fixed sizes
    replaced; returns it."""
    from onnx import TensorProto, helper, numpy_helper, shape_inference

    shape = {
        vi.name: [d.dim_value for d in vi.type.tensor_type.shape.dim]
        for vi in shape_inference.infer_shapes(model).graph.value_info
    }
    g = model.graph
    const = {n.output[0]: numpy_helper.to_array(n.attribute[0].t) for n in g.node if n.op_type == "Constant"}
    producer = {o: n for n in g.node for o in n.output}
    pools = [n for n in g.node if n.op_type == "GlobalAveragePool"]
    if len(pools) != 1 or sum(n.op_type == "Expand" for n in g.node) != 1:
        raise SystemExit("expected one image-pooling branch (GlobalAveragePool ... Expand)")
    feature = pools[0].input[0]  # the 1/16 feature map the pooled features are spread over
    nodes = []
    for n in g.node:
        if n.op_type == "Resize":
            x, sizes = n.input[0], n.input[3]
            out_hw = const[producer[sizes].input[1]]  # Concat(N and C of the input, constant (h, w))
            in_hw = shape[x][2:]
            scales = np.array([1.0, 1.0, out_hw[0] / in_hw[0], out_hw[1] / in_hw[1]], np.float32)
            if not all(float(s).is_integer() for s in scales):
                raise SystemExit(f"{n.name}: the resize is not by a whole factor ({scales.tolist()})")
            name = "scales_" + n.output[0].strip("/").replace("/", "_")
            g.initializer.append(numpy_helper.from_array(scales, name))
            del n.input[:]
            n.input.extend([x, "", name])
        elif n.op_type == "Expand":
            ones = helper.make_tensor("ones", TensorProto.INT64, [2], [1, 1])
            nodes.append(helper.make_node("Shape", [feature], ["pool_hw"], start=2, end=4))
            nodes.append(helper.make_node("Constant", [], ["pool_ones"], value=ones))
            nodes.append(helper.make_node("Concat", ["pool_ones", "pool_hw"], ["pool_shape"], axis=0))
            n.input[1] = "pool_shape"
        nodes.append(n)
    del g.node[:]
    g.node.extend(nodes)
    for vi in (g.input[0], g.output[0]):
        for d, name in zip(vi.type.tensor_type.shape.dim[2:], ("height", "width")):
            d.ClearField("dim_value")
            d.dim_param = name
    del g.value_info[:]
    prune(g, initializers=False)  # drop the nodes that computed the fixed sizes
    return model


def _same_logits(a_path: str, b_path: str, *, runs: int = 3) -> bool:
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads, so.log_severity_level = 1, 3
    a = ort.InferenceSession(a_path, so, providers=["CPUExecutionProvider"])
    b = ort.InferenceSession(b_path, so, providers=["CPUExecutionProvider"])
    shape = [d if isinstance(d, int) else 1 for d in b.get_inputs()[0].shape]
    name = b.get_inputs()[0].name
    for seed in range(runs):
        x = np.random.default_rng(seed).normal(0, 1.5, size=shape).astype(np.float32)
        if not np.array_equal(a.run(None, {name: x})[0], b.run(None, {name: x})[0]):
            return False
    return True


def main(argv=None) -> int:
    import onnx

    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("source", help="the exported graph (fixed 640 x 400 input)")
    ap.add_argument("out", help="where to write the graph that takes any size")
    a = ap.parse_args(argv)
    model = any_size(onnx.load(a.source))
    onnx.checker.check_model(model)
    tmp = a.out + ".tmp"
    onnx.save(model, tmp)
    if not _same_logits(tmp, a.source):
        print("the rewritten graph does not give the same logits at the exported size: not written")
        return 1
    import os

    os.replace(tmp, a.out)
    print(f"wrote {a.out}: the same logits as {a.source} at its input size, and any size with sides multiple of 16")
    return 0


if __name__ == "__main__":
    sys.exit(main())
