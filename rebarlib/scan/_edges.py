"""A bar at the scan's edge: whether the cloud shows that its cross-section is whole.

A scan that stops at a bar (a partly scanned mesh, the end of a station's field of view, a crop)
may cut the bar's cross-section lengthwise: the returns of the part beyond the edge are missing,
and the points' mean, or the streaks' centre (:mod:`._sides`), moves toward the part that is left.
Where the range noise is at least the bar's radius, as in most site scans, the points of the part
left do not show the arc's shape; they are a streak whose offset from the axis depends on where
the cut lies, and moving the axis and the cut together leaves the points the same. So the axis of
a cut section is fixed only by the edge's position, and the cloud gives that only to within its
noise across (the edge is smeared by it). Such a bar is kept, found, but its position across is
"not measured" unless the cloud shows that it goes on beyond the bar's section.
"""

from __future__ import annotations

import dataclasses
import math

import numpy as np

from .. import geometry as G
from .._status import MEASURED, NOT_MEASURED
from ._util import _band_side, _dot

#: how far beyond the section's outer side, in the cloud's noise across, the edge must be shown to
#: lie: the edge is estimated from points smeared by that noise (decision 032: edges 5-19 mm from
#: the axis came out 13-25 mm at a noise across of 8-11 mm; with one σ a cut bar was kept)
EDGE_MARGIN_SIGMA = 2.0


def _step_tail(x: float) -> float:
    """∫_{-∞}^{x} Φ(s) ds = x Φ(x) + φ(x): the points of a unit-density step smeared by a unit
    Gaussian lying beyond a position ``x`` σ short of the step's edge (per σ)."""
    return x * 0.5 * (1.0 + math.erf(x / math.sqrt(2.0))) + math.exp(-0.5 * x * x) / math.sqrt(2.0 * math.pi)


def edge_beyond(u, radius_mm: float, sigma_mm: float, room_mm: float) -> tuple[float, int, int] | None:
    """Where the cloud ends beyond a bar, from the points on both sides of it.

    The points' offsets ``u`` from the bar's axis (positive outward, away from the other bars of
    its set) are counted in a window beyond the bar's own points (from ``radius + 2.5 σ + 2`` mm
    for ``room_mm`` further) and in the same window on the inner side, which gives the cloud's
    density there. A cloud that ends at an edge ``e`` (mm from the axis), smeared by the noise
    across ``σ``, puts ``density · σ · (T((e - u₀)/σ) - T((e - u₀ - W)/σ))`` points in the outer
    window (``T`` the integral of the normal CDF); ``e`` is solved for from the count there, less
    the stray points (outliers, mixed returns) counted in the next window out, which a cloud that
    has ended still holds (taken off only where that window holds under a tenth of the inner
    window's count).

    Parameters
    ----------
    u : (N,) offsets across the bar of the cloud's points along its extent, mm, outward positive
    radius_mm : the bar's radius
    sigma_mm : the cloud's noise across the bars in plan, mm
    room_mm : width of the windows (the gap to the next bar less both bars' bands), mm

    Returns
    -------
    (edge, outer count, inner count): the edge's estimated offset from the axis in mm (at most
    the windows' far end plus 5 σ: the cloud goes on), the points in the outer and inner windows;
    None where the inner window holds under 20 points (no density to compare with)

    Examples
    --------
    >>> g = np.random.default_rng(0)
    >>> u = np.r_[g.uniform(-300, 60, 40_000)] + g.normal(0, 10, 40_000)  # a cloud ending 60 mm out
    >>> e, n_out, n_in = edge_beyond(u, 7.0, 10.0, 120.0)
    >>> abs(e - 60.0) < 5.0
    True
    """
    u = np.asarray(u, float)
    sig = max(float(sigma_mm), 0.5)
    u0 = _band_side(radius_mm, sig)
    w = max(float(room_mm), 2.0 * sig)
    n_out = int(np.count_nonzero((u >= u0) & (u < u0 + w)))
    n_in = int(np.count_nonzero((u <= -u0) & (u > -u0 - w)))
    n_far = int(np.count_nonzero((u >= u0 + w) & (u < u0 + 2 * w)))
    if n_in < 20:
        return None
    rho = n_in / w
    # the next window out holds only stray points where the cloud has ended before it; where it
    # holds a tenth of the inner density or more the cloud goes on and nothing is taken off
    target = max(n_out - n_far, 0) if n_far < 0.1 * n_in else n_out

    def expected(e: float) -> float:
        return rho * sig * (_step_tail((e - u0) / sig) - _step_tail((e - u0 - w) / sig))

    lo, hi = -3.0 * radius_mm - 3.0 * sig, u0 + w + 5.0 * sig
    if expected(hi) <= target:
        return hi, n_out, n_in
    for _ in range(50):
        mid = 0.5 * (lo + hi)
        lo, hi = (mid, hi) if expected(mid) < target else (lo, mid)
    return 0.5 * (lo + hi), n_out, n_in


def mark_cut_sections(q, bars: list, noise: dict) -> list:
    """The bars with the first and last bar of each set (lattice and level) "not measured" where
    the cloud does not show that it goes on beyond their cross-section.

    For such a bar the cloud's points at every height along its extent (the formwork's, both
    lattices') are taken, and where they end beyond it is estimated (:func:`edge_beyond`): the
    scan's end, not only its lattice's (a lattice's own points beyond a bar are the crossing bars
    alone, a few hundred, and their ends: for an upper bar 4.6 mm inside the scan's edge on a
    synthetic scan at σ 15 mm, they put the edge 26.5 mm from its axis, the whole cloud 18.5 mm).
    Its position is kept as measured only where that edge lies at least ``EDGE_MARGIN_SIGMA``
    times the noise across beyond its section's outer side (radius): the edge is smeared by that
    noise, and on synthetic scans at σ 15 mm (noise across 8-11 mm) edges 5-19 mm from the axis
    were estimated at 13-25 mm, so a cut section and a whole one just inside the edge look alike.
    A bar whose position is not measured gives "not measured" spacings to its neighbour with the
    reason; it is still a bar found.

    Parameters
    ----------
    q : (N, 3) slab-frame points, mm
    bars : list of :class:`rebarlib.geometry.BarAxis` (slab frame)
    noise : ``{layer: (plan σ, height σ)}``, mm

    Returns
    -------
    list of BarAxis, in the same order
    """
    out = list(bars)
    plan = q[:, :2]
    for layer in G.LAYERS:
        for level in G.LEVELS:
            same = [i for i, b in enumerate(out) if b.layer == layer and b.level == level and b.status == MEASURED]
            if len(same) < 2:
                continue
            sig = float(noise.get(layer, (10.0, 10.0))[0])
            ref = out[same[0]]
            mid = float(np.median([out[i].t_mid for i in same]))
            across = {i: _across_at(out[i], ref, mid) for i in same}
            order = sorted(same, key=lambda i: across[i])
            for i, nb, sign in ((order[0], order[1], -1.0), (order[-1], order[-2], 1.0)):
                b = out[i]
                gap = abs(across[i] - across[nb])
                room = gap - 2.0 * _band_side(b.radius_mm, sig)
                t = _dot(plan, b.direction)
                m = (t >= b.t0_mm) & (t <= b.t1_mm)
                u = _dot(plan[m], b.normal2d) - (b.offset_mm + b.slope * t[m])
                u = u * (sign * _orient(b, ref))
                est = edge_beyond(u, b.radius_mm, sig, room)
                if est is None:
                    continue
                edge, n_out, n_in = est
                need = b.radius_mm + EDGE_MARGIN_SIGMA * sig
                if edge >= need:
                    continue
                out[i] = dataclasses.replace(
                    b,
                    status=NOT_MEASURED,
                    reason=(
                        f"at the scan's edge: the cloud ends about {edge:.0f} mm beyond its axis "
                        f"({n_out} points in {max(room, 2 * sig):.0f} mm beyond its band against {n_in} on its "
                        f"inner side), within {EDGE_MARGIN_SIGMA:g} × the noise across ({sig:.1f} mm) of "
                        f"its section ({b.radius_mm:.1f} mm): its cross-section may be cut, and a cut "
                        "section's points do not fix its axis"
                    ),
                )
    return out


def _orient(b: G.BarAxis, ref: G.BarAxis) -> float:
    """+1 where bar ``b``'s plan normal points the way ``ref``'s does, else -1."""
    return 1.0 if float(b.normal2d @ ref.normal2d) >= 0 else -1.0


def _across_at(b: G.BarAxis, ref: G.BarAxis, t_ref: float) -> float:
    """Bar ``b``'s offset across along ``ref``'s normal, at ``t_ref`` along ``ref``."""
    p = b.plan_point(float(np.sign(b.direction @ ref.direction) or 1.0) * t_ref)
    return float(p @ ref.normal2d)
