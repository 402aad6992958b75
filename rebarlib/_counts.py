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

from ._camera import Intrinsics, backproject, project
from ._status import (EXTRA, MEASURED, MISSING, NOT_EXTRA, NOT_IN_VIEW, NOT_MEASURED, OUTSIDE,
                      PRESENT, PRESENT_NO_DEPTH)
from .geometry import LAYERS, LEVELS, BarAxis, Plane, _in_image, from_slab_frame, to_slab_frame

__all__ = ["CountParams", "examine_positions", "mesh_boundary", "count_table", "settle_spacings",
           "POSITION_COLUMNS"]


POSITION_COLUMNS = ["layer", "level", "kind", "offset_mm", "status", "reason", "in_view_mm", "empty_mm",
                    "occupied_mm", "no_depth_mm", "hidden_mm", "mask_mm", "position_sigma_mm", "bar_id",
                    "start_x_mm", "start_y_mm", "start_z_mm", "end_x_mm", "end_y_mm", "end_z_mm"]


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
# Footprints of the found bars in the image


def _footprints(bars: list, plane: Plane, intr: Intrinsics) -> np.ndarray:
    """(H, W) int32: 1 + index of the found bar drawn at each pixel (its projected cylinder,
    1 px wider each side), 0 where none; nearer bars drawn last."""
    import cv2

    img = np.zeros((intr.height, intr.width), np.int32)
    order = []
    for i, b in enumerate(bars):
        if b.t1_mm <= b.t0_mm:
            continue
        t = np.linspace(b.t0_mm, b.t1_mm, max(2, int((b.t1_mm - b.t0_mm) / 50.0) + 1))
        cam = from_slab_frame(b.axis_points(t), plane)
        order.append((-float(np.mean(cam[:, 2])), i, cam))
    for _, i, cam in sorted(order):
        ok = cam[:, 2] > 1.0
        if ok.sum() < 2:
            continue
        cam = cam[ok]
        uv = project(cam, intr)
        width = 2.0 * bars[i].radius_mm * 0.5 * (intr.fx + intr.fy) / cam[:, 2]
        for k in range(len(cam) - 1):
            th = int(math.ceil(0.5 * (width[k] + width[k + 1]))) + 2
            p0 = tuple(int(round(x)) for x in np.clip(uv[k], -1e4, 1e4))
            p1 = tuple(int(round(x)) for x in np.clip(uv[k + 1], -1e4, 1e4))
            cv2.line(img, p0, p1, int(i + 1), thickness=max(th, 1))
    return img


# ----------------------------------------------------------------------------------------------
# The mesh's boundary


def _plan_ends(b: BarAxis) -> np.ndarray:
    return b.plan_point(np.array([b.t0_mm, b.t1_mm]))


def _end_seen(b: BarAxis, t_end: float, sign: float, plane: Plane, depth, intr: Intrinsics,
              tol_mm: float) -> bool:
    """Does bar ``b`` really end at ``t_end``? Where it would continue (2-6 radii beyond, at its
    top), at least two pixels in the image show something lower than its underside and none
    shows something at its height: had it continued, it would have been seen there. (Pixels
    showing something above it, another bar, say nothing either way.)"""
    r = max(b.radius_mm, 3.0)
    t = t_end + sign * np.array([2.0, 3.0, 4.0, 5.0, 6.0]) * r
    pts = b.axis_points(t)
    pts[:, 2] += r
    cam = from_slab_frame(pts, plane)
    uv = np.round(project(cam, intr)).astype(int)
    H, W = depth.shape
    inside = (uv[:, 0] >= 3) & (uv[:, 0] < W - 3) & (uv[:, 1] >= 3) & (uv[:, 1] < H - 3) & (cam[:, 2] > 0)
    if inside.sum() < 2:
        return False
    u, v = uv[inside, 0], uv[inside, 1]
    z = depth[v, u]
    ok = z > 0
    h = _heights(u[ok], v[ok], z[ok], plane, intr)
    lower = h < b.underside_mm - tol_mm
    at_bar = (h >= b.underside_mm - tol_mm) & (h <= b.top_mm + tol_mm)
    return bool(lower.sum() >= 2 and not at_bar.any())


def _heights(u, v, z, plane: Plane, intr: Intrinsics) -> np.ndarray:
    """Heights above ``plane`` of pixels (u, v) with depth z."""
    return plane.height(backproject(np.column_stack((u, v)), z, intr))


def mesh_boundary(bars: list, *, plane: Plane, depth_mm, intrinsics: Intrinsics,
                  noise_mm: float = 1.0) -> dict:
    """Where each lattice's mesh ends in the capture, from where its bars end.

    For each lattice and direction group, the extent across the group's bars covered by the
    crossing bars (the other group of the lattice): ``reach_minus_mm`` / ``reach_plus_mm`` (plan
    offsets across the group, the same frame as the bars' offsets), and whether the crossing
    bars' ends there are *seen* ends (``edge_minus`` / ``edge_plus``: the formwork or the level
    below is seen where they would continue) or ends at the image's border or under something.
    ``corners_camera_mm`` (4, 3): the mesh's outline at its lowest bars' height where both
    directions have bars (None otherwise).
    """
    depth = np.asarray(depth_mm, float)
    tol = max(3.0 * noise_mm, 2.0)
    out = {}
    for layer in LAYERS:
        groups = {lv: [b for b in bars if b.layer == layer and b.level == lv and b.t1_mm > b.t0_mm]
                  for lv in LEVELS}
        info = {}
        for lv, other in (("bottom", "top"), ("top", "bottom")):
            rows, cross = groups[lv], groups[other]
            if not rows or not cross:
                info[lv] = None
                continue
            n2 = rows[0].normal2d
            lo, hi, edge_lo, edge_hi = math.inf, -math.inf, [], []
            for c in cross:
                ends = _plan_ends(c) @ n2
                for t_end, sign, e in ((c.t0_mm, -1.0, ends[0]), (c.t1_mm, 1.0, ends[1])):
                    s = sign * float(np.sign(c.direction @ n2) or 1.0)  # which side it reaches
                    seen = _end_seen(c, t_end, sign, plane, depth, intrinsics, tol)
                    if s > 0:
                        edge_hi.append((e, seen))
                        hi = max(hi, e)
                    else:
                        edge_lo.append((e, seen))
                        lo = min(lo, e)
            info[lv] = {"direction": rows[0].direction.round(6).tolist(), "normal": n2.round(6).tolist(),
                        "reach_minus_mm": round(lo, 1), "reach_plus_mm": round(hi, 1),
                        "edge_minus": _edge(edge_lo, lo, min), "edge_plus": _edge(edge_hi, hi, max),
                        "n_crossing": len(cross)}
        out[layer] = {**info, "corners_camera_mm": _corners(info, groups, plane)}
    return out


def _edge(ends: list, reach: float, pick) -> bool:
    """The mesh ends at ``reach`` when the crossing bars that reach farthest (within 30 mm of
    it) end in view there, for most of them."""
    near = [seen for e, seen in ends if abs(e - reach) <= 30.0]
    return bool(near) and sum(near) >= max(1, math.ceil(0.5 * len(near)))


def _corners(info: dict, groups: dict, plane: Plane):
    """(4, 3) camera-frame corners of a lattice's outline at its lowest bars' height, from the
    reach of each direction's crossing bars; None unless both directions have it."""
    a, b = info.get("bottom"), info.get("top")
    if not a or not b:
        return None
    n_a, n_b = np.array(a["normal"]), np.array(b["normal"])
    A = np.vstack((n_a, n_b))
    if abs(np.linalg.det(A)) < 1e-3:
        return None
    h = float(np.median([x.underside_mm for x in groups["bottom"]]))
    pts = []
    for ca, cb in ((a["reach_minus_mm"], b["reach_minus_mm"]), (a["reach_plus_mm"], b["reach_minus_mm"]),
                   (a["reach_plus_mm"], b["reach_plus_mm"]), (a["reach_minus_mm"], b["reach_plus_mm"])):
        xy = np.linalg.solve(A, np.array([ca, cb]))
        pts.append([xy[0], xy[1], h])
    return from_slab_frame(np.array(pts), plane).round(2).tolist()


# ----------------------------------------------------------------------------------------------
# Examining one position


@dataclass
class _Row:
    layer: str
    level: str
    bars: list  # the row's found bars, in order across
    index: list  # their indices in the full bar list
    offsets: np.ndarray  # plan offsets across (along normal2d of the first)
    spacing: float
    height: float  # the level's axis height (median of the measured bars)
    height_sd: float
    radius: float
    direction: np.ndarray
    normal: np.ndarray


def _offset(b: BarAxis, n2) -> float:
    return float(b.plan_point(b.t_mid) @ n2)


def _samples(row: _Row, p: float, t: np.ndarray, c: np.ndarray, h: float, plane: Plane, intr: Intrinsics):
    """Pixels (T, C, 2 int) and in-image flags of the plan grid (t along, p + c across) at
    height ``h``."""
    plan = t[:, None, None] * row.direction + (p + c)[None, :, None] * row.normal
    pts = np.concatenate([plan, np.full(plan.shape[:2] + (1,), h)], axis=2).reshape(-1, 3)
    cam = from_slab_frame(pts, plane)
    uv = np.round(project(cam, intr)).astype(int)
    ok = _in_image(uv, cam, intr)
    shape = (len(t), len(c))
    return uv.reshape(shape + (2,)), ok.reshape(shape)


def _runs(flags: np.ndarray) -> list:
    """(start, stop) of each run of True in a 1-D boolean array."""
    f = np.r_[False, flags, False].astype(np.int8)
    d = np.diff(f)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _examine(row: _Row, p: float, t_range, *, plane, depth, intr, foot, row_ids, higher, noise, prm):
    """The depth's evidence at plan offset ``p`` of ``row``: a dict of lengths (mm) and the
    per-slice states (:func:`_add_mask` adds the colour mask's)."""
    s, r = row.spacing, row.radius
    t = np.arange(t_range[0], t_range[1] + 1e-9, prm.step_mm)
    c = np.arange(-s / 2, s / 2 + 1e-9, prm.sample_mm)
    core = np.abs(c) <= prm.core_fraction * s + r
    top = row.height + r
    uv, inside = _samples(row, p, t, c, top, plane, intr)
    u = np.clip(uv[..., 0], 0, intr.width - 1)
    v = np.clip(uv[..., 1], 0, intr.height - 1)
    owner = foot[v, u]
    own_row = np.isin(owner, row_ids) & inside
    # found bars higher than this level hide the spot; lower ones are its support, judged by depth
    other = np.isin(owner, higher) & ~own_row & inside
    z = depth[v, u]
    h = np.where(z > 0, _heights(u.ravel(), v.ravel(), z.ravel(), plane, intr).reshape(z.shape), np.nan)
    margin = max(0.35 * r, 3.0 * noise)
    band_lo = row.height - r + margin
    band_hi = top + max(3.0 * noise, 2.0)
    nodepth = inside & ~own_row & ~other & (z <= 0)
    seen = inside & ~own_row & ~other & (z > 0)
    above = seen & (h > band_hi)
    band = seen & (h >= band_lo) & (h <= band_hi)  # below band_lo: the support, seen through
    hidden = other | above

    step = prm.sample_mm
    in_view = np.all(inside | ~core[None, :], axis=1)
    state = np.zeros(len(t), np.int8)  # 0 unknown, 1 empty, 2 occupied
    cause_nd = np.zeros(len(t), bool)
    cause_hid = np.zeros(len(t), bool)
    for k in np.flatnonzero(in_view):
        if any((b - a) * step >= r for a, b in _runs(band[k])):
            state[k] = 2
            continue
        # unseen stretches of the core, where a bar within a quarter spacing of its place would
        # lie (outside the image does not count: the core is in it). A bar could hide in an
        # unseen stretch farther out only a quarter spacing or more off its place, a defect of
        # its own that leaves its position empty.
        unseen = (nodepth[k] | hidden[k] | band[k]) & core
        long = [(a, b) for a, b in _runs(unseen) if (b - a) * step >= 2 * r]
        if not long:
            state[k] = 1
        else:
            # a slice can lack depth where a bar would be and be partly hidden too: each cause
            # that covers a radius of the unseen stretches counts (a bar without depth beside
            # the bar over it is still placed from the colour, where the colour shows it)
            nd = sum(nodepth[k, a:b].sum() for a, b in long) * step
            hd = sum(hidden[k, a:b].sum() for a, b in long) * step
            cause_nd[k], cause_hid[k] = nd >= r, hd >= r
    L = prm.step_mm
    ev = {"in_view_mm": float(in_view.sum() * L), "empty_mm": float((state == 1).sum() * L),
          "occupied_mm": float((state == 2).sum() * L), "no_depth_mm": float((in_view & cause_nd).sum() * L),
          "hidden_mm": float((in_view & cause_hid).sum() * L), "mask_mm": 0.0, "mask_empty_share": math.nan,
          "mask_nodepth_share": math.nan, "mask_occupied_share": math.nan, "centre": math.nan,
          "centre_sigma": math.nan, "t_mask": None}
    ev["_state"], ev["_nd"], ev["_t"], ev["_c"], ev["_in_view"] = state, in_view & cause_nd, t, c, in_view
    return ev


def _add_mask(ev: dict, row: _Row, p: float, m, *, plane, intr, foot, prm) -> dict:
    """The colour mask's evidence over the slices of ``ev`` (:func:`_examine`): how much of the
    row's length shows a bar, the share of the empty / no-depth / occupied slices that do, and
    the centre line of each showing slice. Called only when a verdict needs it."""
    t, c, state, in_view = ev["_t"], ev["_c"], ev["_state"], ev["_in_view"]
    step, r, L = prm.sample_mm, row.radius, prm.step_mm
    # the mask at the axis height: its centre line is the axis's projection
    uv2, inside2 = _samples(row, p, t, c, row.height, plane, intr)
    u2 = np.clip(uv2[..., 0], 0, intr.width - 1)
    v2 = np.clip(uv2[..., 1], 0, intr.height - 1)
    free = inside2 & (foot[v2, u2] == 0)
    on = free & m[v2, u2]
    shows = np.zeros(len(t), bool)
    centre = np.full(len(t), np.nan)
    for k in np.flatnonzero(in_view):
        runs = [(a, b) for a, b in _runs(on[k]) if (b - a) * step >= r]
        if runs:
            a, b = max(runs, key=lambda ab: ab[1] - ab[0])
            shows[k] = True
            centre[k] = 0.5 * (c[a] + c[b - 1])
    ev["mask_mm"] = float(shows.sum() * L)
    for key, sel in (("mask_empty_share", state == 1), ("mask_nodepth_share", ev["_nd"]),
                     ("mask_occupied_share", state == 2)):
        if sel.sum():
            ev[key] = float(shows[sel].mean())
    ev["_shows"], ev["_centre"] = shows, centre
    return ev


def _place_from_mask(row: _Row, p: float, ev: dict, sel: np.ndarray, plane: Plane, intr: Intrinsics,
                     prm) -> tuple:
    """Centre line of the mask over the slices ``sel``: (plan offset, its standard uncertainty,
    t0, t1)."""
    cen = ev["_centre"][sel]
    t = ev["_t"][sel]
    cen, t = cen[np.isfinite(cen)], t[np.isfinite(cen)]
    med = float(np.median(cen))
    mad = float(np.median(np.abs(cen - med))) * 1.4826
    n_eff = max(1.0, (len(cen) * prm.step_mm) / max(4.0 * row.radius, prm.step_mm))
    sd_centre = max(mad, prm.sample_mm / math.sqrt(12)) / math.sqrt(n_eff)
    # the level's height is assumed: a height off by σ_h moves the line of sight across by
    # σ_h × (the ray's slope across the row) where the bar is
    mid = np.r_[float(np.median(t)) * row.direction + (p + med) * row.normal, row.height]
    cam = from_slab_frame(mid[None], plane)[0]
    ray = to_slab_frame(np.vstack((np.zeros(3), cam)), plane)
    d = ray[1] - ray[0]
    slope = abs(float(d[:2] @ row.normal)) / max(abs(float(d[2])), 1e-6)
    # the mask's centre line itself: its two edges (the model's, on either flank) and its
    # registration to the depth image hold to about half a pixel, here in mm across
    f = 0.5 * (intr.fx + intr.fy)
    sd_mask = 0.5 * float(cam[2]) / f
    sd = math.sqrt(sd_centre ** 2 + (row.height_sd * slope) ** 2 + sd_mask ** 2)
    return p + med, sd, float(t.min()), float(t.max())


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


def examine_positions(bars: list, *, design_spacing: dict, plane: Plane, depth_mm, intrinsics: Intrinsics,
                      mask=None, noise_mm: float | None = None, params: CountParams | None = None):
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
            row = _Row(layer, level, [bars[i] for i in order], order,
                       np.array([_offset(bars[i], n2) for i in order]), float(s), float(np.median(hs)),
                       float(1.4826 * np.median(np.abs(hs - np.median(hs)))) if len(hs) > 2 else 1.0,
                       float(np.median([b.radius_mm for b in meas])), bars[idx[0]].direction, n2)
            reach = _reach(boundary, layer, level, row.normal)
            higher = [i + 1 for i, b in enumerate(bars) if b.axis_height_mm > row.height + row.radius]
            # the higher bars along this row (offset across, axis height, radius): where one
            # hides a position, they say from where it would show
            over = [(_offset(b, n2), b.axis_height_mm, b.radius_mm) for b in bars
                    if b.axis_height_mm > row.height + row.radius and abs(float(b.direction @ row.direction)) > 0.95]
            for kind, p, nb in _candidates(row, reach, plane, intr, prm):
                rec = _judge(row, kind, p, nb, reach, plane=plane, depth=depth, intr=intr, foot=foot,
                             higher=higher, mask=get_mask if mask is not None else None, noise=noise, prm=prm)
                if rec["status"] == NOT_MEASURED and rec["reason"].startswith("hidden under"):
                    rec["reason"] += _where_it_shows(row, p, over, plane)
                if rec.pop("_bar", None) is not None:
                    nb_bar = rec.pop("_new")
                    new_bars.append(nb_bar)
                    rec["bar_id"] = len(bars) + len(new_bars) - 1
                rec.update(_line_ends(row, float(rec["offset_mm"]), _t_range(nb), plane))
                rows_out.append({"layer": layer, "level": level, **rec})
            rows_out.extend({"layer": layer, "level": level, **rec}
                            for rec in _pairs(row, plane, intr, foot, get_mask if mask is not None else None, prm))
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
    return (f"; a capture taken with the camera about {move:.0f} mm or more to either side across these bars "
            "(moved, not tilted) would show it beside that bar")


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
            return {**cand, "reach_minus_mm": lo, "reach_plus_mm": hi, "edge_minus": el, "edge_plus": eh,
                    "proxy": f"the {other} lattice's crossing bars"}
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
    return {f"{end}_{c}_mm": round(float(cam[i, j]), 2) for i, end in enumerate(("start", "end"))
            for j, c in enumerate("xyz")}


def _t_range(nb) -> tuple:
    return min(b.t0_mm for b in nb), max(b.t1_mm for b in nb)


def _judge(row: _Row, kind: str, p: float, nb, reach, *, plane, depth, intr, foot, higher, mask, noise,
           prm) -> dict:
    """The verdict on one empty position (a ``positions`` row, with ``_bar``/``_new`` when a bar
    is placed there): outside the mesh, not in view, present (no depth), present, missing or not
    measured, in that order of tests (module docstring)."""
    s = row.spacing
    base = {"kind": kind, "offset_mm": round(p, 1), "bar_id": None, "position_sigma_mm": math.nan}
    if kind == "end":
        side = "plus" if p > row.offsets[-1] else "minus"
        if reach is None:
            return {**base, "status": NOT_MEASURED, "reason": "no crossing bar found: where the mesh ends cannot be "
                    "told, so this position beyond the outermost bar is not judged"}
        r_edge = reach[f"reach_{side}_mm"]
        beyond = (p - r_edge) if side == "plus" else (r_edge - p)
        if beyond > prm.inside_mm:
            edge = reach[f"edge_{side}"]
            return {**base, "status": OUTSIDE, "reason": (
                f"the crossing bars end {beyond:.0f} mm before it"
                + (" (the mesh's edge is in view)" if edge else " (where they leave the view or are hidden)"))}
    row_ids = [i + 1 for i in row.index]
    ev = _examine(row, p, _t_range(nb), plane=plane, depth=depth, intr=intr, foot=foot, row_ids=row_ids,
                  higher=higher, noise=noise, prm=prm)
    E = prm.min_evidence_mm
    seen = ev["empty_mm"] + ev["occupied_mm"]
    # the colour mask is read only where the depth leaves a verdict that needs it
    needs = ev["in_view_mm"] >= E and (ev["occupied_mm"] >= E or ev["empty_mm"] >= E or ev["no_depth_mm"] >= E)
    m = mask() if (mask is not None and needs) else None
    if m is not None:
        ev = _add_mask(ev, row, p, m, plane=plane, intr=intr, foot=foot, prm=prm)
    rec = {**base, **{k: round(ev[k], 1) for k in ("in_view_mm", "empty_mm", "occupied_mm", "no_depth_mm",
                                                    "hidden_mm", "mask_mm")}}
    if ev["in_view_mm"] < E:
        return {**rec, "status": NOT_IN_VIEW, "reason": f"only {ev['in_view_mm']:.0f} mm of it in view (needs {E:.0f})"}
    has_mask = "_shows" in ev
    if ev["occupied_mm"] >= E and ev["occupied_mm"] >= 0.5 * seen:
        share = ev["mask_occupied_share"]
        if has_mask and share >= prm.min_share:
            return _present(row, p, ev, ev["_state"] == 2, plane, intr, prm, rec, PRESENT,
                            f"points at the bar's height along {ev['occupied_mm']:.0f} mm and the colour mask "
                            "along it: a bar the fit did not take")
        return {**rec, "status": NOT_MEASURED, "reason": (
            f"points at the bar's height along {ev['occupied_mm']:.0f} mm, but "
            + ("the colour mask does not show a bar there (another object?)" if has_mask else "no colour mask"))}
    if ev["empty_mm"] >= E and ev["occupied_mm"] <= prm.max_share * seen:
        if not has_mask:
            return {**rec, "status": NOT_MEASURED, "reason": (
                f"the depth shows the support and nothing at the bar's height along {ev['empty_mm']:.0f} mm, "
                "but no colour mask was available to confirm it")}
        share = ev["mask_empty_share"]
        if share <= prm.max_share:
            return {**rec, "status": MISSING, "reason": (
                f"empty: the {'formwork' if row.level == 'bottom' and row.layer == 'lower' else 'support'} "
                f"is seen with depth and nothing at the bar's height along {ev['empty_mm']:.0f} mm of the "
                f"corridor (± {s / 2:.0f} mm), and the colour mask shows no bar there")}
        return {**rec, "status": NOT_MEASURED, "reason": (
            f"the depth shows the corridor empty along {ev['empty_mm']:.0f} mm, but the colour mask shows a bar "
            f"on {share:.0%} of it")}
    if ev["no_depth_mm"] >= E:
        share = ev["mask_nodepth_share"]
        sel = ev["_nd"] & ev["_shows"] if has_mask else None
        if has_mask and share >= prm.min_share and sel.sum() * prm.step_mm >= E:
            return _present(row, p, ev, sel, plane, intr, prm, rec, PRESENT_NO_DEPTH, "")
    if ev["no_depth_mm"] >= E and ev["no_depth_mm"] >= ev["hidden_mm"]:
        share = ev["mask_nodepth_share"]
        return {**rec, "status": NOT_MEASURED, "reason": (
            f"no depth along {ev['no_depth_mm']:.0f} mm of it"
            + (f", and the colour mask shows a bar on only {share:.0%} of that" if has_mask and math.isfinite(share)
               else "" if has_mask else " and no colour mask"))}
    if ev["hidden_mm"] >= ev["no_depth_mm"] and ev["hidden_mm"] > 0:
        return {**rec, "status": NOT_MEASURED, "reason": (
            f"hidden under another bar along {ev['hidden_mm']:.0f} mm; only {ev['empty_mm']:.0f} mm seen empty")}
    return {**rec, "status": NOT_MEASURED, "reason": (
        f"too little evidence: {ev['empty_mm']:.0f} mm seen empty, {ev['occupied_mm']:.0f} mm occupied, "
        f"{ev['no_depth_mm']:.0f} mm without depth (needs {E:.0f} mm of one)")}


def _present(row: _Row, p: float, ev: dict, sel: np.ndarray, plane, intr, prm, rec: dict, status: str,
             why: str) -> dict:
    """A position found holding a bar: the bar placed on the mask's centre line over the slices
    ``sel`` at its level's height, status "not measured" (its axis is not fitted to points)."""
    off, sd, t0, t1 = _place_from_mask(row, p, ev, sel & np.isfinite(ev["_centre"]), plane, intr, prm)
    ok = sd <= prm.max_position_sigma_mm
    how = (f"placed from the colour mask's centre line at its level's height (± {sd:.1f} mm across"
           + ("" if ok else f"; over {prm.max_position_sigma_mm:g} mm, so its spacings are not measured") + ")")
    reason = ("no depth on it: " if status == PRESENT_NO_DEPTH else why + "; ") + how
    ref = row.bars[0]
    bar = BarAxis(layer=row.layer, direction=ref.direction.copy(), offset_mm=float(off), slope=0.0,
                  centre_h_mm=row.height, h_slope=0.0, t0_mm=t0, t1_mm=t1, radius_mm=row.radius, n_points=0,
                  rms_mm=math.nan, point_index=np.zeros(0, int), group=ref.group, level=row.level,
                  status=NOT_MEASURED, reason=reason)
    bar = replace(bar, axis_se_mm=float(sd))
    return {**rec, "status": status, "reason": reason, "position_sigma_mm": round(sd, 2), "offset_mm": round(off, 1),
            "_bar": True, "_new": bar}


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
        base = {"kind": "pair", "offset_mm": round(float(row.offsets[k_extra]), 1), "bar_id": row.index[k_extra],
                "position_sigma_mm": math.nan, "in_view_mm": math.nan, "empty_mm": math.nan, "occupied_mm": math.nan,
                "no_depth_mm": math.nan, "hidden_mm": math.nan, "mask_mm": math.nan}
        gap = abs(float(row.offsets[k_extra] - row.offsets[k_twin]))
        overlap = min(a.t1_mm, b.t1_mm) - max(a.t0_mm, b.t0_mm)
        shorter = min(a.t1_mm - a.t0_mm, b.t1_mm - b.t0_mm)
        what = f"bars {row.index[k_extra]} and {row.index[k_twin]}, {gap:.0f} mm apart on one design position"
        if overlap < prm.overlap_fraction * shorter or overlap < prm.min_evidence_mm:
            yield {**base, "status": NOT_EXTRA, "reason": (
                f"{what}, side by side over {max(overlap, 0):.0f} mm only: a lap or a loose piece, not an extra bar")}
            continue
        weak = [(row.index[k], x) for x, k in ((a, k_extra), (b, k_twin)) if x.status != MEASURED]
        if weak:
            # the position has its bar; the other is no evidence of an extra one
            yield {**base, "status": NOT_EXTRA, "reason": (
                f"{what}: bar {weak[0][0]} is not a measured bar ({weak[0][1].reason[:80]}), so it is no "
                "evidence of an extra bar")}
            continue
        m_img = mask() if mask is not None else None
        if m_img is None:
            yield {**base, "status": NOT_MEASURED, "reason": f"{what}: no colour mask to confirm an extra bar"}
            continue
        shares = [_mask_along(x, plane, intr, foot, row.index[k] + 1, m_img)
                  for x, k in ((a, k_extra), (b, k_twin))]
        if all(math.isfinite(x) and x >= prm.min_share for x in shares):
            yield {**base, "status": EXTRA, "reason": (
                f"{what}, both fitted to points at bar height over {overlap:.0f} mm, the colour mask along both "
                f"({shares[0]:.0%}, {shares[1]:.0%})")}
        else:
            yield {**base, "status": NOT_MEASURED, "reason": (
                f"{what}: the colour mask runs along only {min(shares):.0%} of one of them")}


# ----------------------------------------------------------------------------------------------
# The count table


def count_table(bars: list, positions: pd.DataFrame, design_spacing: dict) -> pd.DataFrame:
    """Per lattice and direction: ``found`` (bars, including those placed from the mask),
    ``expected``, ``missing`` and ``extra`` (evidenced only), ``not_measured`` (positions that
    are neither), ``outside`` (positions beyond the mesh), ``evidence`` (what was seen)."""
    rows = []
    for layer in LAYERS:
        for level in LEVELS:
            found = sum(1 for b in bars if b.layer == layer and b.level == level)
            s = design_spacing.get((layer, level))
            pos = (positions[(positions["layer"] == layer) & (positions["level"] == level)]
                   if len(positions) else positions)
            st = pos["status"].value_counts().to_dict() if len(pos) else {}
            if not found or s is None:
                rows.append({"layer": layer, "level": level, "found": found, "expected": None, "missing": None,
                             "extra": None, "not_measured": None, "outside": None,
                             "evidence": "no bar found" if not found else "no design spacing"})
                continue
            missing, extra = int(st.get(MISSING, 0)), int(st.get(EXTRA, 0))
            nm = int(st.get(NOT_MEASURED, 0))
            parts = [f"{found} found"]
            for key, label in ((PRESENT_NO_DEPTH, "placed from the colour mask (no depth)"),
                               (PRESENT, "seen but not fitted"), (MISSING, "missing (seen empty)"),
                               (EXTRA, "extra"), (NOT_MEASURED, "not measured"), (NOT_EXTRA, "laps/short pieces"),
                               (OUTSIDE, "beyond the mesh's edge")):
                if st.get(key):
                    parts.append(f"{st[key]} {label}")
            rows.append({"layer": layer, "level": level, "found": found, "expected": found - extra + missing,
                         "missing": missing, "extra": extra, "not_measured": nm,
                         "outside": int(st.get(OUTSIDE, 0)), "evidence": ", ".join(parts)})
    df = pd.DataFrame(rows, columns=["layer", "level", "found", "expected", "missing", "extra", "not_measured",
                                     "outside", "evidence"])
    return df


def settle_spacings(spacings: pd.DataFrame, bars: list, positions: pd.DataFrame,
                    params: CountParams | None = None) -> pd.DataFrame:
    """The spacing table once the positions are known.

    - A spacing to a bar placed from the colour mask (no depth) is measured between the two
      axes when the bar's position is known to ``max_position_sigma_mm``; its reason says so.
    - A spacing spanning more than 1.5 design spacings is one real (wide) spacing only where
      every position between the two bars was seen empty (missing); where one of them could not
      be examined it is "not measured", with what was not seen.
    """
    from .geometry import _pair_spacing

    prm = params or CountParams()
    out = spacings.copy()
    placed = {}
    if len(positions):
        for rec in positions.to_dict(orient="records"):
            if rec["status"] in (PRESENT_NO_DEPTH, PRESENT) and rec["bar_id"] is not None \
                    and not pd.isna(rec["bar_id"]):
                placed[int(rec["bar_id"])] = float(rec["position_sigma_mm"])
    for i, s in out.iterrows():
        a, b = int(s["bar_a"]), int(s["bar_b"])
        ds = s["design_spacing_mm"]
        if (a in placed or b in placed) and s["status"] != MEASURED:
            others = [x for x in (a, b) if x not in placed]
            sig = [placed[x] for x in (a, b) if x in placed]
            if all(bars[x].status == MEASURED for x in others) and max(sig) <= prm.max_position_sigma_mm:
                val = _pair_spacing(bars[a], bars[b])
                out.loc[i, "spacing_mm"] = val
                out.loc[i, "deviation_mm"] = val - ds if np.isfinite(ds) else np.nan
                out.loc[i, "status"] = MEASURED
                out.loc[i, "reason"] = (f"bar {', '.join(str(x) for x in (a, b) if x in placed)} placed from "
                                        f"the colour mask (± {max(sig):.1f} mm across)")
                s = out.loc[i]
        if s["status"] != MEASURED or not np.isfinite(ds) or s["spacing_mm"] <= 1.5 * ds:
            continue
        pos = positions[(positions["layer"] == s["layer"]) & (positions["level"] == s["level"])
                        & (positions["kind"] == "gap")] if len(positions) else positions
        n2 = next(x.normal2d for x in bars if x.layer == s["layer"] and x.level == s["level"])
        lo, hi = sorted((_offset(bars[a], n2), _offset(bars[b], n2)))
        # the empty positions between the two (a bar placed there is one of the two, or splits
        # the gap: it is no empty position)
        q = 0.25 * ds
        inner = (pos[(pos["offset_mm"] > lo + q) & (pos["offset_mm"] < hi - q)
                     & ~pos["status"].isin([PRESENT, PRESENT_NO_DEPTH])] if len(pos) else pos)
        if len(inner) and (inner["status"] == MISSING).all():
            continue
        why = "; ".join(str(x) for x in inner["reason"]) if len(inner) else "its positions were not examined"
        out.loc[i, ["spacing_mm", "deviation_mm"]] = np.nan
        out.loc[i, "status"] = NOT_MEASURED
        out.loc[i, "reason"] = (f"{s['spacing_mm']:.0f} mm gap with a bar position between that could not be "
                                f"judged ({why}), so it is not one spacing")
    return out

