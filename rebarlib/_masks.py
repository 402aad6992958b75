"""The rebar mask the diameter stage reads (:func:`rebar_mask`, :func:`registered_mask`): the
colour model's, the depth's, or both fused, optionally soft and tiled at full resolution, and
registered onto the depth image; and the depth with its edge fattening trimmed
(:func:`trim_edge_fattening`).
"""

from __future__ import annotations

import dataclasses
import functools
import math

import numpy as np

from ._capture import Capture
from ._checks import RebarInputError
from ._design import Design

__all__ = ["rebar_mask", "registered_mask", "trim_edge_fattening", "widest_bar_px", "MODEL_THREADS"]

#: Where the rebar mask of the diameter stage comes from: the colour model alone (the paper),
#: the depth alone, or both fused (ours: edges from colour, presence from depth).
MASK_SOURCES = ("fused", "model", "depth")
#: Depth step (mm) that marks an occluding edge in prepare_cloud: well above the sensor noise
#: (σz ≈ 1–2 mm at 600–800 mm) and well below the smallest step of a slab (bar top to formwork,
#: cover + bar ≥ 20 mm; lower to upper lattice ≥ 40 mm).
EDGE_MM = 10.0
#: Refined diameters: a colour-depth misregistration (``segmentation.estimate_registration``) of
#: at least this many pixels is undone before the masks are fused and the bars measured; a
#: smaller one is left: the estimate's own error is up to 0.4 px on captures without any (three
#: times the flying pixels of the default sensor; 0.1-0.3 px otherwise), so correcting less
#: would as often add an error as remove one. Beyond ``REGISTRATION_WARN_PX`` the result says
#: to check the camera's depth-to-colour alignment.
REGISTRATION_MIN_PX = 0.5
REGISTRATION_WARN_PX = 3.0


#: Threads of the shipped segmentation model's session (None: onnxruntime's default, every
#: core). A batch's workers set 1 (``rebarlib.batch``): N workers, N cores.
MODEL_THREADS = None


@functools.lru_cache(maxsize=1)
def _default_model():
    from .segmentation import SegmentationModel

    return SegmentationModel.default(threads=MODEL_THREADS)


def rebar_mask(
    capture: Capture,
    *,
    source: str = "fused",
    plane=None,
    model=None,
    rng=None,
    soft: bool = False,
    tiled: bool = False,
    bar_width_px=None,
) -> np.ndarray:
    """The rebar mask of a capture for the diameter stage: (H, W) bool, or float32 with ``soft``.

    ``source``: "model" = the segmentation model on the colour image (the paper's way), "depth" =
    what stands above the formwork, "fused" (default) = both (``segmentation.fuse_masks``).
    ``plane``: the formwork plane if known (``(normal, offset_mm)``); ``model``: a
    ``SegmentationModel`` (default: the shipped one). ``soft``: return (H, W) float32 instead,
    the model's probability wherever it agrees with the mask (``segmentation.soft_mask``), so
    the refined diameter stage places the edges to a fraction of a pixel. ``tiled``: run the
    model on full-resolution tiles of the image (``SegmentationModel.predict_proba``): a bar's
    edges placed about twice as finely as from the image down-scaled to the model's input; the
    refined method uses it (docs/diameters.md, "A full-resolution mask"). ``bar_width_px``: the
    widest bar's width in the image (:func:`widest_bar_px`), so that the tiles are down-scaled
    where the bars would be wider than the model knows (``SegmentationModel.tile_scale``).

    The mask is the colour image's, as it comes; :func:`registered_mask` also moves it onto the
    depth image where the two are misregistered.
    """
    return _mask(
        capture,
        source=source,
        plane=plane,
        model=model,
        rng=rng,
        soft=soft,
        tiled=tiled,
        bar_width_px=bar_width_px,
        register=False,
    )[0]


def registered_mask(
    capture: Capture,
    *,
    source: str = "fused",
    plane=None,
    model=None,
    rng=None,
    soft: bool = False,
    tiled: bool = False,
    bar_width_px=None,
):
    """:func:`rebar_mask` on the depth image's pixels: ``(mask, capture, registration)``.

    The colour image's bars are registered to the depth image's
    (``segmentation.estimate_registration``); where they lie :data:`REGISTRATION_MIN_PX` or more
    apart, the model's probability and the colour image are moved onto the depth image before
    the masks are fused, so that the mask meets the axes fitted to the depth. ``capture`` is
    then a copy with the moved colour image (the one given is not changed), else the one given.
    ``registration``: ``{"shift_px": [du, dv], "correlation": cc, "applied": bool,
    "depth_overreach_px": k}`` (du, dv: where the depth image's content lies from the colour
    image's; None where it could not be estimated; k: the depth's edge fattening left out of
    its mask first, ``segmentation.depth_overreach_px``), or None for the "depth" source
    (nothing to register).
    """
    return _mask(
        capture,
        source=source,
        plane=plane,
        model=model,
        rng=rng,
        soft=soft,
        tiled=tiled,
        bar_width_px=bar_width_px,
        register=True,
    )


def trim_edge_fattening(depth_mm, px: int, *, edge_mm: float = EDGE_MM) -> np.ndarray:
    """The depth image without the nearer surface's last ``px`` pixels at every occluding edge.

    A stereo camera's matching window gives the nearer surface's depth to the first pixels
    beyond its edge (edge fattening, ``docs/sensors.md``): a bar's points then reach past its
    flank. Seen from one side only (the other in the projector's shadow), a cylinder of the
    bar's radius fitted to them slides towards the fattened side, and the spacing to the next
    bar is off by a millimetre or more. A pixel is left out (set to 0) where a pixel within
    ``px`` (a disk) has depth more than ``edge_mm`` farther; pixels without depth do not count
    as farther, so a flank beside the projector's shadow keeps its points. ``px`` comes from the
    capture (``inspect`` uses the depth's over-reach beyond the colour's bars,
    ``segmentation.depth_overreach_px``); 0 returns the depth image as it is (a copy).

    Examples
    --------
    >>> depth = np.full((1, 9), 500.0); depth[0, 3:6] = 470.0; depth[0, 8] = 0
    >>> trim_edge_fattening(depth, 1)[0].tolist()
    [500.0, 500.0, 500.0, 0.0, 470.0, 0.0, 500.0, 500.0, 0.0]
    """
    depth = np.asarray(depth_mm)
    if depth.ndim != 2:
        raise RebarInputError(f"depth_mm: expected an (H, W) depth image, got shape {depth.shape}")
    if int(px) != px or px < 0:
        raise RebarInputError(f"px: expected a whole number of pixels >= 0, got {px!r}")
    out = depth.copy()
    if px == 0:
        return out
    d = depth.astype(np.float32)
    out[(d > 0) & (_farthest_within(d, px) - d > edge_mm)] = 0
    return out


def _farthest_within(d, px: int) -> np.ndarray:
    """Per pixel of the float32 depth image ``d``, the farthest depth within ``px`` (a disk);
    pixels without depth are 0, never the farther surface."""
    import cv2

    return cv2.dilate(d, cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * int(px) + 1, 2 * int(px) + 1)))


def _nearest_within(d, px: int) -> np.ndarray:
    """Per pixel of the float32 depth image ``d``, the nearest valid depth within ``px`` (a
    square); 1e9 where there is none."""
    import cv2

    near = d.copy()
    near[near <= 0] = np.float32(1e9)
    return cv2.erode(near, np.ones((2 * int(px) + 1, 2 * int(px) + 1), np.uint8))


def _mask(capture, *, source, plane, model, rng, soft, tiled, bar_width_px, register):
    from .segmentation import (
        depth_overreach_px,
        estimate_registration,
        fuse_masks,
        mask_from_depth,
        shift_image,
        soft_mask,
        trim_depth_overreach,
    )

    if source not in MASK_SOURCES:
        raise RebarInputError(f"mask source: expected one of {MASK_SOURCES}, got {source!r}")
    if source == "depth":
        depth = mask_from_depth(capture, plane=plane, rng=rng)
        return (depth.astype(np.float32) if soft else depth), capture, None
    model = model or _default_model()
    proba = model.predict_proba(capture.color, tiled=tiled, bar_width_px=bar_width_px)
    depth = mask_from_depth(capture, plane=plane, rng=rng) if (register or source == "fused") else None
    valid = capture.depth_mm > 0
    colour = proba > model.threshold
    reach = 0
    if depth is not None:
        # the depth's bars reach beyond the colour's on every side where the sensor fattens its
        # edges: that over-reach would widen the fused mask and, with one side of each bar in
        # the projector's shadow, pull the registration towards the other (3 px of fattening:
        # 0.8 px); it is left out of the depth mask for both. A ring pixel is background where
        # the colour mask leaves it out (under the model's threshold): the shipped network's
        # edges ramp over a pixel or two, its first ring outside a bar at 0.2-0.5, and with a
        # margin below the threshold 3 px of fattening went unseen (decision 053)
        reach = depth_overreach_px(colour, depth, color_proba=proba, low_proba=model.threshold, depth_valid=valid)
        depth = trim_depth_overreach(colour, depth, reach)
    registration = None
    if register:
        du, dv, cc = estimate_registration(proba, depth, depth_valid=valid)
        applied = bool(math.hypot(du, dv) >= REGISTRATION_MIN_PX)  # False for NaN
        registration = {
            "shift_px": [round(du, 3), round(dv, 3)] if math.isfinite(du) else None,
            "correlation": round(cc, 4) if math.isfinite(cc) else None,
            "applied": applied,
            "depth_overreach_px": reach,
        }
        if applied:
            proba = shift_image(proba, du, dv)
            colour = proba > model.threshold
            capture = dataclasses.replace(capture, color=shift_image(capture.color, du, dv))
    if source == "model":
        mask = soft_mask(colour, proba, threshold=model.threshold) if soft else colour
    else:
        fused = fuse_masks(colour, depth, color_proba=proba, depth_valid=valid, overreach_px=0)
        mask = soft_mask(fused, proba, threshold=model.threshold) if soft else fused
    return mask, capture, registration


def widest_bar_px(capture: Capture, design: Design) -> float:
    """Width in the image, in pixels, of the widest bar of the design (its rib envelope) at the
    nearest depth in the capture (1st percentile of the valid depths: the tops of the nearest
    bars, or anything nearer); NaN without valid depth."""
    from .diameter.barsizes import observed_width_mm

    z = capture.depth_mm[capture.depth_mm > 0]
    if z.size == 0:
        return math.nan
    widest = max(
        observed_width_mm(design.lattice(layer).level(level).diameter_mm, system=design.bar_system)
        for layer in ("lower", "upper")
        for level in ("bottom", "top")
    )
    return float(widest * capture.intrinsics.fx / np.percentile(z, 1))
