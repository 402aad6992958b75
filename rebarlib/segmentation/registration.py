"""Colour-depth registration: how far the depth image's bars lie from the colour image's.

:func:`estimate_registration` measures the translation; :func:`shift_image` applies one.
"""

from __future__ import annotations

import math

import numpy as np

from .._checks import RebarInputError

__all__ = ["estimate_registration", "shift_image"]


def estimate_registration(
    color_proba, depth_mask, *, depth_valid=None, blur_px=(4.0, 2.0, 1.0)
) -> tuple[float, float, float]:
    """How far the depth image's content lies from the colour image's, in pixels: (du, dv, cc)
    with ``depth(x + (du, dv)) ≈ colour(x)``, and the correlation coefficient reached.

    A camera's "aligned" depth is the depth re-projected into the colour camera with its factory
    calibration; what that leaves (a pixel or more, more after a knock or a re-mount) moves every
    bar's mask off the axes fitted to its depth: widths taken from one edge and the axis, the
    point cloud read across the mask's runs and the fused mask (which keeps colour pixels next to
    depth ones) all suffer. The bars' pixels seen by colour (the segmentation model's
    probability) and by depth (:func:`mask_from_depth`) are the same objects, so their
    translation is the misregistration: found by maximising their correlation coefficient
    (OpenCV's ECC, translation only), coarse to fine over Gaussian blurs of ``blur_px`` (the
    coarsest reaches a few pixels). Pixels without depth are left out.

    Measured on synthetic captures of two cameras (docs/benchmarks.md, "Colour-depth
    registration"): within
    0.3 px (0.7 px with three times the flying pixels) for whole-pixel shifts up to 4 px; within
    0.6 px where the colour is also moved by a fraction of a pixel (both masks aliased, as on
    synthetic images, pull the estimate toward whole pixels).

    Parameters
    ----------
    color_proba : (H, W) float rebar probability (or bool mask) from the colour image
    depth_mask : (H, W) bool, rebar pixels from depth
    depth_valid : (H, W) bool, where depth exists; default all
    blur_px : Gaussian σ (px) of each pass, coarse to fine

    Returns
    -------
    (du, dv, cc); NaN, NaN, NaN where the search fails (no bars, too little overlap).

    Examples
    --------
    >>> colour = np.zeros((60, 80)); colour[:, 20:30] = 1; colour[40:48, :] = 1
    >>> depth = np.roll(np.roll(colour, 2, axis=1), -1, axis=0) > 0.5  # 2 px right, 1 px up
    >>> du, dv, cc = estimate_registration(colour, depth)
    >>> round(du, 1), round(dv, 1)
    (2.0, -1.0)
    """
    import cv2

    a0 = np.asarray(color_proba, np.float32)
    b0 = np.asarray(depth_mask, np.float32)
    if a0.ndim != 2 or a0.shape != b0.shape:
        raise RebarInputError(f"depth_mask: expected the shape of color_proba {a0.shape}, got {b0.shape}")
    valid = np.ones(a0.shape, np.uint8) if depth_valid is None else np.asarray(depth_valid).astype(np.uint8)
    if valid.shape != a0.shape:
        raise RebarInputError(f"depth_valid: expected the shape of color_proba {a0.shape}, got {valid.shape}")
    fail = (math.nan, math.nan, math.nan)
    if not (b0.any() and (a0 > 0.5).any()):
        return fail
    warp = np.eye(2, 3, dtype=np.float32)
    cc = math.nan
    crit = (cv2.TERM_CRITERIA_EPS | cv2.TERM_CRITERIA_COUNT, 50, 1e-4)
    for s in blur_px:
        a = cv2.GaussianBlur(a0, (0, 0), s)
        b = cv2.GaussianBlur(b0, (0, 0), s)
        try:
            cc, warp = cv2.findTransformECC(a, b, warp, cv2.MOTION_TRANSLATION, crit, valid, 1)
        except cv2.error:  # did not converge: the masks share too little
            return fail
    return float(warp[0, 2]), float(warp[1, 2]), float(cc)


def shift_image(image, du: float, dv: float) -> np.ndarray:
    """``image`` moved ``du`` pixels right and ``dv`` down (bilinear; the border's pixels repeat
    into what comes in from outside): ``out(x) = image(x − (du, dv))``. The input is not changed.

    Parameters
    ----------
    image : (H, W) or (H, W, C) array of a type OpenCV warps (uint8, float32, float64, ...;
        not bool): a probability, a depth map (mm) or an image
    du, dv : the move right and down, px (fractions allowed; negative: left, up). To bring a
        depth image onto the colour one, pass minus the ``(du, dv)`` of
        :func:`estimate_registration`

    Returns
    -------
    array of ``image``'s shape and type, a new one.

    Examples
    --------
    >>> shift_image(np.arange(5, dtype=np.float32)[None, :], 1.0, 0.0).tolist()
    [[0.0, 0.0, 1.0, 2.0, 3.0]]
    """
    import cv2

    img = np.asarray(image)
    h, w = img.shape[:2]
    m = np.float32([[1, 0, du], [0, 1, dv]])
    return cv2.warpAffine(img, m, (w, h), flags=cv2.INTER_LINEAR, borderMode=cv2.BORDER_REPLICATE)
