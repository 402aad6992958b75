"""rebarlib: rebar inspection of reinforced-concrete slabs from one RGB-D capture.

Data flows one way: capture -> cloud -> formwork & layers -> bars -> spacing / cover /
diameter -> result tables -> acceptance -> report. Each arrow is a public function here.
"""

from ._camera import GEMINI2, Cloud, Intrinsics, backproject, depth_to_points, project
from ._capture import Capture, load_capture, load_cloud, read_intrinsics, save_capture
from ._checks import RebarInputError, check_points
from ._cloud import remove_outliers, voxel_downsample
from ._design import BarSet, Design, Lattice, design_from_dict, load_design

__version__ = "0.1.0"

__all__ = [
    "GEMINI2", "Intrinsics", "Cloud", "project", "backproject", "depth_to_points",
    "Capture", "load_capture", "save_capture", "load_cloud", "read_intrinsics",
    "RebarInputError", "check_points", "remove_outliers", "voxel_downsample",
    "BarSet", "Lattice", "Design", "load_design", "design_from_dict", "__version__",
]
