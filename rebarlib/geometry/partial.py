"""Bars seen only in part: the approximate axis of a bar found but not measured, and bars the
image border cuts lengthwise.
"""

from __future__ import annotations

import numpy as np

from .._camera import Intrinsics, project
from .._status import MEASURED, NOT_MEASURED
from .axis import BarAxis, _level_axis, _run_length
from .levels import level_heights
from .plane import Plane, from_slab_frame, to_slab_frame
from .second_look import _POSITION_STEP_MM


def _approximate_axes(bars: list, offsets: dict, h=None, camera=None) -> list:
    """A bar reported "not measured" only says that a bar is there: its fitted axis (if any) is
    the misplaced circle that made it "not measured" (slid along a sliver, tilted in height by
    a few one-sided points). Its axis in the table is replaced by an approximate one: the
    direction's plan direction, at the median axis height of the measured bars of its direction
    (its level), level along its length, and across where a circle of its radius at that height
    passes through its points (:func:`_offset_at_height`; given the points' heights ``h`` and the
    camera), else at the median of its points' offsets.
    ``offsets``: ``{group: the layer's points' offsets across that group's direction}``."""
    levels = level_heights(bars)
    noise = _layer_noise(bars)
    out = []
    for b in bars:
        if b.status == MEASURED or b.point_index is None or len(b.point_index) == 0 or b.group not in offsets:
            out.append(b)
            continue
        height = levels.get(b.group, b.axis_height_mm)
        hb = None if h is None or b.group not in levels else h[b.point_index]
        out.append(
            _level_axis(b, _placed_offset(b, offsets[b.group][b.point_index], hb, height, camera, noise), height)
        )
    return out


def _placed_offset(b: BarAxis, s, h, height_mm: float, camera, noise_mm: float) -> float:
    """Offset across for the approximate axis of bar ``b`` at ``height_mm``, from its points'
    offsets ``s`` and heights ``h``: where a circle of its radius at that height passes through
    them, facing the camera (:func:`_offset_at_height`), else their median offset (also without
    heights or camera)."""
    off = None
    if h is not None and camera is not None:
        off = _offset_at_height(
            s, h, height_mm, b.radius_mm, float(np.asarray(camera[:2]) @ b.normal2d), float(camera[2]), noise_mm
        )
    return float(np.median(s)) if off is None else off


def _layer_noise(bars: list) -> float:
    """Depth noise on the bars of one lattice: the median residual of its measured bars' cylinder
    fits (at least 0.3 mm; 1 mm when none was measured)."""
    rms = [b.rms_mm for b in bars if b.status == MEASURED and np.isfinite(b.rms_mm)]
    return max(float(np.median(rms)), 0.3) if rms else 1.0


def _offset_at_height(
    s,
    h,
    height_mm: float,
    radius_mm: float,
    cam_s: float,
    cam_h: float,
    noise_mm: float,
    *,
    step_mm: float = 0.05,
    max_points: int = 2000,
) -> float | None:
    """Offset across of the axis of a bar seen only in part (a sliver beside a bar over it, a
    strip along the image border), when its axis height is known (its level's: the bars of one
    level lie on the same supports).

    A fixed-radius circle through a short arc slides along it when its centre height is free;
    at a fixed height only the offset is left, and the arc fixes it. The points ``(s, h)``
    (offsets across, heights) lie on the circle's side that faces the camera (``cam_s``,
    ``cam_h``), which picks one of the two mirror positions. Scan of the offset (``step_mm``)
    minimising a robust (Tukey, 4.685 ``noise_mm``) sum of distances from the circle, over the
    offsets whose circle holds at least half the points (within 2.5 ``noise_mm``), most of them
    facing the camera; None where no offset does, or the best lies at the end of the scan.
    """
    s, h = np.asarray(s, float), np.asarray(h, float)
    if len(s) < 5:
        return None
    k = max(1, len(s) // max_points)
    s, h = s[::k], h[::k]
    mid = float(np.median(s))
    grid = np.arange(mid - radius_mm - 2.0, mid + radius_mm + 2.0 + step_mm / 2, step_mm)
    ds = s[None, :] - grid[:, None]
    dh = (h - height_mm)[None, :]
    res = np.hypot(ds, dh) - radius_mm
    c = 4.685 * noise_mm
    u = np.clip(np.abs(res) / c, 0.0, 1.0)
    cost = np.sum(1.0 - (1.0 - u**2) ** 3, axis=1)
    inlier = np.abs(res) < 2.5 * noise_mm
    facing = (ds * (cam_s - s)[None, :] + dh * (cam_h - h)[None, :]) > 0
    n_in = inlier.sum(axis=1)
    ok = (n_in >= 0.5 * len(s)) & ((inlier & facing).sum(axis=1) >= 0.5 * np.maximum(n_in, 1))
    if not ok.any():
        return None
    i = int(np.argmin(np.where(ok, cost, np.inf)))
    if i in (0, len(grid) - 1):
        return None
    return float(grid[i])


def flag_border_cut(
    bars: list, points, *, plane: Plane, intrinsics: Intrinsics, min_whole_fraction: float = 0.5, margin_px: float = 1.0
) -> list:
    """Bars of one lattice that the image border cuts lengthwise, fitted off their level, become
    "not measured".

    Where the border runs along a bar, the image holds only a strip of its cross-section (one
    flank, or the crest without the flanks); near the image corners the depth noise also lies
    along steep rays, across the bar as much as in height. A circle of fixed radius fitted to
    such a strip is held only across the strip and can slide along it, moving the axis by
    millimetres in height and across while its residuals look fine. A bar's cross-section at
    ``t`` is *whole* when both its flanks (axis ± radius across, at axis height) and its crest
    project inside the image (``margin_px`` from the edge). Most bars cut this way still fit
    well; what gives a slid circle away is its height: a measured bar with under
    ``min_whole_fraction`` of its points at whole cross-sections, whose axis lies more than half
    a radius off the median axis height of the other measured bars of its direction, is
    reported "not measured", with an approximate axis as for any such bar. (A bar seen whole
    that far off its level is a real finding and stays measured.)

    Parameters
    ----------
    bars : list of BarAxis of one lattice
    points : the lattice's slab-frame points that ``bars[i].point_index`` refers to
    plane : the formwork Plane (the slab frame)
    intrinsics : the camera's Intrinsics
    min_whole_fraction : a bar with less of its points at whole cross-sections is cut
    margin_px : a cross-section is whole where it projects this far inside the image

    Returns
    -------
    list of BarAxis: the bars, those cut and off their level "not measured" with an
    approximate axis
    """
    q = np.asarray(points, float)
    W, H = intrinsics.width, intrinsics.height
    camera = to_slab_frame(np.zeros((1, 3)), plane)[0]
    noise = _layer_noise(bars)
    out = []
    for b in bars:
        if b.status != MEASURED or b.point_index is None or len(b.point_index) == 0:
            out.append(b)
            continue
        t = q[b.point_index, :2] @ b.direction
        grid = np.arange(float(t.min()), float(t.max()) + _POSITION_STEP_MM, _POSITION_STEP_MM)
        ax = b.axis_points(grid)
        n3 = np.r_[b.normal2d, 0.0]
        whole = np.ones(len(grid), bool)
        for probe in (ax - b.radius_mm * n3, ax + b.radius_mm * n3, ax + np.array([0.0, 0.0, b.radius_mm])):
            cam = from_slab_frame(probe, plane)
            uv = project(cam, intrinsics)
            whole &= (
                (uv[:, 0] >= margin_px)
                & (uv[:, 0] <= W - 1 - margin_px)
                & (uv[:, 1] >= margin_px)
                & (uv[:, 1] <= H - 1 - margin_px)
                & (cam[:, 2] > 0)
            )
        pw = whole[np.clip(np.round((t - grid[0]) / _POSITION_STEP_MM).astype(int), 0, len(grid) - 1)]
        others = [o.axis_height_mm for o in bars if o.group == b.group and o.status == MEASURED and o is not b]
        level = float(np.median(others)) if len(others) >= 2 else b.axis_height_mm
        dh = b.axis_height_mm - level
        if pw.mean() >= min_whole_fraction or abs(dh) <= 0.5 * b.radius_mm:
            out.append(b)
            continue
        seen = _run_length(t[pw], cell_mm=_POSITION_STEP_MM, max_gap_mm=max(60.0, 8 * b.radius_mm))
        off = _placed_offset(b, q[b.point_index, :2] @ b.normal2d, q[b.point_index, 2], level, camera, noise)
        out.append(
            _level_axis(
                b,
                off,
                level,
                status=NOT_MEASURED,
                reason=f"the image border cuts it lengthwise ({pw.mean():.0%} of its points, "
                f"over {seen:.0f} mm, at whole cross-sections) and the circle fitted to "
                f"the strip seen sits {dh:+.1f} mm off the other bars of its direction: "
                "its axis cannot be placed",
            )
        )
    return out
