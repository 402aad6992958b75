"""Bar counts from evidence: a bar is missing only where an empty position is seen.

Each row of bars (one lattice, one direction) is continued at its design spacing. Every
position where no bar was found is *examined*, never assumed:

1. **Inside the mesh?** Between two found bars it is. Beyond the outermost found bar it is only
   where the crossing bars (the other direction of the same lattice) run across it, to within a
   quarter spacing: where they end, the mesh ends (:func:`mesh_boundary`), and a position
   beyond is "outside the mesh", not missing.
2. **In view?** Its *core*, the nominal line ± (¼ spacing + the bar's radius), must project into
   the image over at least ``min_evidence_mm`` of the row's length; else it is "not in view" and
   is not counted at all (a bar within tolerance of its place lies inside the core).
3. **What the depth shows.** The *corridor* (± ½ spacing across, the neighbours' own pixels
   left out) is sampled at the height of the would-be bar's top, slice by slice along the row
   (every ``step_mm``). Each sample's pixel shows something at the bar's height, the support
   below it (formwork, or the level underneath), something above it (another bar, which hides
   the spot), or no depth. A slice is *occupied* when a stretch at least a radius wide anywhere
   in the corridor is at the bar's height, *empty* when it is not and the core shows no unseen
   stretch as wide as the bar (a bar within a quarter spacing of its place would show), and
   *unknown* otherwise (the cause is kept).
4. **What the colour shows.** The rebar mask (the colour model's) is sampled over the same
   slices, at the would-be bar's axis height, outside every found bar's pixels: a slice shows a
   bar when a stretch at least a radius wide is rebar.

Verdicts: **missing** when at least ``min_evidence_mm`` of slices are empty, at most
``max_share`` of the seen slices are occupied, and the mask shows a bar on at most
``max_share`` of the empty slices. **present, no depth** when the slices lack depth over at
least ``min_evidence_mm`` and the mask shows a bar on at least ``min_share`` of them with a
steady centre line: the bar is placed on that centre line at its level's height and counts as
found. **present** when the slices are occupied (points at the bar's height along it) and the
mask agrees. Anything else is **not measured**, with the reason: no depth there, hidden under
another bar, something at the bar's height that the mask does not call a bar, or a mask that
contradicts the depth.

Extra bars need the same kind of evidence: two found bars on one lattice position (the row's
phase, :func:`_lattice_index`) make one extra only where both are measured bars that run side
by side over most of their length (not a lap or a loose piece) and the mask runs along both.

All lengths are in mm; the decisions are in ``docs/verdicts.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np
import pandas as pd

from ._camera import Intrinsics, project
from ._status import EXTRA, MEASURED, MISSING, NOT_EXTRA, NOT_IN_VIEW, NOT_MEASURED, OUTSIDE, PRESENT, PRESENT_NO_DEPTH
from ._evidence import (  # noqa: F401 (names tests and callers reach through this module)
    _add_mask,
    _examine,
    _footprints,
    _heights,
    _offset,
    _place_from_mask,
    _Row,
    _runs,
    _samples,
    mesh_boundary,
)
from ._count_tables import count_table, settle_spacings
from .geometry import LAYERS, LEVELS, BarAxis, Plane, _in_image, from_slab_frame, to_slab_frame

__all__ = ["CountParams", "examine_positions", "mesh_boundary", "count_table", "settle_spacings", "POSITION_COLUMNS"]


POSITION_COLUMNS = [
    "layer",
    "level",
    "kind",
    "offset_mm",
    "status",
    "reason",
    "in_view_mm",
    "empty_mm",
    "occupied_mm",
    "no_depth_mm",
    "hidden_mm",
    "mask_mm",
    "position_sigma_mm",
    "bar_id",
    "start_x_mm",
    "start_y_mm",
    "start_z_mm",
    "end_x_mm",
    "end_y_mm",
    "end_z_mm",
]


@dataclass(frozen=True)
class CountParams:
    """What it takes to call a position missing, present or extra (mm unless stated).

    step_mm : slice spacing along the row
    sample_mm : sample spacing across the corridor
    min_evidence_mm : length of slices a verdict needs (empty, no-depth or occupied ones)
    core_fraction : the core, ± this × spacing (+ radius), must be in the image
    inside_mm : beyond the outermost bar, the crossing bars must reach to within this of the
        position for it to be inside the mesh. Where a bar is missing at a row's end, its
        crossing bars still run on past its place by their overhang; where the mesh ends, they
        stop one spacing less their overhang short of the next position. The position itself is
        the last bar plus a spacing, good to the bars' placing tolerance on site (about 10-15
        mm), which is what this margin allows; a mesh whose crossing bars overhang its last bar
        by more than a spacing less twice this cannot be told from one missing its end bars
    max_share : at most this share of the seen slices occupied (missing), or of the empty
        slices showing a bar in the mask
    min_share : a mask that shows a bar on at least this share of the slices places it
    max_position_sigma_mm : a bar placed from the mask has its spacings measured when its
        position's standard uncertainty is under this; else they are "not measured"
    overlap_fraction : an extra bar runs beside its twin over at least this share of the
        shorter one's length (else it is a lap or a loose piece)
    """

    step_mm: float = 5.0
    sample_mm: float = 2.0
    min_evidence_mm: float = 150.0
    core_fraction: float = 0.25
    inside_mm: float = 15.0
    max_share: float = 0.1
    min_share: float = 0.5
    max_position_sigma_mm: float = 1.5
    overlap_fraction: float = 0.8


# ----------------------------------------------------------------------------------------------
# Rows, positions, extras


def _lattice_index(offsets: np.ndarray, s: float) -> np.ndarray:
    """Integer lattice position of each bar: offsets referred to the row's phase (the circular
    median of offset mod spacing), rounded to spacings."""
    ang = 2 * np.pi * offsets / s
    phase = math.atan2(float(np.median(np.sin(ang))), float(np.median(np.cos(ang)))) * s / (2 * np.pi)
    return np.round((offsets - phase) / s).astype(int), phase


def _mask_along(b: BarAxis, plane: Plane, intr: Intrinsics, foot, own: int, mask) -> float:
    """Share of a bar's axis samples (in the image, not under another found bar) on which the
    rebar mask is set."""
    t = np.arange(b.t0_mm, b.t1_mm + 1e-9, 5.0)
    if len(t) < 2:
        return math.nan
    cam = from_slab_frame(b.axis_points(t), plane)
    uv = np.round(project(cam, intr)).astype(int)
    ok = _in_image(uv, cam, intr)
    u, v = uv[ok, 0], uv[ok, 1]
    free = np.isin(foot[v, u], (0, own))
    if free.sum() < 4:
        return math.nan
    return float(mask[v[free], u[free]].mean())


def examine_positions(
    bars: list,
    *,
    design_spacing: dict,
    plane: Plane,
    depth_mm,
    intrinsics: Intrinsics,
    mask=None,
    noise_mm: float | None = None,
    params: CountParams | None = None,
):
    """Examine every empty design position and every close pair of bars of each row.

    Parameters
    ----------
    bars : list of BarAxis (slab frame), as found
    design_spacing : ``{(layer, level): spacing_mm}``
    plane, depth_mm, intrinsics : the formwork plane and the capture's depth (mm) and camera
    mask : callable returning the (H, W) bool rebar mask (the colour model's), called only when
        a verdict needs it; or None (then no position is called missing or extra)
    noise_mm : the depth noise on the formwork (default 1 mm)

    Returns
    -------
    positions : DataFrame, one row per examined position (:data:`POSITION_COLUMNS`): ``kind``
        "gap" | "end" | "pair", ``status`` missing / present / present (no depth) / extra /
        not measured / not counted / outside the mesh / not in view, with the reason and the
        lengths of evidence (mm)
    new_bars : list of BarAxis placed at positions found present (status "not measured"; their
        ``reason`` says how they were placed); ``positions.bar_id`` refers to ``bars + new_bars``
    boundary : :func:`mesh_boundary`
    """
    prm = params or CountParams()
    noise = float(noise_mm or 1.0)
    depth = np.asarray(depth_mm, float)
    intr = intrinsics
    foot = _footprints(bars, plane, intr)
    cache = {}

    def get_mask():
        if mask is None:
            return None
        if "m" not in cache:
            m = mask()
            cache["m"] = None if m is None else np.asarray(m, bool)
        return cache["m"]

    boundary = mesh_boundary(bars, plane=plane, depth_mm=depth, intrinsics=intr, noise_mm=noise)
    rows_out, new_bars = [], []
    for layer in LAYERS:
        for level in LEVELS:
            s = design_spacing.get((layer, level))
            idx = [i for i, b in enumerate(bars) if b.layer == layer and b.level == level]
            if not idx or not s:
                continue
            n2 = bars[idx[0]].normal2d
            order = sorted(idx, key=lambda i: _offset(bars[i], n2))
            meas = [bars[i] for i in order if bars[i].status == MEASURED]
            if not meas:
                continue
            hs = np.array([b.axis_height_mm for b in meas])
            row = _Row(
                layer,
                level,
                [bars[i] for i in order],
                order,
                np.array([_offset(bars[i], n2) for i in order]),
                float(s),
                float(np.median(hs)),
                float(1.4826 * np.median(np.abs(hs - np.median(hs)))) if len(hs) > 2 else 1.0,
                float(np.median([b.radius_mm for b in meas])),
                bars[idx[0]].direction,
                n2,
            )
            reach = _reach(boundary, layer, level, row.normal)
            higher = [i + 1 for i, b in enumerate(bars) if b.axis_height_mm > row.height + row.radius]
            # the higher bars along this row (offset across, axis height, radius): where one
            # hides a position, they say from where it would show
            over = [
                (_offset(b, n2), b.axis_height_mm, b.radius_mm)
                for b in bars
                if b.axis_height_mm > row.height + row.radius and abs(float(b.direction @ row.direction)) > 0.95
            ]
            for kind, p, nb in _candidates(row, reach, plane, intr, prm):
                rec = _judge(
                    row,
                    kind,
                    p,
                    nb,
                    reach,
                    plane=plane,
                    depth=depth,
                    intr=intr,
                    foot=foot,
                    higher=higher,
                    mask=get_mask if mask is not None else None,
                    noise=noise,
                    prm=prm,
                )
                if rec["status"] == NOT_MEASURED and rec["reason"].startswith("hidden under"):
                    rec["reason"] += _where_it_shows(row, p, over, plane)
                if rec.pop("_bar", None) is not None:
                    nb_bar = rec.pop("_new")
                    new_bars.append(nb_bar)
                    rec["bar_id"] = len(bars) + len(new_bars) - 1
                rec.update(_line_ends(row, float(rec["offset_mm"]), _t_range(nb), plane))
                rows_out.append({"layer": layer, "level": level, **rec})
            rows_out.extend(
                {"layer": layer, "level": level, **rec}
                for rec in _pairs(row, plane, intr, foot, get_mask if mask is not None else None, prm)
            )
    df = pd.DataFrame(rows_out, columns=POSITION_COLUMNS)
    return df, new_bars, boundary


def _where_it_shows(row: _Row, p: float, over: list, plane: Plane) -> str:
    """Advice for a position hidden under a higher bar of its direction: how far to move the
    camera across the row for the bar to show beside that bar ("" where no such bar covers it).

    Seen from the camera's centre, a bar at height ``h`` and offset ``p`` across lies at
    ``c + (p - c) k`` on the higher bar's level (``c`` the camera's offset across, ``k = (zc -
    hu) / (zc - h)``); it clears the higher bar (offset ``q``, radius ``ru``) when that point is
    ``ru + r k`` or more from ``q``. Moving the camera by ``dc`` moves it by ``(1 - k) dc``; tilting
    the camera moves nothing (only its centre matters)."""
    cam = to_slab_frame(np.zeros((1, 3)), plane)[0]
    c, zc = float(cam[:2] @ row.normal), float(cam[2])
    best = None
    for q, hu, ru in over:
        if zc <= hu + 1.0:
            continue
        k = (zc - hu) / (zc - row.height)
        d = (1.0 - k) * c + k * p - q  # the position's place on that bar's level, from the bar
        if best is None or abs(d) < abs(best[0]):
            best = (d, k, ru)
    if best is None:
        return ""
    d, k, ru = best
    need = ru + row.radius * k
    if abs(d) >= need:
        return ""
    # one way it needs (need - |d|) / (1 - k), the other way (need + |d|) / (1 - k): the advice
    # holds either way
    move = 10.0 * math.ceil((need + abs(d)) / max(1.0 - k, 1e-6) / 10.0)
    return (
        f"; a capture taken with the camera about {move:.0f} mm or more to either side across these bars "
        "(moved, not tilted) would show it beside that bar"
    )


def _reach(boundary: dict, layer: str, level: str, n2) -> dict | None:
    """The crossing bars' reach across a row: its own lattice's, or where that lattice's
    crossing bars were not found, the other lattice's bars of the crossing direction (the two
    meshes of a slab are tied over the same area), marked ``proxy``."""
    own = (boundary.get(layer) or {}).get(level)
    if own:
        return own
    other = "upper" if layer == "lower" else "lower"
    for lv in LEVELS:
        cand = (boundary.get(other) or {}).get(lv)
        if not cand:
            continue
        # a group of the other lattice whose own normal is parallel to this row's is crossed
        # by the same direction as this row
        cos = float(np.dot(np.array(cand["normal"]), n2))
        if abs(cos) > 0.9:
            flip = cos < 0
            lo, hi = cand["reach_minus_mm"], cand["reach_plus_mm"]
            el, eh = cand["edge_minus"], cand["edge_plus"]
            if flip:
                lo, hi, el, eh = -hi, -lo, eh, el
            return {
                **cand,
                "reach_minus_mm": lo,
                "reach_plus_mm": hi,
                "edge_minus": el,
                "edge_plus": eh,
                "proxy": f"the {other} lattice's crossing bars",
            }
    return None


def _candidates(row: _Row, reach, plane, intr, prm):
    """(kind, plan offset, the two nearest found bars) of each empty design position: inside
    the gaps of the row, and beyond its outermost bars while the would-be axis is in view."""
    offs, s = row.offsets, row.spacing
    for a, b, oa, ob in zip(row.bars[:-1], row.bars[1:], offs[:-1], offs[1:]):
        k = int(round((ob - oa) / s)) - 1
        for j in range(1, k + 1):
            yield "gap", oa + j * (ob - oa) / (k + 1), (a, b)
    for sign, start, nb in ((-1, offs[0], row.bars[:2]), (1, offs[-1], row.bars[-2:][::-1])):
        for j in range(1, 100):
            p = start + sign * j * s
            if not _line_in_view(row, p, nb[0], plane, intr, prm):
                break
            yield "end", p, tuple(nb)


def _line_in_view(row: _Row, p: float, b: BarAxis, plane, intr, prm) -> bool:
    t = np.arange(b.t0_mm, b.t1_mm + 1e-9, prm.step_mm)
    _, inside = _samples(row, p, t, np.array([0.0]), row.height + row.radius, plane, intr)
    return inside.sum() * prm.step_mm >= prm.min_evidence_mm


def _line_ends(row: _Row, p: float, t_range, plane: Plane) -> dict:
    """Camera-frame ends of the would-be axis at plan offset ``p`` (for drawing it)."""
    t = np.array(t_range, float)
    plan = t[:, None] * row.direction + p * row.normal
    cam = from_slab_frame(np.column_stack((plan, np.full(2, row.height))), plane)
    return {
        f"{end}_{c}_mm": round(float(cam[i, j]), 2)
        for i, end in enumerate(("start", "end"))
        for j, c in enumerate("xyz")
    }


def _t_range(nb) -> tuple:
    return min(b.t0_mm for b in nb), max(b.t1_mm for b in nb)


def _judge(row: _Row, kind: str, p: float, nb, reach, *, plane, depth, intr, foot, higher, mask, noise, prm) -> dict:
    """The verdict on one empty position (a ``positions`` row, with ``_bar``/``_new`` when a bar
    is placed there): outside the mesh, not in view, present (no depth), present, missing or not
    measured, in that order of tests (module docstring)."""
    s = row.spacing
    base = {"kind": kind, "offset_mm": round(p, 1), "bar_id": None, "position_sigma_mm": math.nan}
    if kind == "end":
        side = "plus" if p > row.offsets[-1] else "minus"
        if reach is None:
            return {
                **base,
                "status": NOT_MEASURED,
                "reason": "no crossing bar found: where the mesh ends cannot be "
                "told, so this position beyond the outermost bar is not judged",
            }
        r_edge = reach[f"reach_{side}_mm"]
        beyond = (p - r_edge) if side == "plus" else (r_edge - p)
        if beyond > prm.inside_mm:
            edge = reach[f"edge_{side}"]
            return {
                **base,
                "status": OUTSIDE,
                "reason": (
                    f"the crossing bars end {beyond:.0f} mm before it"
                    + (" (the mesh's edge is in view)" if edge else " (where they leave the view or are hidden)")
                ),
            }
    row_ids = [i + 1 for i in row.index]
    ev = _examine(
        row,
        p,
        _t_range(nb),
        plane=plane,
        depth=depth,
        intr=intr,
        foot=foot,
        row_ids=row_ids,
        higher=higher,
        noise=noise,
        prm=prm,
    )
    E = prm.min_evidence_mm
    seen = ev["empty_mm"] + ev["occupied_mm"]
    # the colour mask is read only where the depth leaves a verdict that needs it
    needs = ev["in_view_mm"] >= E and (ev["occupied_mm"] >= E or ev["empty_mm"] >= E or ev["no_depth_mm"] >= E)
    m = mask() if (mask is not None and needs) else None
    if m is not None:
        ev = _add_mask(ev, row, p, m, plane=plane, intr=intr, foot=foot, prm=prm)
    rec = {
        **base,
        **{
            k: round(ev[k], 1) for k in ("in_view_mm", "empty_mm", "occupied_mm", "no_depth_mm", "hidden_mm", "mask_mm")
        },
    }
    if ev["in_view_mm"] < E:
        return {**rec, "status": NOT_IN_VIEW, "reason": f"only {ev['in_view_mm']:.0f} mm of it in view (needs {E:.0f})"}
    has_mask = "_shows" in ev
    if ev["occupied_mm"] >= E and ev["occupied_mm"] >= 0.5 * seen:
        share = ev["mask_occupied_share"]
        if has_mask and share >= prm.min_share:
            return _present(
                row,
                p,
                ev,
                ev["_state"] == 2,
                plane,
                intr,
                prm,
                rec,
                PRESENT,
                f"points at the bar's height along {ev['occupied_mm']:.0f} mm and the colour mask "
                "along it: a bar the fit did not take",
            )
        return {
            **rec,
            "status": NOT_MEASURED,
            "reason": (
                f"points at the bar's height along {ev['occupied_mm']:.0f} mm, but "
                + ("the colour mask does not show a bar there (another object?)" if has_mask else "no colour mask")
            ),
        }
    if ev["empty_mm"] >= E and ev["occupied_mm"] <= prm.max_share * seen:
        if not has_mask:
            return {
                **rec,
                "status": NOT_MEASURED,
                "reason": (
                    f"the depth shows the support and nothing at the bar's height along {ev['empty_mm']:.0f} mm, "
                    "but no colour mask was available to confirm it"
                ),
            }
        share = ev["mask_empty_share"]
        if share <= prm.max_share:
            return {
                **rec,
                "status": MISSING,
                "reason": (
                    f"empty: the {'formwork' if row.level == 'bottom' and row.layer == 'lower' else 'support'} "
                    f"is seen with depth and nothing at the bar's height along {ev['empty_mm']:.0f} mm of the "
                    f"corridor (± {s / 2:.0f} mm), and the colour mask shows no bar there"
                ),
            }
        return {
            **rec,
            "status": NOT_MEASURED,
            "reason": (
                f"the depth shows the corridor empty along {ev['empty_mm']:.0f} mm, but the colour mask shows a bar "
                f"on {share:.0%} of it"
            ),
        }
    if ev["no_depth_mm"] >= E:
        share = ev["mask_nodepth_share"]
        sel = ev["_nd"] & ev["_shows"] if has_mask else None
        if has_mask and share >= prm.min_share and sel.sum() * prm.step_mm >= E:
            return _present(row, p, ev, sel, plane, intr, prm, rec, PRESENT_NO_DEPTH, "")
    if ev["no_depth_mm"] >= E and ev["no_depth_mm"] >= ev["hidden_mm"]:
        share = ev["mask_nodepth_share"]
        return {
            **rec,
            "status": NOT_MEASURED,
            "reason": (
                f"no depth along {ev['no_depth_mm']:.0f} mm of it"
                + (
                    f", and the colour mask shows a bar on only {share:.0%} of that"
                    if has_mask and math.isfinite(share)
                    else ""
                    if has_mask
                    else " and no colour mask"
                )
            ),
        }
    if ev["hidden_mm"] >= ev["no_depth_mm"] and ev["hidden_mm"] > 0:
        return {
            **rec,
            "status": NOT_MEASURED,
            "reason": (
                f"hidden under another bar along {ev['hidden_mm']:.0f} mm; only {ev['empty_mm']:.0f} mm seen empty"
            ),
        }
    return {
        **rec,
        "status": NOT_MEASURED,
        "reason": (
            f"too little evidence: {ev['empty_mm']:.0f} mm seen empty, {ev['occupied_mm']:.0f} mm occupied, "
            f"{ev['no_depth_mm']:.0f} mm without depth (needs {E:.0f} mm of one)"
        ),
    }


def _present(
    row: _Row, p: float, ev: dict, sel: np.ndarray, plane, intr, prm, rec: dict, status: str, why: str
) -> dict:
    """A position found holding a bar: the bar placed on the mask's centre line over the slices
    ``sel`` at its level's height, status "not measured" (its axis is not fitted to points)."""
    off, sd, t0, t1 = _place_from_mask(row, p, ev, sel & np.isfinite(ev["_centre"]), plane, intr, prm)
    ok = sd <= prm.max_position_sigma_mm
    how = (
        f"placed from the colour mask's centre line at its level's height (± {sd:.1f} mm across"
        + ("" if ok else f"; over {prm.max_position_sigma_mm:g} mm, so its spacings are not measured")
        + ")"
    )
    reason = ("no depth on it: " if status == PRESENT_NO_DEPTH else why + "; ") + how
    ref = row.bars[0]
    bar = BarAxis(
        layer=row.layer,
        direction=ref.direction.copy(),
        offset_mm=float(off),
        slope=0.0,
        centre_h_mm=row.height,
        h_slope=0.0,
        t0_mm=t0,
        t1_mm=t1,
        radius_mm=row.radius,
        n_points=0,
        rms_mm=math.nan,
        point_index=np.zeros(0, int),
        group=ref.group,
        level=row.level,
        status=NOT_MEASURED,
        reason=reason,
    )
    bar = replace(bar, axis_se_mm=float(sd))
    return {
        **rec,
        "status": status,
        "reason": reason,
        "position_sigma_mm": round(sd, 2),
        "offset_mm": round(off, 1),
        "_bar": True,
        "_new": bar,
    }


def _pairs(row: _Row, plane, intr, foot, mask, prm):
    """Extra bars: two found bars on one lattice position."""
    if len(row.bars) < 2:
        return
    m_idx, phase = _lattice_index(row.offsets, row.spacing)
    for m in np.unique(m_idx):
        twins = np.flatnonzero(m_idx == m)
        if len(twins) < 2:
            continue
        # the one farther from the lattice position is the extra one
        dev = np.abs(row.offsets[twins] - (phase + m * row.spacing))
        k_extra = int(twins[np.argmax(dev)])
        others = [int(k) for k in twins if k != k_extra]
        k_twin = min(others, key=lambda k: abs(row.offsets[k] - row.offsets[k_extra]))
        a, b = row.bars[k_extra], row.bars[k_twin]
        base = {
            "kind": "pair",
            "offset_mm": round(float(row.offsets[k_extra]), 1),
            "bar_id": row.index[k_extra],
            "position_sigma_mm": math.nan,
            "in_view_mm": math.nan,
            "empty_mm": math.nan,
            "occupied_mm": math.nan,
            "no_depth_mm": math.nan,
            "hidden_mm": math.nan,
            "mask_mm": math.nan,
        }
        gap = abs(float(row.offsets[k_extra] - row.offsets[k_twin]))
        overlap = min(a.t1_mm, b.t1_mm) - max(a.t0_mm, b.t0_mm)
        shorter = min(a.t1_mm - a.t0_mm, b.t1_mm - b.t0_mm)
        what = f"bars {row.index[k_extra]} and {row.index[k_twin]}, {gap:.0f} mm apart on one design position"
        if overlap < prm.overlap_fraction * shorter or overlap < prm.min_evidence_mm:
            yield {
                **base,
                "status": NOT_EXTRA,
                "reason": (
                    f"{what}, side by side over {max(overlap, 0):.0f} mm only: a lap or a loose piece, not an extra bar"
                ),
            }
            continue
        weak = [(row.index[k], x) for x, k in ((a, k_extra), (b, k_twin)) if x.status != MEASURED]
        if weak:
            # the position has its bar; the other is no evidence of an extra one
            yield {
                **base,
                "status": NOT_EXTRA,
                "reason": (
                    f"{what}: bar {weak[0][0]} is not a measured bar ({weak[0][1].reason[:80]}), so it is no "
                    "evidence of an extra bar"
                ),
            }
            continue
        m_img = mask() if mask is not None else None
        if m_img is None:
            yield {**base, "status": NOT_MEASURED, "reason": f"{what}: no colour mask to confirm an extra bar"}
            continue
        shares = [_mask_along(x, plane, intr, foot, row.index[k] + 1, m_img) for x, k in ((a, k_extra), (b, k_twin))]
        if all(math.isfinite(x) and x >= prm.min_share for x in shares):
            yield {
                **base,
                "status": EXTRA,
                "reason": (
                    f"{what}, both fitted to points at bar height over {overlap:.0f} mm, the colour mask along both "
                    f"({shares[0]:.0%}, {shares[1]:.0%})"
                ),
            }
        else:
            yield {
                **base,
                "status": NOT_MEASURED,
                "reason": (f"{what}: the colour mask runs along only {min(shares):.0%} of one of them"),
            }
