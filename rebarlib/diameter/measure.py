"""``measure_diameters``: the nominal diameter of every bar from the rebar mask, made metric
with each bar's axis (method.md stage 3).

The steps, refined method: each bar's cross-sections are read (:func:`_refined_bar`); the
capture's bars together say whether its camera resolves ribs (:func:`_capture_ribs`) and
calibrate each width against the others (:func:`_calibrate`); each bar is then sized
(:func:`_bar_row`, :func:`~rebarlib.diameter.decision._refined_decision`), and a bar left
between two sizes may be told by its rib pitch (:func:`~rebarlib.diameter.pitch._pitch_settle`).
The paper's method reads the same cross-sections only to find hidden bars, and sizes each bar by
its own procedure (:mod:`~rebarlib.diameter.paper`).
"""

from __future__ import annotations

import math

import numpy as np

from .._checks import RebarInputError
from .._design import DEFAULT_BAR_SYSTEM
from .._status import AXIS_OUTSIDE
from .bars import _check_inputs, _footprints, _prepare
from .barsizes import bar_system, observed_width_mm, rib_height_mm, snap_diameter
from .calibration import _colour_calibration, _mask_between_spread, _mask_lean, _width_calibration
from .closer import closer_advice
from .decision import _check_core, _matches_design, _off_centre, _refined_decision
from .paper import _attribute_pixels, _paper_bar, _paper_vote
from .params import DIAMETER_COLUMNS, HIDDEN, MEASURED, NOT_MEASURED, DiameterParams
from .pitch import _colour_ribs, _mask_ribs_follow_table, _pitch_settle, _pitch_veto
from .plane import boundary_pixels
from .ribs import _face_pitch, _ribs_in_view
from .sections import _refined_bar

__all__ = ["measure_diameters"]

#: why a bar has too few clean cross-sections, by the count of a :class:`BarReading` that lost
#: it the most sections
_LOST = {
    "crossing": "at crossings or next to other bars",
    "no_edge": "no clear mask edges",
    "border": "at the image border",
    "shadow": "in shadow",
    "outlier": "inconsistent widths",
    "holed": "beside a strip without depth, most likely a bar under it peeking out",
}


def measure_diameters(
    capture,
    bars,
    mask,
    *,
    design=None,
    method: str = "refined",
    system: str | None = None,
    deformed: bool = True,
    use_depth: bool = True,
    colour_edges="check",
    use_cloud: bool = True,
    paper_points: int = 20,
    rng=None,
):
    """Nominal diameter of every bar from the rebar mask and the bar axes.

    Parameters
    ----------
    capture : Capture, for the intrinsics, the colour image and the depth
    bars : pandas.DataFrame with :data:`BAR_COLUMNS`: axis end points over the visible extent in
        the camera frame (mm), ``layer`` "lower"/"upper", ``level`` "bottom"/"top"; optional
        ``axis_radius_mm`` or ``radius_mm`` (the radius an axis was placed with, see
        ``use_cloud``), ``stack_mm`` and ``top_mm`` (``geometry.stack_heights``,
        ``geometry.top_heights``) and ``status`` (a bar whose axis is not "measured" is never
        sized from one edge)
    mask : (H, W) bool rebar pixels, or a float rebar probability in 0..1: the refined method
        finds each edge where the profile crosses 0.5 to a fraction of a pixel, the paper's
        uses ``mask >= 0.5``
    design : Design or None: each bar's design size (window size, ``matches_design``)
    method : "refined" (default) or "paper" (method.md stage 3, faithfully)
    system : bar-size standard for snapping; default the design's ``bar_system`` or "GB1499.2"
    deformed : snap to the rib envelope (deformed bars) or to the nominal size (smooth bars)
    use_depth : refined: cut a mask run where it runs on into a bar behind, by the depth
        (:func:`~rebarlib.diameter.runs._mask_runs`)
    colour_edges : refined: ``"check"`` (default) widens a width's uncertainty by how far the
        colour edges next to the mask's disagree with them, less the capture's shading offset
        (:func:`~rebarlib.diameter.calibration._colour_calibration`); ``"replace"`` measures
        between the colour edges; False reads the mask alone
    use_cloud : refined: also measure the diameter from the point cloud and combine it with the
        mask width (True); only check the mask with it (``"veto"``, for axes placed with an
        assumed radius, whose cloud width echoes that radius; the circle fitted to the cloud and
        the bar's top heights then settle or arbitrate: ``decision._settle``,
        ``decision._arbitrate``); or not (False). A bar with a finite ``axis_radius_mm`` or
        ``radius_mm`` is always read in veto mode.
    paper_points : detect-points per bar for ``method="paper"``
    rng : unused (the measurement is deterministic); accepted for the common signature

    Returns
    -------
    pandas.DataFrame
        One row per bar, columns :data:`DIAMETER_COLUMNS`:

        ====================  ===================================================================
        column                meaning
        ====================  ===================================================================
        bar_id                the bar's id in ``bars``
        width_median_mm       median width over the clean cross-sections
        width_spread_mm       their robust spread (IQR / 1.349)
        n_sections            how many cross-sections
        nominal_mm            the size (NaN unless measured)
        confidence            0..1, the size's posterior given the width and its σ
        diameter_status       "measured", "not measured" or "hidden"
        diameter_reason       why not measured, or what the size came from
        design_diameter_mm    the design's size of the bar
        matches_design        whether the size is the design's (None unless measured)
        hidden                mostly covered by nearer bars
        occluded_fraction     share of the cross-sections partly under nearer bars
        one_sided_share       share of the cross-sections sized from one edge and the axis
        cloud_width_mm        the point cloud's diameter (refined)
        width_source          what the size came from: "mask", "cloud", "mask+cloud", "mask+"
                              and the independent widths, those widths alone, "+pitch"
        width_used_mm         the width that was snapped (also for an ambiguous bar)
        width_sigma_mm        its standard uncertainty
        circle_width_mm       diameter of the circle fitted to the cloud, calibrated (veto mode)
        circle_sigma_mm       the σ it is used with
        crest_width_mm        the widths' 95th percentile: the rib crests (24+ sections)
        core_width_mm         their 10th percentile: the core between the ribs
        rib_pitch_mm          the widths' period along the bar where clear (p < 1 %)
        ribs_resolved         the capture's bars show ribs (the same for every bar)
        ====================  ===================================================================

    Where the capture resolves ribs, a bar's silhouette is its core between the ribs and the
    envelope only at the crests: each bar is sized from its crests, its point-cloud width is
    not used, a size its core does not confirm is "not measured", and a bar left between two
    sizes is sized by its rib pitch where the system sets one per size (GB 1499.2). The rules
    and their measurements: ``docs/diameters.md``.

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
    >>> upper = table.merge(bars, on="bar_id").query(
    ...     "layer == 'upper' and diameter_status == 'measured'")
    >>> sorted(set(upper.nominal_mm))
    [12.0]
    """
    import pandas as pd

    m, maskf = _check_inputs(capture, bars, mask, method)
    if system is None:
        system = getattr(design, "bar_system", None) or DEFAULT_BAR_SYSTEM
    bar_system(system)  # validates the name
    intr = capture.intrinsics
    prm = DiameterParams(colour_edges=colour_edges or False)
    prepared = _prepare(
        bars,
        design,
        system,
        deformed,
        default_expected_mm=observed_width_mm(prm.default_size_mm, system=DEFAULT_BAR_SYSTEM, deformed=deformed),
    )
    _check_options(use_cloud, colour_edges)
    fp = _footprints(prepared, intr, prm.footprint_margin_rel, prm.footprint_margin_px)
    gray, rgb, depth, depth_img = _images(capture, use_depth, use_cloud)
    # an axis placed with an assumed radius: its cloud width echoes that radius, so it may only
    # veto, and the circle fitted to its cloud is what can size the bar (the refined decision
    # only: the paper's method never reads it)
    cloud_mode = ["veto" if use_cloud and math.isfinite(bar.axis_radius_mm) else use_cloud for bar in prepared]
    results = [
        _refined_bar(
            i,
            bar,
            maskf,
            gray,
            depth,
            intr,
            fp,
            prm,
            rgb,
            depth_img,
            circle=method == "refined" and cloud_mode[i] == "veto",
        )
        for i, bar in enumerate(prepared)
    ]
    sizes, ribs = _capture_ribs(
        results, prepared, prm, method=method, system=system, deformed=deformed, colour_edges=colour_edges
    )
    if ribs:
        cloud_mode = [False if m is True else m for m in cloud_mode]
    if method == "refined" and not ribs:
        # the capture's masks leaning wide (a photograph's soft edges), taken off them (decision 058)
        lean_px = _mask_lean(results, prepared, prm, system=system, deformed=deformed)
        if lean_px:
            for r in results:
                if len(r.widths) and math.isfinite(r.px_mm):
                    r.mask_lean_mm = lean_px * r.px_mm
                    r.widths = np.asarray(r.widths) - r.mask_lean_mm
                    r.mask_width_mm = float(np.median(r.widths))
    _calibrate(results, prepared, cloud_mode, prm, system=system, deformed=deformed)
    rows, shadows = _bar_rows(
        prepared,
        results,
        m,
        intr,
        cloud_mode,
        ribs,
        prm,
        method=method,
        system=system,
        deformed=deformed,
        paper_points=paper_points,
    )
    if method == "refined" and ribs:
        _pitch_settle(
            rows,
            results,
            sizes,
            shadows,
            prm,
            system=system,
            face=lambda i: _face_pitch(prepared[i], results[i], gray, intr, prm, fp, i),
        )
    if method == "refined" and deformed:
        _pitch_veto(rows, results, prm, system=system)
    if method == "refined":  # what a capture from closer would settle (advice only: no size changes)
        for bar, row in zip(prepared, rows):
            if row["diameter_status"] == NOT_MEASURED:
                row["diameter_reason"] += closer_advice(
                    row,
                    bar.p0,
                    bar.p1,
                    intr,
                    min_confidence=prm.min_confidence,
                    system=system,
                    deformed=deformed,
                    design=design,
                )
    df = pd.DataFrame(rows, columns=list(DIAMETER_COLUMNS))
    df["matches_design"] = df["matches_design"].astype(object)
    return df


def _bar_rows(prepared, results, m, intr, cloud_mode, ribs, prm, *, method, system, deformed, paper_points):
    """Each bar's row of the table, from its reading (and, for the paper's method, its own
    detect-points on the mask's boundary), and whether it lies in shadow.

    Parameters
    ----------
    prepared : list of _Bar
        The bars as :func:`~rebarlib.diameter.bars._prepare` gives them.
    results : list of BarReading
        Each bar's reading (:func:`_refined_bar`).
    m : ndarray of bool
        The rebar mask.
    intr : Intrinsics
    cloud_mode : list
        Each bar's ``use_cloud`` (True, False or "veto").
    ribs : bool
        Whether the capture resolves ribs.
    prm : DiameterParams
    method, system, deformed, paper_points
        As for :func:`measure_diameters`.

    Returns
    -------
    rows : list of tuple
        One row of :data:`DIAMETER_COLUMNS` per bar.
    shadows : list of bool
        Whether each bar is in shadow over its whole length (its mask edges the least
        reliable there are, so its size is never reported with high confidence).
    """
    edge, owner = _paper_owners(m, prepared, intr) if method == "paper" else (None, None)
    lums = np.array([r.lum for r in results], float)
    ref_lum = float(np.nanmedian(lums)) if np.isfinite(lums).any() else math.nan
    rows, shadows = [], []
    for i, bar in enumerate(prepared):
        reading = results[i]
        in_shadow = bool(np.isfinite(ref_lum) and reading.lum < prm.shadow_ratio * ref_lum)
        paper_w = (
            _paper_bar(i, bar, m, edge, intr, paper_points, owner, prm.paper_short_px) if method == "paper" else None
        )
        rows.append(
            _bar_row(
                bar,
                reading,
                paper_w,
                in_shadow,
                cloud_mode[i],
                ribs,
                prm,
                method=method,
                system=system,
                deformed=deformed,
            )
        )
        shadows.append(in_shadow)
    return rows, shadows


def _check_options(use_cloud, colour_edges) -> None:
    """Refuse a ``use_cloud`` or ``colour_edges`` that :func:`measure_diameters` does not know."""
    if use_cloud not in (True, False, "veto"):
        raise RebarInputError(f"use_cloud: expected True, False or 'veto', got {use_cloud!r}")
    if colour_edges not in ("check", "replace", False, None):
        raise RebarInputError(f"colour_edges: expected 'check', 'replace' or False, got {colour_edges!r}")


def _images(capture, use_depth, use_cloud):
    """``(gray, rgb, depth, depth_img)`` of a capture as the cross-sections read them: the
    colour image as luminance and as float RGB (None without colour), the depth for cutting
    mask runs (None unless ``use_depth``) and for the point-cloud widths (None unless
    ``use_cloud``)."""
    gray = rgb = None
    if capture.color is not None:
        import cv2

        rgb = np.ascontiguousarray(capture.color, dtype=np.float32)
        gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)  # luminance: only compared with itself
    depth = np.asarray(capture.depth_mm, np.float32) if use_depth else None
    depth_img = np.asarray(capture.depth_mm, np.float32) if (use_cloud and capture.depth_mm is not None) else None
    return gray, rgb, depth, depth_img


def _paper_owners(m, prepared, intr):
    """The paper's method: the mask's boundary pixels and, per boundary pixel, the bar whose
    projected axis is nearest (-1 elsewhere)."""
    edge = boundary_pixels(m)
    vv, uu = np.nonzero(edge)
    owner = np.full(m.shape, -1, np.int32)  # bar index of each boundary pixel
    owner[vv, uu] = _attribute_pixels(np.column_stack((uu, vv)), prepared, intr)
    return edge, owner


def _capture_ribs(results, prepared, prm, *, method, system, deformed, colour_edges):
    """``(sizes, ribs)``: each bar's size for its rib pitch (its design's, else the size its
    median width is nearest), and whether the capture resolves ribs (refined, deformed bars:
    in its mask widths, else in its colour widths). Sets each reading's ``mask_width_mm``: its
    sections' median, or where ribs are resolved the envelope read from its crests."""
    for r in results:
        r.mask_width_mm = float(np.median(r.widths)) if len(r.widths) else math.nan
        r.rib_sigma_mm = 0.0
    sizes = [
        b.design_mm
        if math.isfinite(b.design_mm) or not len(r.widths)
        else snap_diameter(r.mask_width_mm, system=system, deformed=deformed)[0]
        for b, r in zip(prepared, results)
    ]
    ribs_p = (
        _ribs_in_view([(r.rib_pitch_mm, r.rib_p) for r in results], prm, sizes)
        if method == "refined" and deformed
        else 1.0
    )
    ribs = ribs_p < prm.rib_capture_p
    if ribs:
        # periodic widths are ribs only at the standard's spacings (decision 047)
        ribs = _mask_ribs_follow_table(results, sizes, prm, system=system)
    if method == "refined" and deformed and not ribs and colour_edges:
        # a mask that smooths the ribs away: the colour image may still show them. Where a bar's
        # point cloud would be fused with its mask width (axes found without an assumed radius),
        # both then read a ribbed bar a size down and agree. An axis placed with an assumed
        # radius vetoes that for a bar of the design size, but not for a bar one size larger
        # than designed: read a size down, it gives the design size, which the cloud echoes
        ribs = _colour_ribs(results, sizes, prm, system=system)
    # Ribs resolved: each bar's mask width is the envelope read from its crests, and its
    # point-cloud width (a surface over crests and core alike) is no envelope
    for r in results:
        if ribs and math.isfinite(r.crest_mm):
            h = rib_height_mm(r.crest_mm, system=system)
            r.mask_width_mm, r.rib_sigma_mm = r.crest_mm + prm.rib_reach * h, prm.rib_reach * h
    return sizes, ribs


def _calibrate(results, prepared, cloud_mode, prm, *, system, deformed) -> None:
    """What the capture's bars teach each reading: the colour edges' offset and weight, the
    mask's spread between bars, and the calibrated independent widths (the circle fitted to
    the cloud, the bar's top above the bars it rests on and above its level's supports; only
    for axes placed with an assumed radius, see ``decision._settle``)."""
    _colour_calibration(results, prepared, prm)
    _mask_between_spread(results, prepared, prm)
    for i, bar in enumerate(prepared):
        r = results[i]
        r.stack_width_mm = bar.stack_mm if cloud_mode[i] == "veto" else math.nan
        r.level_width_mm = bar.top_mm if cloud_mode[i] == "veto" else math.nan
        r.stack_sigma_mm = r.level_sigma_mm = 0.0
    # each bar's width calibrated on the other bars, never on masks the design all contradicts
    designs = [b.design_mm for b in prepared]
    _width_calibration(results, "circle", prm, system=system, deformed=deformed, designs=designs)
    _width_calibration(results, "stack", prm, system=system, deformed=deformed, designs=designs)
    # the bars of one level rest on the same supports: a bar's top above the formwork less the
    # supports' height, learnt from its level's bars that the mask sizes clearly
    _width_calibration(
        results,
        "level",
        prm,
        system=system,
        deformed=deformed,
        groups=[(b.layer, b.level) for b in prepared],
        designs=designs,
    )
    for r in results:  # a bar's own top counts once: where it has a stack height, that is its top
        if math.isfinite(r.stack_width_mm) and math.isfinite(r.stack_between_mm):
            r.level_width_mm = math.nan


def _new_row(bar, reading, occ_frac, ribs, prm, method) -> dict:
    """A bar's row of :data:`DIAMETER_COLUMNS` before it is sized: not measured, with what its
    cross-sections read."""
    return {
        "bar_id": bar.bar_id,
        "width_median_mm": math.nan,
        "width_spread_mm": math.nan,
        "n_sections": 0,
        "nominal_mm": math.nan,
        "confidence": 0.0,
        "diameter_status": NOT_MEASURED,
        "diameter_reason": "",
        "design_diameter_mm": bar.design_mm,
        "matches_design": None,
        "hidden": False,
        "occluded_fraction": round(occ_frac, 3),
        "one_sided_share": round(reading.one_sided_share, 3) if method == "refined" else 0.0,
        "cloud_width_mm": math.nan,
        "width_source": "",
        "width_used_mm": math.nan,
        "width_sigma_mm": math.nan,
        "mask_lean_mm": round(reading.mask_lean_mm, 3),
        "circle_width_mm": reading.circle_width_mm,
        "circle_sigma_mm": reading.circle_sigma_mm,
        "crest_width_mm": reading.crest_mm,
        "core_width_mm": reading.core_mm,
        "rib_pitch_mm": reading.rib_pitch_mm if reading.rib_p < prm.rib_bar_p else math.nan,
        "ribs_resolved": ribs,
    }


def _bar_row(bar, reading, paper_w, in_shadow, cloud_mode, ribs, prm, *, method, system, deformed) -> dict:
    """One bar's row of :data:`DIAMETER_COLUMNS`: its widths' statistics and its size, or why
    it has none (outside the image, hidden, too few clean sections, no size). ``paper_w``: the
    paper's widths of the bar (None for the refined method)."""
    n_in = int(reading.in_image.sum())
    occ_frac = float(reading.occluded.sum() / n_in) if n_in else 0.0
    row = _new_row(bar, reading, occ_frac, ribs, prm, method)
    w = reading.widths
    clean = len(w)  # hidden-bar detection is shared by both methods (the refined analysis)
    if method == "paper":
        w = paper_w
    med = math.nan
    if len(w):
        q1, med, q3 = np.percentile(w, [25, 50, 75])
        row.update(width_median_mm=float(med), width_spread_mm=float((q3 - q1) / 1.349), n_sections=len(w))
    few = len(w) < (1 if method == "paper" else prm.min_sections)
    if n_in == 0:
        row["diameter_reason"] = AXIS_OUTSIDE
    elif clean < prm.min_sections and occ_frac >= prm.hidden_fraction:
        row.update(diameter_status=HIDDEN, hidden=True, diameter_reason=_hidden_reason(bar, reading, occ_frac, prm))
    elif few:
        why = max(("crossing", "no_edge", "border", "shadow", "outlier", "holed"), key=lambda k: getattr(reading, k))
        row["diameter_reason"] = (
            f"too few clean cross-sections ({len(w)} of {reading.stations}; most lost {_LOST[why]})"
        )
    elif method == "paper":
        nominal, share = _paper_vote(w, system, prm.paper_bin_mm)
        if math.isfinite(nominal):
            row.update(
                nominal_mm=nominal,
                confidence=round(share, 3),
                diameter_status=MEASURED,
                width_source="mask",
                width_used_mm=float(med),
            )
        else:
            row["diameter_reason"] = f"no width within ±1 mm of a {system} size (median {med:.1f} mm)"
    elif ribs and not math.isfinite(reading.crest_mm):
        row["diameter_reason"] = (
            f"ribs resolved in this capture: {len(w)} clean cross-sections "
            "are too few to read the bar's rib crests (at least "
            f"{prm.rib_min_sections})"
        )
    else:
        row.update(
            _refined_decision(
                reading.mask_width_mm,
                row["width_spread_mm"],
                len(w),
                reading,
                in_shadow,
                prm,
                system=system,
                deformed=deformed,
                use_cloud=cloud_mode,
                assumed_mm=bar.axis_radius_mm,
                mask_median=med,
                covered=occ_frac,
            )
        )
        if ribs and row["diameter_status"] == MEASURED:
            _check_core(row, reading, prm, system=system)
        if (
            row["diameter_status"] == NOT_MEASURED
            and occ_frac >= prm.hidden_fraction
            and (_off_centre(reading, med, prm) or reading.one_sided_share >= prm.hidden_fraction)
        ):
            # the side the mask lacks is under the nearer bars along most of the bar: no section
            # shows its whole width, so it is hidden for its size, as a bar wholly under them is.
            # Seen as runs centred off the axis, or as most sections sized from one edge and the
            # axis (docs/decisions/024-one-sided-bars-under-nearer-bars.md)
            row.update(
                diameter_status=HIDDEN,
                hidden=True,
                diameter_reason=(
                    f"hidden: {occ_frac:.0%} of its cross-sections lie partly under nearer bars and the "
                    f"mask shows one side only ({row['diameter_reason']})"
                ),
            )
    if row["diameter_status"] == MEASURED:
        row["matches_design"] = _matches_design(row["nominal_mm"], bar.design_mm)
    return row


def _hidden_reason(bar, reading, occ_frac, prm) -> str:
    """Why a bar mostly under nearer bars is "hidden", and, for a sliver seen beside them, why
    it still gives no size."""
    reason = f"hidden: {occ_frac:.0%} of its cross-sections lie wholly or partly under nearer bars"
    if not bar.axis_ok and reading.one_edge >= prm.min_sections:
        # a sliver beside the bar over it: what is seen is not nothing, and the inspector
        # should know why it still gives no size
        reason += (
            f"; {reading.one_edge} cross-sections show one edge of it beside them (a "
            "sliver): a width from one edge needs the axis placed to a fraction of a "
            "millimetre, which a sliver does not give without taking the bar's radius "
            "as known"
        )
    return reason
