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

#: a bar shows its width where sections that show both its edges cover this many of its diameters
#: along it (a shorter stretch is a crossing bar's gap or a corner at the border). The count hardly
#: depends on the line: of the reference set's 636 bars in view, 566 show 1 diameter or more, 559
#: show 3 or more and 556 show 5 or more; 580 show any.
SHOWS_WIDTH_D = 3.0

#: the stack, from the formwork up (the camera looks down on it): a nearer bar has a higher rank
_RANK = {("lower", "bottom"): 0, ("lower", "top"): 1, ("upper", "bottom"): 2, ("upper", "top"): 3}


def width_sections(cap, step_px: float = 3.0) -> dict[int, tuple[int, float]]:
    """For every visible bar of the truth: (sections that show its width, their length along the
    bar in mm)."""
    ids = np.asarray(cap.bar_ids, np.int64) - 1  # -1: no bar
    h, w = ids.shape
    intr = cap.intrinsics
    fx, fy, cx, cy = intr.fx, intr.fy, intr.cx, intr.cy
    bars = {int(b["id"]): b for b in cap.truth["bars"]}
    rank = {i: _RANK[(b["layer"], b["level"])] for i, b in bars.items()}
    rank_img = np.full(len(bars) + 1, -1)
    for i, r in rank.items():
        rank_img[i] = r

    def project(p):
        p = np.asarray(p, float)
        return np.array([fx * p[0] / p[2] + cx, fy * p[1] / p[2] + cy])

    out = {}
    for i, b in bars.items():
        if not b.get("visible"):
            continue
        p0, p1 = np.asarray(b["visible_start_mm"], float), np.asarray(b["visible_end_mm"], float)
        a0, a1 = project(p0), project(p1)
        n_px = np.linalg.norm(a1 - a0)
        if n_px < 1:
            out[i] = (0, 0.0)
            continue
        tang = (a1 - a0) / n_px
        nrm = np.array([-tang[1], tang[0]])
        good, length = 0, 0.0
        reach = int(4 * b["envelope_mm"] * fx / min(p0[2], p1[2])) + 4  # px: far beyond the half-width
        for s in np.arange(step_px / 2, n_px, step_px):
            c = a0 + s * tang
            u, v = int(round(c[0])), int(round(c[1]))
            if not (0 <= u < w and 0 <= v < h) or ids[v, u] != i:
                continue
            ok = True
            for sign in (-1.0, 1.0):
                k = 1
                while True:
                    q = c + sign * k * 0.5 * nrm
                    uu, vv = int(round(q[0])), int(round(q[1]))
                    if not (0 <= uu < w and 0 <= vv < h):
                        ok = False  # the image border cuts the bar
                        break
                    j = ids[vv, uu]
                    if j != i:
                        if j >= 0 and rank_img[j] > rank[i]:
                            ok = False  # a nearer bar covers this edge
                        break
                    k += 1
                    if k * 0.5 > reach:
                        ok = False
                        break
                if not ok:
                    break
            if ok:
                good += 1
                z = p0[2] + (p1[2] - p0[2]) * s / n_px
                length += step_px * z / fx
        out[i] = (good, length)
    return out


def shows_width(cap, min_length_d: float = SHOWS_WIDTH_D, step_px: float = 3.0) -> set[int]:
    """Ids of the bars whose whole width the image shows over at least ``min_length_d`` of
    their own diameters (see the module's docstring)."""
    bars = {int(b["id"]): b for b in cap.truth["bars"]}
    return {i for i, (_, length) in width_sections(cap, step_px).items()
            if length >= min_length_d * bars[i]["diameter_mm"]}
