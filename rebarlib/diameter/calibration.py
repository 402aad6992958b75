"""What a capture's own bars teach about its widths: bars of one design size have one true
width, so the spread between them is each width's error per bar, and the bars the mask sizes
clearly calibrate the widths that do not come from the mask.
"""

from __future__ import annotations

import math
from collections import defaultdict

import numpy as np

from .barsizes import observed_width_mm, size_half_gaps_mm, snap_diameter


def _between_bar_deviations(values: dict, prepared) -> list:
    """Deviations of per-bar values ``{bar index: value}`` from the median of their design size
    (sizes with at least 3 bars; bars without a design size are left out). Bars of one size have
    one true width, so these are the values' errors per bar."""
    dev = []
    for size in {prepared[i].design_mm for i in values if math.isfinite(prepared[i].design_mm)}:
        v = np.array([values[i] for i in values if prepared[i].design_mm == size])
        if len(v) >= 3:
            dev.extend(v - np.median(v))
    return dev


def _robust_sigma(dev) -> float:
    return 1.4826 * float(np.median(np.abs(dev)))


def _two_sided(info) -> bool:
    # whether a bar's width was measured between its two edges only (its info): a width from one
    # edge and the axis carries the axis's error too, so the capture's calibrations do not learn
    # from it, and it cannot overturn the radius the axis was placed with
    return info.one_sided_share == 0.0


def _mask_width(result) -> float:
    """A bar's width from its mask: ``mask_width_mm`` where :func:`measure_diameters` set it (the
    envelope from the rib crests where the capture resolves ribs), else its sections' median."""
    w = result.mask_width_mm
    return float(w) if w is not None else float(np.median(result.widths))


def _mask_lean(results, prepared, prm, *, system, deformed) -> float:
    """How far the capture's mask reads its bars wide (px, > 0), or 0 where the capture cannot
    tell it or its mask reads them narrow.

    A photograph's softened, compressed edges make a network's mask lean outwards by a share of a
    pixel, alike on every bar of the capture (docs/verdicts.md, "Slabs rendered a way not tried
    before"). A mask that reads the bars narrow is not taken for such a lean: ribs in relief show
    their core between the transverse ribs more or less by each bar's roll, so that narrow reading
    is a bar's own, not the capture's (decision 058: a Φ14 that showed its full envelope was read
    a size up once a capture's narrow median was taken off it). Two readings must agree:

    - the capture's bars with a design size, seen from both edges: the median of their mask
      width less the design's envelope, in pixels at each bar. A lean if it lies farther from 0
      than twice its standard error (1.2533 x the robust spread / sqrt(n)). Alone it cannot tell
      a lean from a set of bars of another size than designed;
    - the bars among them whose height above the bars they rest on (their stack height, which
      does not depend on the colour) gives their design size (``snap_diameter``): those are of
      that size, so their median is the lean itself, from fewer bars. It must lie within twice
      the two medians' combined standard error of the first.

    Each needs ``prm.colour_offset_bars`` bars; the lean is the first median.
    """
    every, confirmed = [], []
    for r, b in zip(results, prepared):
        if len(r.widths) < prm.min_sections or not _two_sided(r) or not math.isfinite(r.px_mm):
            continue
        if not math.isfinite(b.design_mm):
            continue
        lean = (_mask_width(r) - observed_width_mm(b.design_mm, system=system, deformed=deformed)) / r.px_mm
        every.append(lean)
        if math.isfinite(b.stack_mm) and snap_diameter(b.stack_mm, system=system, deformed=deformed)[0] == b.design_mm:
            confirmed.append(lean)
    if len(confirmed) < prm.colour_offset_bars:
        return 0.0

    def median_and_se(v):
        med = float(np.median(v))
        return med, 1.2533 * _robust_sigma(np.asarray(v) - med) / math.sqrt(len(v))

    lean, se = median_and_se(every)
    lean_c, se_c = median_and_se(confirmed)
    if lean <= 2.0 * se or abs(lean_c - lean) > 2.0 * math.hypot(se, se_c):
        return 0.0
    return lean


def _mask_between_spread(results, prepared, prm) -> None:
    """Store in every bar's info ``mask_between_mm``: the robust spread (1.4826 MAD) of the mask
    widths between the capture's bars of the same design size, around each size's median.

    Bars of one size have one true width, so this is the mask's error per bar as this capture
    shows it: pixel rounding on bars along pixel rows, and a learnt mask's bias per bar that its
    own spread along the bar does not show (a mask that eats both sides of a bar evenly). Needs
    ``prm.colour_offset_bars`` bars with a design size (at least 3 of a size); else 0.
    """
    dev = _between_bar_deviations(
        {i: _mask_width(r) for i, r in enumerate(results) if len(r.widths) >= prm.min_sections and _two_sided(r)},
        prepared,
    )
    s_m = _robust_sigma(dev) if len(dev) >= prm.colour_offset_bars else 0.0
    for r in results:
        r.mask_between_mm = s_m


def _width_calibration(results, key, prm, *, system, deformed, groups=None, designs=None) -> None:
    """Calibrate an independent width of every bar of a capture (``key`` "circle": the point
    cloud's circle, :func:`_cloud_circle`; "stack": the bar's height above the bars it rests on,
    ``geometry.stack_heights``; "level": its top above the formwork, ``geometry.top_heights``, per
    level) against the bars its masks size clearly, and store in every bar's
    info ``{key}_offset_mm`` (subtracted from ``{key}_width_mm``), ``{key}_between_mm`` and the
    ``{key}_sigma_mm`` the width is used with.

    A bar whose mask width lies within a quarter of a size step of a size's envelope (robustly
    one size) has that envelope as its true width; its ``key`` width minus that envelope is the
    width's error on that bar. The median of those errors is a bias the whole capture shares and
    is removed (circle: depth quantised in disparity flattens or bulges every bar's arc alike,
    +1.4 mm, median, on 848 × 480 captures at 400-600 mm; stack: the bars of one level sitting a
    little apart or pressed into each other); their root-mean-square around it (not a robust
    spread: the errors have heavy tails, which a robust spread would hide) is the width's error
    per bar, what a circle's own residuals do not show (quantisation repeating in every section of
    a bar at one depth, noise correlated over more pixels than assumed) and what a stack height
    has no other measure of (how well each bar touches those under it). The σ used is the larger
    of the bar's own (``{key}_sigma_mm``, 0 for a stack height) and that spread. Learning from
    the mask's sizes, not the design's, keeps a bar of another size than designed from counting
    its true difference as an error. Needs ``prm.colour_offset_bars`` such bars; else the width is
    not used (``{key}_between_mm`` NaN).

    ``groups`` (one key per bar, e.g. its layer and level): the offset is learnt per group, from
    at least 2 of its bars (a group with fewer is not used), and the spread is pooled over the
    groups around their own offsets (k = n − groups degrees of freedom, at least
    ``prm.colour_offset_bars`` − 1); each bar's σ then also holds its group's offset's error,
    spread / √(bars it was learnt from). Without ``groups``, all bars are one group, learnt from
    at least ``prm.colour_offset_bars`` bars, whose offset's error the spread's bound covers.

    A bar's offset is learnt from the other bars (leave one out; a level still needs 2 clear
    bars, so a clear bar's offset may come from one other, its σ then the spread times √2): a
    width calibrated on the bar it is then to confirm carries that bar's mask in its own offset
    and adds no evidence (two Φ14 bars whose masks read Φ16 made their level's only clear bars,
    and their tops, calibrated on themselves, "confirmed" Φ16 at confidence 1.00). ``designs``
    (one design size per bar, NaN where none): where every bar an offset would be learnt from
    has a mask that reads another size than its design, the offset rests on nothing but masks
    the design contradicts, and the width is not used for that bar (a level whose clear bars
    all read off the design cannot confirm them, nor settle another bar of it)."""
    per_group = groups is not None
    groups = list(groups) if per_group else [0] * len(results)
    designs = [math.nan] * len(results) if designs is None else list(designs)
    # per group: (bar index, width − envelope, whether its mask reads another size than its design)
    cal = defaultdict(list)
    for i, (r, g) in enumerate(zip(results, groups)):
        cw = getattr(r, f"{key}_width_mm")
        if len(r.widths) < prm.min_sections or not math.isfinite(cw) or not _two_sided(r):
            continue
        med = _mask_width(r)
        nominal, _ = snap_diameter(med, system=system, deformed=deformed)
        if not math.isfinite(nominal):
            continue
        env = observed_width_mm(nominal, system=system, deformed=deformed)
        lo, hi = size_half_gaps_mm(nominal, system=system, deformed=deformed)
        if abs(med - env) <= 0.5 * (lo if med < env else hi):  # a quarter of the step to the next size
            off_design = math.isfinite(designs[i]) and abs(nominal - designs[i]) > 1e-6
            cal[g].append((i, cw - env, off_design))
    if per_group:
        cal = {g: c for g, c in cal.items() if len(c) >= 2}
    dev = {g: np.array([d for _, d, _ in c]) for g, c in cal.items()}
    off = {g: float(np.median(d)) for g, d in dev.items()}
    res = np.concatenate([d - off[g] for g, d in dev.items()]) if dev else np.zeros(0)
    k = len(res) - len(dev)  # degrees of freedom: one offset learnt per group
    s_c = math.nan
    if k >= prm.colour_offset_bars - 1:
        # learnt from a dozen bars or so, the spread may fall short of the errors' tails: the
        # upper 90 % confidence bound of σ from k degrees of freedom (χ² quantile by the
        # Wilson-Hilferty approximation)
        chi2_10 = k * (1 - 2 / (9 * k) - 1.2816 * math.sqrt(2 / (9 * k))) ** 3
        s_c = float(np.sqrt(np.sum(np.square(res)) / chi2_10))
    for i, (r, g) in enumerate(zip(results, groups)):
        # the bars this one's offset is learnt from: its group's, itself left out
        others = [(d, o) for j, d, o in cal.get(g, ()) if j != i]
        learnt = (
            math.isfinite(s_c)
            and len(others) > 0
            and not all(o for _, o in others)  # not only masks the design contradicts
        )
        offset = float(np.median([d for d, _ in others])) if learnt else 0.0
        setattr(r, f"{key}_offset_mm", offset)
        setattr(r, f"{key}_width_mm", getattr(r, f"{key}_width_mm") - offset)
        setattr(r, f"{key}_between_mm", s_c if learnt else math.nan)
        s_g = s_c * math.sqrt(1 + 1 / len(others)) if per_group and learnt else s_c
        setattr(r, f"{key}_sigma_mm", float(np.fmax(getattr(r, f"{key}_sigma_mm"), s_g)))


def _colour_calibration(results, prepared, prm) -> None:
    """Learn from the capture's own bars how far to trust its colour edges against its mask.

    Stores in every bar's info ``colour_offset_px``, the capture's typical colour-minus-mask
    width (px: the colour edges of a round bar sit inside its silhouette by an amount set by the
    light), and ``colour_weight`` in 0..1, the share of a colour-mask disagreement that is blamed
    on the mask. Bars of the same design size have the same true width, so the spread of their
    widths between bars (robust, around each size's median) is each estimator's error per bar:
    s_mask for the mask widths, s_colour for the offset-corrected colour widths. A disagreement
    r = colour − mask then says the mask is off by about r · s_mask² / (s_mask² + s_colour²)
    (the part of r that the mask's error explains); the part of r beyond ``prm.veto_k`` times
    their combined spread hypot(s_mask, s_colour) is more than either explains and counts in
    full (``colour_spread_mm``), so a mask gone wrong on one bar is still caught. Both need
    ``prm.colour_offset_bars`` bars with both widths; otherwise offset 0 and weight 1 (the
    whole disagreement counts).
    """
    have = [
        i
        for i, r in enumerate(results)
        if len(r.widths) >= prm.min_sections and math.isfinite(r.colour_width_mm) and _two_sided(r)
    ]
    off, weight, spread = 0.0, 1.0, 0.0
    if len(have) >= prm.colour_offset_bars:
        med = {i: float(np.median(results[i].widths)) for i in have}
        off = float(np.median([(results[i].colour_width_mm - med[i]) / results[i].px_mm for i in have]))
        # without a design size the bars' true widths are unknown: no between-bar spread
        dm = _between_bar_deviations(med, prepared)
        dc = _between_bar_deviations({i: results[i].colour_width_mm - off * results[i].px_mm for i in have}, prepared)
        if len(dm) >= prm.colour_offset_bars:
            s_m, s_c = _robust_sigma(dm), _robust_sigma(dc)
            if s_m + s_c > 0:
                weight, spread = s_m**2 / (s_m**2 + s_c**2), math.hypot(s_m, s_c)
    for r in results:
        r.colour_offset_px, r.colour_weight, r.colour_spread_mm = off, weight, spread
