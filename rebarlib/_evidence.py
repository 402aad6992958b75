"""The evidence at a bar position, for the bar counts (:mod:`rebarlib._counts`): the found
bars' pixels, where the mesh ends (:func:`mesh_boundary`), and what the depth and the colour mask
show across a would-be bar's corridor, slice by slice along its row (:func:`_examine`,
:func:`_add_mask`).

All lengths are in mm; the rules that read this evidence are in ``docs/verdicts.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ._camera import Intrinsics, backproject, project
from .geometry import LAYERS, LEVELS, BarAxis, Plane, _in_image, _runs, from_slab_frame, to_slab_frame

__all__ = ["mesh_boundary"]

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


def _end_seen(b: BarAxis, t_end: float, sign: float, plane: Plane, depth, intr: Intrinsics, tol_mm: float) -> bool:
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


def mesh_boundary(bars: list, *, plane: Plane, depth_mm, intrinsics: Intrinsics, noise_mm: float = 1.0) -> dict:
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
        groups = {lv: [b for b in bars if b.layer == layer and b.level == lv and b.t1_mm > b.t0_mm] for lv in LEVELS}
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
            info[lv] = {
                "direction": rows[0].direction.round(6).tolist(),
                "normal": n2.round(6).tolist(),
                "reach_minus_mm": round(lo, 1),
                "reach_plus_mm": round(hi, 1),
                "edge_minus": _edge(edge_lo, lo, min),
                "edge_plus": _edge(edge_hi, hi, max),
                "n_crossing": len(cross),
            }
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
    for ca, cb in (
        (a["reach_minus_mm"], b["reach_minus_mm"]),
        (a["reach_plus_mm"], b["reach_minus_mm"]),
        (a["reach_plus_mm"], b["reach_plus_mm"]),
        (a["reach_minus_mm"], b["reach_plus_mm"]),
    ):
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


def _height_grid(u, v, z, plane: Plane, intr: Intrinsics) -> np.ndarray:
    """Heights above the formwork (mm) of a grid of pixels ``(u, v)`` with depths ``z``; NaN where
    there is no depth."""
    return np.where(z > 0, _heights(u.ravel(), v.ravel(), z.ravel(), plane, intr).reshape(z.shape), np.nan)


def _band_top(row: _Row, noise: float) -> float:
    """The highest a point on a bar of ``row`` reads: its top plus the depth noise (3 σ, at least
    2 mm). Above it is something else: a nearer bar, or whatever lies over the spot."""
    return row.height + row.radius + max(3.0 * noise, 2.0)


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
    h = _height_grid(u, v, z, plane, intr)
    margin = max(0.35 * r, 3.0 * noise)
    band_lo = row.height - r + margin
    band_hi = _band_top(row, noise)
    nodepth = inside & ~own_row & ~other & (z <= 0)
    seen = inside & ~own_row & ~other & (z > 0)
    above = seen & (h > band_hi)
    band = seen & (h >= band_lo) & (h <= band_hi)  # below band_lo: the support, seen through
    hidden = other | above

    step = prm.sample_mm
    in_view = np.all(inside | ~core[None, :], axis=1)
    # slices at the image's border: the core partly outside, the would-be bar's own width (± r of
    # its place) inside. They cannot show a position empty or occupied (a bar off its place could
    # lie outside), but they can show a bar without depth in the colour (decision 060)
    edge = ~in_view & np.any(inside & (np.abs(c) <= r)[None, :], axis=1)
    state = np.zeros(len(t), np.int8)  # 0 unknown, 1 empty, 2 occupied
    cause_nd = np.zeros(len(t), bool)
    cause_hid = np.zeros(len(t), bool)
    for k in np.flatnonzero(edge):
        if any((b - a) * step >= r for a, b in _runs(band[k])):
            continue  # something at the bar's height there: its own evidence, not this slice's
        unseen = nodepth[k] & core & inside[k]
        cause_nd[k] = any((b - a) * step >= 2 * r for a, b in _runs(unseen))
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
    ev = {
        "in_view_mm": float(in_view.sum() * L),
        "empty_mm": float((state == 1).sum() * L),
        "occupied_mm": float((state == 2).sum() * L),
        "no_depth_mm": float((in_view & cause_nd).sum() * L),
        "hidden_mm": float((in_view & cause_hid).sum() * L),
        "mask_mm": 0.0,
        "mask_empty_share": math.nan,
        "mask_nodepth_share": math.nan,
        "mask_occupied_share": math.nan,
        "centre": math.nan,
        "centre_sigma": math.nan,
        "t_mask": None,
    }
    ev["_state"], ev["_nd"], ev["_t"], ev["_c"], ev["_in_view"] = (state, in_view & cause_nd, t, c, in_view)
    ev["_nd_edge"] = edge & cause_nd
    return ev


def _add_mask(ev: dict, row: _Row, p: float, m, *, plane, intr, foot, prm, depth=None, noise: float = 1.0) -> dict:
    """The colour mask's evidence over the slices of ``ev`` (:func:`_examine`): how much of the
    row's length shows a bar, the share of the empty / no-depth / occupied slices that do, and
    the centre line of each showing slice. Called only when a verdict needs it.

    The mask is read outside every found bar's pixels and, given the ``depth`` (mm), outside
    the pixels whose depth shows something above the would-be bar's top (as :func:`_examine`
    reads it): rebar there is a nearer bar the fit did not take (a lap's second piece), not a
    bar at this level (docs/decisions/075)."""
    t, c, state, in_view = ev["_t"], ev["_c"], ev["_state"], ev["_in_view"]
    step, r, L = prm.sample_mm, row.radius, prm.step_mm
    # the mask at the axis height: its centre line is the axis's projection
    uv2, inside2 = _samples(row, p, t, c, row.height, plane, intr)
    u2 = np.clip(uv2[..., 0], 0, intr.width - 1)
    v2 = np.clip(uv2[..., 1], 0, intr.height - 1)
    covered = inside2 & (foot[v2, u2] != 0)
    if depth is not None:
        z = depth[v2, u2]
        covered |= inside2 & (z > 0) & (_height_grid(u2, v2, z, plane, intr) > _band_top(row, noise))
    free = inside2 & ~covered
    on = free & m[v2, u2]
    shows = np.zeros(len(t), bool)
    centre = np.full(len(t), np.nan)
    # a run whose end meets a found bar's pixels, or a nearer surface's, is cut by it: its
    # middle is the middle of what shows beside that bar, not of the bar
    cut = np.zeros(len(t), bool)
    edge = ev["_nd_edge"]
    n_c = len(c)
    for k in np.flatnonzero(in_view | edge):
        runs = [(a, b) for a, b in _runs(on[k]) if (b - a) * step >= r]
        if edge[k]:  # at the image's border: a run the border cuts has no centre
            runs = [(a, b) for a, b in runs if a > 0 and b < n_c and inside2[k, a - 1] and inside2[k, b]]
        if runs:
            a, b = max(runs, key=lambda ab: ab[1] - ab[0])
            shows[k] = True
            centre[k] = 0.5 * (c[a] + c[b - 1])
            cut[k] = (a > 0 and covered[k, a - 1]) or (b < n_c and covered[k, b])
    ev["mask_mm"] = float(shows[in_view].sum() * L)
    for key, sel in (
        ("mask_empty_share", state == 1),
        ("mask_nodepth_share", ev["_nd"]),
        ("mask_occupied_share", state == 2),
    ):
        if sel.sum():
            ev[key] = float(shows[sel].mean())
    ev["_shows"], ev["_centre"], ev["_cut"] = shows, centre, cut
    return ev


def _place_from_mask(row: _Row, p: float, ev: dict, sel: np.ndarray, plane: Plane, intr: Intrinsics, prm) -> tuple:
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
    sd = math.sqrt(sd_centre**2 + (row.height_sd * slope) ** 2 + sd_mask**2)
    return p + med, sd, float(t.min()), float(t.max())
