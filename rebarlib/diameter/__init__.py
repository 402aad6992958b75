"""Stage 3 of the method (method.md): the nominal diameter of every bar from the rebar mask, made
metric with each bar's axis.

Each bar's axis (from the point cloud) defines the imaginary plane γ: it contains the axis and
faces the camera. A pixel on the bar's silhouette edge is back-projected as a ray and met with γ,
so widths come out in millimetres without using the (often missing or wrong) depth at the bar's
edges.

Two methods:

- ``"paper"``: the paper's procedure (§3.3): parallelogram regions at detect-points, boundary
  pixels, D = min distance between the two sides, a vote in ±1 mm bins around the nominal sizes.
- ``"refined"`` (default): many cross-sections per bar; both edges found per section at sub-pixel
  precision on the mask profile; sections at crossings, under a nearer bar, at the image border
  or in deep shadow are dropped; the median width is snapped to the observed (rib-envelope)
  width of a standard size with a confidence; weak evidence gives "not measured". How far the
  colour edges and the mask can be trusted is learnt from the capture's own bars of one design
  size (their true widths are equal): the colour edges' shading offset, each width's spread
  between bars.

Modules, in the order the data flows:

- :mod:`~rebarlib.diameter.barsizes`: the standards' bar sizes and snapping a width to a size
- :mod:`~rebarlib.diameter.plane`: the plane γ and the paper's regions
- :mod:`~rebarlib.diameter.bars`: the bars table read in, each bar's footprint in the image
- :mod:`~rebarlib.diameter.sections`: cross-sections and their edges (refined)
- :mod:`~rebarlib.diameter.runs`: the mask run through the axis in each section, cut at depth steps
- :mod:`~rebarlib.diameter.cloud`: widths from the point cloud
- :mod:`~rebarlib.diameter.ribs`, :mod:`~rebarlib.diameter.pitch`: ribs and rib pitches
- :mod:`~rebarlib.diameter.calibration`: what the capture's own bars teach
- :mod:`~rebarlib.diameter.decision`: size, confidence and reason of one bar (refined)
- :mod:`~rebarlib.diameter.paper`: the paper's procedure
- :mod:`~rebarlib.diameter.measure`: :func:`measure_diameters`, the entry point
"""

from __future__ import annotations

from .bars import bars_from_truth
from .barsizes import BAR_SYSTEMS, BarSystem, bar_system, barset_width_mm, observed_width_mm, snap_diameter
from .measure import measure_diameters
from .params import BAR_COLUMNS, DIAMETER_COLUMNS, DiameterParams
from .plane import (
    BarPlane,
    boundary_pixels,
    cross_section_direction,
    diameter_region,
    imaginary_plane,
    intersect_rays_plane,
    pixels_in_region,
)
from .reading import BarReading

__all__ = [
    "BarPlane",
    "imaginary_plane",
    "intersect_rays_plane",
    "cross_section_direction",
    "diameter_region",
    "pixels_in_region",
    "boundary_pixels",
    "bars_from_truth",
    "measure_diameters",
    "BAR_COLUMNS",
    "DIAMETER_COLUMNS",
    "BAR_SYSTEMS",
    "BarSystem",
    "bar_system",
    "barset_width_mm",
    "observed_width_mm",
    "snap_diameter",
    "BarReading",
    "DiameterParams",
]
