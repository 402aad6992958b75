"""Inspecting a scanned point cloud (laser scanner, mobile LiDAR, photogrammetry): ``inspect_cloud``.

A scan differs from an RGB-D capture in everything the camera pipeline relies on: there is no
camera position (several stations are merged, the origin can be anywhere), no pixels, the noise
is 2–20 mm against bars of 8–20 mm, and the density varies tenfold across the cloud and between
directions. So the stages here are statistical: a bar is where the points pile up across a
direction, and its axis is the mean of many noisy points, not a fitted cross-section.

Stages (each a function):

1. :func:`mesh_up` — the mesh's normal (the formwork's, or the thin direction of the bars' cloud)
   and its sign: the given ``up``, else away from the formwork, else from the file's normals
   (oriented to the scanner), else guessed from the crossings (:func:`crossing_lift`). Never
   from the origin.
2. :func:`find_datum` — the formwork (or ground) plane under the mesh if the scan holds one, with
   the range noise measured on it; cover is measured from it, and without it cover is "not
   measured".
3. :func:`split_lattices` — the valley of the noise-smoothed height histogram between the lattices.
4. :func:`lattice_bars` — per lattice, the two bar directions (angular scan of the plan offsets),
   then the bars of each as peaks of the offset histogram that stand out of their local
   background by more than its counting noise (thresholds from the measured density and noise,
   not fixed ratios), and that run at least ``min_length_mm``.
5. Axes: per bar, a robust line through its band's points; height from the mean height of its
   points away from the crossings (points cover the upper half of a bar: the mean lies 2r/π
   above the axis), over a formwork as one component of a formwork/bar mixture.
6. Spacings (:func:`rebarlib.geometry.measure_spacings`), layer distance, cover, diameters (only
   where the noise allows, see :func:`diameter_resolvable`).

The stages live in private modules (``_datum``, ``_bars``, ``_axes``, ``_measure``,
``_pipeline``); everything public is imported here.
"""

from __future__ import annotations

from ._axes import crossing_lift
from ._bars import lattice_bars
from ._datum import Datum as Datum, find_datum, mesh_up, split_lattices
from ._input import METHOD as METHOD, as_scan_cloud, cloud_manifest, parse_up
from ._measure import diameter_resolvable
from ._pipeline import inspect_cloud

__all__ = [
    "as_scan_cloud",
    "cloud_manifest",
    "crossing_lift",
    "diameter_resolvable",
    "find_datum",
    "inspect_cloud",
    "lattice_bars",
    "mesh_up",
    "parse_up",
    "split_lattices",
]
