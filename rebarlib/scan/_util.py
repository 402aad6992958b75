"""Array helpers of the scanned-cloud stages: projections without BLAS, sampling, a
smoothed histogram, a robust spread."""

from __future__ import annotations


import numpy as np

from .. import geometry as G


def _dot(a, v) -> np.ndarray:
    """``a @ v`` for (N, k) points and a k-vector, column by column: a matrix product of a tall
    thin array goes through BLAS threads, which on a busy 2-core machine cost 50x more."""
    out = a[:, 0] * float(v[0])
    for j in range(1, len(v)):
        out += a[:, j] * float(v[j])
    return out


def _slab_frame(points, plane: G.Plane) -> np.ndarray:
    """:func:`rebarlib.geometry.to_slab_frame` without a matrix product (see :func:`_dot`)."""
    R = G.plane_frame(plane)
    return np.column_stack([_dot(points, R[0]), _dot(points, R[1]), _dot(points, R[2]) + plane.offset_mm])


def _sample(n: int, k: int, rng) -> np.ndarray:
    """Sorted indices of at most ``k`` of ``n`` items, drawn without replacement."""
    return np.arange(n) if n <= k else np.sort(rng.choice(n, k, replace=False))


def _smoothed_hist(x, bin_mm: float, sd_mm: float, lo=None, hi=None):
    """Bin centres, Gaussian-smoothed counts (kernel σ ``sd_mm``) and raw counts of ``x``."""
    lo = float(np.min(x)) if lo is None else lo
    hi = float(np.max(x)) if hi is None else hi
    edges = np.arange(lo, hi + bin_mm, bin_mm)
    if len(edges) < 2:
        edges = np.array([lo, lo + bin_mm])
    c, _ = np.histogram(x, edges)
    k = max(sd_mm / bin_mm, 0.5)
    ker = np.exp(-0.5 * (np.arange(-int(4 * k) - 1, int(4 * k) + 2) / k) ** 2)
    # the full convolution cropped to the histogram's bins (``mode="same"`` returns the longer
    # of the two, which is the kernel's when the noise is wide against the histogram's span)
    h = (len(ker) - 1) // 2
    s = np.convolve(c.astype(float), ker / ker.sum(), mode="full")[h : h + len(c)]
    return 0.5 * (edges[:-1] + edges[1:]), s, c


def _mad(x) -> float:
    """Robust standard deviation (1.4826 × the median absolute value) of residuals ``x``."""
    return 1.4826 * float(np.median(np.abs(x)))


def _band_side(radius_mm: float, sigma_mm: float) -> float:
    """Offset from a bar's axis (mm) past which its own points, smeared by the noise across
    ``sigma_mm``, no longer reach: the half width of the band that gathers a bar's points (where
    :func:`._edges.edge_beyond`'s windows start, and the crossing bars' bands of
    :func:`._bars._drop_phantoms`)."""
    return radius_mm + 2.5 * sigma_mm + 2.0
