"""The paper's diameter procedure (method.md stage 3.3), faithfully: parallelogram regions at
detect-points along the projected axis, the mask's boundary pixels in each, D = the least
distance between the region's two sides in γ, and a vote in ±1 mm bins around the nominal
sizes.
"""

from __future__ import annotations

import math

import numpy as np

from .._camera import project
from .bars import _Bar, _stations
from .barsizes import bar_system
from .plane import cross_section_direction, diameter_region, intersect_rays_plane, pixels_in_region


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


def _paper_bar(i, bar: _Bar, mask, edge, intr, n_points: int, owner, short_px: float = 6.0):
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
        region = pixels_in_region(diameter_region(c, across, along, long_px=long_px, short_px=short_px), mask.shape)
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


def _paper_vote(Ds, system, bin_mm: float = 1.0):
    sizes = np.array(bar_system(system).sizes_mm)
    if len(Ds) == 0:
        return math.nan, 0.0
    # bins of ±1 mm around the nominal sizes (8 ↔ 7–9, 10 ↔ 9–11, ...); outside every bin: no vote
    k = np.abs(Ds[:, None] - sizes[None, :]).argmin(axis=1)
    inbin = np.abs(Ds - sizes[k]) <= bin_mm
    if not inbin.any():
        return math.nan, 0.0
    counts = np.bincount(k[inbin], minlength=len(sizes))
    win = int(counts.argmax())
    return float(sizes[win]), float(counts[win] / len(Ds))
