"""``inspect_cloud``: the stages of a scanned cloud in order."""

from __future__ import annotations

import math
import time

import numpy as np

from .. import geometry as G
from .._checks import RebarInputError
from .._design import Design
from .._results import InspectionResult
from ..cloud_io import ScanCloud
from ._axes import _all_axes, _frame, crossing_lift
from ._datum import Datum, find_datum, mesh_up
from ._edges import mark_cut_sections
from ._input import as_scan_cloud
from ._measure import _assemble


def inspect_cloud(
    cloud,
    design: Design,
    *,
    units: str | None = None,
    up=None,
    min_length_mm: float = 100.0,
    diameters: bool = True,
    rng=0,
    name: str | None = None,
) -> InspectionResult:
    """Cover, layer distance, bars, spacings (and diameters where the scan resolves them) of a
    scanned point cloud of a two-lattice mesh.

    Parameters
    ----------
    cloud : a cloud file (any format of :mod:`rebarlib.cloud_io`; ``units`` required), a
        :class:`~rebarlib.cloud_io.ScanCloud`, or an (N, 3) array (mm unless ``units="m"``)
    design : the slab's :class:`~rebarlib.Design`
    units : "mm" or "m" for a file or an array in metres
    up : "+x", "-x", "+y", "-y", "+z", "-z" or a vector: the mesh's up side in the cloud's frame;
        None: found (away from the formwork, else toward the denser lattice; the result's notes
        say which)
    min_length_mm : a bar is reported when at least this much of it is scanned
    diameters : size the bars where the scan's noise allows (:func:`diameter_resolvable`)

    Returns
    -------
    InspectionResult with ``method="cloud"``; bar coordinates are in the cloud's frame re-centred
    (``extras["cloud"]["offset_mm"]`` added gives the file's frame, in mm).
    """
    if not isinstance(design, Design):
        raise RebarInputError(
            f"design: expected a rebarlib.Design (use rebarlib.load_design), got {type(design).__name__}"
        )
    t_start = time.perf_counter()
    sc = as_scan_cloud(cloud, units=units)
    pts = sc.points
    if len(pts) < 500:
        raise RebarInputError(f"cloud {sc.source or 'array'}: {len(pts)} points, at least 500 needed for a mesh")
    rng = np.random.default_rng(rng)
    notes = []
    normal, up_how = mesh_up(pts, up=up, rng=rng)
    datum = find_datum(pts, normal, rng=rng)
    if datum.found and up is None:
        normal, up_how = (datum.plane.normal, "away from the formwork/ground plane found under the mesh")
    elif datum.found and float(datum.plane.normal @ normal) < 0:
        datum = Datum(
            G.Plane(normal, 0.0),
            False,
            None,
            datum.share,
            "the only plane found lies above the mesh (for the up given): no formwork in the scan",
        )
    plane, q, split = _frame(pts, normal, datum)
    result_bars, noise = _all_axes(q, split, design, datum, min_length_mm, rng)
    if not datum.found and up is None:
        # nothing else settles the sign: a scanner looks down on the mesh, so where two bars
        # cross, the one beneath is hidden and the band along it holds the crossing bar's points,
        # which lie higher than its own: heights lift at the crossings only when up is up
        facing = _normals_facing(sc, plane.normal)
        if facing is not None:
            flip = facing < 0
            up_how = (
                f"the mesh plane from the bars (no formwork in the scan); its sign from the file's normals "
                f"({100 * abs(facing):.0f} % more of them face that side: the scanner's)"
            )
            if flip:
                plane, q, split = _frame(pts, -normal, datum)
                result_bars, noise = _all_axes(q, split, design, datum, min_length_mm, rng)
        else:
            (plane, q, split, result_bars, noise), up_how = _sign_from_crossings(
                pts, normal, datum, design, (plane, q, split, result_bars, noise), min_length_mm, rng
            )
    notes.append(f"up: {up_how}")
    if not result_bars:
        notes.append(
            "no bar found: nothing in the cloud lines up as the design's two lattices of bars (a slab's "
            "mesh seen from above or below); check the units, up= and the design's spacings and diameters"
        )
    result_bars = mark_cut_sections(q, result_bars, noise)
    sig = float(np.median([v[0] for v in noise.values()]))
    if not result_bars:  # no spread across bars to report (sig is then the search's starting guess)
        notes.append(
            f"noise σ: {datum.noise_mm or float('nan'):.1f} mm across the formwork; no bars to measure a spread on"
            if datum.found
            else "noise σ: not measured (no formwork and no bars in the scan)"
        )
    else:
        notes.append(
            f"noise σ: {datum.noise_mm or float('nan'):.1f} mm across the formwork, "
            f"spread {sig:.1f} mm across the bars in plan (noise and what lies beside them)"
            if datum.found
            else f"spread σ: {sig:.1f} mm across the bars in plan (noise and what lies beside them; no formwork)"
        )
    return _assemble(
        sc, design, plane, datum, result_bars, sig, notes, diameters, q, name=name, t_start=t_start, up_how=up_how
    )


def _normals_facing(sc: ScanCloud, normal) -> float | None:
    """The share of the file's normals on ``normal``'s side less that on the other side, or None
    without normals or when they are unoriented (under 20 % more on one side)."""
    nrm = sc.fields.get("normals")
    if nrm is None or np.ndim(nrm) != 2 or np.shape(nrm)[1] != 3:
        return None
    dots = np.asarray(nrm, float) @ np.asarray(normal, float)
    dots = dots[np.isfinite(dots) & (np.abs(dots) > 0.1)]
    if len(dots) < 100:
        return None
    facing = float(np.mean(dots > 0) - np.mean(dots < 0))
    return facing if abs(facing) >= 0.2 else None


def _sign_from_crossings(pts, normal, datum: Datum, design: Design, current, min_length_mm, rng):
    """The frame (plane, points, split, bars, noise) of the two signs of ``normal`` in which the
    heights lift more at the bars' crossings (:func:`crossing_lift`), and how it was chosen.
    ``current`` is the frame along ``normal``, already measured."""
    lift = crossing_lift(current[1], current[3], current[4])
    try:
        plane, q, split = _frame(pts, -normal, datum)
    except RebarInputError:
        other, lift_other = None, -math.inf
    else:
        bars, noise = _all_axes(q, split, design, datum, min_length_mm, rng)
        other, lift_other = (plane, q, split, bars, noise), crossing_lift(q, bars, noise)
    best, (hi, lo) = (other, (lift_other, lift)) if lift_other > lift else (current, (lift, lift_other))
    how = (
        "the mesh plane from the bars (no formwork in the scan); its sign GUESSED from the crossings, "
        f"where the bar on top hides the one beneath (heights {hi:+.1f} mm there against {lo:+.1f} mm "
        "the other way up): right in 8 of 8 synthetic scans from above at σ 5 and at σ 15 mm; "
        "give up= (--up) where you know it"
    )
    return best, how
