"""``measure_diameters``: the nominal diameter of every bar from the rebar mask, made metric
with each bar's axis (method.md stage 3).
"""

from __future__ import annotations

import math

import numpy as np

from .._checks import RebarInputError
from .bars import _check_inputs, _footprints, _prepare
from .barsizes import bar_system, observed_width_mm, rib_height_mm, snap_diameter
from .calibration import _colour_calibration, _mask_between_spread, _width_calibration
from .decision import _check_core, _matches_design, _off_centre, _refined_decision
from .paper import _attribute_pixels, _paper_bar, _paper_vote
from .params import DIAMETER_COLUMNS, HIDDEN, MEASURED, NOT_MEASURED, _RefinedParams
from .pitch import _colour_ribs, _pitch_settle, _pitch_veto
from .plane import boundary_pixels
from .ribs import _face_pitch, _ribs_in_view
from .sections import _refined_bar


def measure_diameters(capture, bars, mask, *, design=None, method: str = "refined",
                      system: str | None = None, deformed: bool = True, use_depth: bool = True,
                      colour_edges="check", use_cloud: bool = True,
                      paper_points: int = 20, rng=None):
    """Nominal diameter of every bar from the rebar mask and the bar axes.

    Parameters
    ----------
    capture : Capture, for the intrinsics and the colour image (shadow check)
    bars : pandas.DataFrame with :data:`BAR_COLUMNS`: axis end points over the visible extent in
        the camera frame (mm), ``layer`` "lower"/"upper", ``level`` "bottom"/"top"; optional
        ``axis_radius_mm`` or ``radius_mm`` (see ``use_cloud``); optional ``status`` (the
        geometry stage's: a bar whose axis is not "measured" is never sized from one edge)
    mask : (H, W) bool, rebar pixels (any bar); or a float rebar probability in 0..1 (e.g.
        ``segmentation.soft_mask``): the refined method then finds each edge where the profile
        crosses 0.5 to a fraction of a pixel, the paper's method uses ``mask >= 0.5``
    design : Design or None; gives each bar's design size (window size, ``matches_design``)
    method : "refined" (default) or "paper" (method.md Stage 3, faithfully)
    system : bar-size standard for snapping; default the design's ``bar_system`` or "GB1499.2"
    deformed : snap against the rib envelope (deformed bars) or the nominal size (smooth bars)
    use_depth : refined: separate a bar from a bar peeking out behind it by the depth image
        where the mask runs on past the bar's footprint, or within it over at least 2 px whose
        depth lies well behind the bar (a sliver of a bar under it, found or not by the geometry
        stage); edges at such depth steps are used only when too few sections have two clean
        mask edges. Where the runs end, at one side only, in a strip behind the bar or without
        depth (a sliver in the projector's shadow) and lie off the axis towards it, that side is
        no edge of the bar: it is sized from its other edge where its axis was measured
    colour_edges : refined: ``"check"`` (default) finds the colour edge within 2.5 px of each
        mask edge and widens the width's uncertainty by the disagreement between the colour and
        mask widths (a biased mask then gives "not measured", not a wrong size), less the
        capture's shading offset and weighted by how the two widths scatter between the
        capture's bars of one size (:func:`_colour_calibration`); ``"replace"``
        measures between the colour edges instead; False uses the mask alone
    use_cloud : refined: also measure the diameter from the point cloud (twice the median
        distance of the bar's depth points from its axis) and combine it with the mask width
        (a conflict is "not measured"; a sound cloud width alone sizes a bar whose mask is
        unreliable). Only valid when the axes were found without assuming a bar radius (true
        axes, free cylinder fits): an axis placed at the design radius below the visible
        surface makes the cloud width that radius: use ``"veto"`` then (the cloud width only
        rules out mask sizes it contradicts, "not measured"), or False (mask widths alone).
        A bar whose row in ``bars`` has a finite ``axis_radius_mm`` (the radius its axis was
        placed with; else the geometry stage's ``radius_mm`` of its fixed-radius cylinder fit)
        is always treated as ``"veto"``. In veto mode, where the mask alone is ambiguous or
        clearly gives another size than the cloud's echo, the circle fitted to the bar's cloud
        (``circle_width_mm``, independent of where the axis lies) is combined with the mask
        instead (:func:`_settle`, with the bar's height above the bars it rests on where the
        bars table has ``stack_mm``, else its top above its level's supports from ``top_mm``):
        the bar is measured where they agree and their combined width is clear,
        ``width_source`` "mask+" and the widths used, joined by "+" ("mask+circle",
        "mask+stack", "mask+level+circle", ...). Where the mask and the assumed size disagree,
        those widths alone arbitrate between the two (:func:`_arbitrate`, ``width_source`` the
        widths used: "stack", "level", "level+circle", ...): the assumed size where the mask is
        not clear about its own, the mask's size only where it is
    paper_points : detect-points per bar for ``method="paper"``
    rng : unused (the measurement is deterministic); accepted for the common signature

    Returns
    -------
    pandas.DataFrame, one row per bar, columns :data:`DIAMETER_COLUMNS`: ``width_median_mm`` and
    ``width_spread_mm`` (robust σ, IQR/1.349) of the widths over ``n_sections`` cross-sections
    (refined: between the two edges; where too few sections show both, as on a bar cut lengthwise
    by the image border, also twice one edge's distance from the axis), ``nominal_mm`` (NaN
    unless measured), ``confidence`` 0..1, ``diameter_status`` ("measured",
    "not measured", "hidden"), ``diameter_reason``, ``design_diameter_mm``, ``matches_design``
    (None unless measured with a known design), ``hidden`` (mostly covered by nearer bars),
    ``occluded_fraction`` (share of the cross-sections lying wholly or partly under nearer bars: some
    of the bar's width there is inside a nearer bar's footprint), ``one_sided_share`` (refined:
    share of the ``n_sections`` whose width is twice one edge's distance from the axis, the
    other edge at the image border, under a nearer bar or beside a strip without depth; such a
    width is off by twice any error of the axis across the bar, so it is given a larger
    uncertainty; 0 for the paper's method), ``cloud_width_mm``
    (refined: diameter from the point cloud, twice the median distance of the bar's points from
    its axis), ``width_source`` ("mask", "cloud", "mask+cloud", or "mask+" the independent widths
    of veto mode, above, or those widths alone where they arbitrated, and "+pitch" at the end
    where the rib pitch told two sizes apart, below: what the size came from), ``width_used_mm``
    (the width that was snapped; refined, also for a bar left
    ambiguous between two sizes) and ``width_sigma_mm`` (refined: its standard uncertainty, what
    the confidence is computed from with the size table's own 0.15 mm), ``circle_width_mm`` and
    ``circle_sigma_mm`` (refined, for axes placed with an assumed radius, where it is used: the
    diameter of the circle fitted to the bar's point cloud, :func:`_cloud_circle`, less the
    offset the capture's circles share against the bars their masks size clearly, and the σ it
    is used with: the fit's standard error or the circle's error per bar learnt from those bars,
    whichever is larger, :func:`_width_calibration`; else NaN). ``crest_width_mm`` and
    ``core_width_mm`` (refined, bars with at least 24 clean sections): the 95th and 10th
    percentiles of the section widths; ``rib_pitch_mm``: the period of the widths along the bar
    where it is clear (p < 1 %, :func:`_rib_periodicity`), else NaN; ``ribs_resolved`` (the same
    for every bar): the capture's bars together show ribs (:func:`_ribs_in_view`), in their mask
    widths or, where a bar's cloud would be fused with its mask, in their colour widths at the
    size table's rib spacings (:func:`_colour_ribs`: a learnt mask may smooth the ribs away). A
    deformed bar's silhouette is then its core between the ribs and the rib envelope only at the crests,
    so its median width reads about the next smaller size: each bar is sized from its crests
    (``crest_width_mm`` + 0.3 h, σ 0.3 h: how far crescent ribs reach in silhouette depends on
    the bar's roll), its point-cloud width is not used (a surface over crests and core alike),
    and a size its core (``core_width_mm`` against the standard's core diameters) does not
    confirm is "not measured". A bar left between two sizes there (ambiguous, crests against
    core, mask against cloud) is sized by its rib pitch (its width's, else both its edges' where
    they agree, :func:`_edge_pitch`, else the shading along its face or, seen from one side,
    along its visible half, :func:`_face_pitch`) where the system sets one per size
    (GB 1499.2) and the capture's bars show that they follow it (:func:`_pitch_settle`:
    ``width_source`` ending "+pitch", the reason naming the pitch and the two sizes' spacings).

    Examples
    --------
    >>> from rebarlib.synth import synth_capture, SensorModel
    >>> from rebarlib.data import paper_design
    >>> from rebarlib import GEMINI2
    >>> from rebarlib.diameter import bars_from_truth
    >>> cap = synth_capture(paper_design(), height_mm=400, tilt_deg=0, sensor=SensorModel.ideal(),
    ...                     intrinsics=GEMINI2.scaled(0.5), seed=1)
    >>> bars = bars_from_truth(cap.truth)
    >>> table = measure_diameters(cap, bars, cap.labels > 0, design=paper_design())
    >>> upper = table.merge(bars, on="bar_id").query("layer == 'upper' and diameter_status == 'measured'")
    >>> sorted(set(upper.nominal_mm))
    [12.0]
    """
    import pandas as pd

    m, maskf = _check_inputs(capture, bars, mask, method)
    if system is None:
        system = getattr(design, "bar_system", None) or "GB1499.2"
    bar_system(system)  # validates the name
    intr = capture.intrinsics
    prepared = _prepare(bars, design, system, deformed,
                        default_expected_mm=observed_width_mm(20.0, system="GB1499.2", deformed=deformed))
    fp = _footprints(prepared, intr)
    if use_cloud not in (True, False, "veto"):
        raise RebarInputError(f"use_cloud: expected True, False or 'veto', got {use_cloud!r}")
    if colour_edges not in ("check", "replace", False, None):
        raise RebarInputError(f"colour_edges: expected 'check', 'replace' or False, got {colour_edges!r}")
    prm = _RefinedParams(colour_edges=colour_edges or False)
    gray = rgb = None
    if capture.color is not None:
        import cv2

        rgb = np.ascontiguousarray(capture.color, dtype=np.float32)
        gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)  # luminance: only compared with itself
    depth = np.asarray(capture.depth_mm, np.float32) if use_depth else None
    edge, owner = None, None
    if method == "paper":
        edge = boundary_pixels(m)
        vv, uu = np.nonzero(edge)
        owner = np.full(m.shape, -1, np.int32)  # bar index of each boundary pixel
        owner[vv, uu] = _attribute_pixels(np.column_stack((uu, vv)), prepared, intr)
    depth_img = np.asarray(capture.depth_mm, np.float32) if (use_cloud and capture.depth_mm is not None) else None
    # an axis placed with an assumed radius: its cloud width echoes that radius, so it may only
    # veto, and the circle fitted to its cloud is what can size the bar (the refined decision
    # only: the paper's method never reads it)
    cloud_mode = ["veto" if use_cloud and math.isfinite(bar.axis_radius_mm) else use_cloud for bar in prepared]
    results = [_refined_bar(i, bar, maskf, gray, depth, intr, fp, prm, rgb, depth_img,
                            circle=method == "refined" and cloud_mode[i] == "veto")
               for i, bar in enumerate(prepared)]
    for r in results:
        r.mask_width_mm = float(np.median(r.widths)) if len(r.widths) else math.nan
        r.rib_sigma_mm = 0.0
    # Ribs resolved (refined, deformed bars): each bar's mask width is the envelope read from its
    # crests, and its point-cloud width (a surface over crests and core alike) is no envelope
    # (the bars' sizes for their rib pitches: the design's, else the size their median width is nearest)
    sizes = [b.design_mm if math.isfinite(b.design_mm) or not len(r.widths)
             else snap_diameter(r.mask_width_mm, system=system, deformed=deformed)[0]
             for b, r in zip(prepared, results)]
    ribs_p = (_ribs_in_view([(r.rib_pitch_mm, r.rib_p) for r in results], prm, sizes)
              if method == "refined" and deformed else 1.0)
    ribs = ribs_p < prm.rib_capture_p
    if method == "refined" and deformed and not ribs and colour_edges:
        # a mask that smooths the ribs away: the colour image may still show them. Where a bar's
        # point cloud would be fused with its mask width (axes found without an assumed radius),
        # both then read a ribbed bar a size down and agree. An axis placed with an assumed
        # radius vetoes that for a bar of the design size, but not for a bar one size larger
        # than designed: read a size down, it gives the design size, which the cloud echoes
        ribs = _colour_ribs(results, sizes, prm, system=system)
    for r in results:
        info = r
        if ribs and math.isfinite(info.crest_mm):
            h = rib_height_mm(info.crest_mm, system=system)
            info.mask_width_mm, info.rib_sigma_mm = info.crest_mm + prm.rib_reach * h, prm.rib_reach * h
    if ribs:
        cloud_mode = [False if m is True else m for m in cloud_mode]
    _colour_calibration(results, prepared, prm)
    _mask_between_spread(results, prepared, prm)
    for i, bar in enumerate(prepared):  # only for axes placed with an assumed radius (see _settle)
        info = results[i]
        info.stack_width_mm = bar.stack_mm if cloud_mode[i] == "veto" else math.nan
        info.level_width_mm = bar.top_mm if cloud_mode[i] == "veto" else math.nan
        info.stack_sigma_mm = info.level_sigma_mm = 0.0
    _width_calibration(results, "circle", prm, system=system, deformed=deformed)
    _width_calibration(results, "stack", prm, system=system, deformed=deformed)
    # the bars of one level rest on the same supports: a bar's top above the formwork less the
    # supports' height, learnt from its level's bars that the mask sizes clearly
    _width_calibration(results, "level", prm, system=system, deformed=deformed,
                       groups=[(b.layer, b.level) for b in prepared])
    for r in results:  # a bar's own top counts once: where it has a stack height, that is its top
        if math.isfinite(r.stack_width_mm) and math.isfinite(r.stack_between_mm):
            r.level_width_mm = math.nan
    lums = np.array([r.lum for r in results], float)
    ref_lum = float(np.nanmedian(lums)) if np.isfinite(lums).any() else math.nan
    rows, shadows = [], []
    for i, bar in enumerate(prepared):
        info = results[i]
        w, occluded, in_img = info.widths, info.occluded, info.in_image
        # a bar in shadow over its whole length: its mask edges are the least reliable there is,
        # so its size is never reported with high confidence
        in_shadow = bool(np.isfinite(ref_lum) and info.lum < prm.shadow_ratio * ref_lum)
        n_in = int(in_img.sum())
        occ_frac = float(occluded.sum() / n_in) if n_in else 0.0
        row = {"bar_id": bar.bar_id, "width_median_mm": math.nan, "width_spread_mm": math.nan,
               "n_sections": 0, "nominal_mm": math.nan, "confidence": 0.0,
               "diameter_status": NOT_MEASURED, "diameter_reason": "", "design_diameter_mm": bar.design_mm,
               "matches_design": None, "hidden": False, "occluded_fraction": round(occ_frac, 3),
               "one_sided_share": round(info.one_sided_share, 3) if method == "refined" else 0.0,
               "cloud_width_mm": math.nan, "width_source": "", "width_used_mm": math.nan, "width_sigma_mm": math.nan,
               "circle_width_mm": info.circle_width_mm, "circle_sigma_mm": info.circle_sigma_mm,
               "crest_width_mm": info.crest_mm, "core_width_mm": info.core_mm,
               "rib_pitch_mm": info.rib_pitch_mm if info.rib_p < prm.rib_bar_p else math.nan,
               "ribs_resolved": ribs}
        clean = len(w)  # hidden-bar detection is shared by both methods (the refined analysis)
        if method == "paper":
            w = _paper_bar(i, bar, m, edge, intr, paper_points, owner)
        if len(w):
            q1, med, q3 = np.percentile(w, [25, 50, 75])
            row.update(width_median_mm=float(med), width_spread_mm=float((q3 - q1) / 1.349), n_sections=len(w))
        few = len(w) < (1 if method == "paper" else prm.min_sections)
        if n_in == 0:
            row["diameter_reason"] = "bar axis is outside the image"
        elif clean < prm.min_sections and occ_frac >= prm.hidden_fraction:
            row.update(diameter_status=HIDDEN, hidden=True,
                       diameter_reason=(f"hidden: {occ_frac:.0%} of its cross-sections lie wholly or partly "
                                        "under nearer bars"))
            if not bar.axis_ok and info.one_edge >= prm.min_sections:
                # a sliver beside the bar over it: what is seen is not nothing, and the inspector
                # should know why it still gives no size
                row["diameter_reason"] += (
                    f"; {info.one_edge} cross-sections show one edge of it beside them (a sliver): a width "
                    "from one edge needs the axis placed to a fraction of a millimetre, which a sliver "
                    "does not give without taking the bar's radius as known")
        elif few:
            why = max(("crossing", "no_edge", "border", "shadow", "outlier", "holed"), key=lambda k: getattr(info, k))
            text = {"crossing": "at crossings or next to other bars", "no_edge": "no clear mask edges",
                    "border": "at the image border", "shadow": "in shadow", "outlier": "inconsistent widths",
                    "holed": "beside a strip without depth, most likely a bar under it peeking out"}
            row["diameter_reason"] = (f"too few clean cross-sections ({len(w)} of {info.stations}; "
                                      f"most lost {text[why]})")
        elif method == "paper":
            nominal, share = _paper_vote(w, system)
            if math.isfinite(nominal):
                row.update(nominal_mm=nominal, confidence=round(share, 3), diameter_status=MEASURED,
                           width_source="mask", width_used_mm=float(med))
            else:
                row["diameter_reason"] = f"no width within ±1 mm of a {system} size (median {med:.1f} mm)"
        elif ribs and not math.isfinite(info.crest_mm):
            row["diameter_reason"] = (f"ribs resolved in this capture: {len(w)} clean cross-sections are too few to "
                                      f"read the bar's rib crests (at least {prm.rib_min_sections})")
        else:
            row.update(_refined_decision(info.mask_width_mm, row["width_spread_mm"], len(w), info, in_shadow,
                                         prm, system=system, deformed=deformed, use_cloud=cloud_mode[i],
                                         assumed_mm=bar.axis_radius_mm, mask_median=med,
                                         covered=occ_frac))
            if ribs and row["diameter_status"] == MEASURED:
                _check_core(row, info, prm, system=system)
            if (row["diameter_status"] == NOT_MEASURED and occ_frac >= prm.hidden_fraction
                    and _off_centre(info, med, prm)):
                # the side the mask lacks is most likely under the nearer bars: say so
                row["diameter_reason"] += (f"; {occ_frac:.0%} of its cross-sections lie partly under nearer bars: "
                                           "what is seen may be a sliver beside them")
        if row["diameter_status"] == MEASURED:
            row["matches_design"] = _matches_design(row["nominal_mm"], bar.design_mm)
        rows.append(row)
        shadows.append(in_shadow)
    if method == "refined" and ribs:
        _pitch_settle(rows, results, sizes, shadows, prm, system=system,
                      face=lambda i: _face_pitch(prepared[i], results[i], gray, intr, prm, fp, i))
    if method == "refined" and deformed:
        _pitch_veto(rows, results, prm, system=system)
    df = pd.DataFrame(rows, columns=list(DIAMETER_COLUMNS))
    df["matches_design"] = df["matches_design"].astype(object)
    return df
