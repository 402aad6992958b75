"""The two lattices: the height between them, and each point's layer."""

from __future__ import annotations

import numpy as np


LAYERS, LEVELS = ("lower", "upper"), ("bottom", "top")


def find_layer_split(
    heights, *, bin_mm: float = 1.0, min_gap_mm: float = 6.0, empty_fraction: float = 0.03
) -> float | None:
    """Height (mm) between the two lattices: the middle of the widest nearly empty band of the
    height histogram of the bar points, or ``None`` when there is no such band (one lattice).

    A bin is "empty" when it holds less than ``empty_fraction`` of the 95th-percentile bin count
    (chairs and tie wire put a few points between the lattices).

    Parameters
    ----------
    heights : array
        Heights of the bar points above the formwork (mm).
    bin_mm : float
        The histogram's bin.
    min_gap_mm : float
        The least width of the empty band.
    empty_fraction : float
        A bin under this share of the 95th-percentile count is empty.

    Returns
    -------
    float or None
        The split height (mm), or None (under 10 points, too narrow a spread, or no band).

    Examples
    --------
    >>> h = np.r_[np.linspace(20, 50, 300), np.linspace(105, 130, 300)]
    >>> round(find_layer_split(h), 1)
    77.3
    """
    h = np.asarray(heights, float)
    if len(h) < 10:
        return None
    lo, hi = np.percentile(h, [0.5, 99.5])
    if hi - lo < 2 * min_gap_mm:
        return None
    edges = np.arange(lo, hi + bin_mm, bin_mm)
    counts, _ = np.histogram(h, edges)
    ref = np.percentile(counts[counts > 0], 95)
    empty = counts < empty_fraction * ref
    best, best_len, start = None, 0, None
    for i, e in enumerate(np.r_[empty, False]):
        if e and start is None:
            start = i
        elif not e and start is not None:
            if i - start > best_len and start > 0 and i < len(counts):
                best, best_len = (start, i), i - start
            start = None
    if best is None or best_len * bin_mm < min_gap_mm:
        return None
    return float((edges[best[0]] + edges[best[1]]) / 2)


def split_layers(heights, *, split_mm: float | None) -> np.ndarray:
    """Layer of each point by its height.

    Parameters
    ----------
    heights : (N,) heights above the formwork (mm)
    split_mm : the height between the lattices (:func:`find_layer_split`); None: one lattice

    Returns
    -------
    (N,) int8: 0 = lower, 1 = upper (everything lower without a split)

    Examples
    --------
    >>> split_layers([20.0, 90.0, 110.0], split_mm=77.3).tolist()
    [0, 1, 1]
    """
    h = np.asarray(heights, float)
    if split_mm is None:
        return np.zeros(len(h), np.int8)
    return (h >= split_mm).astype(np.int8)
