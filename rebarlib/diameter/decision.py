"""The refined decision for one bar: its size, confidence, status and reason from its mask
width, its point-cloud width and the widths that depend on neither.
"""

from __future__ import annotations

import math

import numpy as np

from .barsizes import bar_system, bracketing_sizes, observed_width_mm, size_half_gaps_mm, snap_diameter
from .calibration import _two_sided
from .params import MEASURED, NOT_MEASURED


def _alert_other_size(out: dict, med, nom_m, conf_m, dw, nom_c, prm, covered: float = 0.0) -> None:
    """A bar vetoed by a cloud that echoes an assumed radius: where the mask alone is clear about
    another size (``nom_m`` with confidence ``conf_m``, from the mask width ``med``) than the one
    the axis was placed with (``nom_c``), the reason says so and names it. The cloud (width
    ``dw``) cannot confirm it, so the bar stays "not measured", but the inspector learns which
    bar may be of another size.

    Not for a bar most of whose cross-sections (``covered``, a share, at least
    ``prm.hidden_fraction``) lie partly under nearer bars: its mask width is read on what is seen
    beside them, a sliver or one edge and an axis placed with the assumed radius, and the
    confidence its σ gives is not earned. Seen over seven benchmark runs (detected axes, fused
    mask, 1 to 8 alerts each): every alert on such a bar named a size the bar is not (12 of 12),
    and every alert that named a bar's true size was on a bar with at most a quarter of its
    sections covered. Its reason says why no size is suggested."""
    if not (math.isfinite(nom_m) and nom_m != nom_c and conf_m >= prm.min_confidence):
        return
    if covered >= prm.hidden_fraction:
        out["diameter_reason"] += (
            f"; {covered:.0%} of its cross-sections lie partly under nearer bars: its mask width "
            "is read on what is seen beside them and suggests no other size"
        )
    else:
        out["diameter_reason"] = (
            f"possible wrong size: the mask width {med:.1f} mm gives Φ{nom_m:g} (confidence {conf_m:.2f}), "
            f"but the axis was fitted with the radius of Φ{nom_c:g}, so the point cloud ({dw:.1f} mm) "
            "cannot confirm another size: check this bar by hand"
        )


#: the widths that do not depend on where an axis placed with an assumed radius lies: how the
#: reason names each
_INDEPENDENT = {
    "stack": "its top {w:.1f} ± {s:.1f} mm above the bars it rests on",
    "level": "its top {w:.1f} ± {s:.1f} mm above its level's supports",
    "circle": "the point cloud's shape, circle fit {w:.1f} ± {s:.1f} mm",
}


def _independent_widths(info) -> list:
    """``(key, width, σ)`` of each width of a bar that depends neither on its mask nor on where
    an axis placed with an assumed radius lies (:data:`_INDEPENDENT`) and is sound: measured,
    with a σ, and calibrated against the capture's bars (``{key}_between_mm`` finite,
    :func:`_width_calibration`)."""
    used = []
    for key in _INDEPENDENT:
        w, sg = getattr(info, f"{key}_width_mm"), getattr(info, f"{key}_sigma_mm")
        learnt = math.isfinite(getattr(info, f"{key}_between_mm"))
        if math.isfinite(w) and math.isfinite(sg) and sg > 0 and learnt:
            used.append((key, w, sg))
    return used


def _birge_mean(widths, sigmas) -> tuple[float, float]:
    """Weighted mean of independent estimates of one width and its σ, enlarged by the Birge
    ratio (the scatter of the estimates around their mean against their σ) where they lie
    further apart than their σ say; one estimate is its own mean."""
    ws = np.asarray(widths, float)
    wt = 1 / np.asarray(sigmas, float) ** 2
    width = float((wt * ws).sum() / wt.sum())
    birge = math.sqrt(float((wt * (ws - width) ** 2).sum()) / (len(ws) - 1)) if len(ws) > 1 else 1.0
    return width, max(1.0, birge) / math.sqrt(float(wt.sum()))


def _arbitrate(out, med, conf_m, pair, info, in_shadow, prm, *, system, deformed, covered: float = 0.0):
    """``out`` as a bar sized by its independent widths alone (:func:`_independent_widths`),
    where its mask width ``med`` and the size its axis was placed with disagree (``pair``: the
    mask's size and the assumed one); None where they cannot tell.

    Of two sources in conflict one is biased, and which one the two cannot say: the mask (a
    learnt mask eating into a bar, an edge read at a depth step, a width from one edge and an
    axis a fraction of a millimetre off) or the assumed size (a bar of another size than
    designed). A third measurement that depends on neither arbitrates, as the rib pitch does
    (:func:`_pitch_settle`): the bar's top above the bars it rests on, above its level's
    supports, the circle fitted to its cloud. Their weighted mean, its σ enlarged where they
    lie further apart than their σ say (Birge ratio), must be clear on its own: its σ within
    the smaller half step from the size to its neighbours, its confidence at least
    ``prm.min_confidence``, and the size one of the two in conflict (a third size would mean a
    third source is off too: nothing is settled). Which of the two they may give is the mask's
    word (``conf_m``, its own confidence in its size): the mask's size where the mask is clear
    about it (at least ``prm.min_confidence``), else the assumed size. They never give the
    assumed size against a clear mask (that bar keeps its "possible wrong size",
    :func:`_alert_other_size`), nor another size on their word alone."""
    used = _independent_widths(info)
    if not used or not all(math.isfinite(x) for x in pair):
        return None
    width, sigma = _birge_mean([w for _, w, _ in used], [sg for _, _, sg in used])
    nominal, conf = snap_diameter(width, system=system, deformed=deformed, sigma_mm=sigma)
    if (
        nominal not in pair
        or conf < prm.min_confidence
        or sigma > min(size_half_gaps_mm(nominal, system=system, deformed=deformed))
    ):
        return None
    # a mask width from one edge and the axis of a bar seen beside nearer bars (``covered``: the
    # share of its sections partly under them) carries the axis's error twice, and the axis of
    # such a bar is fitted to the side it shows: it is no clear word against the radius that
    # axis was placed with (:func:`_two_sided`). Four such bars, their tops read 2-3 mm low,
    # were sized a size down on it at confidence 0.85-0.98
    clear = conf_m >= prm.min_confidence and (_two_sided(info) or covered < prm.hidden_fraction)
    if pair[0] != pair[1] and (nominal == pair[0]) != clear:
        # The mask's own word decides which of the two these widths may confirm. A mask clear
        # about another size than the assumed one is the alert a bar of the wrong size gives:
        # one width with tails of its own (a bar lifted off its supports by a tie reads a size
        # up) does not silence it. And a size other than the assumed one is not given on such a
        # width where the mask is not clear about it too (on a D435-like capture, a bar lying
        # 1 mm low on its supports, its top read 2 mm low, read a size down with a mask leaning
        # that way at 0.74)
        return None
    why = (
        f"its mask width {med:.1f} mm is nearest Φ{pair[0]:g}, the axis was fitted with the radius of "
        f"Φ{pair[1]:g}, and these widths, which depend on neither, tell the two apart"
        if pair[0] != pair[1]
        else f"its mask width {med:.1f} mm and its point cloud, which echoes the radius its axis was fitted with, "
        "disagree, and these widths depend on neither"
    )
    reason = f"size from {' and '.join(_INDEPENDENT[k].format(w=w, s=sg) for k, w, sg in used)}: {why}"
    return _sized(out, nominal, conf, width, sigma, "+".join(k for k, _, _ in used), reason, in_shadow, prm)


def _settle(out, med, sigma_m, info, in_shadow, prm, *, system, deformed, size, against=math.nan):
    """``out`` as a bar sized from its mask width and the widths that do not depend on an axis
    placed with an assumed radius, whose own cloud width only echoes that radius: the circle
    fitted to its point cloud (:func:`_cloud_circle`) and, for a bar resting on others, its
    top's height above theirs (``geometry.stack_heights``), else its top above its level's
    supports (``geometry.top_heights``); None where they do not settle the size.

    Each such width is used where it is sound (and ``prm.colour_offset_bars`` bars gave its
    between-bar spread, :func:`_width_calibration`, the σ it is used with: ``{key}_sigma_mm``);
    every sound one must lie within ``prm.veto_k`` combined σ of the mask width (one that does
    not is a conflict: nothing is settled), and together (their weighted mean's σ) they must be
    within the smaller half step from ``size`` to the next sizes (else they could not have told
    it from a neighbour and confirm nothing). Their weighted mean with the mask width, its σ
    enlarged where they lie further apart than their σ say (Birge ratio), must snap to ``size``
    (the mask's own: they confirm, never overturn) with confidence ≥ ``prm.min_confidence``.

    ``against``: the size the axis was placed with, where ``size`` is another (the mask gives a
    bar of the wrong size). Such a size fails the bar, so the widths that depend on neither the
    mask nor that axis must themselves lie nearer ``size``'s observed width than ``against``'s
    (decision 070): within the veto they may lean either way, and a mask read wide all along (a
    grey bar among rusty ones) would be "confirmed" by a top height that points to the designed
    size.
    """
    used = _independent_widths(info)
    if not used or any(abs(med - w) / math.hypot(sigma_m, sg) > prm.veto_k for _, w, sg in used):
        return None
    if math.isfinite(against) and against != size:
        alone, _ = _birge_mean([w for _, w, _ in used], [sg for _, _, sg in used])
        to_size = abs(alone - observed_width_mm(size, system=system, deformed=deformed))
        if to_size >= abs(alone - observed_width_mm(against, system=system, deformed=deformed)):
            return None
    # confirming needs evidence that could have told the size from its neighbours: the widths
    # together within a half size step at one σ (a circle fitted to a few millimetres of arc
    # with a σ of 5 mm, or a top height with 2 mm, agrees with any size the mask gives)
    wt = 1 / np.array([sg for _, _, sg in used]) ** 2
    if 1 / math.sqrt(float(wt.sum())) > min(size_half_gaps_mm(size, system=system, deformed=deformed)):
        return None
    width, sigma = _birge_mean([med] + [w for _, w, _ in used], [sigma_m] + [sg for _, _, sg in used])
    nominal, conf = snap_diameter(width, system=system, deformed=deformed, sigma_mm=sigma)
    if nominal != size or conf < prm.min_confidence:
        return None
    reason = "size from the mask and " + " and ".join(_INDEPENDENT[k].format(w=w, s=sg) for k, w, sg in used)
    return _sized(out, nominal, conf, width, sigma, "mask+" + "+".join(k for k, _, _ in used), reason, in_shadow, prm)


def _sized(out, nominal, conf, width, sigma, source, reason, in_shadow, prm) -> dict:
    """``out`` as a measured bar: its size, confidence (capped for a bar in shadow, saying so),
    and the width it came from with its σ and source."""
    if in_shadow:
        conf = min(conf, prm.shadow_confidence)
        reason = (reason + "; " if reason else "") + "bar in shadow: confidence capped"
    out.update(
        nominal_mm=nominal,
        confidence=round(conf, 4),
        diameter_status=MEASURED,
        diameter_reason=reason,
        width_source=source,
        width_used_mm=round(width, 3),
        width_sigma_mm=round(sigma, 3),
    )
    return out


def _off_centre(info, med, prm) -> bool:
    """Whether a bar's mask runs are centred this far off its axis: one side of the bar is lost."""
    return abs(info.centre_mm) > prm.max_offcentre_rel * med


def _check_core(row: dict, info, prm, *, system) -> None:
    """A bar sized from its rib crests must have a core between them that a bar of that size
    can show: where it cannot, the bar is "not measured".

    The core between the transverse ribs is never narrower than the size's core d1 nor wider
    than its rib envelope; a bar turned with its longitudinal ribs towards the sides shows
    about the envelope all along, so the core may read anywhere between (one σ of the bar's width
    beyond either bound is allowed). And where the core is also one the next size up can show
    (at least its d1), only the crests tell the two apart: they are read from the few widest
    sections, the first lost where a flank is hidden or cut at a bar beside it, so they are
    not trusted alone to rule the larger size out.
    """
    sysm = bar_system(system)
    nominal, c = row["nominal_mm"], info.core_mm
    tol = row["width_sigma_mm"] if math.isfinite(row["width_sigma_mm"]) else 0.0
    d1 = sysm.of_size(sysm.core_mm, nominal, math.nan)
    env = sysm.of_size(sysm.envelope_mm, nominal, math.nan)
    # the next size up and its d1
    larger = next(((s, k) for s, k in zip(sysm.sizes_mm, sysm.core_mm) if s > nominal), None)
    if c < d1 - tol:  # the size the core can be: the largest whose d1 it reaches
        core = max((s for s, k in zip(sysm.sizes_mm, sysm.core_mm) if k <= c), default=math.nan)
    elif c > env + tol:  # the smallest whose envelope it fits in
        core = next((s for s, e in zip(sysm.sizes_mm, sysm.envelope_mm) if e >= c), math.nan)
    elif larger and c >= larger[1]:
        core = larger[0]
    else:
        return
    reason = (
        f"ribs resolved: the rib crests ({info.crest_mm:.1f} mm) give {sysm.label(nominal)}, "
        f"the core between them ({c:.1f} mm) {sysm.label(core) or 'no size'}: check it by hand"
    )
    # (the two sizes they point to: the rib pitch may tell them apart, _pitch_settle)
    row.update(
        nominal_mm=math.nan, confidence=0.0, diameter_status=NOT_MEASURED, diameter_reason=reason, _pair=(nominal, core)
    )


def _matches_design(nominal_mm, design_mm):
    """Whether a measured size is the design's; None where the bar has no design size."""
    return bool(abs(nominal_mm - design_mm) < 1e-6) if math.isfinite(design_mm) else None


def _ambiguous_reason(width, source, conf, nominal, pair, system) -> str:
    """Why a width gives no size: the two sizes it lies between (``pair``, from
    :func:`bracketing_sizes`: what a check by hand must tell apart) and the one it is nearer to,
    with that size's confidence."""
    sysm = bar_system(system)
    if pair is None:  # (beyond the table: snap_diameter gives no size there)
        return f"ambiguous: width {width:.1f} mm ({source}) lies between two {system} sizes (confidence {conf:.2f})"
    (a, wa), (b, wb) = pair
    return (
        f"ambiguous: width {width:.1f} mm ({source}) lies between {sysm.label(a)} ({wa:.1f} mm) and "
        f"{sysm.label(b)} ({wb:.1f} mm), nearer {sysm.label(nominal)} (confidence {conf:.2f}): check it by hand"
    )


def _refined_decision(
    med,
    spread,
    n,
    info,
    in_shadow,
    prm,
    *,
    system,
    deformed,
    use_cloud,
    assumed_mm=math.nan,
    mask_median=None,
    covered: float = 0.0,
) -> dict:
    """Size, confidence, status and reason of one bar from its mask widths and point-cloud width.

    The mask width and the point-cloud width are two independent measurements, each with a
    standard uncertainty. Where both are sound they must agree (else "not measured": one of them
    is biased) and their weighted mean is snapped; where the mask's edges are unreliable
    (scattered, off-centre) a sound point-cloud width alone gives the size, its confidence
    capped because it relies on the axis lying at the bar's centre.

    Parameters
    ----------
    med : the mask's width (the ribs' envelope read from their crests where the capture resolves
        them, with ``info.rib_sigma_mm`` for how far a crest's reach varies with the bar's roll)
    spread, n : the robust spread of the section widths and how many sections
    info : the bar's :class:`BarReading`
    in_shadow : the bar lies in shadow over its whole length (its confidence is capped)
    prm : DiameterParams
    system, deformed : the bar-size standard and whether the bars are deformed
    use_cloud : True, False or "veto" (see :func:`measure_diameters`)
    assumed_mm : the radius the axis was placed with (NaN: none assumed)
    mask_median : the sections' median width, which the colour edges are checked against where
        ``med`` is read from the crests (None: ``med``)
    covered : the share of its cross-sections that lie partly under nearer bars (a bar mostly
        covered is not alerted as of another size, :func:`_alert_other_size`)

    Returns
    -------
    dict of the row's columns that the decision sets (``nominal_mm``, ``confidence``,
    ``diameter_status``, ``diameter_reason``, ``cloud_width_mm``, ``width_source``,
    ``width_used_mm``, ``width_sigma_mm``) and, for a bar left between two sizes, ``_pair``.
    """
    sigma_m = _mask_sigma(med, spread, n, info, prm, mask_median)
    mask_problem = _mask_problem(med, spread, n, info, prm)
    dw = info.depth_width_mm
    cloud = bool(use_cloud and math.isfinite(dw))
    veto_only = use_cloud == "veto"
    sigma_c = _cloud_sigma(info, prm) if cloud else math.inf
    out = {"cloud_width_mm": dw, "confidence": 0.0, "diameter_status": NOT_MEASURED}
    if use_cloud and info.depth_off_share > 0.5:  # (NaN: no cloud, no verdict)
        out["diameter_reason"] = _off_bar_reason(info)
        return out
    cap = 1.0
    if not mask_problem and cloud:
        done, width, sigma, source = _mask_and_cloud(
            out,
            med,
            sigma_m,
            sigma_c,
            info,
            in_shadow,
            prm,
            system=system,
            deformed=deformed,
            veto_only=veto_only,
            assumed_mm=assumed_mm,
            covered=covered,
            sigma_word=_mask_sigma(med, spread, n, info, prm, mask_median, swept=False),
        )
        if done is not None:
            return done
    elif not mask_problem:
        width, sigma, source = med, sigma_m, "mask"
        if use_cloud:
            sigma = _mask_alone_sigma(
                out, med, sigma_m, spread, n, info, prm, system, deformed, assumed_mm, mask_median
            )
            if sigma is None:
                return out
    elif cloud and not veto_only:
        width, sigma, source = dw, sigma_c, "cloud"
        cap = prm.cloud_only_confidence
    else:
        out["diameter_reason"] = mask_problem
        return out
    nominal, conf = snap_diameter(width, system=system, deformed=deformed, sigma_mm=sigma)
    if not math.isfinite(nominal):
        out["diameter_reason"] = f"width {width:.1f} mm matches no {system} size"
        return out
    if conf < prm.min_confidence and veto_only and cloud and not mask_problem:
        # the mask alone is ambiguous: the shape of the cloud (a circle fit) may settle it, for
        # the size the mask is nearest to only: the circle's errors have heavy tails, so it may
        # confirm what the mask leans to but never overturn it
        settled = _settle(out, med, sigma_m, info, in_shadow, prm, system=system, deformed=deformed, size=nominal)
        if settled is not None:
            return settled
    if conf < prm.min_confidence:
        pair = bracketing_sizes(width, system=system, deformed=deformed)
        out.update(
            confidence=conf,
            width_source=source,
            width_used_mm=round(width, 3),
            width_sigma_mm=round(sigma, 3),
            diameter_reason=_ambiguous_reason(width, source, conf, nominal, pair, system),
        )
        if pair is not None:
            out["_pair"] = (pair[0][0], pair[1][0])
        return out
    reason = f"size from the point cloud; {mask_problem}" if source == "cloud" else ""
    return _sized(out, nominal, min(conf, cap), width, sigma, source, reason, in_shadow, prm)


def _mask_alone_sigma(out, med, sigma_m, spread, n, info, prm, system, deformed, assumed_mm, mask_median):
    """The σ a bar's mask width ``med`` (its usual σ ``sigma_m``, :func:`_mask_sigma`) is
    snapped with where the bar has no point cloud (no depth
    across it: the projector's shadow of a bar above, a hole), or None where ``out`` now says
    it is "possible wrong size" (decision 052).

    Where a cloud exists, a mask that gives another size than the one the axis was placed with
    (``assumed_mm``, a radius) must be confirmed by widths that depend on neither
    (:func:`_mask_and_cloud`, :func:`_arbitrate`); without a cloud there are none, and the
    mask's edges, a learnt network's, are the bar's only reading. So where the mask's nearest
    size is not the assumed one, its word is weighed as against a cloud, each edge's rounding to
    the pixel grid in full (:func:`_mask_sigma` with ``swept=False``): clear about another size
    even so, the bar is a possible wrong size, not measured, and names it; not clear, it is
    ambiguous at that σ (and the advice for a closer capture follows). Where the mask gives the
    assumed size, or no size was assumed, the mask's σ is as before. Seen on a bar of the
    lowest layer, ribs in relief, no depth along it: a Φ16 whose mask read 16.5 mm was sized Φ14
    at 0.82 and failed a clean slab's bar sizes."""
    if not math.isfinite(assumed_mm):
        return sigma_m
    nom_c = snap_diameter(2 * assumed_mm, system=system, deformed=deformed)[0]
    nearest = snap_diameter(med, system=system, deformed=deformed, sigma_mm=sigma_m)[0]
    if not math.isfinite(nearest) or not math.isfinite(nom_c) or nearest == nom_c:
        return sigma_m
    sigma_word = _mask_sigma(med, spread, n, info, prm, mask_median, swept=False)
    nom_m, conf_m = snap_diameter(med, system=system, deformed=deformed, sigma_mm=sigma_word)
    if conf_m < prm.min_confidence or nom_m == nom_c:
        return sigma_word
    out.update(width_source="mask", width_used_mm=round(med, 3), width_sigma_mm=round(sigma_word, 3))
    out["diameter_reason"] = (
        f"possible wrong size: the mask width {med:.1f} mm gives Φ{nom_m:g} (confidence {conf_m:.2f}), "
        f"but the bar has no point cloud and its axis was placed with the radius of Φ{nom_c:g}: "
        "nothing but the mask says another size: check this bar by hand"
    )
    return None


def _mask_sigma(med, spread, n, info, prm, mask_median=None, *, swept=True) -> float:
    """The standard uncertainty of a bar's mask width ``med``: the sections' scatter, the mask's
    error per bar, its runs off the axis, the colour edges' disagreement, one-sided sections and
    the rib crests' reach (see :func:`_refined_decision`).

    ``swept``: the edges' rounding to the pixel grid (``prm.quantisation_px``) is divided by
    √(pixel phases the edges sweep along the bar), as rounding at many phases averages out.
    False: it is not (see :func:`_mask_and_cloud`: a mask's word against the cloud's)."""
    px_mm, off = info.px_mm, abs(info.centre_mm)
    # the colour edges of a round bar sit inside its silhouette by an amount set by the light
    # (shading towards the limbs): that common offset of the capture is not the mask's error
    cdiff = 0.0
    if math.isfinite(info.colour_width_mm):
        r = abs(info.colour_width_mm - (med if mask_median is None else mask_median) - info.colour_offset_px * px_mm)
        typical = prm.veto_k * info.colour_spread_mm
        cdiff = info.colour_weight * min(r, typical) + max(r - typical, 0.0)
    # A learnt mask's error is mostly a bias per bar, not noise that averages out over the
    # sections: part of the spread is kept as a systematic term.
    quant_px = prm.quantisation_px / math.sqrt(max(1.0, info.phase_sweep_px) if swept else 1.0)
    # the mask's error per bar: pixel rounding and the part of its spread that is a bias of the
    # whole bar, or what the capture's bars of one size show between them if that is more
    per_bar = max(math.hypot(quant_px * px_mm, prm.mask_spread_sys * spread), info.mask_between_mm)
    # a width from one edge and the axis (one-sided sections) is off by twice the axis's error
    one_sided = 2 * prm.axis_sigma_mm * info.one_sided_share
    return math.hypot(
        1.2533 * spread / math.sqrt(n),
        per_bar,
        2 * max(off - prm.axis_sigma_mm, 0.0),
        max(cdiff - prm.colour_tolerance_px * px_mm, 0.0),
        one_sided,
        info.rib_sigma_mm,
    )


def _mask_problem(med, spread, n, info, prm) -> str:
    """Why a bar's mask width cannot be trusted (its runs off the axis, its widths too
    scattered); "" where it can."""
    if _off_centre(info, med, prm):
        return (
            f"mask not centred on the axis ({abs(info.centre_mm):.1f} mm off over a {med:.1f} mm width): "
            f"one side lost to shadow or segmentation"
        )
    if spread > prm.max_spread_rel * med:
        return f"mask widths too scattered (robust σ {spread:.1f} mm over {n} sections)"
    return ""


def _cloud_sigma(info, prm) -> float:
    """The standard uncertainty of a bar's point-cloud width: its points' scatter (neighbours
    sharing their noise), the axis's lateral error and the camera's bias, growing with z²."""
    # depth noise grows with z²; besides its random part, the cloud of an active stereo
    # camera is off by up to about a millimetre on a bar's diameter at 500-700 mm
    d_spread, d_n = info.depth_spread_mm, info.depth_points
    return math.hypot(
        1.2533 * d_spread / math.sqrt(max(d_n / prm.depth_correlated_px, 1.0)),
        2 * prm.axis_sigma_mm,
        prm.cloud_bias_mm_per_m2 * (info.z_mm / 1000) ** 2,
    )


def _off_bar_reason(info) -> str:
    """Why a bar whose point cloud across the mask runs lies mostly off the bar is not sized."""
    off_bar = info.depth_off_share
    if info.depth_off_covered:
        # every section under a nearer bar (a sliver beside it): the band from its one edge to
        # the axis runs under that bar, and too few of the bar's own points are left there
        return (
            f"{off_bar:.0%} of the point cloud between its visible edge and the axis lies on "
            "the bar over it, and too few of its own points are left to check a width from one "
            "edge"
        )
    # the depth across the mask runs lies mostly beyond a diameter from the axis: what the
    # mask shows there is mostly another object (the bar over this one), not this bar
    return (
        f"{off_bar:.0%} of the point cloud across the mask runs lies farther from the axis "
        "than the bar's diameter: the mask there shows another object (a bar over it)"
    )


def _mask_and_cloud(
    out, med, sigma_m, sigma_c, info, in_shadow, prm, *, system, deformed, veto_only, assumed_mm, covered, sigma_word
):
    """A sound mask width against a point-cloud width: ``(done, width, sigma, source)``, where
    ``done`` is the bar's finished row where they disagree (else None, and the width to snap:
    their weighted mean, or in veto mode the mask's alone). ``sigma_word``: the mask width's σ
    with its edges' rounding to the pixel grid in full (:func:`_mask_sigma`, ``swept=False``),
    which its word against the size the axis was placed with is weighed with."""
    dw = info.depth_width_mm
    # With an assumed axis radius the cloud width echoes it: a mask giving another size can
    # never be confirmed by the cloud, so in veto mode the mask must give the assumed size.
    # That size is the assumed radius's where it is known, not the echo's: where the axis is
    # off across the bar, the echo drifts with it, and so does a width from one edge to the
    # axis; the two would then agree on a wrong size (seen on a bar seen from one side only)
    nom_c = nom_m = math.nan
    conf_m = 0.0
    if veto_only:
        nom_c = (
            snap_diameter(2 * assumed_mm, system=system, deformed=deformed)[0]
            if math.isfinite(assumed_mm)
            else snap_diameter(dw, system=system, deformed=deformed)[0]
        )
        nom_m, conf_m = snap_diameter(med, system=system, deformed=deformed, sigma_mm=sigma_m)
    strict = veto_only and nom_c != nom_m
    if strict:
        # The mask gives another size than the axis was placed with, and the cloud echoes that
        # radius: the two disagree, and the mask's word against it is weighed at the capture's
        # pixel size. A slanted bar's edges sweep many pixel phases, which averages a binary
        # edge's rounding out; a learnt mask placing both edges a fraction of a pixel off along
        # the whole bar is not averaged, and the robust spread between the capture's bars
        # (``mask_between_mm``) shows that bias for the typical bar, not for the one bar in
        # its tail that now overturns a size. So here each edge's rounding counts in full
        # (``prm.quantisation_px``, 0.41 px for the width): at 1.3-1.5 mm a pixel (a D435-like
        # camera at 848 × 480, 550-650 mm) that is 0.55-0.6 mm, where Φ12 and Φ14 lie 2.3 mm
        # (1.7 px) apart, and a Φ14 read a pixel narrow (14.8 mm, σ 0.47) had been "clearly"
        # Φ12 at 0.87 and sized Φ12 at 0.97 with its top above its level's supports
        sigma_m = sigma_word
        nom_m, conf_m = snap_diameter(med, system=system, deformed=deformed, sigma_mm=sigma_m)
    if strict or abs(med - dw) > prm.veto_k * math.hypot(sigma_m, sigma_c):
        out["diameter_reason"] = f"mask width {med:.1f} mm and point-cloud width {dw:.1f} mm disagree"
        if not veto_only:  # (veto mode has snapped both above)
            nom_m, nom_c = (snap_diameter(x, system=system, deformed=deformed)[0] for x in (med, dw))
        out["_pair"] = (nom_m, nom_c)  # the rib pitch may tell them apart (_pitch_settle)
        if not veto_only:
            return out, None, None, None
        _alert_other_size(out, med, nom_m, conf_m, dw, nom_c, prm, covered)
        # the shape of the cloud (a circle fit) does not depend on the assumed radius: where
        # it confirms the size the mask alone gives clearly, that size is measured. Not a
        # width from one edge to the axis: the axis was placed with the assumed radius (a
        # fit over part of the bar's arc slides with it), so that width cannot overturn it
        if conf_m >= prm.min_confidence and _two_sided(info):
            settled = _settle(
                out, med, sigma_m, info, in_shadow, prm, system=system, deformed=deformed, size=nom_m, against=nom_c
            )
            if settled is not None:
                return settled, None, None, None
        # else the widths that depend on neither the mask nor the axis may tell the
        # mask's size from the assumed one
        return (
            (
                _arbitrate(
                    out,
                    med,
                    conf_m,
                    (nom_m, nom_c),
                    info,
                    in_shadow,
                    prm,
                    system=system,
                    deformed=deformed,
                    covered=covered,
                )
                or out
            ),
            None,
            None,
            None,
        )
    if veto_only:  # the cloud only checks the mask: it may echo an assumed radius
        return None, med, sigma_m, "mask"
    wm, wc = 1 / sigma_m**2, 1 / sigma_c**2
    width, sigma = (wm * med + wc * dw) / (wm + wc), 1 / math.sqrt(wm + wc)
    # two estimates further apart than their σ say: the σ are too small (Birge ratio)
    sigma *= max(1.0, abs(med - dw) / math.hypot(sigma_m, sigma_c))
    return None, width, sigma, "mask+cloud"
