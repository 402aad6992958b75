"""Cross-sections of one bar (refined method): the mask profile across the bar at many
stations along it, both edges found at sub-pixel precision, and the sections left out (at
crossings, under a nearer bar, at the image border, in deep shadow, cut at a depth step).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._camera import project
from .bars import _Bar, _candidates, _hits_footprints, _remap, _stations
from .cloud import _cloud_circle, _depth_width
from .params import DiameterParams
from .reading import BarReading
from .runs import _mask_runs
from .ribs import _rib_periodicity


def _tangent_correct(width_mm, distance_mm):
    # Silhouette rays are tangent to the cylinder: they meet γ at ±r·D/√(D² − r²), slightly
    # wider than the bar. Invert for the radius (exact for a circular cross-section).
    half = np.asarray(width_mm, float) / 2
    return 2 * half * distance_mm / np.sqrt(distance_mm**2 + half**2)

    # about d1 + 1.4h at others: crest widths are read as d1 + 1.7h ± 0.3h


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


def _thinned(idx, n: int):
    """Every k-th of ``idx``, k the smallest that leaves at most ``n`` of them."""
    return idx[:: max(1, -(-len(idx) // n))]


@dataclass
class _Sections:
    """One bar's cross-sections while they are read (mm across the bar in γ, from the axis).

    ``st`` (M, 3): the stations on the axis (camera frame); ``t`` (K,): the profile's samples
    across the bar; ``u``, ``v``, ``z`` (M, K): each sample's pixel and depth;
    ``inside_px`` (M, K): the sample lies in the image; ``in_img`` (M,): the station does. Per
    station: ``ok`` (two clean edges so far), ``one_sided``, ``occluded`` (under a nearer bar),
    ``cut`` (an edge at a depth step), the section's ``widths`` and ``centres``, its colour
    width ``colour_w``, the band the point cloud is read in (``d_centre``, ``d_width``), its two
    edges (``edge_lo``, ``edge_hi``) or its one edge (``side_lo``, ``side_hi``). From the mask
    runs: the profiles ``m``, the samples ``behind`` the bar, the runs' ends ``left`` and
    ``right`` (indices into ``t``), the sections with only their low or high edge
    (``one_lo``, ``one_hi``), the side of a strip without depth (``strip_side``) and the
    sections whose low or high end was cut where a nearer bar's shadow takes the depth
    (``shaded_lo``, ``shaded_hi``: no edge of this bar there).
    """

    st: np.ndarray
    t: np.ndarray
    u: np.ndarray
    v: np.ndarray
    z: np.ndarray
    inside_px: np.ndarray
    in_img: np.ndarray
    ok: np.ndarray = None
    one_sided: np.ndarray = None
    occluded: np.ndarray = None
    cut: np.ndarray = None
    widths: np.ndarray = None
    centres: np.ndarray = None
    colour_w: np.ndarray = None
    d_centre: np.ndarray = None
    d_width: np.ndarray = None
    edge_lo: np.ndarray = None
    edge_hi: np.ndarray = None
    side_lo: np.ndarray = None
    side_hi: np.ndarray = None
    m: np.ndarray = None
    behind: np.ndarray = None
    left: np.ndarray = None
    right: np.ndarray = None
    one_lo: np.ndarray = None
    one_hi: np.ndarray = None
    strip_side: str = ""
    shaded_lo: np.ndarray = None
    shaded_hi: np.ndarray = None


def _refined_bar(
    i, bar: _Bar, maskf, gray, depth, intr, fp, prm: DiameterParams, rgb=None, depth_img=None, circle=False
) -> BarReading:
    """Read one bar's cross-sections (refined method).

    Parameters
    ----------
    i : the bar's index in ``fp`` (its footprint; the others are the bars that may hide it)
    bar : the bar (:func:`~rebarlib.diameter.bars._prepare`)
    maskf : (H, W) float rebar probability (a bool mask as 0/1)
    gray, rgb : the colour image as luminance and as RGB (None: no colour)
    depth : (H, W) depth (mm) for separating a bar from one behind it (None: not used)
    intr : Intrinsics
    fp : the capture's footprints (:func:`~rebarlib.diameter.bars._footprints`)
    prm : DiameterParams
    depth_img : (H, W) depth (mm) for the point-cloud widths (None: not read)
    circle : also fit a circle to the bar's cloud (axes placed with an assumed radius)

    Returns
    -------
    BarReading: the kept sections' widths and everything read along the way.
    """
    sec = _profiles(bar, maskf.shape, intr, prm)
    reading = BarReading(stations=len(sec.st), border=int((~sec.in_img).sum()))
    cand = _occlusion(i, bar, sec, fp, prm)
    reading.n_occluded = int(sec.occluded.sum())
    _mask_runs(i, bar, sec, maskf, depth, intr, fp, prm, reading)
    rows = np.flatnonzero(sec.ok | sec.one_lo | sec.one_hi)
    if len(rows):
        _section_edges(i, bar, sec, rows, rgb, cand, intr, fp, prm, reading)
        if gray is not None:
            _shadowed_sections(bar, sec, gray, intr, prm, reading)
    w, c, cw, kept, cut_off = _kept_widths(bar, sec, intr, prm, reading)
    reading.one_sided_share = float(sec.one_sided[kept].mean()) if len(kept) else 0.0
    s_k = (sec.st[kept] - bar.p0) @ bar.plane.direction  # the sections' places along the bar (mm)
    # each edge along the bar, for a rib pitch read from one side at a time (_edge_pitch)
    reading.edges = (s_k, sec.edge_lo[kept], sec.edge_hi[kept])
    # (a face read from one side: _face_pitch)
    reading.one_edges = (s_k, sec.side_lo[kept], sec.side_hi[kept])
    _read_ribs(i, bar, sec, w, kept, cut_off, s_k, intr, fp, prm, reading)
    _read_cloud(bar, sec, kept, depth_img, circle, intr, prm, reading)
    _read_colour_and_place(sec, c, cw, kept, s_k, gray, intr, prm, reading)
    reading.widths, reading.occluded, reading.in_image = w, sec.occluded, sec.in_img
    return reading


def _profiles(bar: _Bar, shape, intr, prm) -> _Sections:
    """The stations along the bar's axis and the profile samples across it at each, in γ."""
    H, W = shape
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
    nan = np.full(M, np.nan)
    return _Sections(
        st,
        t,
        u,
        v,
        z,
        inside_px,
        in_img,
        ok=in_img.copy(),
        one_sided=np.zeros(M, bool),
        cut=np.zeros(M, bool),
        widths=nan.copy(),
        centres=nan.copy(),
        colour_w=nan.copy(),
        d_centre=nan.copy(),
        d_width=nan.copy(),
        edge_lo=nan.copy(),
        edge_hi=nan.copy(),
        side_lo=nan.copy(),
        side_hi=nan.copy(),
    )


def _occlusion(i, bar: _Bar, sec: _Sections, fp, prm):
    """Mark the stations whose section lies under a nearer bar across the expected width (for
    "hidden"); the bars whose footprints reach the bar's window (their indices)."""
    u, v, in_img, st, M = sec.u, sec.v, sec.in_img, sec.st, len(sec.st)
    win_uv = np.column_stack((u[in_img].ravel(), v[in_img].ravel())) if in_img.any() else np.zeros((1, 2))
    cand = _candidates(i, fp, [win_uv[:, 0].min(), win_uv[:, 1].min(), win_uv[:, 0].max(), win_uv[:, 1].max()])
    probe_t = np.array(prm.probe_fractions) * bar.expected_mm
    occluded = np.zeros(M, bool)
    if len(cand):
        P = (st[:, None, :] + probe_t[None, :, None] * bar.plane.across).reshape(-1, 3)
        _, nearer = _hits_footprints(P, fp, cand)
        occluded = nearer.any(axis=1).reshape(M, -1).any(axis=1)
    occluded &= in_img
    sec.occluded = occluded
    return cand


def _section_edges(i, bar: _Bar, sec: _Sections, rows, rgb, cand, intr, fp, prm, reading) -> None:
    """Both edges of the sections ``rows`` to a fraction of a sample, checked against the colour
    image and against the other bars' footprints; each section's width, centre and edges."""
    t, pl = sec.t, bar.plane
    la, ra = sec.left[rows], sec.right[rows]  # every usable row has its two run ends
    m = sec.m
    ma0, ma1 = m[rows, la], m[rows, la + 1]
    mb0, mb1 = m[rows, ra - 1], m[rows, ra]
    dt = t[1] - t[0]
    # sub-pixel: where the interpolated mask profile crosses 0.5
    t_lo = t[la] + np.clip((0.5 - ma0) / np.maximum(ma1 - ma0, 1e-9), 0, 1) * dt
    t_hi = t[ra - 1] + np.clip((mb0 - 0.5) / np.maximum(mb0 - mb1, 1e-9), 0, 1) * dt
    # an edge cut at a depth step lies half-way between the samples either side of it
    cut_lo, cut_hi = sec.behind[rows, la], sec.behind[rows, ra]
    t_lo = np.where(cut_lo, t[la] + dt / 2, t_lo)
    t_hi = np.where(cut_hi, t[ra] - dt / 2, t_hi)
    two = sec.ok[rows]
    has_lo, has_hi = two | sec.one_lo[rows], two | sec.one_hi[rows]
    # a one-sided section's edge must be a clean mask edge
    has_lo &= ~(cut_lo & ~two)
    has_hi &= ~(cut_hi & ~two)
    sec.cut[rows] = two & (cut_lo | cut_hi)
    if rgb is not None and prm.colour_edges and two.any():
        _colour_check(sec, rows, two, t_lo, t_hi, cut_lo, cut_hi, rgb, intr, prm, reading)
    bad_lo, bad_hi = _edges_at_other_bars(i, sec, rows, t_lo, t_hi, two, has_lo, has_hi, cand, pl, intr, fp, reading)
    if sec.strip_side:  # nor is the end at a strip without depth beside the bar (_mask_runs)
        reading.holed = int(two.sum())
        bad_lo |= sec.strip_side == "lo"
        bad_hi |= sec.strip_side == "hi"
    if sec.shaded_lo is not None:  # nor an end cut where a nearer bar's shadow begins
        bad_lo |= sec.shaded_lo[rows]
        bad_hi |= sec.shaded_hi[rows]
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
    sec.colour_w[rows[~is_two]] = np.nan
    sec.ok[rows] = is_two
    sec.one_sided[rows] = is_one
    sec.widths[rows] = np.where(is_two, t_hi - t_lo, np.where(has_lo, -2 * t_lo, 2 * t_hi))
    sec.centres[rows] = np.where(is_two, (t_hi + t_lo) / 2, 0.0)
    sec.edge_lo[rows] = np.where(is_two, t_lo, np.nan)
    sec.edge_hi[rows] = np.where(is_two, t_hi, np.nan)
    sec.side_lo[rows] = np.where(is_one & has_lo, t_lo, np.nan)
    sec.side_hi[rows] = np.where(is_one & has_hi, t_hi, np.nan)
    # the point cloud of a one-sided section: from the visible half, between edge and axis
    sec.d_centre[rows] = np.where(is_two, sec.centres[rows], np.where(has_lo, t_lo, t_hi) / 2)
    sec.d_width[rows] = np.where(is_two, sec.widths[rows], sec.widths[rows] / 2)
    # one-sided sections only where the sections with both edges are too few to size the
    # bar and fewer than the one-sided ones (a bar along the image border, or along a bar
    # over it): elsewhere the width does not depend on where the axis lies across the bar
    if int(sec.ok.sum()) >= max(prm.min_sections, int(sec.one_sided.sum())):
        sec.one_sided[:] = False


def _colour_check(sec: _Sections, rows, two, t_lo, t_hi, cut_lo, cut_hi, rgb, intr, prm, reading) -> None:
    """The colour edges next to the two-edged sections' mask edges: their widths
    (``sec.colour_w``), and with ``prm.colour_edges == "replace"`` the edges themselves (in
    place in ``t_lo``, ``t_hi``; never an edge cut at a depth step)."""
    r2 = rows[two]
    g = _remap(rgb, sec.u[r2], sec.v[r2])
    c_lo, c_hi, moved = _colour_edges_rgb(g, sec.t, t_lo[two], t_hi[two], sec.st[r2, 2] / intr.fx, prm)
    reading.colour_edges = int(moved.sum())
    both = ~cut_lo[two] & ~cut_hi[two] & (c_lo != t_lo[two]) & (c_hi != t_hi[two])
    sec.colour_w[r2[both]] = (c_hi - c_lo)[both]
    if prm.colour_edges == "replace":
        t_lo[two] = np.where(cut_lo[two], t_lo[two], c_lo)
        t_hi[two] = np.where(cut_hi[two], t_hi[two], c_hi)


def _edges_at_other_bars(i, sec: _Sections, rows, t_lo, t_hi, two, has_lo, has_hi, cand, pl, intr, fp, reading):
    """Per section of ``rows``, whether its low and its high edge may belong to another bar:
    inside the footprint of a nearer bar (ours is occluded there), or beyond our own expected
    width and inside a farther bar's footprint (our run merged with the bar behind)."""
    bad_lo = np.zeros(len(rows), bool)
    bad_hi = np.zeros(len(rows), bool)
    if len(cand):
        st = sec.st
        px_mm = st[rows, 2] / intr.fx
        tt = np.column_stack((t_lo - 1.5 * px_mm, t_lo, t_lo + px_mm, t_hi - px_mm, t_hi, t_hi + 1.5 * px_mm))
        P = (st[rows][:, None, :] + tt[:, :, None] * pl.across).reshape(-1, 3)
        inside, nearer = _hits_footprints(P, fp, cand)
        beyond = (np.abs(tt) > fp.half_mm[i]).reshape(-1)
        bad = (nearer.any(axis=1) | (inside.any(axis=1) & beyond)).reshape(len(rows), -1)
        bad_lo, bad_hi = bad[:, :3].any(axis=1), bad[:, 3:].any(axis=1)
        reading.crossing = int((two & (bad_lo | bad_hi)).sum())
        # sections with one clean edge and the other at another bar (a sliver beside it)
        reading.one_edge = int(((has_lo & ~bad_lo) ^ (has_hi & ~bad_hi)).sum())
    return bad_lo, bad_hi


def _shadowed_sections(bar: _Bar, sec: _Sections, gray, intr, prm, reading) -> None:
    """Drop the sections whose middle is much darker than the bar usually is (in shadow): the
    station on the axis, the middle of the visible part for a one-sided section."""
    ok, one_sided, t = sec.ok, sec.one_sided, sec.t
    K = len(t)
    rows = np.flatnonzero(ok | one_sided)
    if len(rows) >= prm.min_sections:
        pos = np.where(
            ok[rows], 0.0, (t[np.clip(sec.left[rows] + 1, 0, K - 1)] + t[np.clip(sec.right[rows] - 1, 0, K - 1)]) / 2
        )
        uvc = project(sec.st[rows] + pos[:, None] * bar.plane.across, intr)
        lum = _remap(gray, uvc[:, 0:1], uvc[:, 1:2])[:, 0]
        dark = lum < prm.shadow_ratio * np.median(lum)
        if (len(rows) - dark.sum()) >= prm.min_sections:
            reading.shadow = int(dark.sum())
            ok[rows[dark]] = False
            one_sided[rows[dark]] = False


def _kept_widths(bar: _Bar, sec: _Sections, intr, prm, reading):
    """The sections the bar is sized from: ``(widths, centres, colour widths, their stations'
    indices, the sections left out for an edge at a depth step)``; widths corrected for
    silhouette rays tangent to the bar, outliers left out."""
    ok, cut, st, pl = sec.ok, sec.cut, sec.st, bar.plane
    # edges from the mask are sharper than edges at depth steps (a depth camera fattens a nearer
    # object's edge): use the latter only if needed, that is unless the sections with mask edges
    # alone are enough with room for the outliers dropped below (twice the minimum: with just
    # the minimum, one outlier left a bar with hundreds of sections "too few")
    cut_off = np.zeros(len(st), bool)  # sections left out for their edge at a depth step
    if (ok & ~cut).sum() >= 2 * prm.min_sections:
        reading.depth_cut = int((ok & cut).sum())
        cut_off = ok & cut
        ok &= ~cut
    sel = ok | sec.one_sided
    kept = np.flatnonzero(sel)
    w = _tangent_correct(sec.widths[sel], pl.offset_mm)
    c = sec.centres[sel]
    cw = _tangent_correct(sec.colour_w[sel], pl.offset_mm)
    if len(w) >= 3:
        med = np.median(w)
        mad = 1.4826 * np.median(np.abs(w - med))
        px_mm = float(np.median(st[sel, 2])) / intr.fx
        keep = np.abs(w - med) <= max(prm.outlier_k * mad, prm.outlier_floor_px * px_mm)
        reading.outlier = int((~keep).sum())
        w, c, cw, kept = w[keep], c[keep], cw[keep], kept[keep]
    return w, c, cw, kept, cut_off


def _read_ribs(i, bar: _Bar, sec: _Sections, w, kept, cut_off, s_k, intr, fp, prm, reading) -> None:
    """The crests and core of the bar's widths and, where they differ by more than the pixel
    grid's steps, the period of the widths along the bar (its rib pitch)."""
    st = sec.st
    if len(w) >= prm.rib_min_sections:  # a high quantile of fewer sections is their largest one
        reading.crest_mm, reading.core_mm = (float(q) for q in np.quantile(w, [prm.crest_quantile, prm.core_quantile]))
    # A binary mask's width along a slanted bar steps by a pixel periodically as its edges cross
    # the pixel rows: a periodicity within that is the pixel grid's, not ribs'
    if math.isfinite(reading.crest_mm) and reading.crest_mm - reading.core_mm >= (
        prm.rib_min_px * float(np.median(st[kept, 2])) / intr.fx
    ):
        reading.rib_pitch_mm, reading.rib_p = _rib_periodicity(s_k, w, band=prm.rib_band)
        reading.rib_length_mm = float(s_k.max() - s_k.min())
    # The crests are the widest sections, and where a bar's silhouette touches one beside it
    # (a bar under it peeking out) they are the sections whose runs merge with it and are cut
    # at the depth step, left out above: the crests would then be read from the core between
    # them (a Φ12 bar beside a lower bar read 11.6 mm over its crests, 12.9 mm with them). A cut
    # section ends at the first sample behind the bar or without depth: at its flank, or inside
    # it where the flank has no depth. So the crests are read over the cut sections too, those
    # within the bar's footprint (room for a size larger).
    if math.isfinite(reading.crest_mm) and cut_off.any():
        wc = _tangent_correct(sec.widths[cut_off], bar.plane.offset_mm)
        wc = wc[np.isfinite(wc) & (wc <= 2 * fp.half_mm[i])]
        if len(wc):
            reading.crest_mm = float(np.quantile(np.concatenate([w, wc]), prm.crest_quantile))


def _read_cloud(bar: _Bar, sec: _Sections, kept, depth_img, circle, intr, prm, reading) -> None:
    """The bar's diameter from its point cloud (:func:`_depth_width`) and, for an axis placed
    with an assumed radius (``circle``), the circle fitted to it (:func:`_cloud_circle`)."""
    st, pl, occluded = sec.st, bar.plane, sec.occluded
    # the point cloud gives several points per section: every few sections of a long bar suffice
    ck = _thinned(kept, prm.cloud_sections)
    (reading.depth_width_mm, reading.depth_spread_mm, reading.depth_points, reading.depth_off_share) = (
        _depth_width(depth_img, intr, pl, st[ck], sec.d_centre[ck], sec.d_width[ck], prm, bar.expected_mm, occluded[ck])
        if depth_img is not None
        else (math.nan, math.nan, 0, math.nan)
    )
    # that share was read where every section lies under a nearer bar
    reading.depth_off_covered = bool(len(ck) and occluded[ck].all())
    if depth_img is not None and circle:  # (only for axes placed with an assumed radius)
        two_k = _thinned(kept[~sec.one_sided[kept]], prm.cloud_sections)
        reading.circle_width_mm, reading.circle_sigma_mm = _cloud_circle(
            depth_img, intr, pl, st[two_k], sec.centres[two_k], sec.widths[two_k], prm
        )


def _read_colour_and_place(sec: _Sections, c, cw, kept, s_k, gray, intr, prm, reading) -> None:
    """The colour widths, how far the mask runs are centred off the axis, the pixel's footprint
    and depth, the pixel phases the edges sweep and the bar's luminance."""
    st, in_img = sec.st, sec.in_img
    # The colour edges next to the mask edges are an independent check of the mask: where the
    # two widths disagree the mask may be biased (a learnt mask bleeding into a shadow or eating
    # into a dark bar), and the width is no better known than their difference.
    # (along the bar, for a capture whose mask smooths its ribs away: _colour_ribs)
    reading.colour_widths = (s_k, cw)
    cw = cw[np.isfinite(cw)]
    reading.colour_width_mm = float(np.median(cw)) if len(cw) >= prm.min_sections else math.nan
    # A mask run off-centre from the axis has lost one side (shadow, poor segmentation) or
    # the axis is off: either way the width may be wrong by twice the offset.
    two_kept = ~sec.one_sided[kept]  # a one-sided section has no centre of its own
    reading.centre_mm = float(np.median(c[two_kept])) if two_kept.any() else (0.0 if len(c) else math.nan)
    reading.px_mm = float(np.median(st[:, 2])) / intr.fx
    # How many pixel phases the bar's edges sweep over the sections kept: a binary mask puts an
    # edge on the pixel grid, so along a bar parallel to a pixel row every section has the same
    # rounding; a slanted bar's edges cross the grid min(|du|, |dv|) times and the rounding
    # averages out over the sections.
    if len(kept) >= 2:
        uv_k = project(st[kept[[0, -1]]], intr)
        reading.phase_sweep_px = float(np.abs(uv_k[1] - uv_k[0]).min())
    reading.z_mm = float(np.median(st[:, 2]))
    if gray is not None and in_img.any():
        uvc = project(st[in_img], intr)
        reading.lum = float(np.median(_remap(gray, uvc[:, 0:1], uvc[:, 1:2])))
