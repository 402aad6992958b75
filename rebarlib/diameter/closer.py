"""Advice for a bar the capture leaves between two sizes: how near a capture aimed at it must be.

A bar's width is read in pixels and made metric by its distance: one pixel covers
``z / f`` mm at depth ``z``. A bar left *ambiguous* (its width between two sizes' rib envelopes,
the nearer size's posterior under ``min_confidence``) is read here with an error that this
capture shows: the width's standard uncertainty ``σ`` and the reading's offset ``e`` from the
nearer size's envelope. Kept in pixels, that error shrinks in millimetres with the distance: from
``r z`` it would be ``σ r`` and ``e r``. The advised distance is the farthest ``r z`` at which a
width off the nearer size's envelope by ``e r``, with the uncertainty ``σ r``, gets the nearer
size at ``min_confidence`` (:func:`needed_ratio`, the posterior of
:func:`~rebarlib.diameter.barsizes.snap_diameter`, the table's own envelope uncertainty
included). Nothing in it is fitted to a benchmark; it is the same decision the diameter stage
takes, at the scale a nearer camera gives.

The distance is capped where a nearer capture stops being a capture of the slab
(:class:`CloserParams`): the camera's near range, and the view's coverage (the image's short
side must span ``coverage_spacings`` of the design's largest spacing at the bar, so that the bar
and its neighbours on either side are in view and the lattice is found by its structure). Where
the distance needed lies nearer than either cap, no capture is advised.

A bar with too few clean cross-sections, most of them lost at the image's border, is advised a
capture aimed at it from no farther than this one (in the middle of the view its sections are
in the image). No capture is advised from farther than the capture guide's greatest height
(``CloserParams.far_mm``): a bar 1 m away at the far border of a tilted view would otherwise be
aimed at from 1 m, where most bars are left between two sizes. Other losses (crossings,
shadows, a strip without depth) do not shrink with the distance and are given no advice, nor is
a bar whose ambiguity is a systematic reading (mask and cloud disagreeing, a possible wrong size,
ribs whose crests and core disagree): a nearer capture reads the same disagreement, and no
measurement here says otherwise.

The side to aim towards is named as the hidden-position advice names it (``_counts._towards``):
the image edge the bar's seen middle lies towards, from the image's centre. The advice ends by
telling how to mark the capture taken (``MARK``): its folder's ``aim.json`` naming this capture
and bar, with which the slab's captures are placed where it was aimed (docs/formats.md,
docs/decisions/043).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .barsizes import bar_system, bracketing_sizes, snap_diameter

__all__ = ["CloserParams", "needed_ratio", "closer_advice"]


@dataclass(frozen=True)
class CloserParams:
    """Where a capture from closer is advised (mm unless stated).

    near_mm : the camera's near range: the nearest its depth is valid. 150 mm is the reference
        camera's (Orbbec Gemini 2, docs/sensors.md); set it for another camera
    coverage_spacings : the image's short side at the bar must span this many of the design's
        largest spacing (the bar and a neighbour on either side of it, in both directions)
    centre_share : a bar's seen middle within this share of the image's half-size from its
        centre needs no aiming
    far_mm : no capture is advised from farther than this: the greatest height above the upper
        bars that docs/capturing.md advises (450-650 mm; from 800-1000 mm many bars are left
        between two sizes). A bar seen 1 m away at the far border of a tilted view is told to be
        aimed at from no farther than this, not from its own distance (docs/decisions/041)
    """

    near_mm: float = 150.0
    coverage_spacings: float = 2.0
    centre_share: float = 0.25
    far_mm: float = 650.0


def needed_ratio(width_mm, sigma_mm, *, min_confidence, system, deformed=True, tol=1e-3) -> float:
    """The largest ``r`` in (0, 1] at which the error of a width read with ``sigma_mm`` is small
    enough, scaled by ``r`` (the same error in pixels, from ``r`` times the distance), for the
    size its width is nearer to: a width off that size's envelope by ``r (width - envelope)``, with
    the uncertainty ``r sigma_mm``, gets the size at ``min_confidence`` or more. NaN for a width
    outside the size table or a σ that is not finite; 1.0 where the width already gets it."""
    pair = bracketing_sizes(width_mm, system=system, deformed=deformed)
    if pair is None or not (math.isfinite(sigma_mm) and sigma_mm >= 0):
        return math.nan
    (_, wa), (_, wb) = pair
    env = wa if abs(width_mm - wa) <= abs(width_mm - wb) else wb
    e = width_mm - env

    def clear(r: float) -> bool:
        return snap_diameter(env + e * r, system=system, deformed=deformed, sigma_mm=sigma_mm * r)[1] >= min_confidence

    if clear(1.0):
        return 1.0
    lo, hi = 0.0, 1.0  # clear at lo (a width on the envelope, no error), not at hi
    if not clear(1e-6):  # (the table's own envelope uncertainty alone leaves it unclear)
        return math.nan
    while hi - lo > tol:
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if clear(mid) else (lo, mid)
    return lo


def _aim(mid_cam: np.ndarray, intr, prm: CloserParams) -> str:
    """Which image edge to aim towards for the bar's seen middle to come to the view's middle."""
    u = intr.fx * mid_cam[0] / mid_cam[2] + intr.cx
    v = intr.fy * mid_cam[1] / mid_cam[2] + intr.cy
    du, dv = (u - intr.cx) / (intr.width / 2), (v - intr.cy) / (intr.height / 2)
    if max(abs(du), abs(dv)) < prm.centre_share:
        return "aimed at its middle (near the image's middle already)"
    edge = ("right" if du > 0 else "left") if abs(du) >= abs(dv) else ("bottom" if dv > 0 else "top")
    return f"aimed at its middle (towards the image's {edge} edge)"


#: how to mark a capture taken as advised, appended to the advice
MARK = " (mark it with an aim.json naming this capture and bar, docs/formats.md)"


def _floor(z: float) -> float:
    return 10.0 * math.floor(z / 10.0)


def closer_advice(row: dict, p0, p1, intr, *, min_confidence, system, deformed=True, design=None, prm=None) -> str:
    """The advice to append to a not-measured bar's reason ("" where a capture from closer is not
    expected to settle it). ``p0``, ``p1``: the bar's seen axis ends (camera frame, mm)."""
    prm = prm or CloserParams()
    reason = str(row.get("diameter_reason") or "")
    mid = 0.5 * (np.asarray(p0, float) + np.asarray(p1, float))
    if intr is None or not np.all(np.isfinite(mid)) or mid[2] <= 0:
        return ""
    z = float(mid[2])
    fov = min(intr.width / intr.fx, intr.height / intr.fy)  # the view's short side per mm of depth
    caps = [prm.near_mm]
    if design is not None:
        spacings = [design.lattice(ly).level(lv).spacing_mm for ly in ("lower", "upper") for lv in ("bottom", "top")]
        caps.append(prm.coverage_spacings * max(spacings) / fov)
    cap = max(caps)
    aim = _aim(mid, intr, prm)
    if reason.startswith("too few clean cross-sections") and reason.endswith("most lost at the image border)"):
        return (
            f"; a capture {aim}, from about {_floor(min(z, prm.far_mm)):.0f} mm or less (this one: {z:.0f} mm), "
            "would show it away from the border" + MARK
        )
    if not reason.startswith("ambiguous: width"):
        return ""
    w, s = float(row.get("width_used_mm", math.nan)), float(row.get("width_sigma_mm", math.nan))
    r = needed_ratio(w, s, min_confidence=min_confidence, system=system, deformed=deformed)
    if not math.isfinite(r):
        return ""
    need = min(r * z, prm.far_mm)
    if need < cap:
        return (
            f"; no capture from closer is advised: it would need the camera within about {need:.0f} mm of the bar, "
            f"nearer than {cap:.0f} mm (the camera's near range, or the bar's neighbours out of view)"
        )
    (a, wa), (b, wb) = bracketing_sizes(w, system=system, deformed=deformed)
    sysm = bar_system(system)
    return (
        f"; a capture with the camera about {_floor(need):.0f} mm or less from the bar (this one: {z:.0f} mm), {aim}, "
        f"would tell {sysm.label(a)} from {sysm.label(b)} (envelopes {wb - wa:.1f} mm apart) at this capture's "
        "error in pixels" + MARK
    )
