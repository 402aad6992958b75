"""Cross-sections of one bar (refined method): the mask profile across the bar at many
stations along it, both edges found at sub-pixel precision, and the sections left out (at
crossings, under a nearer bar, at the image border, in deep shadow, cut at a depth step).
"""

from __future__ import annotations

import math

import numpy as np

from .._camera import project
from .bars import _Bar, _candidates, _hits_footprints, _remap, _stations
from .cloud import _cloud_circle, _depth_width
from .params import _RefinedParams
from .reading import BarReading
from .ribs import _rib_periodicity


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
    info = BarReading(stations=M, border=int((~in_img).sum()))
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
    info.n_occluded = int(occluded.sum())

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
    info.border += int((ok & at_border).sum())
    info.no_edge = int((ok & ~edged & ~at_border).sum())
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
            info.colour_edges = int(moved.sum())
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
            info.crossing = int((two & (bad_lo | bad_hi)).sum())
            # sections with one clean edge and the other at another bar (a sliver beside it)
            info.one_edge = int(((has_lo & ~bad_lo) ^ (has_hi & ~bad_hi)).sum())
        if strip_side:  # nor is the end at a strip without depth beside the bar (above)
            info.holed = int(two.sum())
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
                    info.shadow = int(dark.sum())
                    ok[rows[dark]] = False
                    one_sided[rows[dark]] = False
    # edges from the mask are sharper than edges at depth steps (a depth camera fattens a nearer
    # object's edge): use the latter only if needed, that is unless the sections with mask edges
    # alone are enough with room for the outliers dropped below (twice the minimum: with just
    # the minimum, one outlier left a bar with hundreds of sections "too few")
    cut_off = np.zeros(M, bool)  # sections left out for their edge at a depth step
    if (ok & ~cut).sum() >= 2 * prm.min_sections:
        info.depth_cut = int((ok & cut).sum())
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
        info.outlier = int((~keep).sum())
        w, c, cw, kept = w[keep], c[keep], cw[keep], kept[keep]
    info.one_sided_share = float(one_sided[kept].mean()) if len(kept) else 0.0
    info.rib_pitch_mm, info.rib_p, info.crest_mm, info.core_mm = math.nan, 1.0, math.nan, math.nan
    info.rib_length_mm = math.nan
    s_k = (st[kept] - bar.p0) @ pl.direction  # the sections' places along the bar (mm)
    # each edge along the bar, for a rib pitch read from one side at a time (_edge_pitch)
    info.edges = (s_k, edge_lo[kept], edge_hi[kept])
    info.one_edges = (s_k, side_lo[kept], side_hi[kept])  # (a face read from one side: _face_pitch)
    if len(w) >= prm.rib_min_sections:  # a high quantile of fewer sections is their largest one
        info.crest_mm, info.core_mm = (float(q) for q in np.quantile(w, [prm.crest_quantile,
                                                                               prm.core_quantile]))
    # A binary mask's width along a slanted bar steps by a pixel periodically as its edges cross
    # the pixel rows: a periodicity within that is the pixel grid's, not ribs'
    if math.isfinite(info.crest_mm) and info.crest_mm - info.core_mm >= prm.rib_min_px * float(
            np.median(st[kept, 2])) / intr.fx:
        info.rib_pitch_mm, info.rib_p = _rib_periodicity(s_k, w, band=prm.rib_band)
        info.rib_length_mm = float(s_k.max() - s_k.min())
    # The crests are the widest sections, and where a bar's silhouette touches one beside it
    # (a bar under it peeking out) they are the sections whose runs merge with it and are cut
    # at the depth step, left out above: the crests would then be read from the core between
    # them (a Φ12 bar beside a lower bar read 11.6 mm over its crests, 12.9 mm with them). A cut
    # section ends at the first sample behind the bar or without depth: at its flank, or inside
    # it where the flank has no depth. So the crests are read over the cut sections too, those
    # within the bar's footprint (room for a size larger).
    if math.isfinite(info.crest_mm) and cut_off.any():
        wc = _tangent_correct(widths[cut_off], pl.offset_mm)
        wc = wc[np.isfinite(wc) & (wc <= 2 * fp.half_mm[i])]
        if len(wc):
            info.crest_mm = float(np.quantile(np.concatenate([w, wc]), prm.crest_quantile))
    # the point cloud gives several points per section: every few sections of a long bar suffice
    ck = _thinned(kept, prm.cloud_sections)
    info.depth_width_mm, info.depth_spread_mm, info.depth_points, info.depth_off_share = _depth_width(
        depth_img, intr, pl, st[ck], d_centre[ck], d_width[ck], prm, bar.expected_mm,
        occluded[ck]) if depth_img is not None else (math.nan, math.nan, 0, math.nan)
    # that share was read where every section lies under a nearer bar
    info.depth_off_covered = bool(len(ck) and occluded[ck].all())
    info.circle_width_mm = info.circle_sigma_mm = math.nan
    if depth_img is not None and circle:  # only used where the axis was placed with an assumed radius
        two_k = _thinned(kept[~one_sided[kept]], prm.cloud_sections)
        info.circle_width_mm, info.circle_sigma_mm = _cloud_circle(
            depth_img, intr, pl, st[two_k], centres[two_k], widths[two_k], prm)
    # The colour edges next to the mask edges are an independent check of the mask: where the
    # two widths disagree the mask may be biased (a learnt mask bleeding into a shadow or eating
    # into a dark bar), and the width is no better known than their difference.
    # (along the bar, for a capture whose mask smooths its ribs away: _colour_ribs)
    info.colour_widths = (s_k, cw)
    cw = cw[np.isfinite(cw)]
    info.colour_width_mm = float(np.median(cw)) if len(cw) >= prm.min_sections else math.nan
    # A mask run off-centre from the axis has lost one side (shadow, poor segmentation) or
    # the axis is off: either way the width may be wrong by twice the offset.
    two_kept = ~one_sided[kept]  # a one-sided section has no centre of its own
    info.centre_mm = float(np.median(c[two_kept])) if two_kept.any() else (0.0 if len(c) else math.nan)
    info.px_mm = float(np.median(st[:, 2])) / intr.fx
    # How many pixel phases the bar's edges sweep over the sections kept: a binary mask puts an
    # edge on the pixel grid, so along a bar parallel to a pixel row every section has the same
    # rounding; a slanted bar's edges cross the grid min(|du|, |dv|) times and the rounding
    # averages out over the sections.
    info.phase_sweep_px = 0.0
    if len(kept) >= 2:
        uv_k = project(st[kept[[0, -1]]], intr)
        info.phase_sweep_px = float(np.abs(uv_k[1] - uv_k[0]).min())
    info.z_mm = float(np.median(st[:, 2]))
    info.lum = math.nan
    if gray is not None and in_img.any():
        uvc = project(st[in_img], intr)
        info.lum = float(np.median(_remap(gray, uvc[:, 0:1], uvc[:, 1:2])))
    info.widths, info.occluded, info.in_image = w, occluded, in_img
    return info
