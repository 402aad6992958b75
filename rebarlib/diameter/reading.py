"""What the refined method reads on one bar: :class:`BarReading`.

The cross-sections (:mod:`~rebarlib.diameter.sections`) fill most of it; the capture's
calibrations (:mod:`~rebarlib.diameter.calibration`) and :func:`measure_diameters` add what the
capture's bars together teach. The decision (:mod:`~rebarlib.diameter.decision`) and the rib
pitch (:mod:`~rebarlib.diameter.pitch`) read it.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

__all__ = ["BarReading", "INDEPENDENT_KEYS"]

#: the widths that depend neither on the mask nor on where an axis placed with an assumed radius
#: lies: each has ``{key}_width_mm``, ``{key}_sigma_mm``, ``{key}_offset_mm`` and
#: ``{key}_between_mm`` fields (:func:`~rebarlib.diameter.calibration._width_calibration`)
INDEPENDENT_KEYS = ("stack", "level", "circle")


def _no_track():
    return (np.zeros(0),) * 3


def _no_colour_track():
    return (np.zeros(0), np.zeros(0))


@dataclass(slots=True)
class BarReading:
    """One bar's cross-sections as the refined method read them (mm unless named otherwise).

    Attributes
    ----------
    widths : (n,) float, the kept sections' widths (corrected for silhouette rays tangent to the
        bar), the ones the bar is sized from
    occluded : (M,) bool, per station along the bar: partly under a nearer bar
    in_image : (M,) bool, per station: the station on the axis lies in the image
    stations : int, stations along the bar (M)
    n_occluded, border, crossing, no_edge, shadow, outlier, holed : int, stations lost (under a
        nearer bar, at the image border, with an edge at another bar, without two mask edges, in
        shadow, an outlier width, beside a strip without depth)
    colour_edges : int, sections whose mask edges moved to a colour edge
    one_edge : int, sections with one clean edge and the other at another bar (a sliver)
    depth_cut : int, sections left out for an edge at a depth step
    one_sided_share : float, share of the kept sections sized from one edge and the axis
    rib_pitch_mm, rib_p, rib_length_mm : the period of the widths along the bar, the chance
        that noise gives as strong a period, and the length it was read over
    crest_mm, core_mm : the widths' high and low quantiles (rib crests, core between them)
    edges : (s, lo, hi), the sections with two edges: place along the bar and both edges
        across it in γ (NaN where a section has not both)
    one_edges : (s, lo, hi), the one-sided sections' edges (NaN on the side not seen)
    depth_width_mm, depth_spread_mm, depth_points : the point cloud's diameter, its robust
        spread and how many points
    depth_off_share : share of the point cloud farther from the axis than a diameter (NaN: no
        verdict); ``depth_off_covered``: that share was read with every section covered
    circle_width_mm, circle_sigma_mm : the diameter of the circle fitted to the cloud and its σ
        (after :func:`~rebarlib.diameter.calibration._width_calibration`, less the capture's
        offset)
    colour_widths : (s, widths), the colour widths along the bar
    colour_width_mm : the colour widths' median (NaN with too few)
    centre_mm : the mask runs' median centre off the axis
    px_mm : one pixel's footprint at the bar; ``z_mm``: its median depth
    phase_sweep_px : how many pixel phases the edges sweep along the bar
    lum : the bar's median luminance on its axis (NaN without colour)
    mask_width_mm : the width the mask gives (the rib envelope from the crests where the capture
        resolves ribs); None until :func:`measure_diameters` sets it (the sections' median then)
    rib_sigma_mm : σ of a width read from the rib crests (how far they reach with the roll)
    mask_lean_mm : how far the capture's masks read bars wide at this bar's distance, taken off
        its widths (``calibration._mask_lean``; 0 where not learnt)
    mask_between_mm : the spread of mask widths between the capture's bars of one size
    colour_offset_px, colour_weight, colour_spread_mm : the capture's colour-minus-mask offset,
        the share of a colour-mask disagreement blamed on the mask, and their combined spread
    stack_width_mm, level_width_mm : the bar's top above the bars it rests on, above its
        level's supports; each with ``_sigma_mm``, ``_offset_mm`` and ``_between_mm`` as the
        circle's (:data:`INDEPENDENT_KEYS`)
    circle_offset_mm, circle_between_mm : the offset removed from the circle widths and their
        spread between bars
    """

    widths: np.ndarray = field(default_factory=lambda: np.zeros(0))
    occluded: np.ndarray = None
    in_image: np.ndarray = None
    stations: int = 0
    n_occluded: int = 0
    border: int = 0
    crossing: int = 0
    no_edge: int = 0
    shadow: int = 0
    outlier: int = 0
    colour_edges: int = 0
    one_edge: int = 0
    holed: int = 0
    depth_cut: int = 0
    one_sided_share: float = 0.0
    rib_pitch_mm: float = math.nan
    rib_p: float = 1.0
    rib_length_mm: float = math.nan
    crest_mm: float = math.nan
    core_mm: float = math.nan
    edges: tuple = field(default_factory=_no_track)
    one_edges: tuple = field(default_factory=_no_track)
    depth_width_mm: float = math.nan
    depth_spread_mm: float = math.nan
    depth_points: int = 0
    depth_off_share: float = math.nan
    depth_off_covered: bool = False
    circle_width_mm: float = math.nan
    circle_sigma_mm: float = math.nan
    colour_widths: tuple = field(default_factory=_no_colour_track)
    colour_width_mm: float = math.nan
    centre_mm: float = math.nan
    px_mm: float = math.nan
    phase_sweep_px: float = 0.0
    z_mm: float = math.nan
    lum: float = math.nan
    mask_width_mm: float | None = None
    mask_lean_mm: float = 0.0
    rib_sigma_mm: float = 0.0
    mask_between_mm: float = 0.0
    colour_offset_px: float = 0.0
    colour_weight: float = 1.0
    colour_spread_mm: float = 0.0
    stack_width_mm: float = math.nan
    stack_sigma_mm: float = math.nan
    stack_offset_mm: float = 0.0
    stack_between_mm: float = math.nan
    level_width_mm: float = math.nan
    level_sigma_mm: float = math.nan
    level_offset_mm: float = 0.0
    level_between_mm: float = math.nan
    circle_offset_mm: float = 0.0
    circle_between_mm: float = math.nan
