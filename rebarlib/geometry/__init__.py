"""Stages 1–2 of the method (method.md): formwork plane, alignment, layers, cover, layer distance,
individual bars and spacing — the paper's procedure and ours, as small composable functions.

Frames. Everything starts in the camera frame (OpenCV, mm). ``plane_frame(plane)`` gives a rotation
whose third row is the formwork normal pointing at the camera; in that *slab frame* a point is
``(a, b, h)``: two plan coordinates and the height above the formwork. Bars are fitted there and
their axes are converted back to the camera frame for the result tables.

Two methods
-----------
``paper``   the published procedure, step by step (``paper_*`` functions).
``refined`` ours (the default). What changes and why:

1. **Formwork plane**: RANSAC (Open3D) with a threshold derived from the design cover, then a
   least-squares refit on inliers re-selected at 4 robust standard deviations of the measured
   noise: the plane is then limited by the sensor noise, not by the RANSAC threshold. A plane
   is accepted as formwork only if almost nothing lies beneath it; otherwise (a capture of bars
   alone) cover is "not measured" and the bars are still measured relative to each other.
2. **Layers from the data**: the split is the widest empty band of the height histogram, not a
   fixed 50 mm, so any cover and layer distance work.
3. **Bars by structure, not by sequential RANSAC**: the two bar directions of a lattice are the
   angles at which the points' plan offsets are sharpest (an angular scan); across each
   direction, bars are peaks of the offset histogram. This finds every bar in one pass, with no
   random misses and no phantom lines through crossing bars.
4. **Cross-section model**: each bar's points are fitted with a cylinder of the design rib
   envelope radius (robust Gauss–Newton, axis allowed to drift linearly along the bar). The
   camera sees only the top of a bar; the fitted circle's centre is the true axis (no bias toward
   the camera) and centre height − radius is the bar's underside, so cover and layer distance
   follow the definitions in method.md without the paper's 1.2·d correction.
5. **Spacing** is the perpendicular distance between fitted axes at the middle of the two bars'
   common visible stretch, so it is centre to centre whatever the bars' diameters.
6. **Counts**: a design position with no bar is counted missing only if the depth image shows the
   formwork there (a position hidden by an upper bar or outside the image is not "missing").
7. **Found, but not measured**: a bar whose axis the data cannot place (seen as a sliver, as
   specks beside the bar above it, or as a strip along the image border with its fit off its
   level: ``flag_border_cut``) is reported "not measured" with an approximate axis, never
   dropped and never given the failed fit's axis.

Modules, in the order the data flows:

- :mod:`~rebarlib.geometry.plane`: the formwork plane and the slab frame
- :mod:`~rebarlib.geometry.layers`: the split between the two lattices
- :mod:`~rebarlib.geometry.bars`, :mod:`~rebarlib.geometry.fit`, :mod:`~rebarlib.geometry.axis`:
  the bars of one lattice, the cylinder fitted to each, a fitted bar
- :mod:`~rebarlib.geometry.directions`: a lattice's bar directions and the bars' places across
  each; :mod:`~rebarlib.geometry.bar_checks`: the checks on the fitted bars
- :mod:`~rebarlib.geometry.partial`: bars seen only in part
- :mod:`~rebarlib.geometry.levels`: bottom and top levels, tops and stack heights
- :mod:`~rebarlib.geometry.spacing`: spacings, the paper's counts, the bars table
- :mod:`~rebarlib.geometry.second_look`: a second look at the empty positions of a row
- :mod:`~rebarlib.geometry.paper`: the paper's procedure
- :mod:`~rebarlib.geometry.scoring`: a result scored against a synthetic capture's truth
- :mod:`~rebarlib.geometry.params`: :class:`GeometryParams`, the bar search's tuning
"""

from __future__ import annotations

from .axis import BarAxis, envelope_mm
from .bars import bar_directions, direction_sharpness, find_bars
from .layers import LAYERS, LEVELS, find_layer_split, split_layers
from .levels import assign_levels, level_heights, stack_heights, top_heights
from .paper import group_directions, paper_find_bars, paper_spacings
from .params import GeometryParams
from .partial import flag_border_cut
from .plane import Plane, fit_formwork, from_slab_frame, paper_fit_formwork, plane_frame, to_slab_frame
from .second_look import _in_image, find_missed_bars  # noqa: F401  (_in_image: rebarlib._counts)
from .spacing import _pair_spacing, bars_table, count_bars, measure_spacings  # noqa: F401
from .axis import _runs  # noqa: F401  (rebarlib._evidence)

__all__ = [
    "Plane",
    "BarAxis",
    "fit_formwork",
    "paper_fit_formwork",
    "plane_frame",
    "to_slab_frame",
    "from_slab_frame",
    "split_layers",
    "find_layer_split",
    "bar_directions",
    "find_bars",
    "paper_find_bars",
    "group_directions",
    "bars_table",
    "measure_spacings",
    "paper_spacings",
    "level_heights",
    "stack_heights",
    "top_heights",
    "count_bars",
    "envelope_mm",
    "direction_sharpness",
    "flag_border_cut",
    "assign_levels",
    "find_missed_bars",
    "LAYERS",
    "LEVELS",
    "GeometryParams",
]
