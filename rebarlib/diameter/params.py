"""Column names, statuses and tuning parameters of the diameter stage."""

from __future__ import annotations

from dataclasses import dataclass


#: Columns the bars table must have (camera frame axis end points, mm).
BAR_COLUMNS = ("bar_id", "layer", "level", "start_x_mm", "start_y_mm", "start_z_mm",
               "end_x_mm", "end_y_mm", "end_z_mm")


#: Columns of the table :func:`measure_diameters` returns (one row per bar, merge on bar_id).
DIAMETER_COLUMNS = ("bar_id", "width_median_mm", "width_spread_mm", "n_sections", "nominal_mm",
                    "confidence", "diameter_status", "diameter_reason", "design_diameter_mm",
                    "matches_design", "hidden", "occluded_fraction", "one_sided_share",
                    "cloud_width_mm", "width_source", "width_used_mm", "width_sigma_mm",
                    "circle_width_mm", "circle_sigma_mm",
                    "crest_width_mm", "core_width_mm", "rib_pitch_mm", "ribs_resolved")


MEASURED, NOT_MEASURED, HIDDEN = "measured", "not measured", "hidden"


@dataclass(frozen=True)
class _RefinedParams:
    step_px: float = 3.0  # cross-sections about this far apart along the bar (image)
    max_sections: int = 512  # (a bar across a 1280 x 800 image's diagonal still gets them 3 px apart:
    # sparser sections would not sample a small bar's ribs, see _rib_periodicity)
    cloud_sections: int = 200  # the point-cloud widths read at most this many of them, evenly spread
    window: float = 1.0  # half-window across the bar, in expected widths (2x the width in all)
    sample_px: float = 0.5  # profile sampling step
    min_sections: int = 8
    max_spread_rel: float = 0.12  # robust spread above this fraction of the width: too scattered
    outlier_k: float = 3.0
    shadow_ratio: float = 0.5  # section centre darker than this x the bar's median: in shadow
    hidden_fraction: float = 0.5
    min_confidence: float = 0.8  # below: ambiguous between two sizes, not measured
    quantisation_px: float = 0.4  # std. uncertainty of a width from pixel edges (two edges, each
    # uniform over a pixel: 1/√6 = 0.41 px); divided by √(pixel phases the edges sweep, ≥ 1)
    shadow_confidence: float = 0.7  # cap for a bar in shadow over its whole length
    behind_mm: float = 15.0  # depth this far behind the bar's surface: another object
    sliver_min_px: float = 2.0  # a run going on this far (px) over a surface well behind: cut there
    colour_edges: object = "check"  # colour edges near the mask edges: "check" the mask, "replace" it, False
    depth_correlated_px: float = 4.0  # neighbouring depth points share noise: effective count / this
    cloud_bias_mm_per_m2: float = 1.5  # systematic uncertainty of a point-cloud diameter, x z² (m)
    veto_k: float = 2.0  # mask and cloud widths further apart than this many σ: not measured
    mask_spread_sys: float = 0.5  # share of the mask widths' spread that is a bias of the whole bar
    cloud_only_confidence: float = 0.85  # cap for a size from the point cloud alone (relies on the axis)
    depth_core: float = 0.5  # point-cloud points from the middle this fraction of each run
    circle_core: float = 0.8  # the circle fit reads the cloud over this fraction of each run
    colour_tolerance_px: float = 0.5  # colour and mask widths may differ this much (cylinder shading)
    colour_offset_bars: int = 5  # bars needed to learn the capture's colour-minus-mask offset
    edge_search_px: float = 2.5  # how far from the mask edge the colour edge may lie
    edge_min_contrast: float = 12.0  # grey levels between bar and background, else keep the mask
    edge_peak_share: float = 0.3  # the gradient peak must carry this share of the step per pixel
    axis_sigma_mm: float = 0.3  # lateral axis error tolerated before the centring counts against a width
    max_offcentre_rel: float = 0.2  # mask run centre this far (x width) off the axis: not measured
    # Ribs in the silhouette (see _rib_periodicity, _ribs_in_view): a deformed bar seen closely
    # enough shows its core between the transverse ribs and the rib envelope only at their
    # crests, so its median width reads about the next smaller size's envelope.
    rib_band: tuple = (0.4, 1.2)  # rib pitches searched, x the bar's median width (standards: 0.5-0.7 d)
    # sections needed to read a bar's crests and core and look for its rib pitch
    rib_min_sections: int = 24
    # the capture shows ribs where its bars' periodicity together is this unlikely from noise
    rib_capture_p: float = 1e-6
    rib_p_floor: float = 1e-8  # one bar's p-value counts at most this much (one striped bar is not a capture)
    rib_min_bars: int = 3  # bars needed to judge a capture; as many must show one pitch clearly
    rib_pitch_tol: float = 0.1  # a bar's clear pitch agrees with its size's where within this share of it
    rib_min_px: float = 1.5  # crest minus core widths at least this (px): more than the pixel grid's 1-px steps
    rib_bar_p: float = 0.01  # a bar's own rib pitch is reported where its periodicity is this unlikely from noise
    crest_quantile: float = 0.95  # the crests: the widest 5 % of the sections (crests with their flanks
    # cover a fifth to a third of the pitch)
    core_quantile: float = 0.1  # the core between the ribs
    pitch_k: float = 3.0  # a pitch matches a size's l within this many standard errors (_pitch_band)
    face_fractions: tuple = (0.2, 0.35, 0.5, 0.65, 0.8)  # lines along a bar's face, edge to edge (_face_pitch)
    face_step_px: float = 1.0  # samples along each line this far apart (image)
    face_oversample: int = 4  # periodogram frequencies per resolution (1 / length read)
    rib_reach: float = 0.3  # x rib height h: crescent ribs reach d1 + 2h in silhouette at some rolls,
