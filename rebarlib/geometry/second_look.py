"""A second look, at full resolution, at every position of a row where no bar was found."""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

from .._camera import Cloud, Intrinsics, backproject, project
from .._status import MEASURED, NOT_MEASURED
from .axis import BarAxis, _longest_run
from .layers import LAYERS, LEVELS
from .plane import Plane, from_slab_frame, to_slab_frame
from .spacing import _order_across

_POSITION_STEP_MM = 5.0  # sampling of a would-be bar's axis when checking what the camera sees there


_POSITION_T = np.arange(-3000.0, 3000.0, _POSITION_STEP_MM)  # along a would-be bar, mm


def find_missed_bars(
    bars: list,
    *,
    depth_mm,
    intrinsics: Intrinsics,
    plane: Plane,
    design_spacing: dict,
    noise_mm: float | None = None,
    min_length_mm: float = 50.0,
    min_points: int = 8,
    min_fill: float = 0.25,
    search_fraction: float = 0.25,
    step_mm: float = 0.5,
) -> tuple[list, list]:
    """A second look, at full resolution, at every position of a row where no bar was found.

    The bar search works on a thinned cloud with the pixels just behind occluding edges removed
    (``prepare_cloud``). Two kinds of bar lose most of their points there: a lower bar seen only
    as 1–2 pixel slivers beside the upper bar right above it (the slivers are edge pixels, and a
    stride of 2 keeps a quarter of them), and a bar cut by an image corner to a few centimetres.
    Each such bar sits where its row says a bar should be: between two found bars of its
    direction whose gap spans several design spacings, or beyond the outermost one.

    At each empty position (found bars' row continued at the design spacing, no found bar within
    half a spacing; a row needs one measured bar, which gives its level's height) the
    full-resolution depth pixels of a corridor ``± search_fraction`` × spacing wide are turned
    into points. A bar there is a cylinder of its level's radius with its
    axis at the level's height (median of the measured bars of its direction), so its points lie
    within ``tol`` of that cylinder: ``tol`` = max(2 mm, 3 × the sensor noise measured on the
    formwork), covering the depth noise and 1 mm storage steps. The axis offset is scanned across
    the corridor; the best offset is a bar when its cylinder points run continuously (gaps up to
    10 mm) along at least ``min_length_mm`` minus one pixel footprint, with at least
    ``min_points`` of them and at least one per 1 / ``min_fill`` pixels of its length (a bar in view,
    or a sliver of it, is a continuous stripe in the image; chance hits of flying pixels along
    an edge are sparser). Only the side of the cylinder facing the camera counts (else a strip
    of one flank fits a circle on either side of it). What else could lie on that cylinder does
    not run along it: a crossing bar is a bar width long, a tie or chair a few centimetres, and
    the mixed depths of pixels along an upper bar's edge (flying pixels) land on a given surface
    only now and then, so their hits are far apart. And a bar is solid: where more points lie
    inside the cylinder, or beyond it on rays from the camera that pass through it, than half the
    points on it, something else is there (the formwork seen where the bar would be, the edge of
    a board), and the position stays empty.

    A bar found this way is reported with status "not measured" (it is there, but a sliver does
    not place its axis to the millimetre): its axis is the scanned offset at its level's height.
    It counts as found, so the position is no longer "hidden" or "missing", and both spacings
    to its neighbours are "not measured" rather than one spacing twice the real one.

    Parameters
    ----------
    bars : list of BarAxis found so far (both lattices, ``level`` set)
    depth_mm : (H, W) the full-resolution depth image (mm; 0 = none)
    intrinsics : the camera's Intrinsics
    plane : the formwork Plane (the slab frame)
    design_spacing : ``{(layer, level): spacing_mm}``
    noise_mm : the sensor noise measured on the formwork (sets ``tol``)
    min_length_mm, min_points, min_fill : what a bar there must show (above)
    search_fraction : the corridor's half-width, in design spacings
    step_mm : the scan step of the offset across the corridor

    Returns
    -------
    ``(bars, clouds)``: the new bars and, for each, its points (camera frame, with pixels)
    """
    depth = np.asarray(depth_mm, float)
    tol = max(2.0, 3.0 * (noise_mm if noise_mm and np.isfinite(noise_mm) else 0.0))
    look = _Look(tol, step_mm, min_length_mm, min_points, min_fill)
    eye = to_slab_frame(np.zeros((1, 3)), plane)[0]  # the camera in the slab frame
    new, clouds = [], []
    for layer in LAYERS:
        for level in LEVELS:
            grp = _order_across([b for b in bars if b.layer == layer and b.level == level])
            s = design_spacing.get((layer, level))
            measured = [b for b in grp if b.status == MEASURED]
            if not measured or not s or not np.isfinite(s):
                continue
            ref = measured[0]
            r = float(np.median([b.radius_mm for b in measured]))
            h_axis = float(np.median([b.axis_height_mm for b in measured]))
            offs = np.array([float(b.plan_point(b.t_mid) @ ref.normal2d) for b in grp])
            half = search_fraction * s
            for off, inside in _empty_positions(ref, offs, s, h_axis, r, plane, intrinsics):
                if np.min(np.abs(offs - off)) < 0.5 * s:
                    continue
                found = _look_at_position(ref, off, inside, half, h_axis, r, depth, intrinsics, plane, eye, look)
                if found is None:
                    continue
                c, t0, t1, cloud = found
                new.append(_bar_seen_at(ref, layer, level, c, t0, t1, h_axis, r, cloud))
                clouds.append(cloud)
                offs = np.sort(np.append(offs, c))
    return new, clouds


def _empty_positions(ref: BarAxis, offs, s, h_axis, r, plane, intrinsics) -> list:
    """The positions of a row (offsets ``offs`` across ``ref``'s direction, design spacing
    ``s``) where a bar may be missing: between two found bars a gap of several spacings holds,
    and beyond the outermost ones as long as they are in view; each with the samples along it
    where its surface is in the image (:func:`_surface_in_image`)."""
    cand = []
    for a_off, b_off in zip(offs[:-1], offs[1:]):
        k = int(round((b_off - a_off) / s)) - 1
        cand += [
            (o, _surface_in_image(ref, o, h_axis, r, plane, intrinsics))
            for o in (a_off + j * (b_off - a_off) / (k + 1) for j in range(1, k + 1))
        ]
    for start, sign in ((offs[0], -1), (offs[-1], 1)):
        for j in range(1, 200):
            off = start + sign * j * s
            inside = _surface_in_image(ref, off, h_axis, r, plane, intrinsics)
            if not inside.any():
                break
            cand.append((off, inside))
    return cand


def _bar_seen_at(ref: BarAxis, layer, level, c, t0, t1, h_axis, r, cloud) -> BarAxis:
    """The bar the second look found at offset ``c``: "not measured", its axis at its level's
    height."""
    return BarAxis(
        layer,
        ref.direction,
        c,
        0.0,
        h_axis,
        0.0,
        t0,
        t1,
        r,
        len(cloud),
        float("nan"),
        None,
        ref.group,
        level=level,
        status=NOT_MEASURED,
        reason=(
            f"seen only at full resolution, {len(cloud)} depth pixels over "
            f"{t1 - t0:.0f} mm (slivers beside a bar above it, or cut by the "
            "image border): it is there, but its axis cannot be placed to the "
            "millimetre"
        ),
    )


class _Look(NamedTuple):
    """How :func:`find_missed_bars` looks at an empty position: the cylinder's tolerance, the
    scan step of its offset, and what a bar there must show (a run of ``min_length_mm``, at
    least ``min_points`` points, one per 1 / ``min_fill`` pixels of its length)."""

    tol: float
    step_mm: float
    min_length_mm: float
    min_points: int
    min_fill: float


def _look_at_position(
    ref: BarAxis,
    off: float,
    inside,
    half: float,
    h_axis: float,
    r: float,
    depth,
    intr: Intrinsics,
    plane: Plane,
    eye,
    look: _Look,
):
    """Full-resolution points of the corridor ``off ± half`` on the cylinder of radius ``r`` at
    height ``h_axis``: ``(offset, t0, t1, Cloud)`` of the best bar there, or None. ``inside``:
    the samples of ``_POSITION_T`` where the position's surface is in the image; ``eye``: the
    camera in the slab frame."""
    if inside.sum() < 2:
        return None
    found = _corridor_points(ref, off, inside, half, h_axis, r, depth, intr, plane, look.min_points)
    if found is None:
        return None
    o, t, hz, pix, pts, o_all, t_all, h_all = found
    # the footprint of one pixel on the bar: the bars' gaps are judged against it
    pitch = float(np.median(pts[:, 2])) / (0.5 * (intr.fx + intr.fy))
    # the camera sees the side of a cylinder that faces it: a point on the far flank of a circle
    # is not on it (without this, a strip of one flank fits a circle on either side of it)
    eye_o, eye_h = float(eye[:2] @ ref.normal2d), float(eye[2])

    def on_cylinder(c):
        ro, rh = o - c, hz - h_axis
        return (np.abs(np.hypot(ro, rh) - r) < look.tol) & (ro * (eye_o - o) + rh * (eye_h - hz) > 0)

    c = _best_offset(o, t, hz, off, half, h_axis, r, pitch, on_cylinder, look)
    if c is None:
        return None
    on = on_cylinder(c)
    t0, t1 = _longest_run(t[on], cell_mm=5.0, max_gap_mm=10.0, by="length")
    on &= (t >= t0) & (t <= t1)
    along = (t_all >= t0) & (t_all <= t1)
    if _seen_through(c, o_all[along], h_all[along], h_axis, r, eye_o, eye_h, look.tol) > 0.5 * on.sum():
        return None
    # a bar in view is a continuous stripe in the image, a sliver of it at least a pixel wide:
    # along its run, at least ``min_fill`` of the pixels' length must hold one of its points.
    # Chance hits of mixed depths (flying pixels along an edge) are sparser than that
    if on.sum() < look.min_fill * (t1 - t0) / pitch:
        return None
    return c, t0, t1, Cloud(pts[on], pix[on])


def _corridor_points(ref: BarAxis, off, inside, half, h_axis, r, depth, intr, plane, min_points):
    """The depth pixels of the corridor ``off ± half`` (from the formwork to a little over a
    bar's top) as points: ``(o, t, h, pixels, camera points)`` of those at a bar's height and
    ``(o, t, h)`` of all in the corridor (offsets across, positions along, heights); None with
    too few."""
    import cv2

    H, W = depth.shape
    ta, tb = _POSITION_T[inside].min() - 2 * half, _POSITION_T[inside].max() + 2 * half
    # the corridor's footprint in the image, from the formwork to a little over a bar's top
    corners = []
    for t in (ta, tb):
        for o in (off - half - r, off + half + r):
            for hh in (0.0, h_axis + 1.5 * r):
                corners.append(np.r_[t * ref.direction + o * ref.normal2d, hh])
    cc = from_slab_frame(np.array(corners), plane)
    if np.any(cc[:, 2] <= 0):
        return None
    pc = project(cc, intr)
    hull = cv2.convexHull(np.round(np.clip(pc, -4 * W, 4 * W)).astype(np.int32))
    # fill the hull within its bounding box only (a corridor is a thin slice of the image)
    x0, y0, bw, bh = cv2.boundingRect(hull)
    u0, v0, u1, v1 = max(x0, 0), max(y0, 0), min(x0 + bw, W), min(y0 + bh, H)
    if u1 <= u0 or v1 <= v0:
        return None
    mask = np.zeros((v1 - v0, u1 - u0), np.uint8)
    cv2.fillConvexPoly(mask, hull - np.array([u0, v0], np.int32), 1)
    v, u = np.nonzero((mask > 0) & (depth[v0:v1, u0:u1] > 0))
    if len(u) < min_points:
        return None
    u, v = u + u0, v + v0
    pix = np.column_stack((u, v)).astype(np.int32)
    pts = backproject(pix, depth[v, u], intr)
    q = to_slab_frame(pts, plane)
    o = q[:, :2] @ ref.normal2d
    t = q[:, :2] @ ref.direction
    corridor = (np.abs(o - off) < half + r) & (q[:, 2] < h_axis + 1.5 * r)
    o_all, t_all, h_all = o[corridor], t[corridor], q[corridor, 2]
    band = corridor & (q[:, 2] > h_axis - 0.5 * r)
    if band.sum() < min_points:
        return None
    return o[band], t[band], q[band, 2], pix[band], pts[band], o_all, t_all, h_all


def _best_offset(o, t, hz, off, half, h_axis, r, pitch, on_cylinder, look: _Look):
    """The offset across the corridor whose cylinder explains the most points along a long
    run (the middle of the offsets that do about as well), or None where none runs
    ``min_length_mm`` (less a pixel) with ``min_points``."""
    offsets = np.arange(off - half, off + half + look.step_mm, look.step_mm)
    # how many points each offset's cylinder holds, all offsets at once (the facing test is
    # left to the loop): only offsets that can reach min_points are looked at further
    near = np.zeros(len(offsets), int)
    for k in range(0, len(offsets), 64):
        c_ = offsets[k : k + 64, None]
        near[k : k + 64] = (np.abs(np.hypot(o[None, :] - c_, (hz - h_axis)[None, :]) - r) < look.tol).sum(axis=1)
    scores = []  # (offset, run start, run end, points on the cylinder along the run)
    for c in offsets[near >= look.min_points]:
        on = on_cylinder(c)
        if on.sum() < look.min_points:
            continue
        t0, t1 = _longest_run(t[on], cell_mm=5.0, max_gap_mm=10.0, by="length")
        scores.append((float(c), t0, t1, int(np.sum(on & (t >= t0) & (t <= t1)))))
    ok = [x for x in scores if x[2] - x[1] >= look.min_length_mm - pitch and x[3] >= look.min_points]
    if not ok:
        return None
    # the offsets that explain the most points along a long run; several neighbouring offsets do
    # about as well (the tolerance band is wider than the scan step): take their middle
    longest = max(x[2] - x[1] for x in ok)
    ok = [x for x in ok if x[2] - x[1] >= 0.9 * longest]
    most = max(x[3] for x in ok)
    return float(np.median([x[0] for x in ok if x[3] >= 0.95 * most]))


def _seen_through(c, o, h, h_axis, r, eye_o, eye_h, tol) -> int:
    """How many points ``(o, h)`` (offsets across, heights) could not be seen if a bar of radius
    ``r`` lay at offset ``c``: inside it (by more than ``tol``), or beyond it on a ray from the
    camera that passes inside it.

    A bar is solid: many such points (the formwork seen where the bar would be, the top of a
    board lower than a bar) mean there is no bar there, whatever lies on its flanks; a bar's own
    slivers never give them. In the cross-section plane (the cylinder runs along t): distance
    from the axis to the segment camera -> point."""
    eo, eh = o - eye_o, h - eye_h
    wo, wh = c - eye_o, h_axis - eye_h
    s_ = np.clip((wo * eo + wh * eh) / np.maximum(eo * eo + eh * eh, 1e-9), 0.0, 1.0)
    closest = np.hypot(wo - s_ * eo, wh - s_ * eh)
    dist = np.hypot(o - c, h - h_axis)
    return int(np.sum(((closest < r - tol) & (dist > r + tol)) | (dist < r - tol)))


def _position_axis(ref: BarAxis, off: float, height_mm: float, plane: Plane, intr: Intrinsics):
    """Samples every 5 mm of a line parallel to ``ref`` at plan offset ``off`` and ``height_mm``:
    (camera-frame points (N, 3), their pixels (N, 2))."""
    t = _POSITION_T
    plan = t[:, None] * ref.direction + off * ref.normal2d
    cam = from_slab_frame(np.c_[plan, np.full(len(t), height_mm)], plane)
    return cam, project(cam, intr)


def _surface_in_image(
    ref: BarAxis, off: float, h_axis: float, radius: float, plane: Plane, intr: Intrinsics
) -> np.ndarray:
    """(len(_POSITION_T),) bool: where along it a would-be bar's surface (either flank or its
    crest) projects into the image."""
    inside = np.zeros(len(_POSITION_T), bool)
    for do, dh in ((-radius, 0.0), (radius, 0.0), (0.0, radius)):
        cam, uv = _position_axis(ref, off + do, h_axis + dh, plane, intr)
        inside |= _in_image(uv, cam, intr)
    return inside


def _in_image(uv, cam, intr: Intrinsics) -> np.ndarray:
    return (uv[:, 0] >= 0) & (uv[:, 0] < intr.width) & (uv[:, 1] >= 0) & (uv[:, 1] < intr.height) & (cam[:, 2] > 0)
