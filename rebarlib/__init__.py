"""rebarlib: rebar inspection of reinforced-concrete slabs from one RGB-D capture.

Data flows one way: capture -> cloud -> formwork & layers -> bars -> spacing / cover /
diameter -> result tables -> acceptance -> report. The top level holds that workflow::

    design = rebarlib.load_design("slab/design.toml")
    results = [rebarlib.inspect(rebarlib.load_capture(c), design) for c in captures]
    acceptance = rebarlib.evaluate(results, design)
    rebarlib.build_report("slab", design, acceptance, out_path="report.pdf")

with the types it reads and returns. Each stage is a module, for those who want to run or study
it step by step: :mod:`rebarlib.capture` (camera model, point cloud, rebar mask),
:mod:`rebarlib.geometry`, :mod:`rebarlib.segmentation`, :mod:`rebarlib.diameter`,
:mod:`rebarlib.acceptance`, :mod:`rebarlib.report`, and beside them :mod:`rebarlib.synth` (the
simulator), :mod:`rebarlib.viz` (plots), :mod:`rebarlib.scan` and :mod:`rebarlib.cloud_io`
(scanned clouds). docs/decisions/014-public-api.md says why the top level is this small.

The names are imported when first used (``rebarlib.inspect`` loads the inspection stage,
``rebarlib.build_report`` the report's), so that ``import rebarlib`` and the ``rebar`` command
start at once: the heavy libraries (NumPy, pandas, Open3D, OpenCV, onnxruntime) load only where
a stage needs them.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: module -> the public names it gives this package (imported on first use, ``__getattr__``)
_EXPORTS = {
    "._capture": ["Capture", "load_capture", "save_capture", "load_cloud"],
    "._camera": ["Intrinsics", "GEMINI2"],
    "._design": ["Design", "Lattice", "BarSet", "load_design", "design_from_dict"],
    "._inspect": ["inspect"],
    ".scan": ["inspect_cloud"],
    ".batch": ["inspect_many"],
    "._results": ["InspectionResult", "Measurement"],
    ".acceptance": ["Acceptance", "Tolerances", "evaluate", "load_tolerances", "list_presets"],
    ".report": ["build_report"],
    "._checks": ["RebarInputError"],
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = ["__version__", *_WHERE]

#: Names the top level gave up to 0.1.0 (docs/decisions/014-public-api.md) -> their module now.
#: Asking the top level for one says where it went.
_MOVED = {
    **dict.fromkeys(
        [
            "Cloud",
            "project",
            "backproject",
            "depth_to_points",
            "read_intrinsics",
            "voxel_downsample",
            "remove_outliers",
            "prepare_cloud",
            "trim_edge_fattening",
            "rebar_mask",
            "registered_mask",
        ],
        "rebarlib.capture",
    ),
    **dict.fromkeys(
        [
            "Plane",
            "BarAxis",
            "fit_formwork",
            "paper_fit_formwork",
            "plane_frame",
            "to_slab_frame",
            "from_slab_frame",
            "find_layer_split",
            "bar_directions",
            "find_bars",
            "paper_find_bars",
            "group_directions",
            "measure_spacings",
        ],
        "rebarlib.geometry",
    ),
    **dict.fromkeys(
        [
            "measure_diameters",
            "bars_from_truth",
            "imaginary_plane",
            "intersect_rays_plane",
            "cross_section_direction",
            "diameter_region",
            "boundary_pixels",
            "bar_system",
            "observed_width_mm",
            "snap_diameter",
        ],
        "rebarlib.diameter",
    ),
    **dict.fromkeys(
        [
            "SegmentationModel",
            "mask_from_depth",
            "fuse_masks",
            "depth_overreach_px",
            "trim_depth_overreach",
            "estimate_registration",
            "shift_image",
            "confusion_counts",
            "pixel_accuracy",
            "iou",
            "dice",
        ],
        "rebarlib.segmentation",
    ),
    **dict.fromkeys(["ScanCloud", "read_cloud", "write_cloud"], "rebarlib.cloud_io"),
}


def __getattr__(name: str):
    if name.startswith("__"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module = _WHERE.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module, __name__), name)
    elif name in _MOVED:
        raise AttributeError(
            f"module {__name__!r} has no attribute {name!r}: it is "
            f"{_MOVED[name]}.{name} (docs/decisions/014-public-api.md)"
        )
    else:
        try:  # a sub-module (``rebarlib.geometry``), as an eager import of it would have bound
            value = importlib.import_module(f".{name}", __name__)
        except ModuleNotFoundError as exc:
            if exc.name != f"{__name__}.{name}":
                raise
            raise AttributeError(f"module {__name__!r} has no attribute {name!r}") from None
    globals()[name] = value
    return value


def __dir__():
    return sorted(set(globals()) | set(_WHERE))
