"""The public API: a small top level for the workflow, the stages as modules
(docs/decisions/014-public-api.md), and ``import rebarlib`` that loads no heavy library."""

from __future__ import annotations

import importlib
import subprocess
import sys

import pytest

import rebarlib

#: The workflow and the types it reads and returns: the whole top level.
TOP_LEVEL = {
    "load_capture",
    "save_capture",
    "load_cloud",
    "load_design",
    "design_from_dict",
    "inspect",
    "inspect_cloud",
    "inspect_many",
    "evaluate",
    "load_tolerances",
    "list_presets",
    "build_report",
    "Capture",
    "Design",
    "Lattice",
    "BarSet",
    "Intrinsics",
    "InspectionResult",
    "Measurement",
    "Acceptance",
    "Tolerances",
    "RebarInputError",
    "GEMINI2",
    "__version__",
}
STAGES = [
    "capture",
    "geometry",
    "segmentation",
    "diameter",
    "acceptance",
    "report",
    "synth",
    "viz",
    "scan",
    "cloud_io",
    "batch",
    "data",
]


def test_the_top_level_is_the_workflow():
    assert set(rebarlib.__all__) == TOP_LEVEL
    for name in rebarlib.__all__:
        assert getattr(rebarlib, name) is not None


@pytest.mark.parametrize("stage", STAGES)
def test_every_stage_is_a_module_with_the_names_it_lists(stage):
    module = getattr(rebarlib, stage)
    assert module is importlib.import_module(f"rebarlib.{stage}")
    for name in getattr(module, "__all__", []):
        assert hasattr(module, name), f"rebarlib.{stage}.{name}"


@pytest.mark.parametrize("name", sorted(rebarlib._MOVED))
def test_a_name_the_top_level_gave_up_says_where_it_is_now(name):
    home = rebarlib._MOVED[name]
    assert hasattr(importlib.import_module(home), name), f"{home}.{name}"
    with pytest.raises(AttributeError, match=rf"it is {home}\.{name}"):
        getattr(rebarlib, name)


def test_unknown_names_are_attribute_errors():
    with pytest.raises(AttributeError, match="no attribute 'no_such_name'"):
        rebarlib.no_such_name


def test_import_loads_no_heavy_library():
    code = (
        "import sys, rebarlib; rebarlib.__version__; "
        "print(sorted(m for m in ('numpy', 'pandas', 'open3d', 'cv2', 'onnxruntime')"
        " if m in sys.modules))"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"


def test_the_runtime_does_not_import_the_simulator():
    code = (
        "import sys, rebarlib; rebarlib.inspect; rebarlib.evaluate; rebarlib.build_report; "
        "rebarlib.inspect_many; rebarlib.inspect_cloud; import rebarlib.capture; "
        "print([m for m in sys.modules if 'synth' in m])"
    )
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, check=True)
    assert out.stdout.strip() == "[]"
