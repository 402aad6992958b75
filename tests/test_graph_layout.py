"""The segmentation graph padded to whole channel blocks computes the shipped graph's numbers, to the bit."""

import numpy as np
import pytest

from rebarlib.segmentation import SegmentationModel
from rebarlib.segmentation._graph import _parse, _serialize, pad_concat_channels
from rebarlib.segmentation.model import MODELS_DIR, _channel_block

ONNX = MODELS_DIR / "rebar_seg.onnx"


def _session(graph):
    import onnxruntime as ort

    so = ort.SessionOptions()
    so.intra_op_num_threads = 1
    so.log_severity_level = 3
    return ort.InferenceSession(graph, so, providers=["CPUExecutionProvider"])


def test_codec_round_trip():
    raw = ONNX.read_bytes()
    assert _serialize(_parse(raw)) == raw


def test_padded_graph_pattern():
    raw = ONNX.read_bytes()
    padded = pad_concat_channels(raw, 16)
    assert padded is not None and padded != raw
    # 48 + 8 = 56 channels is a whole number of 8-channel blocks already: nothing to do
    assert pad_concat_channels(raw, 8) is None
    # the padded graph is itself left alone: its concatenation is whole
    assert pad_concat_channels(padded, 16) is None


@pytest.mark.parametrize("hw", [(400, 640), (96, 160)])
def test_padded_graph_same_numbers(hw):
    raw = ONNX.read_bytes()
    a, b = _session(str(ONNX)), _session(pad_concat_channels(raw, 16))
    x = np.random.default_rng(hw[0]).standard_normal((1, 3) + hw).astype(np.float32)
    ya, yb = a.run(None, {"image": x})[0], b.run(None, {"image": x})[0]
    assert ya.shape == yb.shape == (1, 1) + hw
    assert ya.tobytes() == yb.tobytes()


def test_model_uses_it_where_it_applies(monkeypatch):
    model = SegmentationModel.default(threads=1)
    assert model.layout_padded == (_channel_block() == 16)
    monkeypatch.setattr(SegmentationModel, "pad_layout", False)
    plain = SegmentationModel.default(threads=1)
    assert not plain.layout_padded
    img = np.random.default_rng(3).integers(0, 256, (800, 1280, 3), dtype=np.uint8)
    pa = model.predict_proba(img, tiled=True)
    pb = plain.predict_proba(img, tiled=True)
    assert pa.tobytes() == pb.tobytes()
