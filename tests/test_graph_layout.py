"""A model's blocked variant (its graph padded to whole channel blocks, written by
training/pad_graph.py) computes the graph's numbers, to the bit, and is what the model runs on a
CPU with 16-channel blocks (decision 027). Checked on the stage-4 network (shipped until decision
051, kept in training/candidates), whose one concatenation of 48 + 8 channels needs it. The
shipped network is its trained export rewritten by ``pad_graph.py --resize-scales`` (decision
056): its resizes at constant scales and its concatenations padded, so it needs no variant."""

import shutil
import sys
from pathlib import Path

import numpy as np
import pytest

from rebarlib.segmentation import SegmentationModel
from rebarlib.segmentation.model import MODELS_DIR, _channel_block

CANDIDATES = Path(__file__).resolve().parents[1] / "training" / "candidates"
STAGE4 = CANDIDATES / "deeplab_fine_stage4.onnx"
TRAINED = CANDIDATES / "deeplab_fine_w_dr11.onnx"  # the shipped network as exported after training
SHIPPED = MODELS_DIR / "rebar_seg.onnx"


def _pad_graph():
    pytest.importorskip("onnx")
    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "training"))
    try:
        import pad_graph
    finally:
        sys.path.pop(0)
    return pad_graph


@pytest.fixture(scope="module")
def stage4(tmp_path_factory):
    """The stage-4 model and its sidecar copied to a folder, with its blocked variant beside it."""
    d = tmp_path_factory.mktemp("stage4")
    onnx_path = d / "m.onnx"
    shutil.copy(STAGE4, onnx_path)
    shutil.copy(STAGE4.with_suffix(".json"), d / "m.json")
    assert _pad_graph().main([str(onnx_path), "--block", "16"]) == 0
    return onnx_path, d / "m.blocked16.onnx"


def _session(path):
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.log_severity_level = 3
    return ort.InferenceSession(str(path), so, providers=["CPUExecutionProvider"])


@pytest.mark.parametrize("hw", [(400, 640), (96, 160), (800, 1280)])
def test_blocked_variant_same_numbers(stage4, hw):
    a, b = _session(stage4[0]), _session(stage4[1])
    x = np.random.default_rng(hw[0]).standard_normal((1, 3) + hw).astype(np.float32)
    ya, yb = a.run(None, {"image": x})[0], b.run(None, {"image": x})[0]
    assert ya.shape == yb.shape == (1, 1) + hw
    assert ya.tobytes() == yb.tobytes()


def test_model_uses_it_where_it_applies(stage4, monkeypatch):
    model = SegmentationModel(stage4[0], threads=1)
    assert model.layout_padded == (_channel_block() == 16)
    assert not SegmentationModel.default(threads=1).layout_padded  # nothing to pad: no variant
    monkeypatch.setattr(SegmentationModel, "pad_layout", False)
    plain = SegmentationModel(stage4[0], threads=1)
    assert not plain.layout_padded
    img = np.random.default_rng(3).integers(0, 256, (800, 1280, 3), dtype=np.uint8)
    pa = model.predict_proba(img, tiled=True)
    pb = plain.predict_proba(img, tiled=True)
    assert pa.tobytes() == pb.tobytes()


def test_pad_graph_pads_only_what_needs_it(stage4, tmp_path):
    """training/pad_graph.py writes the same variant again, pads nothing twice, and finds nothing
    to pad in the shipped network (the onnx package is a training and development dependency,
    not a runtime one)."""
    pad_graph = _pad_graph()
    import onnx

    out = tmp_path / "m.blocked16.onnx"
    assert pad_graph.main([str(stage4[0]), "--block", "16", "--out", str(out)]) == 0
    a, b = _session(stage4[1]), _session(out)
    x = np.random.default_rng(1).standard_normal((1, 3, 96, 160)).astype(np.float32)
    assert a.run(None, {"image": x})[0].tobytes() == b.run(None, {"image": x})[0].tobytes()
    # 48 + 8 = 56 channels fill 8-channel blocks already, and the padded graph is whole: nothing to do
    assert pad_graph.pad_concat_channels(onnx.load(str(stage4[0])), 8) is None
    assert pad_graph.pad_concat_channels(onnx.load(str(out)), 16) is None
    assert pad_graph.pad_concat_channels(onnx.load(str(SHIPPED)), 16) is None


def test_the_shipped_graph_is_the_trained_export_rewritten(tmp_path):
    """``pad_graph.py --resize-scales`` on the trained export writes the shipped file's graph again
    (the same output bits); its output stays within 1e-5 of the export's on any input whose sides
    are multiples of 16, and it leaves nothing more to pad."""
    pad_graph = _pad_graph()
    import onnx

    out = tmp_path / "rewritten.onnx"
    assert pad_graph.main([str(TRAINED), "--resize-scales", "--out", str(out)]) == 0
    trained, shipped, again = _session(TRAINED), _session(SHIPPED), _session(out)
    for hw in [(800, 1280), (400, 640), (96, 160), (208, 336)]:
        x = np.random.default_rng(hw[1]).standard_normal((1, 3) + hw).astype(np.float32)
        ys, ya, yt = (s.run(None, {"image": x})[0] for s in (shipped, again, trained))
        assert ys.shape == yt.shape == (1, 1) + hw
        assert ys.tobytes() == ya.tobytes()
        assert np.max(np.abs(ys - yt)) < 1e-5
    graph = onnx.load(str(SHIPPED))
    resizes = [n for n in graph.graph.node if n.op_type == "Resize"]
    assert sum(len(n.input) == 3 for n in resizes) == 2  # the two decoder upsamplings; the logits' keeps its size
    assert pad_graph.pad_concat_channels(graph, 16) is None
    assert pad_graph.resize_scales(graph, 16) is None


def test_pad_graph_refuses_a_rewrite_beyond_its_limit(tmp_path, capsys):
    pad_graph = _pad_graph()
    out = tmp_path / "r.onnx"
    with pytest.raises(SystemExit, match="over --max-diff"):
        pad_graph.main([str(TRAINED), "--resize-scales", "--max-diff", "0", "--out", str(out)])
    assert not out.exists()
