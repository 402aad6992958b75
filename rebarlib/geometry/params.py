"""Tuning parameters of the refined bar search (:func:`~rebarlib.geometry.find_bars`) that are
not among its arguments.

Examples
--------
>>> from rebarlib.geometry import GeometryParams
>>> GeometryParams().run_cell_mm, GeometryParams(refits=3).refits
(5.0, 3)
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["GeometryParams"]


@dataclass(frozen=True)
class GeometryParams:
    """How :func:`~rebarlib.geometry.find_bars` turns a lattice's points into bars (mm unless
    named otherwise). The defaults are the ones the geometry benchmark was measured with.

    Attributes
    ----------
    run_cell_mm : a bar's extent is the longest run of occupied cells this long along it
    run_gap_mm, run_gap_radii : ... with gaps up to the larger of this and this many radii
        closed (a bar under a crossing bar, a tie)
    cell_mm : the candidates' cells along a direction (:func:`_bar_candidates`)
    min_cell_share : with a sample pitch, a cell must hold this share of the points a fully
        seen bar surface gives there
    window_margin_mm : a candidate's band reaches its radius plus this across (without an
        explicit ``window_mm``)
    crossing_share : a candidate whose band holds more than this share of points that also
        belong to a crossing bar is that crossing bar
    refits : the band is gathered again around the fitted axis and refitted this many times
    refit_reach_mm, refit_reach_rms : the refit band keeps to the bar's height: within a radius
        of the axis plus the larger of this and this many times the fit's residual
    refit_margin_mm : ... and within this much beyond the bar's extent along it
    skew_gain : a skewed fit is kept only where it fits its points better than the parallel one
        by more than this factor (root-mean-square residual)
    level_tol_radii : a bar further than this many radii from its direction's median axis
        height is off its level (below: not a bar; above: fitted on a sliver)
    arc_min_share : a bar's points covering less than this share of ``min_arc_deg`` of its
        cross-section do not place its axis
    sparse_density_share : nor where they cover under ``min_arc_deg`` and the bar holds under
        this share of the layer's typical points per mm
    sliver_level_radii : a sparsely sampled bar (under ``sparse_density_share`` of the typical
        points per mm) whose axis lies more than this many radii off its direction's level was
        fitted on a strip of it: "not measured" (docs/decisions/072)
    one_sided_cells : a bar is taken as covered along one flank by a parallel nearer bar (its
        clear flank's last pixel then left out of its fit, docs/decisions/055) where this many
        cells of one diameter show it so (one crossing bar's edge makes one at most)
    ray_check_noise_share : where the depth noise along the lines of sight reaches this share
        of the bar's radius, a circle fit that the placing along the lines of sight contradicts
        is "not measured" (docs/decisions/048: below it the circle fit's first-order noise
        correction holds on any arc of 90° or more)
    lap_min_diameters : a bar is taken as lapped with a bar touching it alongside, at its
        height, over at least this many diameters of its length (more than twice the one or two
        a crossing bar, a tie or a chair spans; a lap, 30 diameters or more, is often cut by the
        image's border); its spacings are then taken from the middle of the lap
        (docs/decisions/071)
    lap_min_share : ... counting a station of one diameter where the points beside number at
        least this share of the bar's own (the far flank of a touching bar is seen edge-on: a
        third of the own points is common); a bar lapped on both sides is one line fitted
        through both pieces, at the lap's middle already (docs/decisions/073)
    """

    run_cell_mm: float = 5.0
    run_gap_mm: float = 60.0
    run_gap_radii: float = 8.0
    cell_mm: float = 5.0
    min_cell_share: float = 0.2
    window_margin_mm: float = 3.0
    crossing_share: float = 0.5
    refits: int = 2
    refit_reach_mm: float = 3.0
    refit_reach_rms: float = 3.0
    refit_margin_mm: float = 20.0
    skew_gain: float = 1.1
    level_tol_radii: float = 1.5
    arc_min_share: float = 2 / 3
    sparse_density_share: float = 0.25
    ray_check_noise_share: float = 0.25
    sliver_level_radii: float = 0.5
    one_sided_cells: int = 3
    lap_min_diameters: float = 5.0
    lap_min_share: float = 0.25
