"""The capture stage: one RGB-D capture on disk and in memory, the camera model, and what the
inspection makes of a capture before the geometry: its point cloud and its rebar mask.

:func:`rebarlib.inspect` runs these steps itself; call them one at a time to look at each
(notebooks 01, 03 and 05):

* reading and writing: :func:`load_capture`, :func:`save_capture`, :func:`read_intrinsics`;
* the pinhole camera: :class:`Intrinsics` (``GEMINI2``, the default device), :func:`project`,
  :func:`backproject`, :func:`depth_to_points` giving a :class:`Cloud` (camera frame, mm,
  with the pixel of every point);
* thinning a cloud: :func:`voxel_downsample`, :func:`remove_outliers`;
* the inspection's first steps: :func:`prepare_cloud` (the cloud the geometry is fitted to),
  :func:`trim_edge_fattening` (a stereo camera's bleeding edges), :func:`rebar_mask` and
  :func:`registered_mask` (the mask the diameter stage reads).

Examples
--------
>>> import numpy as np
>>> from rebarlib.capture import Intrinsics, depth_to_points, project
>>> k = Intrinsics(fx=500.0, fy=500.0, cx=2.0, cy=1.5, width=4, height=3)
>>> cloud = depth_to_points(np.full((3, 4), 600.0), k)
>>> len(cloud.points), bool(np.allclose(project(cloud.points, k), cloud.pixels))
(12, True)
"""

from __future__ import annotations

from ._camera import GEMINI2, Cloud, Intrinsics, backproject, depth_to_points, project
from ._capture import Capture, load_capture, read_intrinsics, save_capture
from ._cloud import remove_outliers, voxel_downsample
from ._inspect import prepare_cloud, rebar_mask, registered_mask, trim_edge_fattening

__all__ = [
    "Capture",
    "load_capture",
    "save_capture",
    "read_intrinsics",
    "Intrinsics",
    "GEMINI2",
    "project",
    "backproject",
    "depth_to_points",
    "Cloud",
    "voxel_downsample",
    "remove_outliers",
    "prepare_cloud",
    "trim_edge_fattening",
    "rebar_mask",
    "registered_mask",
]
