"""Column names, statuses and tuning parameters of the diameter stage.

Examples
--------
>>> from rebarlib.diameter import DiameterParams
>>> prm = DiameterParams()
>>> prm.min_sections, prm.min_confidence
(8, 0.8)
>>> DiameterParams(min_confidence=0.9).min_confidence
0.9
"""

from __future__ import annotations

from dataclasses import dataclass

from .._status import HIDDEN, MEASURED, NOT_MEASURED

__all__ = ["BAR_COLUMNS", "DIAMETER_COLUMNS", "DiameterParams", "MEASURED", "NOT_MEASURED", "HIDDEN"]


#: Columns the bars table must have (camera frame axis end points, mm).
BAR_COLUMNS = ("bar_id", "layer", "level", "start_x_mm", "start_y_mm", "start_z_mm", "end_x_mm", "end_y_mm", "end_z_mm")


#: Columns of the table :func:`measure_diameters` returns (one row per bar, merge on bar_id).
DIAMETER_COLUMNS = (
    "bar_id",
    "width_median_mm",
    "width_spread_mm",
    "n_sections",
    "nominal_mm",
    "confidence",
    "diameter_status",
    "diameter_reason",
    "design_diameter_mm",
    "matches_design",
    "hidden",
    "occluded_fraction",
    "one_sided_share",
    "cloud_width_mm",
    "width_source",
    "width_used_mm",
    "width_sigma_mm",
    "mask_lean_mm",
    "circle_width_mm",
    "circle_sigma_mm",
    "crest_width_mm",
    "core_width_mm",
    "rib_pitch_mm",
    "ribs_resolved",
)


@dataclass(frozen=True)
class DiameterParams:
    """Tuning parameters of the diameter stage (the refined method's; the paper's method reads
    ``min_sections``, ``hidden_fraction`` and the paper fields). The defaults are the ones the
    benchmarks were measured with (``docs/diameters.md``).

    Attributes
    ----------
    step_px : cross-sections about this far apart along the bar, in the image
    max_sections : at most this many per bar (a bar across a 1280 x 800 image's diagonal still
        gets them 3 px apart: sparser sections would not sample a small bar's ribs)
    cloud_sections : the point-cloud widths read at most this many sections, evenly spread
    window : half-window across the bar, in expected widths (twice the width in all)
    sample_px : the mask profile's sampling step across the bar
    min_sections : clean sections a bar needs to be sized
    max_spread_rel : a robust spread of the widths above this share of the width: too scattered
    outlier_k : a width further than this many robust σ from the bar's median is an outlier
    outlier_floor_px : ... but never nearer than this many pixels
    shadow_ratio : a section whose centre is darker than this times the bar's median lies in
        shadow; a bar darker than this times the capture's median is in shadow as a whole
    hidden_fraction : a bar with this share of its sections under nearer bars (and too few
        clean ones) is "hidden"
    min_confidence : a size below this confidence is ambiguous: not measured
    quantisation_px : standard uncertainty of a width from edges on the pixel grid (two edges,
        each uniform over a pixel: 1/√6 = 0.41 px), divided by √(pixel phases swept, ≥ 1)
    shadow_confidence : the confidence cap of a bar in shadow over its whole length
    behind_mm : depth this far behind the bar's surface is another object
    sliver_min_px : a mask run going on this far over a surface well behind is cut there
    own_no_depth_share : a bar whose core (± a quarter of its width about the axis) lacks depth
        in this share of its sections has no depth of its own (a bar placed from the colour
        mask, in a projector's shadow): its pixels without depth are its own, not a bar under it
    colour_edges : colour edges next to the mask edges: ``"check"`` the mask, ``"replace"`` it,
        or False (not read)
    depth_correlated_px : neighbouring depth points share their noise: effective count / this
    cloud_bias_mm_per_m2 : systematic uncertainty of a point-cloud diameter, times z² (m)
    veto_k : mask and cloud widths further apart than this many combined σ disagree
    mask_spread_sys : share of the mask widths' spread that is a bias of the whole bar
    cloud_only_confidence : the confidence cap of a size from the point cloud alone
    depth_core : the point-cloud width reads the middle this share of each mask run
    circle_core : the circle fit reads the cloud over this share of each run
    colour_tolerance_px : colour and mask widths may differ this much (cylinder shading)
    colour_offset_bars : bars needed to learn a capture's colour-minus-mask offset and its
        widths' spreads between bars
    edge_search_px : how far from the mask edge a colour edge may lie
    edge_min_contrast : grey levels between bar and background below which the mask is kept
    edge_peak_share : the gradient peak's share of the step per pixel
    axis_sigma_mm : lateral error of an axis tolerated before the centring counts against a width
    max_offcentre_rel : mask runs centred this far off the axis (times the width): one side lost
    probe_fractions : where across a bar (times its expected width) a station is probed for a
        nearer bar over it
    footprint_margin_rel, footprint_margin_px : a bar's footprint in the image is its expected
        width with room for one size larger (this share) and a mask edge this many px off
    default_size_mm : the nominal size whose envelope is expected of a bar without a design size
    rib_band : rib pitches searched, times the bar's median width (standards: 0.5-0.7 d)
    rib_min_sections : sections needed to read a bar's crests and core and its rib pitch
    rib_capture_p : a capture shows ribs where its bars' periodicity together is this unlikely
        from noise
    rib_p_floor : one bar's p-value counts at most this much (one striped bar is not a capture)
    rib_min_bars : bars needed to judge a capture; as many must show one pitch clearly
    rib_pitch_tol : a bar's clear pitch agrees with its size's within this share of it
    rib_min_px : crest minus core widths of at least this (px): more than the pixel grid's steps
    rib_bar_p : a bar's own rib pitch is reported where its periodicity is this unlikely
    crest_quantile : the crests: the widest 5 % of the sections (crests with their flanks cover
        a fifth to a third of the pitch)
    core_quantile : the core between the ribs
    pitch_k : a pitch matches a size's spacing within this many standard errors
    face_fractions : lines along a bar's face, from one edge (0) to the other (1)
    face_step_px : samples along each line this far apart, in the image
    face_oversample : periodogram frequencies per resolution (1 / the length read)
    rib_reach : times the rib height h: crescent ribs reach d1 + 2h in silhouette at some
        rolls, about d1 + 1.4h at others, so crest widths are read as d1 + 1.7h ± 0.3h
    paper_short_px : the paper's region: its sides along the axis, px
    paper_bin_mm : the paper's vote: half-width of the bins around the nominal sizes
    """

    step_px: float = 3.0
    max_sections: int = 512
    cloud_sections: int = 200
    window: float = 1.0
    sample_px: float = 0.5
    min_sections: int = 8
    max_spread_rel: float = 0.12
    outlier_k: float = 3.0
    shadow_ratio: float = 0.5
    hidden_fraction: float = 0.5
    min_confidence: float = 0.8
    quantisation_px: float = 0.4
    shadow_confidence: float = 0.7
    behind_mm: float = 15.0
    sliver_min_px: float = 2.0
    own_no_depth_share: float = 0.8
    colour_edges: object = "check"
    depth_correlated_px: float = 4.0
    cloud_bias_mm_per_m2: float = 1.5
    veto_k: float = 2.0
    mask_spread_sys: float = 0.5
    cloud_only_confidence: float = 0.85
    depth_core: float = 0.5
    circle_core: float = 0.8
    colour_tolerance_px: float = 0.5
    colour_offset_bars: int = 5
    edge_search_px: float = 2.5
    edge_min_contrast: float = 12.0
    edge_peak_share: float = 0.3
    axis_sigma_mm: float = 0.3
    max_offcentre_rel: float = 0.2
    rib_band: tuple = (0.4, 1.2)
    rib_min_sections: int = 24
    rib_capture_p: float = 1e-6
    rib_p_floor: float = 1e-8
    rib_min_bars: int = 3
    rib_pitch_tol: float = 0.1
    rib_min_px: float = 1.5
    rib_bar_p: float = 0.01
    crest_quantile: float = 0.95
    core_quantile: float = 0.1
    pitch_k: float = 3.0
    face_fractions: tuple = (0.2, 0.35, 0.5, 0.65, 0.8)
    face_step_px: float = 1.0
    face_oversample: int = 4
    rib_reach: float = 0.3
    outlier_floor_px: float = 1.0
    probe_fractions: tuple = (-0.5, -0.25, 0.0, 0.25, 0.5)
    footprint_margin_rel: float = 0.2
    footprint_margin_px: float = 1.5
    default_size_mm: float = 20.0
    paper_short_px: float = 6.0
    paper_bin_mm: float = 1.0
