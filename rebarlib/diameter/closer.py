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

A capture whose bars are left unsized by their widths (:data:`WIDTH_REASONS`) where its pixels
put two neighbouring sizes' envelopes less than ``CloserParams.min_gap_px`` apart gets one note
for them all (:func:`pixels_for_sizes`): how near a capture must be for that gap, or, where that is
nearer than the camera can stand, how many more pixels it needs. This is the capture-wide form of
the advice above, read from the camera's focal length and the size table alone; the gap that
sizes bars reliably is measured on the verdict benchmark (docs/capturing.md).

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

from .._status import NOT_MEASURED
from .barsizes import bar_system, bracketing_sizes, snap_diameter

__all__ = ["CloserParams", "needed_ratio", "closer_advice", "envelope_gap_mm", "pixels_for_sizes", "WIDTH_REASONS"]


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
    min_gap_px : the gap in pixels, focal length x envelope gap / distance, between a bar's size
        and its neighbouring sizes' rib envelopes below which a bar left unsized by its width is
        put down to the camera's pixels (:func:`pixels_for_sizes`). Measured on the verdict
        benchmark's captures (reference and D435-like cameras, default and noisy depth): from
        2.5 px 96-100 % of the bars were sized, at 2 px 91-96 %, at 1.5 px 54-60 %
        (docs/capturing.md, docs/decisions/063)
    """

    near_mm: float = 150.0
    coverage_spacings: float = 2.0
    centre_share: float = 0.25
    far_mm: float = 650.0
    min_gap_px: float = 2.5


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


def _nearest_cap(intr, design, prm: CloserParams) -> float:
    """The nearest a capture of the slab can stand: the camera's near range, or where the view's
    short side still spans ``coverage_spacings`` of the design's largest spacing."""
    caps = [prm.near_mm]
    if design is not None:
        fov = min(intr.width / intr.fx, intr.height / intr.fy)  # the view's short side per mm of depth
        spacings = [design.lattice(ly).level(lv).spacing_mm for ly in ("lower", "upper") for lv in ("bottom", "top")]
        caps.append(prm.coverage_spacings * max(spacings) / fov)
    return max(caps)


#: how a bar's reason begins where its width alone left it unsized: between two sizes, the mask's
#: and the cloud's widths disagreeing, the mask's widths scattered (decision.py) — what more
#: pixels across the bar settle; other reasons (hidden, outside the image, too few sections,
#: shadows, a possible wrong size) are not put down to the pixels
WIDTH_REASONS = ("ambiguous: width", "mask width ", "mask widths too scattered")


def envelope_gap_mm(nominal_mm: float, *, system: str, deformed: bool = True) -> float:
    """The smaller of the gaps between a size's rib envelope (its nominal size where not
    ``deformed``) and its neighbours' in the size table: what the image must resolve to tell the
    size from the next one. NaN for a size not in the table.

    >>> round(envelope_gap_mm(12, system="GB1499.2"), 1)  # Φ10 11.6, Φ12 13.9, Φ14 16.2 mm
    2.3
    """
    sysm = bar_system(system)
    sizes = np.asarray(sysm.sizes_mm, float)
    obs = np.asarray(sysm.envelope_mm if deformed else sysm.sizes_mm, float)
    if not math.isfinite(float(nominal_mm)) or len(sizes) < 2:
        return math.nan
    k = int(np.argmin(np.abs(sizes - float(nominal_mm))))
    if abs(sizes[k] - float(nominal_mm)) > 0.25:
        return math.nan
    gaps = [obs[k] - obs[k - 1]] if k > 0 else []
    gaps += [obs[k + 1] - obs[k]] if k + 1 < len(obs) else []
    return float(min(gaps))


def pixels_for_sizes(bars, intr, *, system: str, deformed: bool = True, design=None, prm=None) -> dict | None:
    """The capture-wide advice for its bars left unsized by their widths where its pixels are too
    few: None where no such bar lies where its design size's envelope and its neighbour's are
    less than ``prm.min_gap_px`` apart in the image (``focal · gap / distance``, the focal length
    the geometric mean of ``fx`` and ``fy``, the distance the bar's seen middle's depth).

    ``bars``: the capture's bar table with the diameter columns (``design_diameter_mm``,
    ``diameter_status``, ``diameter_reason``) and the seen ends (``start_z_mm``, ``end_z_mm``).

    Returns a dict: ``bar_ids`` (those bars), ``distance_mm`` and ``gap_px`` (their [least,
    greatest]), ``envelope_gap_mm`` (the least), ``focal_px``, ``min_gap_px``, ``needed_mm`` (the
    distance, rounded down to 5 mm, from which every one of them gets ``min_gap_px``),
    ``nearest_mm`` (the nearest a capture of the slab can stand: the camera's near range or its
    view keeping two of the largest spacing), ``reachable`` (the distance needed is no nearer),
    ``focal_needed_px`` (the focal length that gives ``min_gap_px`` from ``nearest_mm``),
    ``unsized_with_enough_px`` (the capture's bars left unsized by their widths although their
    sizes lie ``min_gap_px`` or more apart: where there are any, the note says the pixels are
    not the whole cause), ``groups`` (the bars' ids in groups one capture from ``needed_mm``
    each covers, :func:`_groups`) and ``note`` (the sentence for the result's notes).
    """
    prm = prm or CloserParams()
    need_cols = {"bar_id", "design_diameter_mm", "diameter_status", "diameter_reason", "start_z_mm", "end_z_mm"}
    if intr is None or bars is None or len(bars) == 0 or not need_cols <= set(bars.columns):
        return None
    focal = math.sqrt(intr.fx * intr.fy)
    rows, enough = [], 0
    for b in bars.itertuples(index=False):
        reason = str(b.diameter_reason or "")
        if b.diameter_status != NOT_MEASURED or not reason.startswith(WIDTH_REASONS):
            continue
        try:
            z = 0.5 * (float(b.start_z_mm) + float(b.end_z_mm))
            gap = envelope_gap_mm(float(b.design_diameter_mm), system=system, deformed=deformed)
        except (TypeError, ValueError):  # a bar without its design size or its ends
            continue
        if not (math.isfinite(z) and z > 0 and math.isfinite(gap)):
            continue
        if focal * gap / z < prm.min_gap_px:
            mid = [
                0.5 * (float(getattr(b, f"start_{a}_mm", 0.0)) + float(getattr(b, f"end_{a}_mm", 0.0))) for a in "xy"
            ]
            rows.append((int(b.bar_id), z, gap, focal * gap / z, mid))
        else:
            enough += 1
    if not rows:
        return None
    ids, zs, gaps, pxs, mids = (list(c) for c in zip(*rows))
    need = min(focal * g / prm.min_gap_px for g in gaps)
    nearest = _nearest_cap(intr, design, prm)
    reachable = need >= nearest
    # rounded down to 5 mm, but not below the nearest a capture can stand where it can stand there
    needed = max(5.0 * math.floor(need / 5.0), math.ceil(nearest)) if reachable else 5.0 * math.floor(need / 5.0)
    focal_needed = prm.min_gap_px * nearest / min(gaps)
    groups = _groups(ids, mids, needed, intr, design)
    n = len(ids)
    where = f"{zs[0]:.0f} mm" if n == 1 else f"{min(zs):.0f}–{max(zs):.0f} mm"
    px = f"{pxs[0]:.1f} px" if n == 1 else f"{min(pxs):.1f}–{max(pxs):.1f} px"
    head = (
        f"bar sizes: {n} bar(s) left unsized by their widths (between two sizes, or the widths disagreeing) "
        f"{'lies' if n == 1 else 'lie'} {where} from the camera, where its focal length ({focal:.0f} px) puts a "
        f"size's rib envelope and its neighbour's ({min(gaps):.1f} mm apart) {px} apart; bars were sized reliably "
        f"from {prm.min_gap_px:g} px apart (docs/capturing.md)"
    )
    if enough:  # the capture's own bars say the pixels are not the whole cause
        head += (
            f" — though {enough} other bar(s) of this capture, with {prm.min_gap_px:g} px or more, were left unsized "
            "by their widths too: not the pixels alone"
        )
    head += ": "
    if reachable:
        tail = f"a capture from about {needed:.0f} mm or nearer to {'it' if n == 1 else 'them'} gives that"
        if len(groups) > 1:
            tail += (
                f" ({len(groups)} such captures cover them: bars "
                + "; ".join(", ".join(str(i) for i in g) for g in groups)
                + ")"
            )
    else:
        tail = (
            f"that needs the camera within about {needed:.0f} mm, nearer than a capture of this slab can stand "
            f"({nearest:.0f} mm: the camera's near range, or two spacings in view); a camera or mode with more pixels "
            f"across the bars (a focal length of about {focal_needed:.0f} px or more) gives it from there"
        )
    return {
        "bar_ids": ids,
        "distance_mm": [round(min(zs), 1), round(max(zs), 1)],
        "gap_px": [round(min(pxs), 2), round(max(pxs), 2)],
        "envelope_gap_mm": round(min(gaps), 2),
        "focal_px": round(focal, 1),
        "min_gap_px": prm.min_gap_px,
        "needed_mm": needed,
        "nearest_mm": round(nearest, 1),
        "reachable": reachable,
        "focal_needed_px": round(focal_needed, 0),
        "unsized_with_enough_px": enough,
        "groups": groups,
        "note": head + tail,
    }


def _groups(ids: list, mids: list, dist: float, intr, design) -> list:
    """The bars' ids in groups that one capture from ``dist`` each covers: the bars' seen middles
    (camera x, y) binned on a grid of the view's extent at that distance, less the design's
    largest spacing (half of it on either side, so that a bar at a cell's edge keeps its
    neighbours in view; at least half the view), from the least x and y. One group where the
    middles are not known."""
    w, h = dist * intr.width / intr.fx, dist * intr.height / intr.fy
    margin = 0.0
    if design is not None:
        margin = max(design.lattice(ly).level(lv).spacing_mm for ly in ("lower", "upper") for lv in ("bottom", "top"))
    cw, ch = max(w - margin, 0.5 * w), max(h - margin, 0.5 * h)
    xy = np.asarray(mids, float).reshape(-1, 2)
    if not np.all(np.isfinite(xy)):
        return [list(ids)]
    cells = np.floor((xy - xy.min(axis=0)) / np.array([cw, ch])).astype(int)
    out: dict = {}
    for i, c in zip(ids, map(tuple, cells)):
        out.setdefault(c, []).append(int(i))
    return [out[c] for c in sorted(out)]


def closer_advice(row: dict, p0, p1, intr, *, min_confidence, system, deformed=True, design=None, prm=None) -> str:
    """The advice to append to a not-measured bar's reason ("" where a capture from closer is not
    expected to settle it). ``p0``, ``p1``: the bar's seen axis ends (camera frame, mm)."""
    prm = prm or CloserParams()
    reason = str(row.get("diameter_reason") or "")
    mid = 0.5 * (np.asarray(p0, float) + np.asarray(p1, float))
    if intr is None or not np.all(np.isfinite(mid)) or mid[2] <= 0:
        return ""
    z = float(mid[2])
    cap = _nearest_cap(intr, design, prm)
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
