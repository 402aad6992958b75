"""Segmentation metrics: the paper's formulas (method.md, "Segmentation metrics", paper §2.3).

Pixel accuracy, IoU and Dice of a predicted rebar mask against the truth, from the confusion
counts; a ``region`` restricts the counts to a subset of the pixels (bars in shadow, rust).
"""

from __future__ import annotations

import numpy as np

from .._checks import RebarInputError

__all__ = ["confusion_counts", "pixel_accuracy", "iou", "dice"]


def confusion_counts(pred, truth, *, region=None) -> dict:
    """Pixel confusion counts of a predicted rebar mask against the true one.

    Parameters
    ----------
    pred, truth : (H, W) bool (anything non-zero is rebar)
    region : (H, W) bool, optional; count only these pixels (e.g. the shadow subset)

    Returns
    -------
    dict with int ``TP``, ``FP``, ``FN``, ``TN``. Counts of several images add up (sum the dicts
    key by key) to give data-set metrics, as the paper's tables do.

    Examples
    --------
    >>> confusion_counts([[1, 1, 0, 0]], [[1, 0, 1, 0]])
    {'TP': 1, 'FP': 1, 'FN': 1, 'TN': 1}
    """
    p = np.asarray(pred).astype(bool)
    t = np.asarray(truth).astype(bool)
    if p.shape != t.shape:
        raise RebarInputError(f"pred: expected the shape of truth {t.shape}, got {p.shape}")
    if region is not None:
        r = np.asarray(region).astype(bool)
        if r.shape != t.shape:
            raise RebarInputError(f"region: expected the shape of truth {t.shape}, got {r.shape}")
        p, t = p[r], t[r]
    tp = int(np.count_nonzero(p & t))
    fp = int(np.count_nonzero(p & ~t))
    fn = int(np.count_nonzero(~p & t))
    return {"TP": tp, "FP": fp, "FN": fn, "TN": int(p.size) - tp - fp - fn}


def _counts(pred_or_counts, truth):
    if truth is None:
        c = pred_or_counts
        if not isinstance(c, dict) or not {"TP", "FP", "FN", "TN"} <= set(c):
            raise RebarInputError("pred: expected a mask with truth, or a dict with TP, FP, FN, TN")
        return c
    return confusion_counts(pred_or_counts, truth)


def _ratio(num, den) -> float:
    # an empty denominator means the metric is undefined (e.g. no rebar in either mask)
    return float(num) / float(den) if den > 0 else float("nan")


def pixel_accuracy(pred, truth=None) -> float:
    """Pixel Accuracy = (TP + TN) / (TP + TN + FP + FN), in [0, 1].

    ``pred`` is a mask (with ``truth``) or a :func:`confusion_counts` dict (without).

    Parameters
    ----------
    pred : (H, W) array_like mask (anything non-zero is rebar), or a dict with int ``TP``,
        ``FP``, ``FN``, ``TN`` (:func:`confusion_counts`, possibly summed over images)
    truth : (H, W) array_like true mask of the same shape; None (default) when ``pred`` is
        a dict of counts

    Returns
    -------
    float, the share of pixels classified right (rebar and background); NaN when there are no
    pixels to count.

    Examples
    --------
    >>> pixel_accuracy({"TP": 2, "FP": 1, "FN": 1, "TN": 6})
    0.8
    """
    c = _counts(pred, truth)
    return _ratio(c["TP"] + c["TN"], c["TP"] + c["TN"] + c["FP"] + c["FN"])


def iou(pred, truth=None) -> float:
    """IoU of the rebar class = TP / (TP + FP + FN), in [0, 1]; NaN when both masks are empty.

    Parameters
    ----------
    pred : (H, W) array_like mask (anything non-zero is rebar), or a dict with int ``TP``,
        ``FP``, ``FN``, ``TN`` (:func:`confusion_counts`, possibly summed over images)
    truth : (H, W) array_like true mask of the same shape; None (default) when ``pred`` is
        a dict of counts

    Returns
    -------
    float, the intersection over the union of the predicted and the true rebar pixels; NaN
    when neither has any.

    Examples
    --------
    >>> iou([[1, 1, 0, 0]], [[1, 0, 1, 0]])
    0.3333333333333333
    """
    c = _counts(pred, truth)
    return _ratio(c["TP"], c["TP"] + c["FP"] + c["FN"])


def dice(pred, truth=None) -> float:
    """Dice of the rebar class = 2 TP / (2 TP + FP + FN), in [0, 1]; NaN when both are empty.

    Parameters
    ----------
    pred : (H, W) array_like mask (anything non-zero is rebar), or a dict with int ``TP``,
        ``FP``, ``FN``, ``TN`` (:func:`confusion_counts`, possibly summed over images)
    truth : (H, W) array_like true mask of the same shape; None (default) when ``pred`` is
        a dict of counts

    Returns
    -------
    float, twice the overlap of the predicted and the true rebar pixels over their total
    count (the F1 score of the rebar pixels); NaN when neither has any.

    Examples
    --------
    >>> dice({"TP": 2, "FP": 1, "FN": 1, "TN": 6})
    0.6666666666666666
    """
    c = _counts(pred, truth)
    return _ratio(2 * c["TP"], 2 * c["TP"] + c["FP"] + c["FN"])
