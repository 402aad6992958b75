"""rebarlib: rebar inspection of reinforced-concrete slabs from one RGB-D capture.

Data flows one way: capture -> cloud -> formwork & layers -> bars -> spacing / cover /
diameter -> result tables -> acceptance -> report. Each arrow is a public function here.
"""

from ._camera import GEMINI2, Cloud, Intrinsics, backproject, depth_to_points, project
from ._capture import Capture, load_capture, load_cloud, read_intrinsics, save_capture
from ._checks import RebarInputError, check_points
from ._cloud import remove_outliers, voxel_downsample
from ._design import BarSet, Design, Lattice, design_from_dict, load_design
from ._results import InspectionResult, Measurement
from ._inspect import inspect, prepare_cloud, rebar_mask, registered_mask, trim_edge_fattening
from .geometry import (BarAxis, Plane, bar_directions, find_bars, find_layer_split, fit_formwork,
                       from_slab_frame, group_directions, measure_spacings, paper_find_bars,
                       paper_fit_formwork, plane_frame, to_slab_frame)
from ._diameter import (bars_from_truth, boundary_pixels, cross_section_direction, diameter_region,
                        imaginary_plane, intersect_rays_plane, measure_diameters)
from ._barsizes import bar_system, observed_width_mm, snap_diameter
from .segmentation import (SegmentationModel, confusion_counts, depth_overreach_px, dice,
                           estimate_registration, fuse_masks, iou, mask_from_depth, pixel_accuracy,
                           shift_image, trim_depth_overreach)
from .acceptance import Acceptance, Tolerances, evaluate, list_presets, load_tolerances
from .report import build_report

__version__ = "0.1.0"

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
]
