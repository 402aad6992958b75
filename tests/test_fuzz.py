"""Fuzzing the inputs (issue 55): captures (camera.json fields of every JSON type, PNG headers,
image sizes, depth scales, dropout), design files (every key with values of every type and
range, unknown keys) and `rebar report`'s output paths.

Every case must end in a :class:`RebarInputError` naming the file or the key, or in a result
whose every measured value is within its stated uncertainty of the truth (K_SIGMA σ + SLACK_MM)
and every other value "not measured" with a reason; never in another exception, and never with
an input written over.

The default run is short and the same every time (``derandomize``); set REBAR_FUZZ_EXAMPLES to
try more cases per test. Run with ``-s`` to see how many cases each test tried and how they ended.
"""

from __future__ import annotations

import collections
import copy
import hashlib
import json
import os
import shutil
import tempfile
from pathlib import Path

import numpy as np
import pytest

hypothesis = pytest.importorskip("hypothesis")
from hypothesis import HealthCheck, given, settings  # noqa: E402
from hypothesis import strategies as st  # noqa: E402

from rebarlib import GEMINI2, RebarInputError, design_from_dict, inspect, load_capture, save_capture  # noqa: E402
from rebarlib._design import DESIGN_KEYS  # noqa: E402
from rebarlib.cli import main  # noqa: E402
from rebarlib.data import _PAPER as PAPER_DESIGN  # noqa: E402
from rebarlib.data import paper_design  # noqa: E402
from rebarlib.synth import SensorModel, synth_capture  # noqa: E402

EXAMPLES = Path(__file__).resolve().parent.parent / "examples"
N = int(os.environ.get("REBAR_FUZZ_EXAMPLES", "25"))
FUZZ = settings(
    max_examples=N,
    deadline=None,
    derandomize=True,
    database=None,
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.function_scoped_fixture],
)
K_SIGMA, SLACK_MM = 3.0, 0.5
OUTCOMES = collections.defaultdict(collections.Counter)

#: Any JSON value: what a hand-edited or hostile camera.json / design.toml may hold
JSON = st.recursive(
    st.none()
    | st.booleans()
    | st.integers(-(2**40), 2**40)
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=20),
    lambda inner: st.lists(inner, max_size=4) | st.dictionaries(st.text(max_size=8), inner, max_size=3),
    max_leaves=6,
)


@pytest.fixture(scope="module", autouse=True)
def tally():
    yield
    for test, counts in sorted(OUTCOMES.items()):
        print(f"\n{test}: {sum(counts.values())} cases: " + ", ".join(f"{n} {k}" for k, n in sorted(counts.items())))


@pytest.fixture(scope="module")
def capture_dir():
    """A small saved capture (320 x 200) to copy and spoil."""
    root = Path(tempfile.mkdtemp(prefix="rebar_fuzz_"))
    save_capture(synth_capture(paper_design(), intrinsics=GEMINI2.scaled(0.25), seed=2, name="c"), root / "c")
    yield root / "c"
    shutil.rmtree(root, ignore_errors=True)


def _copy(src: Path) -> Path:
    dst = Path(tempfile.mkdtemp(prefix="rebar_fuzz_")) / src.name
    shutil.copytree(src, dst)
    return dst


def _load(folder: Path, test: str, names) -> None:
    """load_capture: a Capture, or a RebarInputError naming one of ``names``; nothing else."""
    try:
        load_capture(folder)
        OUTCOMES[test]["loaded"] += 1
    except RebarInputError as exc:
        assert any(n in str(exc) for n in names), str(exc)
        assert "\n" not in str(exc)
        OUTCOMES[test]["RebarInputError naming the file"] += 1
    finally:
        shutil.rmtree(folder.parent, ignore_errors=True)


# ------------------------------------------------------------------------------------------------
# Captures
# ------------------------------------------------------------------------------------------------

CAMERA_KEYS = ("width", "height", "intrinsic_matrix", "depth_scale_mm", "device", "captured_at")


@FUZZ
@given(key=st.sampled_from(CAMERA_KEYS), value=JSON)
def test_camera_json_any_value_of_any_key(capture_dir, key, value):
    folder = _copy(capture_dir)
    data = json.loads((folder / "camera.json").read_text(encoding="utf-8"))
    data[key] = value
    (folder / "camera.json").write_text(json.dumps(data), encoding="utf-8")
    _load(folder, "camera.json values", ["camera.json"])


@FUZZ
@given(
    offset=st.integers(0, 40),
    junk=st.binary(min_size=1, max_size=16),
    which=st.sampled_from(["depth.png", "color.png"]),
    cut=st.none() | st.integers(0, 200),
)
def test_png_headers_spoilt_or_cut(capture_dir, offset, junk, which, cut):
    folder = _copy(capture_dir)
    raw = bytearray((folder / which).read_bytes())
    raw[offset : offset + len(junk)] = junk
    if cut is not None:
        raw = raw[:cut]
    (folder / which).write_bytes(bytes(raw))
    _load(folder, "PNG headers", [which, "camera.json", str(folder)])


@FUZZ
@given(
    width=st.integers(0, 2**31 - 1), height=st.integers(0, 2**31 - 1), which=st.sampled_from(["depth.png", "color.png"])
)
def test_png_header_declaring_any_size(capture_dir, width, height, which):
    import zlib

    folder = _copy(capture_dir)
    raw = bytearray((folder / which).read_bytes())
    raw[16:24] = width.to_bytes(4, "big") + height.to_bytes(4, "big")
    raw[29:33] = zlib.crc32(bytes(raw[12:29])).to_bytes(4, "big")
    (folder / which).write_bytes(bytes(raw))
    _load(folder, "PNG declared sizes", [which, "camera.json", str(folder)])


@FUZZ
@given(w=st.integers(1, 64), h=st.integers(1, 64), scale=st.floats(1e-4, 200), depth_max=st.integers(0, 65535))
def test_images_of_any_size_and_depth_scale(w, h, scale, depth_max):
    import cv2

    folder = Path(tempfile.mkdtemp(prefix="rebar_fuzz_")) / "c"
    folder.mkdir()
    rng = np.random.default_rng(w * 1000 + h)
    cv2.imwrite(str(folder / "color.png"), rng.integers(0, 255, (h, w, 3), dtype=np.uint8))
    cv2.imwrite(str(folder / "depth.png"), rng.integers(0, depth_max + 1, (h, w)).astype(np.uint16))
    cam = {"width": w, "height": h, "intrinsic_matrix": [w, 0, 0, 0, w, 0, w / 2, h / 2, 1], "depth_scale_mm": scale}
    (folder / "camera.json").write_text(json.dumps(cam), encoding="utf-8")
    _load(folder, "image sizes and scales", ["camera.json", "depth.png", "color.png"])


def _honest(res, truth) -> str:
    kinds = []
    for key in ("cover", "layer_distance", "upper_top"):
        m = getattr(res, key)
        if m.ok:
            err = abs(m.value_mm - truth[f"{key}_mm"])
            assert err <= K_SIGMA * m.uncertainty_mm + SLACK_MM, (key, m, truth[f"{key}_mm"])
            kinds.append("measured")
        else:
            assert m.value_mm is None and m.reason
    return f"{len(kinds)} of 3 heights measured, all within {K_SIGMA:g} sigma + {SLACK_MM} mm"


@pytest.mark.slow
@settings(FUZZ, max_examples=max(2, N // 5))
@given(fraction=st.floats(0.5, 0.99), patch_px=st.sampled_from([0.0, 6.0, 20.0]), seed=st.integers(0, 5))
def test_dropout_gives_right_numbers_or_none(fraction, patch_px, seed):
    design = paper_design()
    sensor = SensorModel(dropout=fraction, dropout_patch_px=patch_px)
    cap = synth_capture(design, intrinsics=GEMINI2.scaled(0.5), sensor=sensor, seed=seed, scene_seed=seed + 10)
    try:
        res = inspect(cap, design, diameters=False, rng=seed)
    except RebarInputError as exc:  # too few points left at all
        assert "capture" in str(exc)
        OUTCOMES["dropout"]["RebarInputError naming the capture"] += 1
        return
    OUTCOMES["dropout"][_honest(res, cap.truth)] += 1


# ------------------------------------------------------------------------------------------------
# Design files
# ------------------------------------------------------------------------------------------------


def _paths(data, prefix=()):
    """Every (path, value) of a nested design dict."""
    for k, v in data.items():
        yield prefix + (k,), v
        if isinstance(v, dict):
            yield from _paths(v, prefix + (k,))


FULL_DESIGN = copy.deepcopy(PAPER_DESIGN)
FULL_DESIGN["slab"].update(
    {
        "standard": "GB50204-2015",
        "element": "slab",
        "project": "p",
        "drawing": "d",
        "contractor": "c",
        "record": "r",
        "lot": "l",
    }
)
FULL_DESIGN["design"]["lower"] = {"diameter_mm": 14, "spacing_mm": 200, "top": {"diameter_mm": 14, "spacing_mm": 200}}
DESIGN_PATHS = [p for p, _ in _paths(FULL_DESIGN)]


def _set(data, path, value):
    d = data
    for k in path[:-1]:
        d = d[k]
    d[path[-1]] = value


@FUZZ
@given(path=st.sampled_from(DESIGN_PATHS), value=JSON | st.floats(-1e6, 1e6) | st.integers(-(10**6), 10**6))
def test_design_any_key_with_any_value(path, value):
    data = copy.deepcopy(FULL_DESIGN)
    _set(data, path, value)
    try:
        design_from_dict(data, source="fuzz.toml")
        OUTCOMES["design values"]["loaded"] += 1
    except RebarInputError as exc:
        msg = str(exc)
        assert msg.startswith("fuzz.toml") and "\n" not in msg
        assert any(str(k) in msg for k in path) or "[" in msg, msg  # names the key or its table
        OUTCOMES["design values"]["RebarInputError naming the key"] += 1


KNOWN = set().union(*DESIGN_KEYS.values())


@FUZZ
@given(
    table=st.sampled_from([(), ("slab",), ("design",), ("design", "lower"), ("design", "upper")]),
    key=st.text(min_size=1, max_size=12).filter(lambda k: k not in KNOWN),
    value=JSON,
)
def test_design_unknown_keys_are_named(table, key, value):
    data = copy.deepcopy(FULL_DESIGN)
    _set(data, table + (key,), value)
    with pytest.raises(RebarInputError) as info:
        design_from_dict(data, source="fuzz.toml")
    assert f"unknown key {key!r}" in str(info.value) or f"unknown key '{key}'" in str(info.value)
    OUTCOMES["design unknown keys"]["RebarInputError naming the key"] += 1


# ------------------------------------------------------------------------------------------------
# `rebar report`'s output paths
# ------------------------------------------------------------------------------------------------

TARGETS = [
    "design",
    "capture file",
    "capture folder",
    "new in capture",
    "results file",
    "results folder",
    "existing folder",
    "new folder/",
    "below a file",
    "existing report",
    "fresh file",
    "slab folder",
    "new in results",
]


def _digest(folder: Path) -> dict:
    return {str(p): hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.rglob("*")) if p.is_file()}


@pytest.mark.slow
@FUZZ
@given(
    target=st.sampled_from(TARGETS),
    force=st.booleans(),
    fmt=st.sampled_from(["html", "htm-suffix"]),
    results=st.booleans(),
    exports=st.booleans(),
)
def test_report_output_paths(capture_dir, monkeypatch, capsys, target, force, fmt, results, exports):
    import rebarlib._cli_report as cli_report

    root = Path(tempfile.mkdtemp(prefix="rebar_fuzz_"))
    try:
        slab = root / "slab"
        slab.mkdir()
        shutil.copy(EXAMPLES / "paper_slab" / "design.toml", slab / "design.toml")
        shutil.copytree(capture_dir, slab / "A")
        res = root / "res"
        (res / "A").mkdir(parents=True)
        (res / "A" / "result.json").write_text("{}", encoding="utf-8")
        (root / "afile").write_text("x", encoding="utf-8")
        (root / "old.html").write_text("old", encoding="utf-8")
        (root / "existing").mkdir()
        out = {
            "design": slab / "design.toml",
            "capture file": slab / "A" / "depth.png",
            "capture folder": slab / "A",
            "new in capture": slab / "A" / "r.pdf",
            "results file": res / "A" / "result.json",
            "results folder": res,
            "existing folder": root / "existing",
            "new folder/": str(root / "new") + "/",
            "below a file": root / "afile" / "r.pdf",
            "existing report": root / "old.html",
            "fresh file": root / "r.html",
            "slab folder": slab,
            "new in results": res / "A" / "r.html",
        }[target]
        monkeypatch.setattr(cli_report, "collect_results", lambda s, **k: ([], [("A", "no result")]))
        inputs = {**_digest(slab), **(_digest(res) if results else {})}  # the results are inputs with --results
        argv = (
            ["report", str(slab), "--out", str(out)]
            + (["--force"] if force else [])
            + (["--format", "html"] if fmt == "html" else [])
            + (["--results", str(res)] if results else [])
            + ([] if exports else ["--no-exports"])
        )
        code = main(argv)
        err = capsys.readouterr().err
        assert code in (0, 2)
        if code == 2:
            assert err.startswith("rebar report: error: --out") and err.count("\n") == 1, err
        after = {**_digest(slab), **(_digest(res) if results else {})}
        assert {k: after.get(k) for k in inputs} == inputs  # no input written over
        new = set(after) - set(inputs)  # nothing new inside a capture or a capture's results
        guarded = [slab / "A"] + ([res / "A"] if results else [])
        assert not [k for k in new if Path(k).parent in guarded], new
        if target in ("design", "capture file", "new in capture", "below a file", "capture folder") or (
            target in ("new in results", "results file") and results
        ):
            assert code == 2
        if target == "existing report":
            assert code == (0 if force else 2)
        OUTCOMES["report --out"]["written" if code == 0 else "refused with a one-line error"] += 1
    finally:
        shutil.rmtree(root, ignore_errors=True)
