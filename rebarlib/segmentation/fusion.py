"""Fusing the colour mask (sharp edges) with the depth mask (presence light cannot fool).

:func:`depth_overreach_px` and :func:`trim_depth_overreach` take the depth's edge fattening off
first; :func:`fuse_masks` combines the two; :func:`soft_mask` makes the result soft again with the
model's probability, for sub-pixel edges.
"""

from __future__ import annotations

import numpy as np

from .._checks import RebarInputError

__all__ = ["depth_overreach_px", "trim_depth_overreach", "fuse_masks", "soft_mask"]


def _two_masks(color_mask, depth_mask):
    """(colour, depth) as bool arrays of one (H, W) shape, else an input error naming it."""
    c = np.asarray(color_mask).astype(bool)
    d = np.asarray(depth_mask).astype(bool)
    if c.shape != d.shape or c.ndim != 2:
        raise RebarInputError(f"depth_mask: expected the shape of color_mask {c.shape}, got {d.shape}")
    return c, d


def depth_overreach_px(
    color_mask,
    depth_mask,
    *,
    color_proba=None,
    low_proba: float = 0.2,
    depth_valid=None,
    max_px: int = 6,
    min_pixels: int = 100,
) -> int:
    """How many pixels the depth's bars reach beyond the colour's, on most rows of every side.

    A stereo camera's matching window straddles a bar's edge and gives the background beside it
    the bar's depth (edge fattening, docs/sensors.md: "a few pixels"); flying pixels do so now
    and then. Ring ``j`` is the pixels ``j`` px (± 0.5) outside the colour mask that the colour
    calls background (probability under ``low_proba`` where ``color_proba`` is given), split by
    the side of the bar they lie on (left, right, above, below: the direction away from the
    colour mask). A side is read where at least ``min_pixels`` of its ring have depth and its
    share with depth is at least half the best side's (a side in the projector's shadow has
    few, and those few lie beside the shadow, where no fattening is). The over-reach is the
    largest ``j`` at which the depth marks at least half of the ring's pixels with depth as bar
    on every side read: beyond that, more than half of a bar's rows would be widened by the
    depth, and the median of its widths with them. Fattening widens a bar on every side; a
    depth image moved against the colour one (misregistration, :func:`estimate_registration`)
    reaches beyond some sides and falls short of the others. With three or four sides read,
    that shows in the rings. With two (one across each direction, the others in the shadow),
    a diagonal move would look the same, so the depth must also mark as bar at least half of
    the pixels 1 px inside the colour mask that have depth (where the colour is sure) on every
    side: a depth image moved away from a side leaves them to the formwork or the shadow. 0
    where half of ring 1 is not reached on a side read, or too few sides are read (a fattening
    now and then leaves a median where the colour puts it). Measured at 500 mm (ring 1, all
    sides together): 0.22 with the benchmark's default sensor (0), 0.63 with 3 px of stereo
    fattening (1), 0.43 with three times the flying pixels (0), 0.03 without edge effects (0).

    Parameters
    ----------
    color_mask, depth_mask : (H, W) bool rebar masks from colour and from depth (anything
        non-zero is rebar)
    color_proba : (H, W) float rebar probability of the colour model, optional; default the
        colour mask as 1 / 0 (every pixel outside it is background)
    low_proba : a ring's pixel counts as background only where ``color_proba`` is under this;
        a pixel 1 px inside the colour mask counts as sure only where it is over ``1 - low_proba``
        (``inspect`` passes the model's threshold: the mask's own edge, decision 053)
    depth_valid : (H, W) bool, where depth exists (e.g. ``capture.depth_mm > 0``); default all
    max_px : the farthest ring looked at, px: the largest over-reach returned
    min_pixels : fewest pixels with depth in a side's ring for that side to be read (and
        1 px inside the colour mask, for that side to be checked there)

    Returns
    -------
    int in ``0..max_px``, the over-reach in pixels, for :func:`trim_depth_overreach` (and
    ``overreach_px`` of :func:`fuse_masks`).

    Examples
    --------
    >>> color = np.zeros((60, 60), bool); color[:, 25:35] = True; color[25:35, :] = True
    >>> depth = np.zeros((60, 60), bool); depth[:, 23:37] = True; depth[23:37, :] = True
    >>> depth_overreach_px(color, depth, min_pixels=10)   # 2 px wider on every side
    2
    >>> depth_overreach_px(color, np.roll(depth, 2, axis=1), min_pixels=10)   # moved, not wider
    0
    """
    import cv2

    c, d = _two_masks(color_mask, depth_mask)
    valid = np.ones_like(c) if depth_valid is None else np.asarray(depth_valid).astype(bool)
    p = np.where(c, 1.0, 0.0) if color_proba is None else np.asarray(color_proba, dtype=np.float32)
    if p.shape != c.shape or valid.shape != c.shape:
        raise RebarInputError(
            f"color_proba, depth_valid: expected the shape of color_mask {c.shape}, got {p.shape}, {valid.shape}"
        )
    outside = cv2.distanceTransform((~c).astype(np.uint8), cv2.DIST_L2, 5)
    inside = cv2.distanceTransform(c.astype(np.uint8), cv2.DIST_L2, 5)
    signed = outside - inside  # grows away from the colour mask, across its edges too
    gx = cv2.Sobel(signed, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(signed, cv2.CV_32F, 0, 1, ksize=3)
    horiz = np.abs(gx) >= np.abs(gy)
    sides = (horiz & (gx > 0), horiz & (gx < 0), ~horiz & (gy > 0), ~horiz & (gy < 0))
    rim = (inside > 0.5) & (inside <= 1.5) & (p > 1 - low_proba) & valid
    rim_n = [int((rim & s).sum()) for s in sides]
    rim_held = all(n < min_pixels or 2 * int((rim & s & d).sum()) >= n for s, n in zip(sides, rim_n))
    reach = 0
    for j in range(1, max_px + 1):
        ring = (outside > j - 0.5) & (outside <= j + 0.5) & (p < low_proba)
        with_depth = [ring & s & valid for s in sides]
        n = np.array([int((ring & s).sum()) for s in sides])
        nv = np.array([int(w.sum()) for w in with_depth])
        share = nv / np.maximum(n, 1)
        read = (nv >= min_pixels) & (share >= 0.5 * share.max())
        # one side read across each direction at least (so two or more)
        if not (read[:2].any() and read[2:].any()) or (read.sum() == 2 and not rim_held):
            break
        if min(float(d[w].mean()) for w, r in zip(with_depth, read) if r) < 0.5:
            break
        reach = j
    return reach


def trim_depth_overreach(color_mask, depth_mask, overreach_px: int) -> np.ndarray:
    """The depth mask without its over-reach (:func:`depth_overreach_px`): its parts outside the
    colour mask thinner than ``2 * overreach_px + 1`` px (a morphological opening) are left out,
    the fattening along edges the colour places; parts as thick as a bar (one the colour missed)
    stay. ``overreach_px`` 0: the depth mask as it is (a copy).

    Parameters
    ----------
    color_mask, depth_mask : (H, W) bool rebar masks from colour and from depth (anything
        non-zero is rebar)
    overreach_px : the depth's over-reach, px (:func:`depth_overreach_px`); 0 or less: none

    Returns
    -------
    (H, W) bool, a new array: the depth mask inside the colour mask, and its parts outside
    that an opening with a ``(2 * overreach_px + 1)``-px square keeps.

    Examples
    --------
    >>> color = np.zeros((1, 12), bool); color[0, 4:7] = True
    >>> depth = np.zeros((1, 12), bool); depth[0, 3:8] = True
    >>> trim_depth_overreach(color[[0] * 5], depth[[0] * 5], 1)[2].astype(int).tolist()
    [0, 0, 0, 0, 1, 1, 1, 0, 0, 0, 0, 0]
    """
    import cv2

    c, d = _two_masks(color_mask, depth_mask)
    if overreach_px <= 0:
        return d.copy()
    k = cv2.getStructuringElement(cv2.MORPH_RECT, (2 * overreach_px + 1, 2 * overreach_px + 1))
    return (d & c) | cv2.morphologyEx((d & ~c).astype(np.uint8), cv2.MORPH_OPEN, k).astype(bool)


def fuse_masks(
    color_mask,
    depth_mask,
    *,
    color_proba=None,
    low_proba: float = 0.2,
    depth_valid=None,
    support_px: int | None = None,
    min_fill_px: int | None = None,
    overreach_px: int | None = None,
) -> np.ndarray:
    """Combine a colour mask (sharp edges) with a depth mask (presence that light cannot fool).

    1. A colour pixel is kept if depth marks a bar within ``support_px`` of it, or if the pixel
       has no depth (holes, projector shadow: no evidence against it). This removes shadow
       lines, stains and marks on flat formwork that look like bars.
    2. With ``color_proba``, a pixel next to depth-confirmed bar is also taken at the lower
       threshold ``low_proba`` (hysteresis): bar edges in shadow or under rust, where the network
       is unsure, come back with the network's edge position.
    3. Depth regions the colour missed are added (components of at least ``min_fill_px``
       pixels): bars in deep shadow, dark rust on dark board.

    Parameters
    ----------
    color_mask, depth_mask : (H, W) bool
    color_proba : (H, W) float rebar probability of the colour model, optional
    low_proba : probability enough for a pixel that depth supports
    depth_valid : (H, W) bool, where depth exists (e.g. ``capture.depth_mm > 0``); default all
    support_px : how far depth evidence reaches, px; default 1 px per 1280 px of width
        (measured best on the validation captures; more lets shadows next to bars back in)
    min_fill_px : smallest depth-only region added, px; default 1 (every depth pixel: on the
        validation captures any larger value lost IoU; raise it for a sensor with specks)
    overreach_px : how far the depth's bars reach beyond the colour's edges on most rows
        (edge fattening); default :func:`depth_overreach_px` of the two masks. Where it is
        above 0 the depth mask loses that over-reach first (:func:`trim_depth_overreach`): the
        depth's fattening along edges the colour places would widen every bar by it.

    Returns
    -------
    (H, W) bool

    Examples
    --------
    >>> color = np.zeros((6, 12), bool); color[:, 2:4] = True; color[:, 8] = True  # 8: a shadow line
    >>> depth = np.zeros((6, 12), bool); depth[:, 2:4] = True; depth[:, 10:12] = True  # 10-11: missed
    >>> fuse_masks(color, depth, min_fill_px=4)[0].astype(int).tolist()
    [0, 0, 1, 1, 0, 0, 0, 0, 0, 0, 1, 1]
    """
    import cv2

    c, d = _two_masks(color_mask, depth_mask)
    H, W = c.shape
    scale = W / 1280.0
    if support_px is None:
        support_px = max(1, round(scale))
    if min_fill_px is None:
        min_fill_px = 1
    valid = np.ones_like(c) if depth_valid is None else np.asarray(depth_valid).astype(bool)
    if valid.shape != c.shape:
        raise RebarInputError(f"depth_valid: expected the shape of color_mask {c.shape}, got {valid.shape}")
    if color_proba is not None and np.shape(color_proba) != c.shape:
        raise RebarInputError(f"color_proba: expected the shape of color_mask {c.shape}, got {np.shape(color_proba)}")
    if overreach_px is None:
        overreach_px = depth_overreach_px(c, d, color_proba=color_proba, low_proba=low_proba, depth_valid=valid)
    d = trim_depth_overreach(c, d, overreach_px)
    if support_px > 0:
        k = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * support_px + 1, 2 * support_px + 1))
        near_bar = cv2.dilate(d.astype(np.uint8), k).astype(bool)
    else:
        near_bar = d
    kept = c & (near_bar | ~valid)
    if color_proba is not None:
        kept |= (np.asarray(color_proba, dtype=np.float32) > low_proba) & near_bar
    missed = d & ~kept
    n, lab, stats, _ = cv2.connectedComponentsWithStats(missed.astype(np.uint8), connectivity=8)
    big = np.flatnonzero(stats[:, cv2.CC_STAT_AREA] >= min_fill_px)
    big = big[big > 0]
    if len(big):
        kept |= np.isin(lab, big)
    return kept


def soft_mask(mask, proba, *, threshold: float = 0.5) -> np.ndarray:
    """A binary mask made soft again: the model's probability where the two agree, 1 / 0 where
    the mask overrides the model (pixels ``fuse_masks`` added from depth or hysteresis, or
    removed as shadow lines).

    The diameter stage finds a bar's edges where its profile crosses 0.5: on a binary mask that
    is always half-way between two pixel centres, on the probability it is sub-pixel, so widths
    of bars lying along the pixel grid lose the half-pixel rounding of each edge.

    Parameters
    ----------
    mask : (H, W) bool, e.g. from :func:`fuse_masks`
    proba : (H, W) float rebar probability of the colour model (``predict_proba``)
    threshold : the model's threshold (``SegmentationModel.threshold``): the probability is
        rescaled piecewise-linearly so that it lies at 0.5

    Returns
    -------
    (H, W) float32 in 0..1, ``>= 0.5`` exactly where ``mask`` is True

    Examples
    --------
    >>> soft_mask(np.array([[True, True, False, False]]), np.array([[0.9, 0.3, 0.7, 0.1]])).tolist()
    [[0.8999999761581421, 1.0, 0.0, 0.10000000149011612]]
    """
    m = np.asarray(mask).astype(bool)
    p = np.asarray(proba, dtype=np.float32)
    if p.shape != m.shape or m.ndim != 2:
        raise RebarInputError(f"proba: expected the shape of mask {m.shape}, got {p.shape}")
    if not 0 < threshold < 1:
        raise RebarInputError(f"threshold: expected a probability strictly between 0 and 1, got {threshold!r}")
    p = np.nan_to_num(np.clip(p, 0, 1), nan=0.0)
    if threshold != 0.5:
        p = np.where(p < threshold, 0.5 * p / threshold, 0.5 + 0.5 * (p - threshold) / (1 - threshold))
    return np.where(m, np.where(p >= 0.5, p, 1.0), np.where(p >= 0.5, 0.0, p)).astype(np.float32)
