"""Nominal bar diameter from the rebar mask, made metric with each bar's axis (method.md Stage 3).

Each bar's axis (from the point cloud) defines the imaginary plane γ: it contains the axis and
faces the camera (normal OA, A the foot of the perpendicular from the camera centre O to the
axis). A pixel on the bar's silhouette edge is back-projected as a ray and met with γ, so widths
come out in millimetres without using the (often missing or wrong) depth at the bar's edges.

Two methods:

- ``"paper"``: the paper's procedure (§3.3): parallelogram regions at detect-points, boundary
  pixels, D = min distance between the two sides, a vote in ±1 mm bins around the nominal sizes.
- ``"refined"`` (default): many cross-sections per bar; both edges found per section at sub-pixel
  precision on the mask profile; sections at crossings, under a nearer bar, at the image border
  or in deep shadow are dropped; the median width is snapped to the observed (rib-envelope)
  width of a standard size with a confidence; weak evidence gives "not measured". How far the
  colour edges and the mask can be trusted is learnt from the capture's own bars of one design
  size (their true widths are equal): the colour edges' shading offset, each width's spread
  between bars.
"""

from __future__ import annotations

import math
from collections import Counter, defaultdict
from dataclasses import dataclass

import numpy as np

from ._barsizes import (_nearest, bar_system, bracketing_sizes, observed_width_mm, rib_height_mm,
                        rib_pitch_mm, size_half_gaps_mm, snap_diameter)
from ._camera import Intrinsics, backproject, project, ray_directions
from ._checks import RebarInputError

__all__ = ["BarPlane", "imaginary_plane", "intersect_rays_plane", "cross_section_direction",
           "diameter_region", "pixels_in_region", "boundary_pixels", "bars_from_truth",
           "measure_diameters", "BAR_COLUMNS", "DIAMETER_COLUMNS"]

#: Columns the bars table must have (camera frame axis end points, mm).
BAR_COLUMNS = ("bar_id", "layer", "level", "start_x_mm", "start_y_mm", "start_z_mm",
               "end_x_mm", "end_y_mm", "end_z_mm")
#: Columns of the table :func:`measure_diameters` returns (one row per bar, merge on bar_id).
DIAMETER_COLUMNS = ("bar_id", "width_median_mm", "width_spread_mm", "n_sections", "nominal_mm",
                    "confidence", "diameter_status", "diameter_reason", "design_diameter_mm",
                    "matches_design", "hidden", "occluded_fraction", "one_sided_share",
                    "cloud_width_mm", "width_source", "width_used_mm", "width_sigma_mm",
                    "circle_width_mm", "circle_sigma_mm",
                    "crest_width_mm", "core_width_mm", "rib_pitch_mm", "ribs_resolved")

MEASURED, NOT_MEASURED, HIDDEN = "measured", "not measured", "hidden"


# --------------------------------------------------------------------------------------------
# Geometry helpers


@dataclass(frozen=True)
class BarPlane:
    """The imaginary plane γ of one bar: ``normal · x = offset_mm`` (camera frame, mm).

    Attributes
    ----------
    normal : (3,) float, unit vector from the camera centre O towards A
    offset_mm : float, |OA|, the distance from O to the axis
    foot_mm : (3,) float, A, the foot of the perpendicular from O to the axis
    direction : (3,) float, unit axis direction v
    across : (3,) float, unit vector in γ perpendicular to the axis (the cross-section direction)
    """

    normal: np.ndarray
    offset_mm: float
    foot_mm: np.ndarray
    direction: np.ndarray
    across: np.ndarray

    def coordinates(self, points) -> tuple[np.ndarray, np.ndarray]:
        """(along, across) coordinates in mm of points in γ, measured from A."""
        d = np.asarray(points, float).reshape(-1, 3) - self.foot_mm
        return d @ self.direction, d @ self.across


def imaginary_plane(start_mm, end_mm) -> BarPlane:
    """Plane γ through the bar axis ``start_mm``-``end_mm`` whose normal is OA (method.md 3.3).

    Parameters
    ----------
    start_mm, end_mm : (3,) float, two points of the axis in the camera frame (mm)

    Returns
    -------
    BarPlane with ``normal · x = offset_mm``, i.e. x_A·x + y_A·y + z_A·z − |A|² = 0 scaled by 1/|A|.

    Examples
    --------
    >>> g = imaginary_plane([-100.0, 50.0, 500.0], [100.0, 50.0, 500.0])
    >>> g.foot_mm.tolist(), round(g.offset_mm, 3)
    ([0.0, 50.0, 500.0], 502.494)
    >>> bool(abs(g.normal @ [1.0, 0.0, 0.0]) < 1e-12)  # the axis lies in γ
    True
    """
    p0 = np.asarray(start_mm, float).reshape(3)
    p1 = np.asarray(end_mm, float).reshape(3)
    if not (np.all(np.isfinite(p0)) and np.all(np.isfinite(p1))):
        raise RebarInputError(f"bar axis: end points must be finite, got {p0.tolist()} and {p1.tolist()}")
    length = np.linalg.norm(p1 - p0)
    if length < 1e-9:
        raise RebarInputError(f"bar axis: start and end points coincide at {p0.tolist()}")
    v = (p1 - p0) / length
    a = p0 - (p0 @ v) * v
    dist = float(np.linalg.norm(a))
    if dist < 1e-6:
        raise RebarInputError("bar axis: passes through the camera centre, plane γ is undefined")
    n = a / dist
    w = np.cross(v, n)
    return BarPlane(n, dist, a, v, w / np.linalg.norm(w))


def intersect_rays_plane(pixels, intrinsics: Intrinsics, plane: BarPlane) -> np.ndarray:
    """Points where the rays through ``pixels`` meet ``plane`` (camera frame, mm).

    Parameters
    ----------
    pixels : (N, 2) float, (u, v) px
    intrinsics : Intrinsics
    plane : BarPlane (or anything with ``normal`` and ``offset_mm``)

    Returns
    -------
    (N, 3) float, mm; NaN for rays parallel to the plane or meeting it behind the camera.

    Examples
    --------
    >>> from rebarlib import Intrinsics
    >>> K = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)
    >>> g = imaginary_plane([-100.0, 0.0, 500.0], [100.0, 0.0, 500.0])
    >>> intersect_rays_plane([[420.0, 240.0]], K, g).tolist()
    [[100.0, 0.0, 500.0]]
    """
    d = ray_directions(intrinsics, np.asarray(pixels, float).reshape(-1, 2))
    den = d @ plane.normal
    with np.errstate(divide="ignore", invalid="ignore"):
        lam = plane.offset_mm / den
    lam = np.where((np.abs(den) > 1e-12) & (lam > 0), lam, np.nan)
    return d * lam[:, None]


def cross_section_direction(point_mm, direction, intrinsics: Intrinsics) -> tuple[np.ndarray, np.ndarray]:
    """Image directions of the cross-section and of the axis at the axis point ``point_mm``.

    The cross-section direction is that of p → q with q = p + (p − O) × v (method.md 3.3, step 4);
    the axis direction that of p → p + v.

    Returns
    -------
    across_px, along_px : (2,) float, unit vectors in the image (u, v)

    Examples
    --------
    >>> from rebarlib import Intrinsics
    >>> K = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)
    >>> across, along = cross_section_direction([0.0, 0.0, 500.0], [1.0, 0.0, 0.0], K)
    >>> np.abs(across).round(6).tolist(), along.round(6).tolist()
    ([0.0, 1.0], [1.0, 0.0])
    """
    p = np.asarray(point_mm, float).reshape(3)
    v = np.asarray(direction, float).reshape(3)
    v = v / np.linalg.norm(v)
    c = np.cross(p, v)
    # a short step keeps q in front of the camera; only the image direction matters
    step = 0.01 * np.linalg.norm(p)
    uv = project(np.vstack((p, p + c / np.linalg.norm(c) * step, p + v * step)), intrinsics)
    across = uv[1] - uv[0]
    along = uv[2] - uv[0]
    return across / np.linalg.norm(across), along / np.linalg.norm(along)


def diameter_region(center_px, across_px, along_px, *, long_px: float, short_px: float = 6.0) -> np.ndarray:
    """Corners of the parallelogram diameter-calculation region (method.md 3.3, step 5).

    Centred on ``center_px``; two sides of length ``long_px`` run along the cross-section
    direction ``across_px``, the other two (``short_px``) along the projected axis ``along_px``.

    Returns
    -------
    (4, 2) float, corners (u, v) in order around the parallelogram

    Examples
    --------
    >>> diameter_region([10.0, 20.0], [0.0, 1.0], [1.0, 0.0], long_px=8, short_px=6).tolist()
    [[7.0, 16.0], [13.0, 16.0], [13.0, 24.0], [7.0, 24.0]]
    """
    c = np.asarray(center_px, float).reshape(2)
    a = np.asarray(across_px, float).reshape(2)
    b = np.asarray(along_px, float).reshape(2)
    a, b = a / np.linalg.norm(a), b / np.linalg.norm(b)
    ha, hb = a * long_px / 2, b * short_px / 2
    return np.array([c - ha - hb, c - ha + hb, c + ha + hb, c + ha - hb])


def pixels_in_region(corners, shape) -> np.ndarray:
    """Integer pixels (u, v) whose centres lie inside the parallelogram ``corners`` (from
    :func:`diameter_region`), clipped to an image of ``shape`` (H, W).

    Examples
    --------
    >>> corners = diameter_region([10.0, 20.0], [0.0, 1.0], [1.0, 0.0], long_px=4, short_px=2)
    >>> pixels_in_region(corners, (40, 40)).tolist()  # doctest: +NORMALIZE_WHITESPACE
    [[9, 18], [10, 18], [11, 18], [9, 19], [10, 19], [11, 19], [9, 20], [10, 20], [11, 20],
     [9, 21], [10, 21], [11, 21], [9, 22], [10, 22], [11, 22]]
    """
    q = np.asarray(corners, float).reshape(4, 2)
    c = q.mean(axis=0)
    e1, e2 = q[1] - q[0], q[3] - q[0]  # along-axis side, cross-section side
    lo = np.floor(q.min(axis=0)).astype(int)
    hi = np.ceil(q.max(axis=0)).astype(int)
    lo = np.maximum(lo, 0)
    hi = np.minimum(hi, [shape[1] - 1, shape[0] - 1])
    if np.any(hi < lo):
        return np.zeros((0, 2), int)
    vv, uu = np.mgrid[lo[1]:hi[1] + 1, lo[0]:hi[0] + 1]
    d = np.column_stack((uu.ravel(), vv.ravel())) - c
    coef = np.linalg.solve(np.column_stack((e1, e2)), d.T).T  # in units of the side lengths
    inside = np.all(np.abs(coef) <= 0.5 + 1e-9, axis=1)
    return np.column_stack((uu.ravel(), vv.ravel()))[inside]


def boundary_pixels(mask) -> np.ndarray:
    """Rebar pixels with at least one background 4-neighbour (image border counts as background).

    Examples
    --------
    >>> m = np.zeros((5, 5), bool); m[1:4, 1:4] = True
    >>> int(boundary_pixels(m).sum()), bool(boundary_pixels(m)[2, 2])
    (8, False)
    """
    m = np.asarray(mask, bool)
    p = np.pad(m, 1)
    inner = p[:-2, 1:-1] & p[2:, 1:-1] & p[1:-1, :-2] & p[1:-1, 2:]
    return m & ~inner


# --------------------------------------------------------------------------------------------
# Inputs


def bars_from_truth(truth: dict, *, visible_only: bool = True):
    """Bars table (:data:`BAR_COLUMNS`) from a synthetic capture's ground truth.

    The axis end points are the true axis over the visible extent (``visible_start_mm`` /
    ``visible_end_mm``), so later stages can be developed and taught on exact axes.

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
        rows.append({"bar_id": int(b["id"]), "layer": b["layer"], "level": b["level"],
                     "start_x_mm": float(s[0]), "start_y_mm": float(s[1]), "start_z_mm": float(s[2]),
                     "end_x_mm": float(e[0]), "end_y_mm": float(e[1]), "end_z_mm": float(e[2])})
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
        raise RebarInputError(f"mask: a float mask must be a rebar probability in 0..1; "
                              f"{int((~np.isfinite(soft)).sum())} values are NaN or infinite")
    if soft.min() < 0 or soft.max() > 1:
        raise RebarInputError(f"mask: a float mask must be a rebar probability in 0..1, got values "
                              f"{float(soft.min()):.3g}..{float(soft.max()):.3g}")
    return soft >= 0.5, soft


# --------------------------------------------------------------------------------------------
# Per-bar geometry shared by both methods


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
        expected = (observed_width_mm(design_mm, system=system, deformed=deformed)
                    if math.isfinite(design_mm) else default_expected_mm)
        plane = imaginary_plane(p0, p1)
        # the radius the axis was placed with: ours, or the geometry stage's fixed-radius fit
        assumed = _optional(r, "axis_radius_mm", _optional(r, "radius_mm"))
        # a bar the geometry stage only located (status "not measured", e.g. its second look)
        # has an axis good for finding its pixels, not for measuring from one edge to it
        axis_ok = str(getattr(r, "status", "measured")) == "measured"
        out.append(_Bar(int(r.bar_id), str(r.layer), str(r.level), p0, p1, plane,
                        float(np.linalg.norm(p1 - p0)), design_mm, expected, assumed, axis_ok,
                        _optional(r, "stack_mm"), _optional(r, "top_mm")))
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
    fp = _Footprints(np.zeros((B, 3)), np.zeros(B), np.zeros((B, 3)), np.zeros((B, 3)), np.zeros((B, 3)),
                     np.zeros(B), np.zeros(B), np.zeros(B), np.zeros((B, 4)))
    for i, b in enumerate(prepared):
        z = max(min(b.p0[2], b.p1[2]), 1.0)
        # the expected width with room for a bar one size larger and for mask edges a pixel off
        half = b.expected_mm / 2 * (1 + margin_rel) + margin_px * z / intr.fx
        # bars go on beyond the extent where they were seen (hidden parts, ties at the ends)
        ext = b.expected_mm
        fp.normal[i], fp.offset[i], fp.p0[i] = b.plane.normal, b.plane.offset_mm, b.p0
        fp.along[i], fp.across[i] = b.plane.direction, b.plane.across
        fp.s_lo[i], fp.s_hi[i], fp.half_mm[i] = -ext, b.length_mm + ext, half
        corners = np.array([b.p0 - ext * b.plane.direction + sg * half * b.plane.across for sg in (-1, 1)]
                           + [b.p1 + ext * b.plane.direction + sg * half * b.plane.across for sg in (-1, 1)])
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


def _deep_end(end, end2, deep, sample_px, min_px) -> np.ndarray:
    """Per section (rows of the (M, K) profiles), whether the mask run's end ``end`` (an index
    into the profile) went on past the depth step at ``end2`` (the same end with the deep samples
    left out) over at least ``min_px`` pixels (``sample_px``: the profile's step in pixels, per
    section) whose depth mostly lies well behind the bar (``deep``: valid depth, not a hole): a
    surface there, not a lone flying pixel."""
    # the samples between the two ends, the run's own end (not a bar sample) left out
    lo, hi = np.minimum(end, end2), np.maximum(end, end2)
    idx = np.arange(deep.shape[1])[None, :]
    part = (idx >= lo[:, None]) & (idx <= hi[:, None]) & (idx != end[:, None])
    n = hi - lo
    return (n * sample_px >= min_px) & (2 * (part & deep).sum(axis=1) >= np.maximum(n, 1))


def _holed_side(t, left, right, left2, right2, rows, sample_px, prm) -> str:
    """"lo" or "hi" where the bar's mask runs (ends ``left``, ``right``: indices into the profile
    ``t``; ``left2``, ``right2``: the same ends with the samples behind the bar or without depth
    left out) end, at that side only, in a strip behind the bar or without depth at least
    ``prm.sliver_min_px`` wide and half that wider than at the other end (medians over the
    sections ``rows``), and are off the axis towards it by at least a quarter of the difference
    and twice the axis's lateral tolerance: what a sliver of a bar under this one does in the
    projector's shadow. "" otherwise (a bar's own edges lose a pixel or so of depth at grazing
    angles, on both sides alike, and its runs stay centred)."""
    rows = np.flatnonzero(rows & (left >= 0) & (right < len(t)))
    if len(rows) < prm.min_sections:
        return ""
    px = sample_px[rows]
    s_lo = float(np.median((left2 - left)[rows] * px))
    s_hi = float(np.median((right - right2)[rows] * px))
    px_mm = float(np.median((t[1] - t[0]) / px))
    centre = float(np.median(t[left[rows] + 1] + t[right[rows] - 1])) / 2 / px_mm  # px, + to hi
    for side, strip, other, sign in (("hi", s_hi, s_lo, 1.0), ("lo", s_lo, s_hi, -1.0)):
        # off-centre by more than the axis's own lateral error could make it
        if (strip >= prm.sliver_min_px and strip - other >= prm.sliver_min_px / 2
                and sign * centre >= max((strip - other) / 4, 2 * prm.axis_sigma_mm / px_mm)):
            return side
    return ""


def _tangent_correct(width_mm, distance_mm):
    # Silhouette rays are tangent to the cylinder: they meet γ at ±r·D/√(D² − r²), slightly
    # wider than the bar. Invert for the radius (exact for a circular cross-section).
    half = np.asarray(width_mm, float) / 2
    return 2 * half * distance_mm / np.sqrt(distance_mm ** 2 + half ** 2)


# --------------------------------------------------------------------------------------------
# Refined method


@dataclass(frozen=True)
class _RefinedParams:
    step_px: float = 3.0  # cross-sections about this far apart along the bar (image)
    max_sections: int = 512  # (a bar across a 1280 x 800 image's diagonal still gets them 3 px apart:
    # sparser sections would not sample a small bar's ribs, see _rib_periodicity)
    cloud_sections: int = 200  # the point-cloud widths read at most this many of them, evenly spread
    window: float = 1.0  # half-window across the bar, in expected widths (2x the width in all)
    sample_px: float = 0.5  # profile sampling step
    min_sections: int = 8
    max_spread_rel: float = 0.12  # robust spread above this fraction of the width: too scattered
    outlier_k: float = 3.0
    shadow_ratio: float = 0.5  # section centre darker than this x the bar's median: in shadow
    hidden_fraction: float = 0.5
    min_confidence: float = 0.8  # below: ambiguous between two sizes, not measured
    quantisation_px: float = 0.4  # std. uncertainty of a width from pixel edges (two edges, each
    # uniform over a pixel: 1/√6 = 0.41 px); divided by √(pixel phases the edges sweep, ≥ 1)
    shadow_confidence: float = 0.7  # cap for a bar in shadow over its whole length
    behind_mm: float = 15.0  # depth this far behind the bar's surface: another object
    sliver_min_px: float = 2.0  # a run going on this far (px) over a surface well behind: cut there
    colour_edges: object = "check"  # colour edges near the mask edges: "check" the mask, "replace" it, False
    depth_correlated_px: float = 4.0  # neighbouring depth points share noise: effective count / this
    cloud_bias_mm_per_m2: float = 1.5  # systematic uncertainty of a point-cloud diameter, x z² (m)
    veto_k: float = 2.0  # mask and cloud widths further apart than this many σ: not measured
    mask_spread_sys: float = 0.5  # share of the mask widths' spread that is a bias of the whole bar
    cloud_only_confidence: float = 0.85  # cap for a size from the point cloud alone (relies on the axis)
    depth_core: float = 0.5  # point-cloud points from the middle this fraction of each run
    circle_core: float = 0.8  # the circle fit reads the cloud over this fraction of each run
    colour_tolerance_px: float = 0.5  # colour and mask widths may differ this much (cylinder shading)
    colour_offset_bars: int = 5  # bars needed to learn the capture's colour-minus-mask offset
    edge_search_px: float = 2.5  # how far from the mask edge the colour edge may lie
    edge_min_contrast: float = 12.0  # grey levels between bar and background, else keep the mask
    edge_peak_share: float = 0.3  # the gradient peak must carry this share of the step per pixel
    axis_sigma_mm: float = 0.3  # lateral axis error tolerated before the centring counts against a width
    max_offcentre_rel: float = 0.2  # mask run centre this far (x width) off the axis: not measured
    # Ribs in the silhouette (see _rib_periodicity, _ribs_in_view): a deformed bar seen closely
    # enough shows its core between the transverse ribs and the rib envelope only at their
    # crests, so its median width reads about the next smaller size's envelope.
    rib_band: tuple = (0.4, 1.2)  # rib pitches searched, x the bar's median width (standards: 0.5-0.7 d)
    # sections needed to read a bar's crests and core and look for its rib pitch
    rib_min_sections: int = 24
    # the capture shows ribs where its bars' periodicity together is this unlikely from noise
    rib_capture_p: float = 1e-6
    rib_p_floor: float = 1e-8  # one bar's p-value counts at most this much (one striped bar is not a capture)
    rib_min_bars: int = 3  # bars needed to judge a capture; as many must show one pitch clearly
    rib_pitch_tol: float = 0.1  # a bar's clear pitch agrees with its size's where within this share of it
    rib_min_px: float = 1.5  # crest minus core widths at least this (px): more than the pixel grid's 1-px steps
    rib_bar_p: float = 0.01  # a bar's own rib pitch is reported where its periodicity is this unlikely from noise
    crest_quantile: float = 0.95  # the crests: the widest 5 % of the sections (crests with their flanks
    # cover a fifth to a third of the pitch)
    core_quantile: float = 0.1  # the core between the ribs
    pitch_k: float = 3.0  # a pitch matches a size's l within this many standard errors (_pitch_band)
    face_fractions: tuple = (0.2, 0.35, 0.5, 0.65, 0.8)  # lines along a bar's face, edge to edge (_face_pitch)
    face_step_px: float = 1.0  # samples along each line this far apart (image)
    face_oversample: int = 4  # periodogram frequencies per resolution (1 / length read)
    rib_reach: float = 0.3  # x rib height h: crescent ribs reach d1 + 2h in silhouette at some rolls,
    # about d1 + 1.4h at others: crest widths are read as d1 + 1.7h ± 0.3h


def _remap(img, u, v):
    import cv2

    return cv2.remap(img, u.astype(np.float32), v.astype(np.float32), cv2.INTER_LINEAR,
                     borderMode=cv2.BORDER_CONSTANT, borderValue=0)


def _colour_edges_rgb(c, t, t_lo, t_hi, px_mm, prm):
    """Move each mask edge to the colour edge near it, in colour (RGB) rather than luminance.

    Grey steel on a green or brown board can have the luminance of the board; the colour step
    remains. Candidates are local maxima of the colour gradient magnitude within
    ``prm.edge_search_px`` of the mask edge; the one where the colour passes from that of the
    bar's middle (inside) to something else (outside) wins, so the edge of a cast shadow next
    to the bar (shadow inside, board outside) loses to the bar's own edge.

    c : (R, K, 3) colour profiles at ``t`` (K,) mm. Returns t_lo, t_hi (R,) mm and moved (R,).
    """
    R, K, _ = c.shape
    dt = t[1] - t[0]
    tm = (t[:-1] + t[1:]) / 2
    mag = np.linalg.norm(np.diff(c, axis=1), axis=2) / dt  # colour change per mm, (R, K-1)
    pm = px_mm[:, None]
    mid = (t_lo + t_hi) / 2
    core = np.abs(t[None, :] - mid[:, None]) <= (t_hi - t_lo)[:, None] / 4
    ref = (c * core[..., None]).sum(axis=1) / np.maximum(core.sum(axis=1), 1)[:, None]  # bar colour
    dist = np.linalg.norm(c - ref[:, None, :], axis=2)  # (R, K) colour distance to the bar
    step = np.maximum(np.rint(px_mm / dt).astype(int), 1)  # one pixel in samples, per row
    j = np.arange(K - 1)[None, :]
    lo_idx = np.clip(j - step[:, None] + 1, 0, K - 1)  # a pixel before the gap j|j+1
    hi_idx = np.clip(j + step[:, None], 0, K - 1)  # a pixel after it
    d_before = np.take_along_axis(dist, lo_idx, axis=1)
    d_after = np.take_along_axis(dist, hi_idx, axis=1)
    peak = np.ones_like(mag, bool)
    peak[:, 1:] &= mag[:, 1:] >= mag[:, :-1]
    peak[:, :-1] &= mag[:, :-1] >= mag[:, 1:]
    strong = mag * pm >= prm.edge_min_contrast
    res, moved = [], np.zeros(R, bool)
    for edge, sign in ((t_lo, -1.0), (t_hi, 1.0)):
        near = np.abs(tm[None, :] - edge[:, None]) <= prm.edge_search_px * pm
        # outside minus inside colour distance to the bar: large for the bar's own edge
        gain = (d_before - d_after) if sign < 0 else (d_after - d_before)
        score = np.where(near & peak & strong & (gain > prm.edge_min_contrast / 2), gain, -np.inf)
        k = score.argmax(axis=1)
        ok = np.isfinite(score[np.arange(R), k])
        win = (np.abs(tm[None, :] - tm[k][:, None]) <= pm) & near
        w = mag * win
        pos = (w * tm[None, :]).sum(axis=1) / np.maximum(w.sum(axis=1), 1e-12)
        res.append(np.where(ok, pos, edge))
        moved |= ok & (np.abs(pos - edge) > 1e-9)
    return res[0], res[1], moved


def _section_points(depth, intr, plane: BarPlane, stations, centres, widths, f, *, unique=False):
    """Camera-frame points, less the foot A of γ, of the depth pixels at ``f`` (fractions of each
    half-width) across the mask run of every cross-section; pixels without depth are left out,
    and with ``unique`` each pixel is taken once."""
    H, W = depth.shape
    t = centres[:, None] + f[None, :] * widths[:, None] / 2
    uv = np.rint(project((stations[:, None, :] + t[..., None] * plane.across).reshape(-1, 3), intr)).astype(int)
    uv = uv[(uv[:, 0] >= 0) & (uv[:, 0] < W) & (uv[:, 1] >= 0) & (uv[:, 1] < H)]
    if unique:
        # rows sorted by u, then v, as np.unique(uv, axis=0) gives them, on a 1-D key (faster)
        key = np.unique(uv[:, 0] * H + uv[:, 1])
        uv = np.column_stack((key // H, key % H))
    z = depth[uv[:, 1], uv[:, 0]]
    good = z > 0
    return backproject(uv[good], z[good], intr) - plane.foot_mm


def _depth_width(depth, intr, plane: BarPlane, stations, centres, widths, prm, expected_mm,
                 covered=None):
    """Diameter from the point cloud: twice the median distance from the bar's axis of the points
    on the middle of its mask run at the given cross-sections (mm), its robust spread (mm) and
    how many points.

    Independent of the mask's edges (a mask a pixel too wide or narrow does not move it), but it
    depends on the axis lying at the bar's centre: an axis placed with an assumed radius would
    return that radius. A point farther from the axis than ``expected_mm`` (the expected
    diameter) is not on this bar's surface: the bar over it, seen where a one-sided section's
    band runs under it, or a flying pixel. Such points are left out (too few left gives NaN,
    never the distance to another object), and their share of the points is returned last:
    where it is most of them, the mask runs the sections were read on are mostly another object.
    That share is taken over the sections not ``covered`` (a boolean per section: partly under
    a nearer bar), where the band should show this bar only. Where every section is covered (a
    bar seen beside the bar over it, its band running under that bar) the points off the axis
    are expected there: the share is NaN, no verdict, as long as enough of the bar's own points
    are left to give a width; where they are not, it is the share over the covered sections
    (nothing then checks a width from the bar's one edge).
    """
    if len(stations) < prm.min_sections:
        return math.nan, math.nan, 0, math.nan
    f = np.linspace(-prm.depth_core, prm.depth_core, 7)  # across the middle of each run
    covered = np.zeros(len(stations), bool) if covered is None else np.asarray(covered, bool)

    def distances(part):  # twice each point's distance from the axis, on the sections ``part``
        if not part.any():
            return np.zeros(0)
        P = _section_points(depth, intr, plane, stations[part], centres[part], widths[part], f)
        return 2 * np.linalg.norm(P - np.outer(P @ plane.direction, plane.direction), axis=1)

    open_d, covered_d = distances(~covered), distances(covered)
    off_share = float(np.mean(open_d > 2 * expected_mm)) if len(open_d) else math.nan
    d = np.concatenate([open_d, covered_d])
    d = d[d <= 2 * expected_mm]
    if len(d) < prm.min_sections * 3:
        if not len(open_d) and len(covered_d):
            off_share = float(np.mean(covered_d > 2 * expected_mm))
        return math.nan, math.nan, len(d), off_share
    q1, med, q3 = np.percentile(d, [25, 50, 75])
    return float(med), float((q3 - q1) / 1.349), len(d), off_share


def _circle_fit(a, b, r0, *, iters: int = 30):
    """Robust fit of the near half of a circle, b = b0 − √(r² − (a − a0)²), to points (a, b)
    whose noise lies along b (a depth camera's: along the line of sight).

    Least squares on the residuals along b, not on the distances to the circle: with depth noise
    the latter shrink the circle (on an arc of ±53° a σ of 0.6 mm on a 7 mm radius gives about
    6.5 mm); the former is unbiased. Gauss–Newton from the centre (0, 5th percentile of b + r0) with
    radius ``r0``, then Tukey weights at 4.685 robust σ (MAD, at least 0.05 mm). Returns
    (a0, b0, r, σ_r, weights): σ_r is the radius's standard error from the normal matrix and
    the weighted residual variance, the points taken as independent; NaN where the fit fails.
    """
    p = np.array([0.0, float(np.percentile(b, 5)) + r0, float(r0)])  # crest: the nearest points
    w = np.ones(len(a))
    fail = (math.nan, math.nan, math.nan, math.nan, w)
    for k in range(iters):
        da = a - p[0]
        q = np.sqrt(np.maximum(p[2] ** 2 - da ** 2, 1e-6))
        res = b - (p[1] - q)
        w = (np.abs(da) < 0.98 * p[2]).astype(float)
        if k:  # the first step from the starting guess is unweighted
            mid = float(np.median(res[w > 0])) if w.any() else 0.0
            s = max(1.4826 * float(np.median(np.abs(res - mid))), 0.05)
            u = (res - mid) / (4.685 * s)
            w *= np.where(np.abs(u) < 1, (1 - u ** 2) ** 2, 0.0)
        J = np.column_stack((-da / q, np.ones_like(q), -p[2] / q))  # d(b0 − q)/d(a0, b0, r)
        JW = J * w[:, None]
        A = J.T @ JW
        try:
            step = np.linalg.solve(A, JW.T @ res)
        except np.linalg.LinAlgError:
            return fail
        p = p + step
        if not np.all(np.isfinite(p)) or p[2] <= 0:
            return fail
        if np.abs(step).max() < 1e-5:
            break
    res = b - (p[1] - np.sqrt(np.maximum(p[2] ** 2 - (a - p[0]) ** 2, 1e-6)))
    var = float((w * res ** 2).sum()) / max(float(w.sum()) - 3.0, 1.0)
    try:
        cov = np.linalg.inv(A) * var
    except np.linalg.LinAlgError:
        return fail
    return float(p[0]), float(p[1]), float(p[2]), float(math.sqrt(max(cov[2, 2], 0.0))), w


def _cloud_circle(depth, intr, plane: BarPlane, stations, centres, widths, prm):
    """Diameter of the bar from the shape of its point cloud alone: a circle fitted to the depth
    points across the sections' mask runs, in the cross-section plane (across, normal of γ).

    Unlike :func:`_depth_width`, it needs no axis at the bar's centre, only its direction and
    roughly its place: an axis placed with an assumed radius (the geometry stage's fixed-radius
    cylinder) gives the same circle. The points are read over the middle ``prm.circle_core`` of
    each run (the flanks beyond face the camera at a grazing angle, where a stereo camera's
    depth is least reliable). Returns (diameter, σ): σ is the fit's standard error with
    neighbouring points counted as sharing their noise (``prm.depth_correlated_px``); NaN where
    too few points or the fit fails.
    """
    if len(stations) < prm.min_sections:
        return math.nan, math.nan
    px_mm = float(np.median(stations[:, 2])) / intr.fx
    n = int(np.clip(np.ceil(np.nanmedian(widths) * prm.circle_core / px_mm), 5, 41))
    f = np.linspace(-prm.circle_core, prm.circle_core, n)
    P = _section_points(depth, intr, plane, stations, centres, widths, f, unique=True)
    if len(P) < prm.min_sections * 5:
        return math.nan, math.nan
    r0 = float(np.nanmedian(widths)) / 2
    _, _, r, s_r, _ = _circle_fit(P @ plane.across, P @ plane.normal, r0)
    if not (math.isfinite(r) and 0.25 * r0 < r < 4 * r0):
        return math.nan, math.nan
    return 2 * r, 2 * s_r * math.sqrt(prm.depth_correlated_px)


def _rib_periodicity(s_mm, w_mm, *, band=(0.4, 1.2), oversample: int = 4,
                     width_mm: float | None = None) -> tuple[float, float]:
    """Strongest periodic component of a bar's section widths along it: ``(pitch_mm, p)``.

    The transverse ribs of a deformed bar make its silhouette's width periodic along the bar, at
    the rib pitch (about 0.5-0.7 x its diameter). The periodogram of the widths ``w_mm`` at their
    positions ``s_mm`` (irregular spacing is fine) is searched over pitches between ``band`` x the
    median width; ``p`` is the chance that noise alone gives a peak as strong (the peak of a
    periodogram of white noise normalised by its variance is exponential with mean 1, times the
    number of independent frequencies searched). ``(nan, 1.0)`` where there is too little to
    look at (fewer than 8 sections, constant widths, a bar shorter than three pitches, sections
    too far apart for the band, no peak inside the band: a spectrum rising to its edge).
    ``width_mm``: the bar's width the band is relative to, where ``w_mm`` is another signal along
    the bar (one edge's position, :func:`_edge_pitch`); default the median of ``w_mm``.

    Only pitches of at least two section spacings (the median one) are searched: sampled that
    sparsely, a shorter period is indistinguishable from a slow one mirrored about the sampling
    rate. Searching beyond it found "ribs" at a pitch just under the sections' spacing on smooth
    bars: the slow wander of a mask's width along the bar, mirrored (a mask computed at half the
    image's resolution, 3 of 38 captures looking ribbed).

    Examples
    --------
    >>> s = np.arange(200) * 1.3  # sections 1.3 mm apart
    >>> w = 12.4 + 0.8 * (np.cos(2 * np.pi * s / 8.0) > 0.5)  # crests every 8 mm
    >>> pitch, p = _rib_periodicity(s, w)
    >>> round(pitch, 1), p < 1e-6
    (8.0, True)
    >>> _rib_periodicity(s, 12.4 + np.random.default_rng(0).normal(0, 0.3, 200))[1] > 0.01
    True
    """
    s = np.asarray(s_mm, float)
    w = np.asarray(w_mm, float)
    if len(w) < 8:
        return math.nan, 1.0
    width = float(np.median(w)) if width_mm is None else float(width_mm)
    w = w - w.mean()
    var = float(w @ w) / len(w)
    length = float(s.max() - s.min())
    if var <= 1e-12 or width <= 0 or length < 3 * band[1] * width:
        return math.nan, 1.0
    fmin = 1 / (band[1] * width)
    fmax = min(1 / (band[0] * width), 0.5 / float(np.median(np.diff(np.sort(s)))))  # (Nyquist)
    if fmax <= fmin:
        return math.nan, 1.0
    f = np.linspace(fmin, fmax, int(math.ceil((fmax - fmin) * length * oversample)) + 1)
    power = _periodogram(s, w, f) / (len(w) * var)
    k = _band_peak(f, power, fmin, fmax, length)
    if k is None:
        return math.nan, 1.0
    return float(1 / f[k]), float(min(1.0, (fmax - fmin) * length * math.exp(-float(power[k]))))


def _periodogram(s, w, f):
    """|Σ w·exp(2πi·f·s)|² at the evenly spaced frequencies ``f``: the terms of each frequency are
    those of the one before times exp(2πi·Δf·s), a running product instead of a sine and a
    cosine per term (five times faster; it agrees with the direct sums to about 1e-13 of the
    peak).

    >>> s = np.array([0.0, 1.0, 2.5]); w = np.array([1.0, -2.0, 0.5]); f = np.linspace(0.1, 0.3, 3)
    >>> direct = np.abs(np.exp(2j * np.pi * np.outer(f, s)) @ w) ** 2
    >>> bool(np.allclose(_periodogram(s, w, f), direct))
    True
    """
    terms = np.empty((len(f), len(s)), complex)
    terms[0] = w * np.exp(2j * np.pi * f[0] * s)
    if len(f) > 1:
        terms[1:] = np.exp(2j * np.pi * (f[1] - f[0]) * s)
    np.cumprod(terms, axis=0, out=terms)
    x = terms.sum(axis=1)
    return x.real ** 2 + x.imag ** 2


def _band_peak(f, power, fmin, fmax, length):
    """Index of the strongest peak of a periodogram ``power`` at frequencies ``f`` (1/mm) inside
    [``fmin``, ``fmax``], or None: a period is a peak, a local maximum at least one resolution
    (1 / ``length``) inside the band. A width that wanders slowly along a smooth bar has a
    spectrum rising towards the longest pitch searched, and its largest value at the band's edge
    is that rise, not a period (seen: smooth Φ10 bars of a learnt mask with "clear" pitches at or
    next to 1.2 x their width)."""
    peak = np.zeros(len(f), bool)
    peak[1:-1] = (power[1:-1] > power[:-2]) & (power[1:-1] >= power[2:])
    peak &= (f >= fmin + 1 / length) & (f <= fmax - 1 / length)
    if not peak.any():
        return None
    return int(np.flatnonzero(peak)[power[peak].argmax()])


def _clear_pitch(pitch, p, length_mm, prm) -> tuple[float, float] | None:
    """``(pitch_mm, relative resolution)`` where a rib pitch read over ``length_mm`` of bar is
    clear (p < ``prm.rib_bar_p``); the resolution is half a periodogram bin, pitch / (2 x
    length). None otherwise."""
    if p < prm.rib_bar_p and math.isfinite(pitch) and length_mm > 0:
        return float(pitch), float(pitch) / (2 * length_mm)
    return None


def _edge_pitch(info, prm) -> tuple[float, float] | None:
    """A bar's rib pitch read from each of its edges on its own: ``(pitch_mm, relative
    resolution)`` where both edges are clearly periodic (p < ``prm.rib_bar_p`` each, from
    :func:`_rib_periodicity`) at one pitch (within a periodogram bin, pitch / length read), else
    None.

    The transverse ribs on the two sides of the longitudinal ribs need not be in step along the
    bar, so its width, the difference of its two edges, can hide the pitch each edge shows. Each
    edge is read against a straight line along the bar (an axis a little askew across the bar
    tilts it). The two edges' noise is independent, so both clear at one pitch is rarer from
    noise than one clear width."""
    s, lo, hi = info.get("edges", (np.zeros(0),) * 3)
    good = np.isfinite(lo) & np.isfinite(hi)
    if good.sum() < prm.rib_min_sections:
        return None
    s, lo, hi = s[good], lo[good], hi[good]
    length = float(s.max() - s.min())
    width = float(np.median(hi - lo))
    pitches, ps = [], []
    for e in (lo, hi):
        e = e - np.polyval(np.polyfit(s, e, 1), s)
        pitch, p = _rib_periodicity(s, e, band=prm.rib_band, width_mm=width)
        if not p < prm.rib_bar_p:
            return None
        pitches.append(pitch)
        ps.append(p)
    pitch = float(np.mean(pitches))
    if abs(pitches[0] - pitches[1]) > pitch * pitch / length:
        return None
    return _clear_pitch(pitch, max(ps), length, prm)


def _face_pitch(bar, info, gray, intr, prm, fp=None, i=None) -> tuple[float, float] | None:
    """A bar's rib pitch read from the shading of its face: ``(pitch_mm, relative resolution)``
    where clear (p < ``prm.rib_bar_p``), else None.

    A transverse rib's flanks catch the light and shade on every side of a deformed bar that
    faces the camera, so the luminance along the bar between its edges is periodic at the rib
    spacing l. This holds at every roll of the bar: where the longitudinal ribs lie at the sides
    of the silhouette (a roll at which its width is constant along the bar and says least of its
    size), one side's transverse ribs face the camera full on. The luminance is read along
    ``prm.face_fractions`` of the way from one mask edge to the other, about a pixel apart, over
    the bar's clean cross-sections with both edges (``info["edges"]``; never under another bar,
    at the image border or at a crossing), less its slow changes (light, rust, shadows; a
    Gaussian over three of the longest pitches searched). The lines' periodograms, each
    normalised by its variance, are summed; the peak must lie inside ``prm.rib_band`` x the
    bar's width (:func:`_band_peak`, as for :func:`_rib_periodicity`). Its p-value takes the
    lines as one (their noise may be correlated: what one line shows, the next may show too):
    number of independent frequencies x exp(-peak / lines).

    A bar seen from one side only (too few sections with both edges; the other side under a
    nearer bar or beyond the image border, ``info["one_edges"]``) is read on its visible half:
    the same lines squeezed between its one edge and the axis (half the fractions, of the width
    twice the edge's distance from the axis). There a sample is kept only inside the image and
    outside the footprint of every nearer bar (``fp``, this bar's index ``i``): the bar over a
    sliver has ribs too, at its own spacing.

    The face lies nearer the camera than the plane γ the positions are measured in, so it is
    magnified on it by D / (D - h) (D the distance to the axis, h the face's height over it, a
    circle through the edges): the pitch is scaled back by (1 - h / D).
    """
    s_k, lo, hi = info.get("edges", (np.zeros(0),) * 3)
    good = np.isfinite(lo) & np.isfinite(hi)
    fr = np.asarray(prm.face_fractions, float)
    one_side = good.sum() < prm.rib_min_sections
    if one_side:
        s_k, lo1, hi1 = info.get("one_edges", (np.zeros(0),) * 3)
        lo = np.where(np.isfinite(lo1), lo1, hi1)  # the visible edge, and its mirror about the axis
        hi = -lo
        good = np.isfinite(lo)
        fr = fr / 2  # lines from the visible edge to the axis
    if gray is None or good.sum() < prm.rib_min_sections:
        return None
    order = np.argsort(s_k[good])
    s_k, lo, hi = s_k[good][order], lo[good][order], hi[good][order]
    pl = bar.plane
    mid = bar.p0 + float(np.median(s_k)) * pl.direction
    dist = float(np.linalg.norm(mid))
    ds = prm.face_step_px * float(mid[2]) / intr.fx  # mm along the bar between samples
    width = float(np.median(np.abs(hi - lo)))
    length = float(s_k[-1] - s_k[0])
    if width <= 0 or length < 3 * prm.rib_band[1] * width:
        return None
    n = int(length / ds) + 1
    s = s_k[0] + ds * np.arange(n)
    j = np.searchsorted(s_k, s).clip(1, len(s_k) - 1)
    gap = np.minimum(np.abs(s - s_k[j - 1]), np.abs(s - s_k[j]))
    keep = gap <= 1.01 * float(np.median(np.diff(s_k)))  # near a clean section
    lo_s, hi_s = np.interp(s, s_k, lo), np.interp(s, s_k, hi)
    t = lo_s[None, :] + fr[:, None] * (hi_s - lo_s)[None, :]  # (lines, n) mm across, in γ
    P = (bar.p0 + s[None, :, None] * pl.direction + t[..., None] * pl.across).reshape(-1, 3)
    uv = project(P, intr)
    lum = _remap(gray, uv[:, 0:1], uv[:, 1:2])[:, 0].reshape(len(fr), n).astype(float)
    m = np.broadcast_to(keep, lum.shape).astype(float)  # (lines, n): the samples read
    if one_side:
        H, W = gray.shape[:2]
        seen = (uv[:, 0] >= 0) & (uv[:, 0] <= W - 1) & (uv[:, 1] >= 0) & (uv[:, 1] <= H - 1)
        if fp is not None and i is not None:
            cand = _candidates(i, fp, [uv[:, 0].min(), uv[:, 1].min(), uv[:, 0].max(), uv[:, 1].max()])
            if len(cand):
                seen &= ~_hits_footprints(P, fp, cand)[1].any(axis=1)
        m = m * seen.reshape(m.shape)
    # slow changes out: a Gaussian over the samples kept (normalised convolution across the gaps)
    sig = 3 * prm.rib_band[1] * width / ds
    half = min(int(3 * sig), (n - 1) // 2)  # (np.convolve "same" keeps n samples while n >= the kernel)
    x_g = np.arange(-half, half + 1)
    g = np.exp(-0.5 * (x_g / sig) ** 2)
    x = np.array([(row - np.convolve(row * mk, g, "same") / np.maximum(np.convolve(mk, g, "same"), 1e-9)) * mk
                  for row, mk in zip(lum, m)])
    cnt = np.maximum(m.sum(axis=1), 1.0)  # samples read per line (a line with none has no variance)
    x -= (x.sum(axis=1) / cnt)[:, None] * m
    var = (x ** 2).sum(axis=1) / cnt
    # a line read over less than half of the bar's clean length says too little (a sliver's
    # line that runs under the bar over it)
    varied = (var > 1e-9) & (cnt >= 0.5 * keep.sum())
    if not varied.any():
        return None
    nfft = 1 << int(math.ceil(math.log2(prm.face_oversample * n)))
    power = (np.abs(np.fft.rfft(x[varied], nfft, axis=1)) ** 2 / (cnt[varied] * var[varied])[:, None]).sum(axis=0)
    f = np.fft.rfftfreq(nfft, ds)
    fmin, fmax = 1 / (prm.rib_band[1] * width), min(1 / (prm.rib_band[0] * width), 0.5 / ds)
    k = _band_peak(f, power, fmin, fmax, length)
    if k is None:
        return None
    p = min(1.0, (fmax - fmin) * length * math.exp(-float(power[k]) / int(varied.sum())))
    # the face's mean height over the axis, on a circle through the edges
    h = float(np.mean(np.sqrt(np.clip(1 - (2 * fr - 1) ** 2, 0, 1)))) * width / 2
    return _clear_pitch(float(1 / f[k]) * (1 - h / dist), p, length, prm)


def _ribs_in_view(reads, prm, sizes=None) -> float:
    """Chance that noise alone gives the periodicity the capture's bars show together (Fisher's
    method over the bars' :func:`_rib_periodicity` reads ``(pitch_mm, p)``, the p-values each
    floored at ``prm.rib_p_floor`` so that one striped bar does not make a capture); 1.0 with
    fewer than ``prm.rib_min_bars`` bars to look at. The bars of one capture are seen by one
    camera at similar distances: where it resolves the ribs of some, it resolves those of all.

    Ribs also repeat at one pitch on every bar of a size (the standard's spacing), while a mask's
    own texture or noise gives each bar a pitch of its own: 1.0 too unless at least
    ``prm.rib_min_bars`` bars show a pitch clearly (p < ``prm.rib_bar_p``) within
    ``prm.rib_pitch_tol`` of the median clear pitch of their size (``sizes``, one key per bar,
    e.g. its design size; None: one size). Seen on a learnt mask of smooth bars: 2-3 bars of a
    capture clearly periodic, at pitches 6.5-16 mm for one size; ribs in relief: every clear pitch
    within 1 % of the true one."""
    sizes = [0] * len(reads) if sizes is None else list(sizes)
    clear = defaultdict(list)
    for (pitch, p), key in zip(reads, sizes):
        if p < prm.rib_bar_p and math.isfinite(pitch):
            clear[key].append(pitch)
    agree = sum(int(np.sum(np.abs(np.array(v) / np.median(v) - 1) <= prm.rib_pitch_tol)) for v in clear.values())
    if agree < prm.rib_min_bars:
        return 1.0
    ps = [max(p, prm.rib_p_floor) for pitch, p in reads if math.isfinite(pitch)]
    half = -float(np.sum(np.log(ps)))  # χ² / 2, with 2 x len(ps) degrees of freedom
    if half <= 0:
        return 1.0
    j = np.arange(len(ps))
    log_terms = j * math.log(half) - np.array([math.lgamma(k + 1) for k in j]) - half
    top = float(log_terms.max())
    return float(min(1.0, math.exp(top) * np.exp(log_terms - top).sum()))


def _thinned(idx, n: int):
    """Every k-th of ``idx``, k the smallest that leaves at most ``n`` of them."""
    return idx[::max(1, -(-len(idx) // n))]


def _refined_bar(i, bar: _Bar, maskf, gray, depth, intr, fp, prm: _RefinedParams, rgb=None, depth_img=None,
                 circle=False):
    H, W = maskf.shape
    pl = bar.plane
    st = _stations(bar, intr, prm.step_px, prm.max_sections)
    M = len(st)
    half_win = prm.window * bar.expected_mm
    z_near = max(float(st[:, 2].min()), 1.0)
    K = int(math.ceil(2 * half_win * intr.fx / z_near / prm.sample_px)) + 1
    t = np.linspace(-half_win, half_win, K)
    X = st[:, None, :] + t[None, :, None] * pl.across  # (M, K, 3) points of γ
    z = X[..., 2]
    u = intr.fx * X[..., 0] / z + intr.cx
    v = intr.fy * X[..., 1] / z + intr.cy
    inside_px = (u >= 0) & (u <= W - 1) & (v >= 0) & (v <= H - 1) & (z > 0)
    in_img = inside_px[:, K // 2]  # the station itself is in the image
    info = {"stations": M, "occluded": 0, "border": int((~in_img).sum()), "crossing": 0,
            "no_edge": 0, "shadow": 0, "outlier": 0, "colour_edges": 0, "one_edge": 0, "holed": 0}
    widths = np.full(M, np.nan)
    centres = np.full(M, np.nan)  # middle of the two edges, mm from the axis in γ
    colour_w = np.full(M, np.nan)  # width between the colour edges next to the mask edges
    d_centre = np.full(M, np.nan)  # middle and width of the band the point cloud is read in
    d_width = np.full(M, np.nan)
    edge_lo = np.full(M, np.nan)  # the two edges of a section with both, mm from the axis in γ
    edge_hi = np.full(M, np.nan)
    side_lo = np.full(M, np.nan)  # the one edge of a one-sided section, mm from the axis in γ
    side_hi = np.full(M, np.nan)
    cut = np.zeros(M, bool)
    ok = in_img.copy()

    # occlusion by a nearer bar across the expected width at each station (for "hidden")
    win_uv = np.column_stack((u[in_img].ravel(), v[in_img].ravel())) if in_img.any() else np.zeros((1, 2))
    cand = _candidates(i, fp, [win_uv[:, 0].min(), win_uv[:, 1].min(), win_uv[:, 0].max(), win_uv[:, 1].max()])
    probe_t = np.array([-0.5, -0.25, 0.0, 0.25, 0.5]) * bar.expected_mm
    occluded = np.zeros(M, bool)
    if len(cand):
        P = (st[:, None, :] + probe_t[None, :, None] * pl.across).reshape(-1, 3)
        _, nearer = _hits_footprints(P, fp, cand)
        occluded = nearer.any(axis=1).reshape(M, -1).any(axis=1)
    occluded &= in_img
    info["occluded"] = int(occluded.sum())

    m = _remap(maskf, u, v)  # (M, K) mask profile across the bar, 0..1
    b = m >= 0.5
    behind = np.zeros_like(b)
    deep = np.zeros_like(b)  # behind, with a valid depth
    if depth is not None:
        # Mask pixels whose depth lies well behind this bar belong to a bar under it that peeks
        # out beside it: the mask alone cannot separate the two, the point cloud can.
        import cv2

        dz = cv2.remap(depth, u.astype(np.float32), v.astype(np.float32), cv2.INTER_NEAREST,
                       borderMode=cv2.BORDER_CONSTANT, borderValue=0)
        # no depth counts too: beside a bar the projector's shadow often hides the bar behind
        deep = b & (dz > z + bar.expected_mm / 2 + prm.behind_mm)
        behind = deep | (b & (dz <= 0))
    kc = K // 2
    idx = np.arange(K)
    rr = np.arange(M)
    # seed: the bar pixel nearest the expected axis within a third of the expected width
    near = np.abs(t) <= bar.expected_mm / 3
    dist = np.where(b & ~behind & near[None, :], np.abs(idx - kc)[None, :], K + 1)
    seed = dist.argmin(axis=1)
    has_seed = dist.min(axis=1) <= K

    def run_ends(fg):
        lo = np.where(~fg & (idx[None, :] < seed[:, None]), idx[None, :], -1).max(axis=1)
        hi = np.where(~fg & (idx[None, :] > seed[:, None]), idx[None, :], K).min(axis=1)
        return lo, hi

    left, right = run_ends(b)
    # Only where the mask run reaches beyond this bar's footprint is it cut at the depth step:
    # a lone deep pixel at an ordinary edge is a flying pixel, not another bar.
    left2, right2 = run_ends(b & ~behind)
    too_far_lo = (left < 0) | (t[np.clip(left, 0, K - 1)] < -fp.half_mm[i])
    too_far_hi = (right >= K) | (t[np.clip(right, 0, K - 1)] > fp.half_mm[i])
    # Nor where the run goes on over a few pixels of a surface well behind: a bar under this one
    # peeking out beside it by a few pixels stays within this bar's footprint (which has room
    # for a size larger), and the run would take the sliver for part of this bar.
    sample_px = (t[1] - t[0]) * intr.fx / st[:, 2]
    too_far_lo |= _deep_end(left, left2, deep, sample_px, prm.sliver_min_px)
    too_far_hi |= _deep_end(right, right2, deep, sample_px, prm.sliver_min_px)
    # A strip behind the bar or without depth at one end of the runs only, with the runs off the
    # axis towards it: most likely a bar under this one peeking out, in the projector's shadow
    # where the depth cannot cut it off (and where it can, the sections cut there and those
    # whose runs merged with it within the footprint disagree). That end is then no edge of this
    # bar (below).
    strip_side = "" if depth is None else _holed_side(t, left, right, left2, right2, in_img & has_seed,
                                                      sample_px, prm)
    left = np.where(too_far_lo, left2, left)
    right = np.where(too_far_hi, right2, right)
    # An edge is where the run meets a non-bar sample inside the image; a run that meets the
    # image border there has that side cut off by the border (not the bar's edge).
    in_lo = inside_px[rr, np.clip(left, 0, K - 1)]
    in_hi = inside_px[rr, np.clip(right, 0, K - 1)]
    lo_edge, hi_edge = has_seed & (left >= 0) & in_lo, has_seed & (right < K) & in_hi
    lo_border, hi_border = has_seed & (left >= 0) & ~in_lo, has_seed & (right < K) & ~in_hi
    edged = has_seed & (left >= 0) & (right < K)
    at_border = edged & ~(in_lo & in_hi)
    edged &= ~at_border
    info["border"] += int((ok & at_border).sum())
    info["no_edge"] = int((ok & ~edged & ~at_border).sum())
    ok &= edged
    # One-sided sections: one edge, the other side cut by the image border (or, below, inside
    # another bar's footprint). The width is then twice the edge's distance from the axis: it
    # needs the axis in the bar's middle to a fraction of a millimetre, so only for axes the
    # geometry stage measured, only where the axis itself is in view (at least half the bar's
    # width is), and only where too few sections show both edges (see below).
    one_lo = lo_edge & hi_border & in_img & bar.axis_ok  # the low edge only
    one_hi = hi_edge & lo_border & in_img & bar.axis_ok
    one_sided = np.zeros(M, bool)
    usable = ok | one_lo | one_hi
    rows = np.flatnonzero(usable)
    if len(rows):
        la, ra = left[rows], right[rows]  # both in the profile: every usable row has its two run ends
        ma0, ma1 = m[rows, la], m[rows, la + 1]
        mb0, mb1 = m[rows, ra - 1], m[rows, ra]
        dt = t[1] - t[0]
        # sub-pixel: where the interpolated mask profile crosses 0.5
        t_lo = t[la] + np.clip((0.5 - ma0) / np.maximum(ma1 - ma0, 1e-9), 0, 1) * dt
        t_hi = t[ra - 1] + np.clip((mb0 - 0.5) / np.maximum(mb0 - mb1, 1e-9), 0, 1) * dt
        # an edge cut at a depth step lies half-way between the samples either side of it
        cut_lo, cut_hi = behind[rows, la], behind[rows, ra]
        t_lo = np.where(cut_lo, t[la] + dt / 2, t_lo)
        t_hi = np.where(cut_hi, t[ra] - dt / 2, t_hi)
        two = ok[rows]
        has_lo, has_hi = two | one_lo[rows], two | one_hi[rows]
        # a one-sided section's edge must be a clean mask edge
        has_lo &= ~(cut_lo & ~two)
        has_hi &= ~(cut_hi & ~two)
        cut[rows] = two & (cut_lo | cut_hi)
        if rgb is not None and prm.colour_edges and two.any():
            r2 = rows[two]
            g = _remap(rgb, u[r2], v[r2])
            c_lo, c_hi, moved = _colour_edges_rgb(g, t, t_lo[two], t_hi[two], st[r2, 2] / intr.fx, prm)
            info["colour_edges"] = int(moved.sum())
            both = ~cut_lo[two] & ~cut_hi[two] & (c_lo != t_lo[two]) & (c_hi != t_hi[two])
            colour_w[r2[both]] = (c_hi - c_lo)[both]
            if prm.colour_edges == "replace":
                t_lo[two] = np.where(cut_lo[two], t_lo[two], c_lo)
                t_hi[two] = np.where(cut_hi[two], t_hi[two], c_hi)
        # An edge is trusted unless it may belong to another bar: inside the footprint of a
        # nearer bar (ours is occluded there), or beyond our own expected width and inside a
        # farther bar's footprint (our run merged with the bar behind).
        bad_lo = np.zeros(len(rows), bool)
        bad_hi = np.zeros(len(rows), bool)
        if len(cand):
            px_mm = st[rows, 2] / intr.fx
            tt = np.column_stack((t_lo - 1.5 * px_mm, t_lo, t_lo + px_mm, t_hi - px_mm, t_hi, t_hi + 1.5 * px_mm))
            P = (st[rows][:, None, :] + tt[:, :, None] * pl.across).reshape(-1, 3)
            inside, nearer = _hits_footprints(P, fp, cand)
            beyond = (np.abs(tt) > fp.half_mm[i]).reshape(-1)
            bad = (nearer.any(axis=1) | (inside.any(axis=1) & beyond)).reshape(len(rows), -1)
            bad_lo, bad_hi = bad[:, :3].any(axis=1), bad[:, 3:].any(axis=1)
            info["crossing"] = int((two & (bad_lo | bad_hi)).sum())
            # sections with one clean edge and the other at another bar (a sliver beside it)
            info["one_edge"] = int(((has_lo & ~bad_lo) ^ (has_hi & ~bad_hi)).sum())
        if strip_side:  # nor is the end at a strip without depth beside the bar (above)
            info["holed"] = int(two.sum())
            bad_lo |= strip_side == "lo"
            bad_hi |= strip_side == "hi"
        # the side at another bar is lost; the other side may still give a one-sided width, if
        # the axis may be measured from
        if not bar.axis_ok:
            bad_lo = bad_hi = bad_lo | bad_hi
        has_lo &= ~bad_lo
        has_hi &= ~bad_hi
        is_two = has_lo & has_hi
        is_one = has_lo ^ has_hi
        # a colour width is the width between two colour edges: it checks a section measured
        # between two mask edges only (a one-sided width runs from one edge to the axis; the
        # colour edges found at its other end belong to the border or to the bar over it)
        colour_w[rows[~is_two]] = np.nan
        ok[rows] = is_two
        one_sided[rows] = is_one
        widths[rows] = np.where(is_two, t_hi - t_lo, np.where(has_lo, -2 * t_lo, 2 * t_hi))
        centres[rows] = np.where(is_two, (t_hi + t_lo) / 2, 0.0)
        edge_lo[rows] = np.where(is_two, t_lo, np.nan)
        edge_hi[rows] = np.where(is_two, t_hi, np.nan)
        side_lo[rows] = np.where(is_one & has_lo, t_lo, np.nan)
        side_hi[rows] = np.where(is_one & has_hi, t_hi, np.nan)
        # the point cloud of a one-sided section: from the visible half, between edge and axis
        d_centre[rows] = np.where(is_two, centres[rows], np.where(has_lo, t_lo, t_hi) / 2)
        d_width[rows] = np.where(is_two, widths[rows], widths[rows] / 2)
        # one-sided sections only where the sections with both edges are too few to size the
        # bar and fewer than the one-sided ones (a bar along the image border, or along a bar
        # over it): elsewhere the width does not depend on where the axis lies across the bar
        if int(ok.sum()) >= max(prm.min_sections, int(one_sided.sum())):
            one_sided[:] = False
        # shadow: the middle of the section much darker than the bar usually is (the station on
        # the axis; the middle of the visible part for a one-sided section)
        if gray is not None:
            rows = np.flatnonzero(ok | one_sided)
            if len(rows) >= prm.min_sections:
                pos = np.where(ok[rows], 0.0, (t[np.clip(left[rows] + 1, 0, K - 1)]
                                               + t[np.clip(right[rows] - 1, 0, K - 1)]) / 2)
                uvc = project(st[rows] + pos[:, None] * pl.across, intr)
                lum = _remap(gray, uvc[:, 0:1], uvc[:, 1:2])[:, 0]
                dark = lum < prm.shadow_ratio * np.median(lum)
                if (len(rows) - dark.sum()) >= prm.min_sections:
                    info["shadow"] = int(dark.sum())
                    ok[rows[dark]] = False
                    one_sided[rows[dark]] = False
    # edges from the mask are sharper than edges at depth steps (a depth camera fattens a nearer
    # object's edge): use the latter only if needed, that is unless the sections with mask edges
    # alone are enough with room for the outliers dropped below (twice the minimum: with just
    # the minimum, one outlier left a bar with hundreds of sections "too few")
    cut_off = np.zeros(M, bool)  # sections left out for their edge at a depth step
    if (ok & ~cut).sum() >= 2 * prm.min_sections:
        info["depth_cut"] = int((ok & cut).sum())
        cut_off = ok & cut
        ok &= ~cut
    sel = ok | one_sided
    kept = np.flatnonzero(sel)
    w = _tangent_correct(widths[sel], pl.offset_mm)
    c = centres[sel]
    cw = _tangent_correct(colour_w[sel], pl.offset_mm)
    if len(w) >= 3:
        med = np.median(w)
        mad = 1.4826 * np.median(np.abs(w - med))
        px_mm = float(np.median(st[sel, 2])) / intr.fx
        keep = np.abs(w - med) <= max(prm.outlier_k * mad, 1.0 * px_mm)
        info["outlier"] = int((~keep).sum())
        w, c, cw, kept = w[keep], c[keep], cw[keep], kept[keep]
    info["one_sided_share"] = float(one_sided[kept].mean()) if len(kept) else 0.0
    info["rib_pitch_mm"], info["rib_p"], info["crest_mm"], info["core_mm"] = math.nan, 1.0, math.nan, math.nan
    info["rib_length_mm"] = math.nan
    s_k = (st[kept] - bar.p0) @ pl.direction  # the sections' places along the bar (mm)
    # each edge along the bar, for a rib pitch read from one side at a time (_edge_pitch)
    info["edges"] = (s_k, edge_lo[kept], edge_hi[kept])
    info["one_edges"] = (s_k, side_lo[kept], side_hi[kept])  # (a face read from one side: _face_pitch)
    if len(w) >= prm.rib_min_sections:  # a high quantile of fewer sections is their largest one
        info["crest_mm"], info["core_mm"] = (float(q) for q in np.quantile(w, [prm.crest_quantile,
                                                                               prm.core_quantile]))
    # A binary mask's width along a slanted bar steps by a pixel periodically as its edges cross
    # the pixel rows: a periodicity within that is the pixel grid's, not ribs'
    if math.isfinite(info["crest_mm"]) and info["crest_mm"] - info["core_mm"] >= prm.rib_min_px * float(
            np.median(st[kept, 2])) / intr.fx:
        info["rib_pitch_mm"], info["rib_p"] = _rib_periodicity(s_k, w, band=prm.rib_band)
        info["rib_length_mm"] = float(s_k.max() - s_k.min())
    # The crests are the widest sections, and where a bar's silhouette touches one beside it
    # (a bar under it peeking out) they are the sections whose runs merge with it and are cut
    # at the depth step, left out above: the crests would then be read from the core between
    # them (a Φ12 bar beside a lower bar read 11.6 mm over its crests, 12.9 mm with them). A cut
    # section ends at the first sample behind the bar or without depth: at its flank, or inside
    # it where the flank has no depth. So the crests are read over the cut sections too, those
    # within the bar's footprint (room for a size larger).
    if math.isfinite(info["crest_mm"]) and cut_off.any():
        wc = _tangent_correct(widths[cut_off], pl.offset_mm)
        wc = wc[np.isfinite(wc) & (wc <= 2 * fp.half_mm[i])]
        if len(wc):
            info["crest_mm"] = float(np.quantile(np.concatenate([w, wc]), prm.crest_quantile))
    # the point cloud gives several points per section: every few sections of a long bar suffice
    ck = _thinned(kept, prm.cloud_sections)
    info["depth_width_mm"], info["depth_spread_mm"], info["depth_points"], info["depth_off_share"] = _depth_width(
        depth_img, intr, pl, st[ck], d_centre[ck], d_width[ck], prm, bar.expected_mm,
        occluded[ck]) if depth_img is not None else (math.nan, math.nan, 0, math.nan)
    # that share was read where every section lies under a nearer bar
    info["depth_off_covered"] = bool(len(ck) and occluded[ck].all())
    info["circle_width_mm"] = info["circle_sigma_mm"] = math.nan
    if depth_img is not None and circle:  # only used where the axis was placed with an assumed radius
        two_k = _thinned(kept[~one_sided[kept]], prm.cloud_sections)
        info["circle_width_mm"], info["circle_sigma_mm"] = _cloud_circle(
            depth_img, intr, pl, st[two_k], centres[two_k], widths[two_k], prm)
    # The colour edges next to the mask edges are an independent check of the mask: where the
    # two widths disagree the mask may be biased (a learnt mask bleeding into a shadow or eating
    # into a dark bar), and the width is no better known than their difference.
    # (along the bar, for a capture whose mask smooths its ribs away: _colour_ribs)
    info["colour_widths"] = (s_k, cw)
    cw = cw[np.isfinite(cw)]
    info["colour_width_mm"] = float(np.median(cw)) if len(cw) >= prm.min_sections else math.nan
    # A mask run off-centre from the axis has lost one side (shadow, poor segmentation) or
    # the axis is off: either way the width may be wrong by twice the offset.
    two_kept = ~one_sided[kept]  # a one-sided section has no centre of its own
    info["centre_mm"] = float(np.median(c[two_kept])) if two_kept.any() else (0.0 if len(c) else math.nan)
    info["px_mm"] = float(np.median(st[:, 2])) / intr.fx
    # How many pixel phases the bar's edges sweep over the sections kept: a binary mask puts an
    # edge on the pixel grid, so along a bar parallel to a pixel row every section has the same
    # rounding; a slanted bar's edges cross the grid min(|du|, |dv|) times and the rounding
    # averages out over the sections.
    info["phase_sweep_px"] = 0.0
    if len(kept) >= 2:
        uv_k = project(st[kept[[0, -1]]], intr)
        info["phase_sweep_px"] = float(np.abs(uv_k[1] - uv_k[0]).min())
    info["z_mm"] = float(np.median(st[:, 2]))
    info["lum"] = math.nan
    if gray is not None and in_img.any():
        uvc = project(st[in_img], intr)
        info["lum"] = float(np.median(_remap(gray, uvc[:, 0:1], uvc[:, 1:2])))
    return w, occluded, in_img, info


# --------------------------------------------------------------------------------------------
# The paper's method


def _attribute_pixels(pixels, prepared, intr) -> np.ndarray:
    """Index of the bar whose projected axis segment is nearest in the image to each pixel
    (method.md 3.3: projecting the axes attributes mask pixels to bars). (N,) int."""
    px = np.asarray(pixels, float).reshape(-1, 2)
    best = np.full(len(px), np.inf)
    owner = np.full(len(px), -1, int)
    for k, b in enumerate(prepared):
        pts = np.vstack((b.p0, b.p1))
        if np.any(pts[:, 2] <= 1.0):
            continue
        a, c = project(pts, intr)
        ab = c - a
        s = np.clip(((px - a) @ ab) / max(ab @ ab, 1e-12), 0, 1)
        d = np.linalg.norm(px - (a + s[:, None] * ab), axis=1)
        closer = d < best
        best[closer], owner[closer] = d[closer], k
    return owner


def _paper_bar(i, bar: _Bar, mask, edge, intr, n_points: int, owner):
    pl = bar.plane
    H, W = mask.shape
    st = _stations(bar, intr, 1.0, n_points)
    design = bar.design_mm if math.isfinite(bar.design_mm) else bar.expected_mm
    Ds = []
    for p in st:
        c = project(p[None, :], intr)[0]
        if not (0 <= c[0] <= W - 1 and 0 <= c[1] <= H - 1):
            continue
        across, along = cross_section_direction(p, pl.direction, intr)
        long_px = 2 * design * intr.fx / p[2]
        region = pixels_in_region(diameter_region(c, across, along, long_px=long_px, short_px=6.0), mask.shape)
        if len(region) == 0:
            continue
        bp = region[edge[region[:, 1], region[:, 0]]]
        bp = bp[owner[bp[:, 1], bp[:, 0]] == i]
        if len(bp) < 2:
            continue
        side = along[0] * (bp[:, 1] - c[1]) - along[1] * (bp[:, 0] - c[0])
        pts = intersect_rays_plane(bp, intr, pl)
        a, b = pts[side > 0], pts[side < 0]
        if len(a) == 0 or len(b) == 0:
            continue
        d = np.sqrt(((a[:, None, :] - b[None, :, :]) ** 2).sum(-1))
        Ds.append(float(np.nanmin(d)))
    return np.array(Ds)


def _paper_vote(Ds, system):
    sizes = np.array(bar_system(system).sizes_mm)
    if len(Ds) == 0:
        return math.nan, 0.0
    # bins of ±1 mm around the nominal sizes (8 ↔ 7–9, 10 ↔ 9–11, ...); outside every bin: no vote
    k = np.abs(Ds[:, None] - sizes[None, :]).argmin(axis=1)
    inbin = np.abs(Ds - sizes[k]) <= 1.0
    if not inbin.any():
        return math.nan, 0.0
    counts = np.bincount(k[inbin], minlength=len(sizes))
    win = int(counts.argmax())
    return float(sizes[win]), float(counts[win] / len(Ds))


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
    return info.get("one_sided_share", 0.0) == 0.0


def _mask_width(result) -> float:
    """A bar's width from its mask: ``mask_width_mm`` where :func:`measure_diameters` set it (the
    envelope from the rib crests where the capture resolves ribs), else its sections' median."""
    w = result[3].get("mask_width_mm")
    return float(w) if w is not None else float(np.median(result[0]))


def _mask_between_spread(results, prepared, prm) -> None:
    """Store in every bar's info ``mask_between_mm``: the robust spread (1.4826 MAD) of the mask
    widths between the capture's bars of the same design size, around each size's median.

    Bars of one size have one true width, so this is the mask's error per bar as this capture
    shows it: pixel rounding on bars along pixel rows, and a learnt mask's bias per bar that its
    own spread along the bar does not show (a mask that eats both sides of a bar evenly). Needs
    ``prm.colour_offset_bars`` bars with a design size (at least 3 of a size); else 0.
    """
    dev = _between_bar_deviations({i: _mask_width(r) for i, r in enumerate(results)
                                   if len(r[0]) >= prm.min_sections and _two_sided(r[3])}, prepared)
    s_m = _robust_sigma(dev) if len(dev) >= prm.colour_offset_bars else 0.0
    for r in results:
        r[3]["mask_between_mm"] = s_m


def _width_calibration(results, key, prm, *, system, deformed, groups=None) -> None:
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
    at least ``prm.colour_offset_bars`` bars, whose offset's error the spread's bound covers."""
    per_group = groups is not None
    groups = list(groups) if per_group else [0] * len(results)
    dev = defaultdict(list)
    for r, g in zip(results, groups):
        cw = r[3][f"{key}_width_mm"]
        if len(r[0]) < prm.min_sections or not math.isfinite(cw) or not _two_sided(r[3]):
            continue
        med = _mask_width(r)
        nominal, _ = snap_diameter(med, system=system, deformed=deformed)
        if not math.isfinite(nominal):
            continue
        env = observed_width_mm(nominal, system=system, deformed=deformed)
        lo, hi = size_half_gaps_mm(nominal, system=system, deformed=deformed)
        if abs(med - env) <= 0.5 * (lo if med < env else hi):  # a quarter of the step to the next size
            dev[g].append(cw - env)
    if per_group:
        dev = {g: d for g, d in dev.items() if len(d) >= 2}
    off = {g: float(np.median(d)) for g, d in dev.items()}
    res = np.concatenate([np.asarray(d) - off[g] for g, d in dev.items()]) if dev else np.zeros(0)
    k = len(res) - len(dev)  # degrees of freedom: one offset learnt per group
    s_c = math.nan
    if k >= prm.colour_offset_bars - 1:
        # learnt from a dozen bars or so, the spread may fall short of the errors' tails: the
        # upper 90 % confidence bound of σ from k degrees of freedom (χ² quantile by the
        # Wilson-Hilferty approximation)
        chi2_10 = k * (1 - 2 / (9 * k) - 1.2816 * math.sqrt(2 / (9 * k))) ** 3
        s_c = float(np.sqrt(np.sum(np.square(res)) / chi2_10))
    for r, g in zip(results, groups):
        learnt = g in off and math.isfinite(s_c)
        r[3][f"{key}_offset_mm"] = off[g] if learnt else 0.0
        r[3][f"{key}_width_mm"] -= r[3][f"{key}_offset_mm"]
        r[3][f"{key}_between_mm"] = s_c if learnt else math.nan
        s_g = s_c * math.sqrt(1 + 1 / len(dev[g])) if per_group and learnt else s_c
        r[3][f"{key}_sigma_mm"] = float(np.fmax(r[3][f"{key}_sigma_mm"], s_g))


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
    have = [i for i, r in enumerate(results)
            if len(r[0]) >= prm.min_sections and math.isfinite(r[3]["colour_width_mm"]) and _two_sided(r[3])]
    off, weight, spread = 0.0, 1.0, 0.0
    if len(have) >= prm.colour_offset_bars:
        med = {i: float(np.median(results[i][0])) for i in have}
        off = float(np.median([(results[i][3]["colour_width_mm"] - med[i]) / results[i][3]["px_mm"] for i in have]))
        # without a design size the bars' true widths are unknown: no between-bar spread
        dm = _between_bar_deviations(med, prepared)
        dc = _between_bar_deviations({i: results[i][3]["colour_width_mm"] - off * results[i][3]["px_mm"]
                                      for i in have}, prepared)
        if len(dm) >= prm.colour_offset_bars:
            s_m, s_c = _robust_sigma(dm), _robust_sigma(dc)
            if s_m + s_c > 0:
                weight, spread = s_m ** 2 / (s_m ** 2 + s_c ** 2), math.hypot(s_m, s_c)
    for r in results:
        r[3]["colour_offset_px"], r[3]["colour_weight"], r[3]["colour_spread_mm"] = off, weight, spread


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
            "is read on what is seen beside them and suggests no other size")
    else:
        out["diameter_reason"] = (
            f"possible wrong size: the mask width {med:.1f} mm gives Φ{nom_m:g} (confidence {conf_m:.2f}), "
            f"but the axis was fitted with the radius of Φ{nom_c:g}, so the point cloud ({dw:.1f} mm) "
            "cannot confirm another size: check this bar by hand")


#: the widths that do not depend on where an axis placed with an assumed radius lies: how the
#: reason names each
_INDEPENDENT = {"stack": "its top {w:.1f} ± {s:.1f} mm above the bars it rests on",
                "level": "its top {w:.1f} ± {s:.1f} mm above its level's supports",
                "circle": "the point cloud's shape, circle fit {w:.1f} ± {s:.1f} mm"}


def _independent_widths(info) -> list:
    """``(key, width, σ)`` of each width of a bar that depends neither on its mask nor on where
    an axis placed with an assumed radius lies (:data:`_INDEPENDENT`) and is sound: measured,
    with a σ, and calibrated against the capture's bars (``{key}_between_mm`` finite,
    :func:`_width_calibration`)."""
    used = []
    for key in _INDEPENDENT:
        w, sg = info.get(f"{key}_width_mm", math.nan), info.get(f"{key}_sigma_mm", math.nan)
        learnt = math.isfinite(info.get(f"{key}_between_mm", math.nan))
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


def _arbitrate(out, med, conf_m, pair, info, in_shadow, prm, *, system, deformed):
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
    if (nominal not in pair or conf < prm.min_confidence
            or sigma > min(size_half_gaps_mm(nominal, system=system, deformed=deformed))):
        return None
    if pair[0] != pair[1] and (nominal == pair[0]) != (conf_m >= prm.min_confidence):
        # The mask's own word decides which of the two these widths may confirm. A mask clear
        # about another size than the assumed one is the alert a bar of the wrong size gives:
        # one width with tails of its own (a bar lifted off its supports by a tie reads a size
        # up) does not silence it. And a size other than the assumed one is not given on such a
        # width where the mask is not clear about it too (on a D435-like capture, a bar lying
        # 1 mm low on its supports, its top read 2 mm low, read a size down with a mask leaning
        # that way at 0.74)
        return None
    why = (f"its mask width {med:.1f} mm is nearest Φ{pair[0]:g}, the axis was fitted with the radius of "
           f"Φ{pair[1]:g}, and these widths, which depend on neither, tell the two apart" if pair[0] != pair[1] else
           f"its mask width {med:.1f} mm and its point cloud, which echoes the radius its axis was fitted with, "
           "disagree, and these widths depend on neither")
    reason = f"size from {' and '.join(_INDEPENDENT[k].format(w=w, s=sg) for k, w, sg in used)}: {why}"
    return _sized(out, nominal, conf, width, sigma, "+".join(k for k, _, _ in used), reason, in_shadow, prm)


def _settle(out, med, sigma_m, info, in_shadow, prm, *, system, deformed, size):
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
    """
    used = _independent_widths(info)
    if not used or any(abs(med - w) / math.hypot(sigma_m, sg) > prm.veto_k for _, w, sg in used):
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
    return _sized(out, nominal, conf, width, sigma, "mask+" + "+".join(k for k, _, _ in used), reason,
                  in_shadow, prm)


def _sized(out, nominal, conf, width, sigma, source, reason, in_shadow, prm) -> dict:
    """``out`` as a measured bar: its size, confidence (capped for a bar in shadow, saying so),
    and the width it came from with its σ and source."""
    if in_shadow:
        conf = min(conf, prm.shadow_confidence)
        reason = (reason + "; " if reason else "") + "bar in shadow: confidence capped"
    out.update(nominal_mm=nominal, confidence=round(conf, 4), diameter_status=MEASURED, diameter_reason=reason,
               width_source=source, width_used_mm=round(width, 3), width_sigma_mm=round(sigma, 3))
    return out


def _off_centre(info, med, prm) -> bool:
    """Whether a bar's mask runs are centred this far off its axis: one side of the bar is lost."""
    return abs(info["centre_mm"]) > prm.max_offcentre_rel * med


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
    nominal, c = row["nominal_mm"], info["core_mm"]
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
    reason = (f"ribs resolved: the rib crests ({info['crest_mm']:.1f} mm) give {sysm.label(nominal)}, "
              f"the core between them ({c:.1f} mm) {sysm.label(core) or 'no size'}: check it by hand")
    # (the two sizes they point to: the rib pitch may tell them apart, _pitch_settle)
    row.update(nominal_mm=math.nan, confidence=0.0, diameter_status=NOT_MEASURED, diameter_reason=reason,
               _pair=(nominal, core))


def _pitch_table(clear: dict, keys, prm, *, system, sizes_of=None):
    """Whether a capture's clear rib pitches follow its size system's spacings (see
    :func:`_pitch_settle`): ``(scale, spread, confidence)``, or None where they cannot show it.

    ``clear``: bar index -> (pitch mm, relative resolution); ``keys``: each bar's size (its
    design's); ``sizes_of(i)``: the sizes bar i may be (default its key). The pitches are grouped
    by size; at least ``prm.rib_min_bars`` of them in groups of two or more. In each group, the
    table's spacing nearest to the most of its pitches must be its own size's (ties count: a bar
    of another size than designed, whose pitch is its own size's, does not outvote the design),
    and at least ``prm.rib_min_bars`` pitches in all must be nearest to their own size's.
    ``scale``: 1 + the median deviation of those pitches from their spacings (shared by all: the
    depth scale, the focal length); ``spread``: their robust spread about it; ``confidence``:
    (k + 1) / (n + 2), k of the n pitches within :func:`_pitch_band` of the scaled spacing of a
    size their bar may be."""
    sysm = bar_system(system)
    if not sysm.rib_pitch_mm:
        return None
    table = np.array(sysm.rib_pitch_mm, float)
    groups = defaultdict(list)
    for i in clear:
        if math.isfinite(rib_pitch_mm(keys[i], system=system)):
            groups[keys[i]].append(i)
    groups = {k: v for k, v in groups.items() if len(v) >= 2}
    if sum(len(v) for v in groups.values()) < prm.rib_min_bars:
        return None
    own = []  # (bar, its size's spacing) for the pitches nearest to their own size's spacing
    for k, v in groups.items():
        lk = rib_pitch_mm(k, system=system)
        nearest = [float(table[np.abs(table - clear[i][0]).argmin()]) for i in v]
        counts = Counter(nearest)
        if counts[lk] < max(counts.values()):
            return None
        own += [(i, lk) for i, x in zip(v, nearest) if x == lk]
    if len(own) < prm.rib_min_bars:
        return None
    dev = np.array([clear[i][0] / lk - 1 for i, lk in own])
    # a scale all of the capture's pitches share (the camera's depth scale, its focal length) is
    # the capture's, not the bars': pitches are matched to the table times it
    scale = 1 + float(np.median(dev))
    spread = 1.4826 * float(np.median(np.abs(dev - np.median(dev))))
    sizes_of = sizes_of or (lambda i: {keys[i]})
    members = [i for v in groups.values() for i in v]
    agree = sum(any(abs(clear[i][0] / (scale * rib_pitch_mm(sz, system=system)) - 1)
                    <= _pitch_band(spread, clear[i][1], prm) for sz in sizes_of(i))
                for i in members)
    return scale, spread, (agree + 1) / (len(members) + 2)


def _pitch_band(spread, resolution, prm) -> float:
    """How far (relative) a pitch may lie from a scaled spacing and still match it:
    ``prm.pitch_k`` standard errors, each the capture's robust spread of pitches and the read's
    own resolution (half a periodogram bin) together. A robust spread of a dozen pitches that
    cluster on a few values of the periodogram's grid falls short of how far single reads stray
    (seen: 12 reads of one size within ±0.7 %, spread 0.14 %), and the resolution bounds how
    finely one read places its pitch."""
    return prm.pitch_k * math.hypot(spread, resolution)


def _colour_ribs(results, keys, prm, *, system) -> bool:
    """Whether the colour image shows the ribs of a capture whose mask widths do not: a learnt
    mask may smooth the ribs away, so that the capture looks like one without resolved ribs,
    and its bars' median widths (mostly core) read a size down.

    The colour widths (between the colour edges next to the mask's, :func:`_colour_edges_rgb`)
    must pass both tests the mask widths' periodicity passes (:func:`_ribs_in_view`) and also
    follow the size table's spacings (:func:`_pitch_table`, confidence at least
    ``prm.min_confidence``): on smooth bars the colour edges of a slanted bar step with the pixel
    grid, periodically and alike on parallel bars, but not at their sizes' rib spacing. A bar's
    pitch agrees with the table at its design size's spacing or at the next size's up or down:
    a bar of another size than designed is most often its neighbour, and its pitch is its own
    size's (the design's groups must still mostly show their own spacing). Only for systems that
    set a spacing per size (GB 1499.2)."""
    sysm = bar_system(system)
    if not sysm.rib_pitch_mm:
        return False
    reads, lengths = [], []
    for r in results:
        s, cw = r[3].get("colour_widths", (np.zeros(0), np.zeros(0)))
        good = np.isfinite(cw)
        enough = good.sum() >= prm.rib_min_sections
        reads.append(_rib_periodicity(s[good], cw[good], band=prm.rib_band) if enough else (math.nan, 1.0))
        lengths.append(float(np.ptp(s[good])) if enough else 0.0)
    if _ribs_in_view(reads, prm, keys) >= prm.rib_capture_p:
        return False
    clear = {i: c for i, ((q, p), length) in enumerate(zip(reads, lengths))
             if (c := _clear_pitch(q, p, length, prm)) is not None}
    fit = _pitch_table(clear, keys, prm, system=system, sizes_of=lambda i: sysm.neighbours(keys[i]))
    return fit is not None and fit[2] >= prm.min_confidence


def _pitch_settle(rows, results, keys, shadows, prm, *, system, face=None) -> None:
    """Bars left between two sizes, sized by their rib pitch where the standard sets one per size.

    Where a capture resolves ribs, each bar whose section widths are clearly periodic has a rib
    pitch (:func:`_rib_periodicity`), and GB 1499.2 sets the spacing l of each size (Φ12 8.0 mm,
    Φ14 9.0 mm: :func:`rib_pitch_mm`). A bar "not measured" because its widths lie between two
    sizes (ambiguous, crests against core, mask against point cloud: ``row["_pair"]``) is sized
    where its pitch lies within the band of exactly one of the two and they differ in l (and of
    no size between them: a pair of sizes two apart, Φ14 and Φ18, is not told apart by a pitch
    that Φ16 shares). Its pitch is its width's where that is clear, else the one both its edges
    show (:func:`_edge_pitch`), else the one the shading of its face shows (``face(i)``,
    :func:`_face_pitch`, on its visible half where it is seen from one side: read only where
    needed, once a bar).

    First the capture must show that its bars follow the table: the bars with a clear pitch (in
    their widths; where those are too few to show it, in their faces too) are grouped by
    ``keys`` (each bar's design size, else the size its width is nearest to); at least
    ``prm.rib_min_bars`` of them in groups of two or more, and in every such group most
    pitches nearest to its own size's l among the table's pitches (:func:`_pitch_table`: bars
    rolled by another standard, or a renderer's own rib spacing, fail here and the pitch is not
    used). Pitches are matched to the table times the scale they share (1 + their median
    deviation from it: the camera's depth scale or focal length a little off moves them all).
    The band (:func:`_pitch_band`) is ``prm.pitch_k`` standard errors, each the robust spread of
    those pitches about that scale (what this capture's bars and mill show) and the bar's own
    pitch resolution (half a periodogram bin, pitch / (2 x the length read)) together. The
    size's confidence is the share of the capture's clear pitches inside the band of a size the
    bar may be (its design size, the size its widths gave, or one of the two they left it
    between), (k + 1) / (n + 2): a capture with few pitches to check the table against gives a
    confidence to match, and one whose pitches often match nothing the bar may be, a low one.
    Rows are changed in place."""
    sysm = bar_system(system)
    if not sysm.rib_pitch_mm:
        return
    clear = {i: c for i, r in enumerate(results)  # bar index -> (pitch, relative resolution)
             if (c := _clear_pitch(r[3]["rib_pitch_mm"], r[3]["rib_p"], r[3]["rib_length_mm"], prm)) is not None}

    def sizes_of(i):  # what bar i may be: its design size, what its widths gave or left it between
        row = rows[i]
        return {keys[i]} | ({row["nominal_mm"]} if row["diameter_status"] == MEASURED else set(row.get("_pair", ())))

    faces = {}  # bar index -> its face's read (None: none clear), each read once

    def face_read(i):
        if i not in faces:
            faces[i] = face(i) if face is not None else None
        return faces[i]

    fit = _pitch_table(clear, keys, prm, system=system, sizes_of=sizes_of)
    if (fit is None or fit[2] < prm.min_confidence) and face is not None:
        # too few widths clearly periodic to test the table: the faces of the others may show it
        more = {i: c for i in range(len(rows)) if i not in clear and (c := face_read(i)) is not None}
        fit = _pitch_table({**clear, **more}, keys, prm, system=system, sizes_of=sizes_of)
    if fit is None or fit[2] < prm.min_confidence:
        return
    scale, spread, conf = fit
    for i, row in enumerate(rows):
        pair = row.get("_pair")
        if row["diameter_status"] != NOT_MEASURED or pair is None:
            continue
        # a bar whose width shows no clear pitch may show it along each of its edges, or in the
        # shading of its face
        read, where = (clear[i], "") if i in clear else (_edge_pitch(results[i][3], prm), " (along both edges)")
        if read is None:
            read, where = face_read(i), " (in the shading along its face)"
        if read is None:
            continue
        p, resolution = read
        ls = [rib_pitch_mm(sz, system=system) for sz in pair]
        if not all(math.isfinite(x) for x in ls):
            continue
        # The pitch must name one size among all those from one of the two to the other, not
        # only between the two (two sizes of one spacing then both match, and the pitch names
        # neither): a mask and a point cloud that disagree may leave a bar between Φ14 and Φ18,
        # and a pitch of 10 mm is Φ16's as much as Φ18's.
        band = _pitch_band(spread, resolution, prm)
        span = [sz for sz in sysm.sizes_mm if min(pair) - 1e-6 <= sz <= max(pair) + 1e-6]
        on = [sz for sz in span if abs(p / (scale * rib_pitch_mm(sz, system=system)) - 1) <= band]
        if len(on) != 1 or on[0] not in pair:
            continue
        j = list(pair).index(on[0])
        size, other = pair[j], pair[1 - j]
        why = row["diameter_reason"].removesuffix(": check it by hand")
        reason = (f"size from the rib pitch {p:.2f} mm{where}: {sysm.label(size)}'s is {ls[j]:g} mm, "
                  f"{sysm.label(other)}'s {ls[1 - j]:g} mm (the widths alone: {why})")
        width = row["width_used_mm"] if math.isfinite(row["width_used_mm"]) else results[i][3]["mask_width_mm"]
        _sized(row, size, conf, width, row["width_sigma_mm"], (row["width_source"] or "mask") + "+pitch",
               reason, shadows[i], prm)
        row["matches_design"] = _matches_design(size, row["design_diameter_mm"])


def _pitch_veto(rows, results, prm, *, system) -> None:
    """A bar sized from its widths whose own widths are clearly periodic at the rib spacing of the
    next size up (GB 1499.2 sets one per size) is not reported at the smaller size: it is "not
    measured", a possible wrong size whose reason names both.

    A mask that smooths a ribbed bar's ribs away reads its core, about the envelope of the size
    below (Φ16's core is Φ14's envelope); where the capture as a whole shows no ribs, neither
    :func:`_pitch_settle` nor the colour image's ribs (:func:`_colour_ribs`) can mend that, but
    the bar's own widths may still show its ribs' pitch. The pitch must lie within
    :func:`_pitch_band` of the next size's spacing on the read's resolution alone (no capture
    spread to add: the table was not checked against this capture) and outside its own size's.
    It overturns a size, so it asks more of the periodicity than a reported pitch does (p <
    ``prm.rib_bar_p``, 1 %): what a whole capture needs to be judged to show ribs, p <
    ``prm.rib_capture_p``. Among some 600 smooth bars a few are periodic at p ~ 10⁻³ by chance,
    one of them right at the next size's spacing (``docs/diameters.md``); the Φ16 bar read as
    Φ14 that this was written for, at 2 × 10⁻¹³. Only the size up: no mechanism reads a ribbed
    bar a size up, and chance pitches fall on either side. Rows are changed in place."""
    sysm = bar_system(system)
    if not sysm.rib_pitch_mm:
        return
    sizes = list(sysm.sizes_mm)
    for row, r in zip(rows, results):
        if (row["diameter_status"] != MEASURED or "pitch" in (row["width_source"] or "")
                or not r[3]["rib_p"] < prm.rib_capture_p):  # (stricter than _clear_pitch's p)
            continue
        read = _clear_pitch(r[3]["rib_pitch_mm"], r[3]["rib_p"], r[3]["rib_length_mm"], prm)
        j = _nearest(sizes, row["nominal_mm"])
        if read is None or j + 1 >= len(sizes):
            continue
        p, resolution = read
        own, up = rib_pitch_mm(sizes[j], system=system), rib_pitch_mm(sizes[j + 1], system=system)
        if not (math.isfinite(own) and math.isfinite(up)):
            continue
        band = _pitch_band(0.0, resolution, prm)
        if abs(p / up - 1) > band or abs(p / own - 1) <= band:
            continue
        this, next_up = sysm.label(sizes[j]), sysm.label(sizes[j + 1])
        conf = row["confidence"]
        reason = (f"possible wrong size: the widths give {this} (confidence {conf:.2f}), but "
                  f"they are periodic with a pitch of {p:.2f} mm, the rib spacing of {next_up} "
                  f"({up:g} mm; {this}'s is {own:g} mm): a mask that smooths the ribs away "
                  "reads a bar's core, a size down; check this bar by hand")
        row.update(diameter_status=NOT_MEASURED, matches_design=None, nominal_mm=math.nan,
                   confidence=0.0, diameter_reason=reason)


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
    return (f"ambiguous: width {width:.1f} mm ({source}) lies between {sysm.label(a)} ({wa:.1f} mm) and "
            f"{sysm.label(b)} ({wb:.1f} mm), nearer {sysm.label(nominal)} (confidence {conf:.2f}): check it by hand")


def _refined_decision(med, spread, n, info, in_shadow, prm, *, system, deformed, use_cloud,
                      assumed_mm=math.nan, mask_median=None, covered: float = 0.0) -> dict:
    """Size, confidence, status and reason of one bar from its mask widths and point-cloud width.

    The mask width and the point-cloud width are two independent measurements, each with a
    standard uncertainty. Where both are sound they must agree (else "not measured": one of them
    is biased) and their weighted mean is snapped; where the mask's edges are unreliable
    (scattered, off-centre) a sound point-cloud width alone gives the size, its confidence
    capped because it relies on the axis lying at the bar's centre. ``med`` is the mask's
    width (the ribs' envelope read from their crests where the capture resolves them, with
    ``info["rib_sigma_mm"]`` for how far a crest's reach varies with the bar's roll; the colour
    edges are then checked against the mask's median, ``mask_median``, the like statistic).
    ``covered``: the share of its cross-sections that lie partly under nearer bars (a bar mostly
    covered is not alerted as of another size, :func:`_alert_other_size`).
    """
    px_mm, off = info["px_mm"], abs(info["centre_mm"])
    # the colour edges of a round bar sit inside its silhouette by an amount set by the light
    # (shading towards the limbs): that common offset of the capture is not the mask's error
    cdiff = 0.0
    if math.isfinite(info["colour_width_mm"]):
        r = abs(info["colour_width_mm"] - (med if mask_median is None else mask_median)
                - info.get("colour_offset_px", 0.0) * px_mm)
        typical = prm.veto_k * info.get("colour_spread_mm", 0.0)
        cdiff = info.get("colour_weight", 1.0) * min(r, typical) + max(r - typical, 0.0)
    # A learnt mask's error is mostly a bias per bar, not noise that averages out over the
    # sections: part of the spread is kept as a systematic term.
    quant_px = prm.quantisation_px / math.sqrt(max(1.0, info.get("phase_sweep_px", 0.0)))
    # the mask's error per bar: pixel rounding and the part of its spread that is a bias of the
    # whole bar, or what the capture's bars of one size show between them if that is more
    per_bar = max(math.hypot(quant_px * px_mm, prm.mask_spread_sys * spread), info.get("mask_between_mm", 0.0))
    # a width from one edge and the axis (one-sided sections) is off by twice the axis's error
    one_sided = 2 * prm.axis_sigma_mm * info.get("one_sided_share", 0.0)
    sigma_m = math.hypot(1.2533 * spread / math.sqrt(n), per_bar, 2 * max(off - prm.axis_sigma_mm, 0.0),
                         max(cdiff - prm.colour_tolerance_px * px_mm, 0.0), one_sided, info.get("rib_sigma_mm", 0.0))
    mask_problem = ""
    if _off_centre(info, med, prm):
        mask_problem = (f"mask not centred on the axis ({off:.1f} mm off over a {med:.1f} mm width): "
                        f"one side lost to shadow or segmentation")
    elif spread > prm.max_spread_rel * med:
        mask_problem = f"mask widths too scattered (robust σ {spread:.1f} mm over {n} sections)"
    dw, d_spread, d_n = info["depth_width_mm"], info["depth_spread_mm"], info["depth_points"]
    cloud = bool(use_cloud and math.isfinite(dw))
    veto_only = use_cloud == "veto"
    sigma_c = math.inf
    if cloud:
        # depth noise grows with z²; besides its random part, the cloud of an active stereo
        # camera is off by up to about a millimetre on a bar's diameter at 500-700 mm
        sigma_c = math.hypot(1.2533 * d_spread / math.sqrt(max(d_n / prm.depth_correlated_px, 1.0)),
                             2 * prm.axis_sigma_mm, prm.cloud_bias_mm_per_m2 * (info["z_mm"] / 1000) ** 2)
    out = {"cloud_width_mm": dw, "confidence": 0.0, "diameter_status": NOT_MEASURED}
    off_bar = info.get("depth_off_share", math.nan)
    if use_cloud and off_bar > 0.5:  # (NaN: no cloud, no verdict)
        if info.get("depth_off_covered"):
            # every section under a nearer bar (a sliver beside it): the band from its one edge to
            # the axis runs under that bar, and too few of the bar's own points are left there
            out["diameter_reason"] = (
                f"{off_bar:.0%} of the point cloud between its visible edge and the axis lies on "
                "the bar over it, and too few of its own points are left to check a width from one "
                "edge")
        else:
            # the depth across the mask runs lies mostly beyond a diameter from the axis: what the
            # mask shows there is mostly another object (the bar over this one), not this bar
            out["diameter_reason"] = (
                f"{off_bar:.0%} of the point cloud across the mask runs lies farther from the axis "
                "than the bar's diameter: the mask there shows another object (a bar over it)")
        return out
    cap = 1.0
    if not mask_problem and cloud:
        # With an assumed axis radius the cloud width echoes it: a mask giving another size can
        # never be confirmed by the cloud, so in veto mode the mask must give the assumed size.
        # That size is the assumed radius's where it is known, not the echo's: where the axis is
        # off across the bar, the echo drifts with it, and so does a width from one edge to the
        # axis; the two would then agree on a wrong size (seen on a bar seen from one side only)
        nom_c = nom_m = math.nan
        conf_m = 0.0
        if veto_only:
            nom_c = (snap_diameter(2 * assumed_mm, system=system, deformed=deformed)[0] if math.isfinite(assumed_mm)
                     else snap_diameter(dw, system=system, deformed=deformed)[0])
            nom_m, conf_m = snap_diameter(med, system=system, deformed=deformed, sigma_mm=sigma_m)
        strict = veto_only and nom_c != nom_m
        if strict or abs(med - dw) > prm.veto_k * math.hypot(sigma_m, sigma_c):
            out["diameter_reason"] = (f"mask width {med:.1f} mm and point-cloud width {dw:.1f} mm disagree")
            if not veto_only:  # (veto mode has snapped both above)
                nom_m, nom_c = (snap_diameter(x, system=system, deformed=deformed)[0] for x in (med, dw))
            out["_pair"] = (nom_m, nom_c)  # the rib pitch may tell them apart (_pitch_settle)
            if veto_only:
                _alert_other_size(out, med, nom_m, conf_m, dw, nom_c, prm, covered)
                # the shape of the cloud (a circle fit) does not depend on the assumed radius: where
                # it confirms the size the mask alone gives clearly, that size is measured. Not a
                # width from one edge to the axis: the axis was placed with the assumed radius (a
                # fit over part of the bar's arc slides with it), so that width cannot overturn it
                if conf_m >= prm.min_confidence and _two_sided(info):
                    settled = _settle(out, med, sigma_m, info, in_shadow, prm, system=system,
                                      deformed=deformed, size=nom_m)
                    if settled is not None:
                        return settled
                # else the widths that depend on neither the mask nor the axis may tell the
                # mask's size from the assumed one
                return _arbitrate(out, med, conf_m, (nom_m, nom_c), info, in_shadow, prm, system=system,
                                  deformed=deformed) or out
            return out
        wm, wc = 1 / sigma_m ** 2, 1 / sigma_c ** 2
        width, sigma, source = (wm * med + wc * dw) / (wm + wc), 1 / math.sqrt(wm + wc), "mask+cloud"
        # two estimates further apart than their σ say: the σ are too small (Birge ratio)
        sigma *= max(1.0, abs(med - dw) / math.hypot(sigma_m, sigma_c))
        if veto_only:  # the cloud only checks the mask: it may echo an assumed radius
            width, sigma, source = med, sigma_m, "mask"
    elif not mask_problem:
        width, sigma, source = med, sigma_m, "mask"
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
        settled = _settle(out, med, sigma_m, info, in_shadow, prm, system=system, deformed=deformed,
                          size=nominal)
        if settled is not None:
            return settled
    if conf < prm.min_confidence:
        pair = bracketing_sizes(width, system=system, deformed=deformed)
        out.update(confidence=conf, width_source=source, width_used_mm=round(width, 3), width_sigma_mm=round(sigma, 3),
                   diameter_reason=_ambiguous_reason(width, source, conf, nominal, pair, system))
        if pair is not None:
            out["_pair"] = (pair[0][0], pair[1][0])
        return out
    reason = f"size from the point cloud; {mask_problem}" if source == "cloud" else ""
    return _sized(out, nominal, min(conf, cap), width, sigma, source, reason, in_shadow, prm)


# --------------------------------------------------------------------------------------------
# Entry point


def measure_diameters(capture, bars, mask, *, design=None, method: str = "refined",
                      system: str | None = None, deformed: bool = True, use_depth: bool = True,
                      colour_edges="check", use_cloud: bool = True,
                      paper_points: int = 20, rng=None):
    """Nominal diameter of every bar from the rebar mask and the bar axes.

    Parameters
    ----------
    capture : Capture, for the intrinsics and the colour image (shadow check)
    bars : pandas.DataFrame with :data:`BAR_COLUMNS`: axis end points over the visible extent in
        the camera frame (mm), ``layer`` "lower"/"upper", ``level`` "bottom"/"top"; optional
        ``axis_radius_mm`` or ``radius_mm`` (see ``use_cloud``); optional ``status`` (the
        geometry stage's: a bar whose axis is not "measured" is never sized from one edge)
    mask : (H, W) bool, rebar pixels (any bar); or a float rebar probability in 0..1 (e.g.
        ``segmentation.soft_mask``): the refined method then finds each edge where the profile
        crosses 0.5 to a fraction of a pixel, the paper's method uses ``mask >= 0.5``
    design : Design or None; gives each bar's design size (window size, ``matches_design``)
    method : "refined" (default) or "paper" (method.md Stage 3, faithfully)
    system : bar-size standard for snapping; default the design's ``bar_system`` or "GB1499.2"
    deformed : snap against the rib envelope (deformed bars) or the nominal size (smooth bars)
    use_depth : refined: separate a bar from a bar peeking out behind it by the depth image
        where the mask runs on past the bar's footprint, or within it over at least 2 px whose
        depth lies well behind the bar (a sliver of a bar under it, found or not by the geometry
        stage); edges at such depth steps are used only when too few sections have two clean
        mask edges. Where the runs end, at one side only, in a strip behind the bar or without
        depth (a sliver in the projector's shadow) and lie off the axis towards it, that side is
        no edge of the bar: it is sized from its other edge where its axis was measured
    colour_edges : refined: ``"check"`` (default) finds the colour edge within 2.5 px of each
        mask edge and widens the width's uncertainty by the disagreement between the colour and
        mask widths (a biased mask then gives "not measured", not a wrong size), less the
        capture's shading offset and weighted by how the two widths scatter between the
        capture's bars of one size (:func:`_colour_calibration`); ``"replace"``
        measures between the colour edges instead; False uses the mask alone
    use_cloud : refined: also measure the diameter from the point cloud (twice the median
        distance of the bar's depth points from its axis) and combine it with the mask width
        (a conflict is "not measured"; a sound cloud width alone sizes a bar whose mask is
        unreliable). Only valid when the axes were found without assuming a bar radius (true
        axes, free cylinder fits): an axis placed at the design radius below the visible
        surface makes the cloud width that radius: use ``"veto"`` then (the cloud width only
        rules out mask sizes it contradicts, "not measured"), or False (mask widths alone).
        A bar whose row in ``bars`` has a finite ``axis_radius_mm`` (the radius its axis was
        placed with; else the geometry stage's ``radius_mm`` of its fixed-radius cylinder fit)
        is always treated as ``"veto"``. In veto mode, where the mask alone is ambiguous or
        clearly gives another size than the cloud's echo, the circle fitted to the bar's cloud
        (``circle_width_mm``, independent of where the axis lies) is combined with the mask
        instead (:func:`_settle`, with the bar's height above the bars it rests on where the
        bars table has ``stack_mm``, else its top above its level's supports from ``top_mm``):
        the bar is measured where they agree and their combined width is clear,
        ``width_source`` "mask+" and the widths used, joined by "+" ("mask+circle",
        "mask+stack", "mask+level+circle", ...). Where the mask and the assumed size disagree,
        those widths alone arbitrate between the two (:func:`_arbitrate`, ``width_source`` the
        widths used: "stack", "level", "level+circle", ...): the assumed size where the mask is
        not clear about its own, the mask's size only where it is
    paper_points : detect-points per bar for ``method="paper"``
    rng : unused (the measurement is deterministic); accepted for the common signature

    Returns
    -------
    pandas.DataFrame, one row per bar, columns :data:`DIAMETER_COLUMNS`: ``width_median_mm`` and
    ``width_spread_mm`` (robust σ, IQR/1.349) of the widths over ``n_sections`` cross-sections
    (refined: between the two edges; where too few sections show both, as on a bar cut lengthwise
    by the image border, also twice one edge's distance from the axis), ``nominal_mm`` (NaN
    unless measured), ``confidence`` 0..1, ``diameter_status`` ("measured",
    "not measured", "hidden"), ``diameter_reason``, ``design_diameter_mm``, ``matches_design``
    (None unless measured with a known design), ``hidden`` (mostly covered by nearer bars),
    ``occluded_fraction`` (share of the cross-sections lying wholly or partly under nearer bars: some
    of the bar's width there is inside a nearer bar's footprint), ``one_sided_share`` (refined:
    share of the ``n_sections`` whose width is twice one edge's distance from the axis, the
    other edge at the image border, under a nearer bar or beside a strip without depth; such a
    width is off by twice any error of the axis across the bar, so it is given a larger
    uncertainty; 0 for the paper's method), ``cloud_width_mm``
    (refined: diameter from the point cloud, twice the median distance of the bar's points from
    its axis), ``width_source`` ("mask", "cloud", "mask+cloud", or "mask+" the independent widths
    of veto mode, above, or those widths alone where they arbitrated, and "+pitch" at the end
    where the rib pitch told two sizes apart, below: what the size came from), ``width_used_mm``
    (the width that was snapped; refined, also for a bar left
    ambiguous between two sizes) and ``width_sigma_mm`` (refined: its standard uncertainty, what
    the confidence is computed from with the size table's own 0.15 mm), ``circle_width_mm`` and
    ``circle_sigma_mm`` (refined, for axes placed with an assumed radius, where it is used: the
    diameter of the circle fitted to the bar's point cloud, :func:`_cloud_circle`, less the
    offset the capture's circles share against the bars their masks size clearly, and the σ it
    is used with: the fit's standard error or the circle's error per bar learnt from those bars,
    whichever is larger, :func:`_width_calibration`; else NaN). ``crest_width_mm`` and
    ``core_width_mm`` (refined, bars with at least 24 clean sections): the 95th and 10th
    percentiles of the section widths; ``rib_pitch_mm``: the period of the widths along the bar
    where it is clear (p < 1 %, :func:`_rib_periodicity`), else NaN; ``ribs_resolved`` (the same
    for every bar): the capture's bars together show ribs (:func:`_ribs_in_view`), in their mask
    widths or, where a bar's cloud would be fused with its mask, in their colour widths at the
    size table's rib spacings (:func:`_colour_ribs`: a learnt mask may smooth the ribs away). A
    deformed bar's silhouette is then its core between the ribs and the rib envelope only at the crests,
    so its median width reads about the next smaller size: each bar is sized from its crests
    (``crest_width_mm`` + 0.3 h, σ 0.3 h: how far crescent ribs reach in silhouette depends on
    the bar's roll), its point-cloud width is not used (a surface over crests and core alike),
    and a size its core (``core_width_mm`` against the standard's core diameters) does not
    confirm is "not measured". A bar left between two sizes there (ambiguous, crests against
    core, mask against cloud) is sized by its rib pitch (its width's, else both its edges' where
    they agree, :func:`_edge_pitch`, else the shading along its face or, seen from one side,
    along its visible half, :func:`_face_pitch`) where the system sets one per size
    (GB 1499.2) and the capture's bars show that they follow it (:func:`_pitch_settle`:
    ``width_source`` ending "+pitch", the reason naming the pitch and the two sizes' spacings).

    Examples
    --------
    >>> from rebarlib.synth import synth_capture, SensorModel
    >>> from rebarlib.data import paper_design
    >>> from rebarlib import GEMINI2
    >>> cap = synth_capture(paper_design(), height_mm=400, tilt_deg=0, sensor=SensorModel.ideal(),
    ...                     intrinsics=GEMINI2.scaled(0.5), seed=1)
    >>> bars = bars_from_truth(cap.truth)
    >>> table = measure_diameters(cap, bars, cap.labels > 0, design=paper_design())
    >>> upper = table.merge(bars, on="bar_id").query("layer == 'upper' and diameter_status == 'measured'")
    >>> sorted(set(upper.nominal_mm))
    [12.0]
    """
    import pandas as pd

    m, maskf = _check_inputs(capture, bars, mask, method)
    if system is None:
        system = getattr(design, "bar_system", None) or "GB1499.2"
    bar_system(system)  # validates the name
    intr = capture.intrinsics
    prepared = _prepare(bars, design, system, deformed,
                        default_expected_mm=observed_width_mm(20.0, system="GB1499.2", deformed=deformed))
    fp = _footprints(prepared, intr)
    if use_cloud not in (True, False, "veto"):
        raise RebarInputError(f"use_cloud: expected True, False or 'veto', got {use_cloud!r}")
    if colour_edges not in ("check", "replace", False, None):
        raise RebarInputError(f"colour_edges: expected 'check', 'replace' or False, got {colour_edges!r}")
    prm = _RefinedParams(colour_edges=colour_edges or False)
    gray = rgb = None
    if capture.color is not None:
        import cv2

        rgb = np.ascontiguousarray(capture.color, dtype=np.float32)
        gray = cv2.cvtColor(rgb, cv2.COLOR_RGB2GRAY)  # luminance: only compared with itself
    depth = np.asarray(capture.depth_mm, np.float32) if use_depth else None
    edge, owner = None, None
    if method == "paper":
        edge = boundary_pixels(m)
        vv, uu = np.nonzero(edge)
        owner = np.full(m.shape, -1, np.int32)  # bar index of each boundary pixel
        owner[vv, uu] = _attribute_pixels(np.column_stack((uu, vv)), prepared, intr)
    depth_img = np.asarray(capture.depth_mm, np.float32) if (use_cloud and capture.depth_mm is not None) else None
    # an axis placed with an assumed radius: its cloud width echoes that radius, so it may only
    # veto, and the circle fitted to its cloud is what can size the bar (the refined decision
    # only: the paper's method never reads it)
    cloud_mode = ["veto" if use_cloud and math.isfinite(bar.axis_radius_mm) else use_cloud for bar in prepared]
    results = [_refined_bar(i, bar, maskf, gray, depth, intr, fp, prm, rgb, depth_img,
                            circle=method == "refined" and cloud_mode[i] == "veto")
               for i, bar in enumerate(prepared)]
    for r in results:
        r[3]["mask_width_mm"] = float(np.median(r[0])) if len(r[0]) else math.nan
        r[3]["rib_sigma_mm"] = 0.0
    # Ribs resolved (refined, deformed bars): each bar's mask width is the envelope read from its
    # crests, and its point-cloud width (a surface over crests and core alike) is no envelope
    # (the bars' sizes for their rib pitches: the design's, else the size their median width is nearest)
    sizes = [b.design_mm if math.isfinite(b.design_mm) or not len(r[0])
             else snap_diameter(r[3]["mask_width_mm"], system=system, deformed=deformed)[0]
             for b, r in zip(prepared, results)]
    ribs_p = (_ribs_in_view([(r[3]["rib_pitch_mm"], r[3]["rib_p"]) for r in results], prm, sizes)
              if method == "refined" and deformed else 1.0)
    ribs = ribs_p < prm.rib_capture_p
    if method == "refined" and deformed and not ribs and colour_edges:
        # a mask that smooths the ribs away: the colour image may still show them. Where a bar's
        # point cloud would be fused with its mask width (axes found without an assumed radius),
        # both then read a ribbed bar a size down and agree. An axis placed with an assumed
        # radius vetoes that for a bar of the design size, but not for a bar one size larger
        # than designed: read a size down, it gives the design size, which the cloud echoes
        ribs = _colour_ribs(results, sizes, prm, system=system)
    for r in results:
        info = r[3]
        if ribs and math.isfinite(info["crest_mm"]):
            h = rib_height_mm(info["crest_mm"], system=system)
            info["mask_width_mm"], info["rib_sigma_mm"] = info["crest_mm"] + prm.rib_reach * h, prm.rib_reach * h
    if ribs:
        cloud_mode = [False if m is True else m for m in cloud_mode]
    _colour_calibration(results, prepared, prm)
    _mask_between_spread(results, prepared, prm)
    for i, bar in enumerate(prepared):  # only for axes placed with an assumed radius (see _settle)
        info = results[i][3]
        info["stack_width_mm"] = bar.stack_mm if cloud_mode[i] == "veto" else math.nan
        info["level_width_mm"] = bar.top_mm if cloud_mode[i] == "veto" else math.nan
        info["stack_sigma_mm"] = info["level_sigma_mm"] = 0.0
    _width_calibration(results, "circle", prm, system=system, deformed=deformed)
    _width_calibration(results, "stack", prm, system=system, deformed=deformed)
    # the bars of one level rest on the same supports: a bar's top above the formwork less the
    # supports' height, learnt from its level's bars that the mask sizes clearly
    _width_calibration(results, "level", prm, system=system, deformed=deformed,
                       groups=[(b.layer, b.level) for b in prepared])
    for r in results:  # a bar's own top counts once: where it has a stack height, that is its top
        if math.isfinite(r[3]["stack_width_mm"]) and math.isfinite(r[3]["stack_between_mm"]):
            r[3]["level_width_mm"] = math.nan
    lums = np.array([r[3]["lum"] for r in results], float)
    ref_lum = float(np.nanmedian(lums)) if np.isfinite(lums).any() else math.nan
    rows, shadows = [], []
    for i, bar in enumerate(prepared):
        w, occluded, in_img, info = results[i]
        # a bar in shadow over its whole length: its mask edges are the least reliable there is,
        # so its size is never reported with high confidence
        in_shadow = bool(np.isfinite(ref_lum) and info["lum"] < prm.shadow_ratio * ref_lum)
        n_in = int(in_img.sum())
        occ_frac = float(occluded.sum() / n_in) if n_in else 0.0
        row = {"bar_id": bar.bar_id, "width_median_mm": math.nan, "width_spread_mm": math.nan,
               "n_sections": 0, "nominal_mm": math.nan, "confidence": 0.0,
               "diameter_status": NOT_MEASURED, "diameter_reason": "", "design_diameter_mm": bar.design_mm,
               "matches_design": None, "hidden": False, "occluded_fraction": round(occ_frac, 3),
               "one_sided_share": round(info["one_sided_share"], 3) if method == "refined" else 0.0,
               "cloud_width_mm": math.nan, "width_source": "", "width_used_mm": math.nan, "width_sigma_mm": math.nan,
               "circle_width_mm": info["circle_width_mm"], "circle_sigma_mm": info["circle_sigma_mm"],
               "crest_width_mm": info["crest_mm"], "core_width_mm": info["core_mm"],
               "rib_pitch_mm": info["rib_pitch_mm"] if info["rib_p"] < prm.rib_bar_p else math.nan,
               "ribs_resolved": ribs}
        clean = len(w)  # hidden-bar detection is shared by both methods (the refined analysis)
        if method == "paper":
            w = _paper_bar(i, bar, m, edge, intr, paper_points, owner)
        if len(w):
            q1, med, q3 = np.percentile(w, [25, 50, 75])
            row.update(width_median_mm=float(med), width_spread_mm=float((q3 - q1) / 1.349), n_sections=len(w))
        few = len(w) < (1 if method == "paper" else prm.min_sections)
        if n_in == 0:
            row["diameter_reason"] = "bar axis is outside the image"
        elif clean < prm.min_sections and occ_frac >= prm.hidden_fraction:
            row.update(diameter_status=HIDDEN, hidden=True,
                       diameter_reason=(f"hidden: {occ_frac:.0%} of its cross-sections lie wholly or partly "
                                        "under nearer bars"))
            if not bar.axis_ok and info["one_edge"] >= prm.min_sections:
                # a sliver beside the bar over it: what is seen is not nothing, and the inspector
                # should know why it still gives no size
                row["diameter_reason"] += (
                    f"; {info['one_edge']} cross-sections show one edge of it beside them (a sliver): a width "
                    "from one edge needs the axis placed to a fraction of a millimetre, which a sliver "
                    "does not give without taking the bar's radius as known")
        elif few:
            why = max(("crossing", "no_edge", "border", "shadow", "outlier", "holed"), key=lambda k: info[k])
            text = {"crossing": "at crossings or next to other bars", "no_edge": "no clear mask edges",
                    "border": "at the image border", "shadow": "in shadow", "outlier": "inconsistent widths",
                    "holed": "beside a strip without depth, most likely a bar under it peeking out"}
            row["diameter_reason"] = (f"too few clean cross-sections ({len(w)} of {info['stations']}; "
                                      f"most lost {text[why]})")
        elif method == "paper":
            nominal, share = _paper_vote(w, system)
            if math.isfinite(nominal):
                row.update(nominal_mm=nominal, confidence=round(share, 3), diameter_status=MEASURED,
                           width_source="mask", width_used_mm=float(med))
            else:
                row["diameter_reason"] = f"no width within ±1 mm of a {system} size (median {med:.1f} mm)"
        elif ribs and not math.isfinite(info["crest_mm"]):
            row["diameter_reason"] = (f"ribs resolved in this capture: {len(w)} clean cross-sections are too few to "
                                      f"read the bar's rib crests (at least {prm.rib_min_sections})")
        else:
            row.update(_refined_decision(info["mask_width_mm"], row["width_spread_mm"], len(w), info, in_shadow,
                                         prm, system=system, deformed=deformed, use_cloud=cloud_mode[i],
                                         assumed_mm=bar.axis_radius_mm, mask_median=med,
                                         covered=occ_frac))
            if ribs and row["diameter_status"] == MEASURED:
                _check_core(row, info, prm, system=system)
            if (row["diameter_status"] == NOT_MEASURED and occ_frac >= prm.hidden_fraction
                    and _off_centre(info, med, prm)):
                # the side the mask lacks is most likely under the nearer bars: say so
                row["diameter_reason"] += (f"; {occ_frac:.0%} of its cross-sections lie partly under nearer bars: "
                                           "what is seen may be a sliver beside them")
        if row["diameter_status"] == MEASURED:
            row["matches_design"] = _matches_design(row["nominal_mm"], bar.design_mm)
        rows.append(row)
        shadows.append(in_shadow)
    if method == "refined" and ribs:
        _pitch_settle(rows, results, sizes, shadows, prm, system=system,
                      face=lambda i: _face_pitch(prepared[i], results[i][3], gray, intr, prm, fp, i))
    if method == "refined" and deformed:
        _pitch_veto(rows, results, prm, system=system)
    df = pd.DataFrame(rows, columns=list(DIAMETER_COLUMNS))
    df["matches_design"] = df["matches_design"].astype(object)
    return df
