"""The mask run through the axis in each cross-section of one bar (refined method,
:mod:`rebarlib.diameter.sections`): its ends cut where it runs on into a bar behind (by the
depth), a strip of a bar under this one peeking out in the projector's shadow, and which
sections have both edges or one edge and the image border on the other side.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from .bars import _Bar, _remap

if TYPE_CHECKING:
    from .sections import _Sections

__all__: list = []


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


def _shaded_end(end, end2, behind, deep, nearer, b) -> np.ndarray:
    """Per section, whether the mask run's end ``end2`` (cut where the depth ends) lies at the
    edge of a nearer bar's projector shadow rather than at this bar's own edge: the first
    sample cut off has no depth (not a surface behind), and the rebar run goes on from there,
    still without depth or with depth nearer than this bar, into a nearer bar (``nearer``)
    before it ends at ``end``. A bar lying beside the bar over it in the image, its side towards
    that bar in that bar's shadow, shows its whole width in colour but depth over part of it
    only; the end of its depth is not its edge (a bar that casts the shadow itself onto a bar
    behind it keeps the edge: beyond the hole the run reaches a surface behind)."""
    M, K = b.shape
    idx = np.arange(K)[None, :]
    lo, hi = np.minimum(end, end2), np.maximum(end, end2)
    between = (idx > lo[:, None]) & (idx < hi[:, None])
    first = np.clip(end2, 0, K - 1)
    hole = behind[np.arange(M), first] & ~deep[np.arange(M), first] & (end2 != end)
    # between the cut and the run's end: rebar samples only, none of them deep behind this bar,
    # and some of them nearer than it
    clean = ~(between & deep).any(axis=1)
    return hole & clean & (between & nearer).any(axis=1)


def _holed_side(t, left, right, left2, right2, rows, sample_px, prm, hollow=None) -> str:
    """ "lo" or "hi" where the bar's mask runs (ends ``left``, ``right``: indices into the profile
    ``t``; ``left2``, ``right2``: the same ends with the samples behind the bar or without depth
    left out) end, at that side only, in a strip behind the bar or without depth at least
    ``prm.sliver_min_px`` wide and half that wider than at the other end (medians over the
    sections ``rows``), and are off the axis towards it by at least a quarter of the difference
    and twice the axis's lateral tolerance: what a sliver of a bar under this one does in the
    projector's shadow. "" otherwise (a bar's own edges lose a pixel or so of depth at grazing
    angles, on both sides alike, and its runs stay centred).

    A run that goes on to the end of the profile at one side, over a strip mostly without depth
    (``hollow``: (M, K) rebar samples without depth beside a bar that has depth), is read too,
    with that end where the profile ends: its strip and its centre's lean are then lower bounds.
    A bar under this one wholly in its projector's shadow gives such a strip, wider than the room
    the profile leaves beside the bar (docs/decisions/067). Where the strip past the profile has
    depth, the depth step already placed the edge; a run over the whole profile is not read."""
    K = len(t)
    inside = (left >= 0) & (right < K)
    if hollow is not None:
        idx = np.arange(K)[None, :]
        past_lo = (left < 0) & (right < K)
        past_hi = (left >= 0) & (right >= K)
        strip = (past_lo[:, None] & (idx < left2[:, None])) | (past_hi[:, None] & (idx > right2[:, None]))
        n = strip.sum(axis=1)
        inside |= (past_lo | past_hi) & (n > 0) & (2 * (strip & hollow).sum(axis=1) >= n)
    rows = np.flatnonzero(rows & inside)
    if len(rows) < prm.min_sections:
        return ""
    px = sample_px[rows]
    s_lo = float(np.median((left2 - left)[rows] * px))  # (an end past the profile's is -1 or K)
    s_hi = float(np.median((right - right2)[rows] * px))
    px_mm = float(np.median((t[1] - t[0]) / px))
    centre = float(np.median(t[left[rows] + 1] + t[right[rows] - 1])) / 2 / px_mm  # px, + to hi
    for side, strip, other, sign in (("hi", s_hi, s_lo, 1.0), ("lo", s_lo, s_hi, -1.0)):
        # off-centre by more than the axis's own lateral error could make it
        if (
            strip >= prm.sliver_min_px
            and strip - other >= prm.sliver_min_px / 2
            and sign * centre >= max((strip - other) / 4, 2 * prm.axis_sigma_mm / px_mm)
        ):
            return side
    return ""


def _mask_runs(i, bar: _Bar, sec: _Sections, maskf, depth, intr, fp, prm, reading) -> None:
    """The mask run through the axis in every section, its ends cut where it runs on into a
    bar behind (by the depth), and which sections have both edges, or one edge and the image
    border on the other side."""
    u, v, t, st = sec.u, sec.v, sec.t, sec.st
    in_img = sec.in_img
    K = u.shape[1]
    m = _remap(maskf, u, v)  # (M, K) mask profile across the bar, 0..1
    b = m >= 0.5
    behind, deep, nearer = _behind(bar, sec, b, depth, prm)
    kc = K // 2
    idx = np.arange(K)
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
    sec.strip_side = (
        ""
        if depth is None
        else _holed_side(t, left, right, left2, right2, in_img & has_seed, sample_px, prm, hollow=behind & ~deep)
    )
    sec.shaded_lo = too_far_lo & _shaded_end(left, left2, behind, deep, nearer, b)
    sec.shaded_hi = too_far_hi & _shaded_end(right, right2, behind, deep, nearer, b)
    left = np.where(too_far_lo, left2, left)
    right = np.where(too_far_hi, right2, right)
    _edges_or_border(bar, sec, left, right, has_seed, reading)
    sec.m, sec.behind, sec.left, sec.right = m, behind, left, right


def _behind(bar: _Bar, sec: _Sections, b, depth, prm) -> tuple:
    """Which mask samples of the sections lie behind the bar, by the depth: mask pixels whose
    depth lies well behind this bar belong to a bar under it that peeks out beside it (the
    mask alone cannot separate the two, the point cloud can).

    Parameters
    ----------
    bar : _Bar
    sec : _Sections
        The sections (their sample pixels ``u``, ``v``, across-offsets ``t``, axis depth ``z``).
    b : ndarray of bool
        (M, K) the mask samples that are rebar.
    depth : ndarray or None
        The depth image (mm); None reads no depth (nothing behind).
    prm : DiameterParams

    Returns
    -------
    behind : ndarray of bool
        (M, K) rebar samples behind the bar, or without depth where the bar itself has depth
        (beside a bar the projector's shadow often hides the bar behind).
    deep : ndarray of bool
        (M, K) rebar samples behind the bar with a valid depth.
    nearer : ndarray of bool
        (M, K) rebar samples with a valid depth well in front of the bar (a bar over it).
    """
    behind = np.zeros_like(b)
    deep = np.zeros_like(b)
    if depth is None:
        return behind, deep, np.zeros_like(b)
    import cv2

    t, z, in_img = sec.t, sec.z, sec.in_img
    dz = cv2.remap(
        depth,
        sec.u.astype(np.float32),
        sec.v.astype(np.float32),
        cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=0,
    )
    # no depth counts too, unless the bar itself has none (then the pixels without depth are
    # its own)
    deep = b & (dz > z + bar.expected_mm / 2 + prm.behind_mm)
    core = np.abs(t) <= bar.expected_mm / 4
    own_none = in_img.any() and float((dz[in_img][:, core] <= 0).mean()) >= prm.own_no_depth_share
    behind = deep if own_none else deep | (b & (dz <= 0))
    nearer = b & (dz > 0) & (dz < z - bar.expected_mm / 2 - prm.behind_mm)
    return behind, deep, nearer


def _edges_or_border(bar: _Bar, sec: _Sections, left, right, has_seed, reading) -> None:
    """Which sections have both edges, and which one edge with the image border on the other
    side. An edge is where the run meets a non-bar sample inside the image; a run that meets
    the image border there has that side cut off by the border (not the bar's edge).

    Sets ``sec.ok`` (both edges), ``sec.one_lo`` / ``sec.one_hi`` (the low / high edge only)
    and counts the sections at the border and without an edge in ``reading``.

    Parameters
    ----------
    bar : _Bar
    sec : _Sections
    left, right : ndarray of int
        Each section's run ends (sample indices; -1 / K where the run reaches the end).
    has_seed : ndarray of bool
        Whether each section has a run through the axis.
    reading : BarReading
    """
    K = sec.u.shape[1]
    rr = np.arange(sec.u.shape[0])
    in_lo = sec.inside_px[rr, np.clip(left, 0, K - 1)]
    in_hi = sec.inside_px[rr, np.clip(right, 0, K - 1)]
    lo_edge, hi_edge = has_seed & (left >= 0) & in_lo, has_seed & (right < K) & in_hi
    lo_border, hi_border = has_seed & (left >= 0) & ~in_lo, has_seed & (right < K) & ~in_hi
    edged = has_seed & (left >= 0) & (right < K)
    at_border = edged & ~(in_lo & in_hi)
    edged &= ~at_border
    reading.border += int((sec.ok & at_border).sum())
    reading.no_edge = int((sec.ok & ~edged & ~at_border).sum())
    sec.ok &= edged
    # One-sided sections: one edge, the other side cut by the image border (or, below, inside
    # another bar's footprint). The width is then twice the edge's distance from the axis: it
    # needs the axis in the bar's middle to a fraction of a millimetre, so only for axes the
    # geometry stage measured, only where the axis itself is in view (at least half the bar's
    # width is), and only where too few sections show both edges (see _section_edges).
    sec.one_lo = lo_edge & hi_border & sec.in_img & bar.axis_ok  # the low edge only
    sec.one_hi = hi_edge & lo_border & sec.in_img & bar.axis_ok
