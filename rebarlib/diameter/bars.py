"""The bars as the diameter stage reads them: the bars table checked, each bar's plane γ,
design size and expected width, and its footprint in the image (where it hides the bars under
it).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._camera import Intrinsics, project
from .._checks import RebarInputError
from .barsizes import observed_width_mm
from .params import BAR_COLUMNS
from .plane import BarPlane, imaginary_plane


def bars_from_truth(truth: dict, *, visible_only: bool = True):
    """Bars table (:data:`BAR_COLUMNS`) from a synthetic capture's ground truth.

    The axis end points are the true axis over the visible extent (``visible_start_mm`` /
    ``visible_end_mm``), so later stages can be developed and taught on exact axes.

    Parameters
    ----------
    truth : a synthetic capture's ``capture.truth``
    visible_only : leave out the bars the renderer flags as not visible

    Returns
    -------
    pandas.DataFrame with :data:`BAR_COLUMNS` (``bar_id`` the true bar's id)

    Examples
    --------
    >>> truth = {"bars": [{"id": 3, "layer": "lower", "level": "top", "visible": True,
    ...          "visible_start_mm": [0, 0, 500], "visible_end_mm": [0, 300, 500]}]}
    >>> bars_from_truth(truth)[["bar_id", "layer", "end_y_mm"]].values.tolist()
    [[3, 'lower', 300.0]]
    """
    import pandas as pd

    if not isinstance(truth, dict) or "bars" not in truth:
        raise RebarInputError("truth: expected a synthetic capture's truth dict with a 'bars' list")
    rows = []
    for b in truth["bars"]:
        if visible_only and not b.get("visible", True):
            continue
        s, e = b["visible_start_mm"], b["visible_end_mm"]
        rows.append(
            {
                "bar_id": int(b["id"]),
                "layer": b["layer"],
                "level": b["level"],
                "start_x_mm": float(s[0]),
                "start_y_mm": float(s[1]),
                "start_z_mm": float(s[2]),
                "end_x_mm": float(e[0]),
                "end_y_mm": float(e[1]),
                "end_z_mm": float(e[2]),
            }
        )
    return pd.DataFrame(rows, columns=list(BAR_COLUMNS))


def _check_inputs(capture, bars, mask, method):
    if method not in ("refined", "paper"):
        raise RebarInputError(f"method: expected 'refined' or 'paper', got {method!r}")
    missing = [c for c in BAR_COLUMNS if c not in getattr(bars, "columns", ())]
    if missing:
        raise RebarInputError(f"bars: expected a DataFrame with columns {list(BAR_COLUMNS)}; missing {missing}")
    m = np.asarray(mask)
    h, w = capture.intrinsics.height, capture.intrinsics.width
    if m.shape != (h, w):
        raise RebarInputError(f"mask: expected shape ({h}, {w}) like the capture, got {m.shape}")
    if m.dtype == bool or np.issubdtype(m.dtype, np.integer):  # integer labels: any non-zero is rebar
        m = m.astype(bool)
        return m, m.astype(np.float32)
    if not np.issubdtype(m.dtype, np.floating):
        raise RebarInputError(f"mask: expected bool, integer or a float rebar probability in 0..1, got dtype {m.dtype}")
    soft = m.astype(np.float32)
    if not np.isfinite(soft).all():
        raise RebarInputError(
            f"mask: a float mask must be a rebar probability in 0..1; "
            f"{int((~np.isfinite(soft)).sum())} values are NaN or infinite"
        )
    if soft.min() < 0 or soft.max() > 1:
        raise RebarInputError(
            f"mask: a float mask must be a rebar probability in 0..1, got values "
            f"{float(soft.min()):.3g}..{float(soft.max()):.3g}"
        )
    return soft >= 0.5, soft


@dataclass
class _Bar:
    bar_id: int
    layer: str
    level: str
    p0: np.ndarray
    p1: np.ndarray
    plane: BarPlane
    length_mm: float
    design_mm: float
    expected_mm: float  # observed width expected from the design size (window sizing)
    axis_radius_mm: float = math.nan  # radius the axis was placed with, if one was assumed
    axis_ok: bool = True  # the axis was measured (not only located): one-sided widths may use it
    stack_mm: float = math.nan  # its top above the tops of the bars it rests on (geometry.stack_heights)
    top_mm: float = math.nan  # its top above the formwork (geometry.top_heights)


def _optional(row, column: str, default: float = math.nan) -> float:
    """A bars-table row's value of an optional column as a float: ``default`` where the table has
    no such column, NaN where the value is None."""
    v = getattr(row, column, default)
    return float(v) if v is not None else math.nan


def _prepare(bars, design, system, deformed, default_expected_mm):
    out = []
    for r in bars.itertuples(index=False):
        p0 = np.array([r.start_x_mm, r.start_y_mm, r.start_z_mm], float)
        p1 = np.array([r.end_x_mm, r.end_y_mm, r.end_z_mm], float)
        design_mm = math.nan
        if design is not None and r.layer in ("lower", "upper") and r.level in ("bottom", "top"):
            design_mm = float(design.lattice(r.layer).level(r.level).diameter_mm)
        expected = (
            observed_width_mm(design_mm, system=system, deformed=deformed)
            if math.isfinite(design_mm)
            else default_expected_mm
        )
        plane = imaginary_plane(p0, p1)
        # the radius the axis was placed with: ours, or the geometry stage's fixed-radius fit
        assumed = _optional(r, "axis_radius_mm", _optional(r, "radius_mm"))
        # a bar the geometry stage only located (status "not measured", e.g. its second look)
        # has an axis good for finding its pixels, not for measuring from one edge to it
        axis_ok = str(getattr(r, "status", "measured")) == "measured"
        out.append(
            _Bar(
                int(r.bar_id),
                str(r.layer),
                str(r.level),
                p0,
                p1,
                plane,
                float(np.linalg.norm(p1 - p0)),
                design_mm,
                expected,
                assumed,
                axis_ok,
                _optional(r, "stack_mm"),
                _optional(r, "top_mm"),
            )
        )
    return out


def _stations(bar: _Bar, intr: Intrinsics, step_px: float, max_n: int) -> np.ndarray:
    """Points on the axis, evenly spread over its extent, about ``step_px`` apart in the image."""
    uv = project(np.vstack((bar.p0, bar.p1)), intr)
    length_px = float(np.linalg.norm(uv[1] - uv[0]))
    n = int(np.clip(length_px / step_px, 1, max_n))
    s = (np.arange(n) + 0.5) / n * bar.length_mm
    return bar.p0 + s[:, None] * bar.plane.direction


@dataclass
class _Footprints:
    """Where each bar is expected in the image: |across| <= half_mm in its γ, along in range."""

    normal: np.ndarray  # (B, 3)
    offset: np.ndarray  # (B,)
    p0: np.ndarray  # (B, 3)
    along: np.ndarray  # (B, 3)
    across: np.ndarray  # (B, 3)
    s_lo: np.ndarray
    s_hi: np.ndarray
    half_mm: np.ndarray
    bbox: np.ndarray  # (B, 4) u0, v0, u1, v1 of the footprint in the image


def _footprints(prepared, intr, margin_rel=0.2, margin_px=1.5):
    B = len(prepared)
    fp = _Footprints(
        np.zeros((B, 3)),
        np.zeros(B),
        np.zeros((B, 3)),
        np.zeros((B, 3)),
        np.zeros((B, 3)),
        np.zeros(B),
        np.zeros(B),
        np.zeros(B),
        np.zeros((B, 4)),
    )
    for i, b in enumerate(prepared):
        z = max(min(b.p0[2], b.p1[2]), 1.0)
        # the expected width with room for a bar one size larger and for mask edges a pixel off
        half = b.expected_mm / 2 * (1 + margin_rel) + margin_px * z / intr.fx
        # bars go on beyond the extent where they were seen (hidden parts, ties at the ends)
        ext = b.expected_mm
        fp.normal[i], fp.offset[i], fp.p0[i] = b.plane.normal, b.plane.offset_mm, b.p0
        fp.along[i], fp.across[i] = b.plane.direction, b.plane.across
        fp.s_lo[i], fp.s_hi[i], fp.half_mm[i] = -ext, b.length_mm + ext, half
        corners = np.array(
            [b.p0 - ext * b.plane.direction + sg * half * b.plane.across for sg in (-1, 1)]
            + [b.p1 + ext * b.plane.direction + sg * half * b.plane.across for sg in (-1, 1)]
        )
        corners = corners[corners[:, 2] > 1.0]
        uv = project(corners, intr) if len(corners) else np.zeros((1, 2))
        fp.bbox[i] = [uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()]
    return fp


def _hits_footprints(points_mm, fp: _Footprints, which: np.ndarray):
    """For camera-frame points, whether the ray through each meets the footprint of each bar in
    ``which``, and whether that bar is nearer along the ray than the point. Returns (N, C) bools."""
    d = points_mm / points_mm[:, 2:3]  # rays with z = 1, so the ray parameter is the depth
    n = fp.normal[which]
    den = d @ n.T
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = fp.offset[which][None, :] / den
    x = lam[:, :, None] * d[:, None, :] - fp.p0[which][None, :, :]
    s = np.einsum("nck,ck->nc", x, fp.along[which])
    t = np.einsum("nck,ck->nc", x, fp.across[which])
    inside = (lam > 0) & (np.abs(t) <= fp.half_mm[which]) & (s >= fp.s_lo[which]) & (s <= fp.s_hi[which])
    nearer = inside & (lam < points_mm[:, 2:3])
    return inside, nearer


def _candidates(i, fp: _Footprints, window_bbox):
    u0, v0, u1, v1 = window_bbox
    b = fp.bbox
    hit = (b[:, 0] <= u1) & (b[:, 2] >= u0) & (b[:, 1] <= v1) & (b[:, 3] >= v0)
    hit[i] = False
    return np.flatnonzero(hit)


def _remap(img, u, v):
    import cv2

    return cv2.remap(
        img, u.astype(np.float32), v.astype(np.float32), cv2.INTER_LINEAR, borderMode=cv2.BORDER_CONSTANT, borderValue=0
    )
