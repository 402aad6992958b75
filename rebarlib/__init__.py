"""rebarlib: rebar inspection of reinforced-concrete slabs from one RGB-D capture.

Data flows one way: capture -> cloud -> formwork & layers -> bars -> spacing / cover /
diameter -> result tables -> acceptance -> report. Each arrow is a public function here.

The names below are imported when first used (``rebarlib.inspect`` loads the inspection stage,
``rebarlib.build_report`` the report's), so that ``import rebarlib`` and the ``rebar`` command
start at once: the heavy libraries (NumPy, pandas, Open3D, OpenCV, onnxruntime) load only where
a stage needs them.
"""

from __future__ import annotations

import importlib

__version__ = "0.1.0"

#: module -> the public names it gives this package (imported on first use, ``__getattr__``)
_EXPORTS = {
    "._camera": ["GEMINI2", "Cloud", "Intrinsics", "backproject", "depth_to_points", "project"],
    "._capture": ["Capture", "load_capture", "load_cloud", "read_intrinsics", "save_capture"],
    "._checks": ["RebarInputError", "check_points"],
    "._cloud": ["remove_outliers", "voxel_downsample"],
    "._design": ["BarSet", "Design", "Lattice", "design_from_dict", "load_design"],
    "._results": ["InspectionResult", "Measurement"],
    "._inspect": ["inspect", "prepare_cloud", "rebar_mask", "registered_mask",
                  "trim_edge_fattening"],
    ".geometry": ["BarAxis", "Plane", "bar_directions", "find_bars", "find_layer_split",
                  "fit_formwork", "from_slab_frame", "group_directions", "measure_spacings",
                  "paper_find_bars", "paper_fit_formwork", "plane_frame", "to_slab_frame"],
    ".diameter": ["bars_from_truth", "boundary_pixels", "cross_section_direction",
                   "diameter_region", "imaginary_plane", "intersect_rays_plane",
                   "measure_diameters"],
    ".diameter.barsizes": ["bar_system", "observed_width_mm", "snap_diameter"],
    ".segmentation": ["SegmentationModel", "confusion_counts", "depth_overreach_px", "dice",
                      "estimate_registration", "fuse_masks", "iou", "mask_from_depth",
                      "pixel_accuracy", "shift_image", "trim_depth_overreach"],
    ".acceptance": ["Acceptance", "Tolerances", "evaluate", "list_presets", "load_tolerances"],
    ".report": ["build_report"],
    ".batch": ["inspect_many"],
    ".scan": ["inspect_cloud"],
    ".cloud_io": ["ScanCloud", "read_cloud", "write_cloud"],
}
_WHERE = {name: module for module, names in _EXPORTS.items() for name in names}

__all__ = [
    "GEMINI2", "Intrinsics", "Cloud", "project", "backproject", "depth_to_points",
    "Capture", "load_capture", "save_capture", "load_cloud", "read_intrinsics",
    "RebarInputError", "check_points", "remove_outliers", "voxel_downsample",
    "BarSet", "Lattice", "Design", "load_design", "design_from_dict", "__version__",
    "InspectionResult", "Measurement", "inspect", "prepare_cloud", "rebar_mask", "registered_mask",
    "trim_edge_fattening",
    "Plane", "BarAxis", "fit_formwork", "paper_fit_formwork", "plane_frame", "to_slab_frame",
    "from_slab_frame", "find_layer_split", "bar_directions", "find_bars", "paper_find_bars",
    "group_directions", "measure_spacings",
    "measure_diameters", "bars_from_truth", "imaginary_plane", "intersect_rays_plane",
    "cross_section_direction", "diameter_region", "boundary_pixels", "bar_system", "observed_width_mm",
    "snap_diameter",
    "SegmentationModel", "mask_from_depth", "fuse_masks", "depth_overreach_px",
    "trim_depth_overreach", "estimate_registration", "shift_image",
    "confusion_counts", "pixel_accuracy", "iou", "dice",
    "Acceptance", "Tolerances", "evaluate", "load_tolerances", "list_presets", "build_report",
    "inspect_many", "inspect_cloud", "ScanCloud", "read_cloud", "write_cloud",
]


def __getattr__(name: str):
    if name.startswith("__"):
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    module = _WHERE.get(name)
    if module is not None:
        value = getattr(importlib.import_module(module, __name__), name)
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
