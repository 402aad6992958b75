"""Which bars of a synthetic capture show their whole width, from the ground truth alone.

A bar's nominal size can only be read where the image shows both of its edges: a lower bar under
an upper bar that runs along it shows a sliver, one edge, whatever the method. The paper left
such "obstructed" bars out of its Table 6 by hand; the benchmarks need the same line drawn
without looking at any method's output, so it is drawn here from the truth's ``bar_ids.png`` and
axes only:

a cross-section of a bar (a line across its projected true axis, every ``step_px`` along its
visible extent) *shows the bar's width* where the pixel on the axis belongs to the bar, and the
bar's run of pixels along the line ends on both sides at the formwork or at a bar further from
the camera (lower in the stack), inside the image. A bar *shows its width* where such
sections cover at least ``min_length_d`` of its own diameters along it.
"""

from __future__ import annotations

import numpy as np

from rebarlib._camera import project

#: a bar shows its width where sections that show both its edges cover this many of its diameters
#: along it (a shorter stretch is a crossing bar's gap or a corner at the border). The count hardly
#: depends on the line: of the reference set's 636 bars in view, 566 show 1 diameter or more, 559
#: show 3 or more and 556 show 5 or more; 580 show any.
SHOWS_WIDTH_D = 3.0

#: the stack, from the formwork up (the camera looks down on it): a nearer bar has a higher rank
_RANK = {("lower", "bottom"): 0, ("lower", "top"): 1, ("upper", "bottom"): 2, ("upper", "top"): 3}


def _run_end(ids, c, step, i, reach_px):
    """What bar ``i``'s run of pixels from ``c`` along ``step`` (half a pixel) ends on: -1 (the
    formwork), another bar's id, or None (the image border, or no end within ``reach_px``)."""
    h, w = ids.shape
    for k in range(1, int(2 * reach_px) + 1):
        u, v = (int(round(x)) for x in c + k * step)
        if not (0 <= u < w and 0 <= v < h):
            return None
        if ids[v, u] != i:
            return int(ids[v, u])
    return None


def width_sections(cap, step_px: float = 3.0) -> dict[int, tuple[int, float]]:
    """For every visible bar of the truth: (sections that show its width, their length along the
    bar in mm)."""
    ids = np.asarray(cap.bar_ids, np.int64) - 1  # -1: no bar
    h, w = ids.shape
    fx = cap.intrinsics.fx
    bars = {int(b["id"]): b for b in cap.truth["bars"]}
    rank = {i: _RANK[(b["layer"], b["level"])] for i, b in bars.items()}
    out = {}
    for i, b in bars.items():
        if not b.get("visible"):
            continue
        p = np.array([b["visible_start_mm"], b["visible_end_mm"]], float)
        a0, a1 = project(p, cap.intrinsics)
        n_px = float(np.linalg.norm(a1 - a0))
        if n_px < 1:
            out[i] = (0, 0.0)
            continue
        tang = (a1 - a0) / n_px
        half = 0.5 * np.array([-tang[1], tang[0]])  # half a pixel across the bar
        reach = int(4 * b["envelope_mm"] * fx / p[:, 2].min()) + 4  # px: far beyond the half-width
        good, length = 0, 0.0
        for s in np.arange(step_px / 2, n_px, step_px):
            c = a0 + s * tang
            u, v = int(round(c[0])), int(round(c[1]))
            if not (0 <= u < w and 0 <= v < h) or ids[v, u] != i:
                continue
            ends = [_run_end(ids, c, sign * half, i, reach) for sign in (-1.0, 1.0)]
            # each end inside the image, at the formwork or at a bar farther from the camera
            if all(e is not None and (e < 0 or rank[e] <= rank[i]) for e in ends):
                good += 1
                length += step_px * (p[0, 2] + (p[1, 2] - p[0, 2]) * s / n_px) / fx
        out[i] = (good, length)
    return out


def shows_width(cap, min_length_d: float = SHOWS_WIDTH_D, step_px: float = 3.0) -> set[int]:
    """Ids of the bars whose whole width the image shows over at least ``min_length_d`` of
    their own diameters (see the module's docstring)."""
    bars = {int(b["id"]): b for b in cap.truth["bars"]}
    return {
        i for i, (_, length) in width_sections(cap, step_px).items() if length >= min_length_d * bars[i]["diameter_mm"]
    }
