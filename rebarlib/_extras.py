"""Extra bars (:mod:`rebarlib._counts`): two found bars on one lattice position of a row make
one extra bar only where both are measured bars that run side by side over most of their length
(not a lap or a loose piece) and the colour mask runs along both.

All lengths are in mm; the rules are in ``docs/verdicts.md``.
"""

from __future__ import annotations

import math

import numpy as np

from ._camera import Intrinsics, project
from ._evidence import _Row
from ._status import EXTRA, MEASURED, NOT_EXTRA, NOT_MEASURED
from .geometry import BarAxis, Plane, _in_image, from_slab_frame

__all__: list = []


def _lattice_index(offsets: np.ndarray, s: float) -> np.ndarray:
    """Integer lattice position of each bar: offsets referred to the row's phase (the circular
    median of offset mod spacing), rounded to spacings.

    Parameters
    ----------
    offsets : ndarray
        The bars' plan offsets across the row (mm).
    s : float
        The row's design spacing (mm).

    Returns
    -------
    index : ndarray of int
        Each bar's lattice position.
    phase : float
        The row's phase (mm).

    Examples
    --------
    >>> import numpy as np
    >>> idx, phase = _lattice_index(np.array([0.0, 203.0, 395.0, 490.0, 601.0]), 200.0)
    >>> idx.tolist()
    [0, 1, 2, 2, 3]
    """
    ang = 2 * np.pi * offsets / s
    phase = math.atan2(float(np.median(np.sin(ang))), float(np.median(np.cos(ang)))) * s / (2 * np.pi)
    return np.round((offsets - phase) / s).astype(int), phase


def _mask_along(b: BarAxis, plane: Plane, intr: Intrinsics, foot, own: int, mask) -> float:
    """Share of a bar's axis samples (in the image, not under another found bar) on which the
    rebar mask is set.

    Parameters
    ----------
    b : BarAxis
    plane, intr : Plane, Intrinsics
    foot : ndarray of int
        The found bars' footprints (1 + index, 0 where none).
    own : int
        The bar's own footprint label.
    mask : ndarray of bool
        The (H, W) rebar mask.

    Returns
    -------
    float
        The share, NaN where under 4 samples are free (or the bar is shorter than 5 mm).
    """
    t = np.arange(b.t0_mm, b.t1_mm + 1e-9, 5.0)
    if len(t) < 2:
        return math.nan
    cam = from_slab_frame(b.axis_points(t), plane)
    uv = np.round(project(cam, intr)).astype(int)
    ok = _in_image(uv, cam, intr)
    u, v = uv[ok, 0], uv[ok, 1]
    free = np.isin(foot[v, u], (0, own))
    if free.sum() < 4:
        return math.nan
    return float(mask[v[free], u[free]].mean())


def _pairs(row: _Row, plane, intr, foot, mask, prm):
    """Extra bars: the verdict on each pair of found bars on one lattice position.

    Parameters
    ----------
    row : _Row
    plane, intr : Plane, Intrinsics
    foot : ndarray of int
        The found bars' footprints.
    mask : callable or None
        Returns the (H, W) bool rebar mask when called; None where there is none.
    prm : CountParams

    Yields
    ------
    dict
        A ``positions`` row (``kind`` "pair") without its ``layer`` and ``level``: extra, not
        counted or not measured, with the reason.
    """
    if len(row.bars) < 2:
        return
    m_idx, phase = _lattice_index(row.offsets, row.spacing)
    for m in np.unique(m_idx):
        twins = np.flatnonzero(m_idx == m)
        if len(twins) < 2:
            continue
        # the one farther from the lattice position is the extra one
        dev = np.abs(row.offsets[twins] - (phase + m * row.spacing))
        k_extra = int(twins[np.argmax(dev)])
        others = [int(k) for k in twins if k != k_extra]
        k_twin = min(others, key=lambda k: abs(row.offsets[k] - row.offsets[k_extra]))
        yield _pair_verdict(row, k_extra, k_twin, plane, intr, foot, mask, prm)


def _pair_verdict(row: _Row, k_extra: int, k_twin: int, plane, intr, foot, mask, prm) -> dict:
    """The verdict on one pair: the bar ``k_extra`` (of the row's bars) beside its twin
    ``k_twin`` on the same lattice position.

    Parameters
    ----------
    row, plane, intr, foot, mask, prm
        As for :func:`_pairs`.
    k_extra, k_twin : int
        The two bars' places in ``row.bars``; ``k_extra`` lies farther from the position.

    Returns
    -------
    dict
        The ``positions`` row (see :func:`_pairs`).
    """
    a, b = row.bars[k_extra], row.bars[k_twin]
    base = {
        "kind": "pair",
        "offset_mm": round(float(row.offsets[k_extra]), 1),
        "bar_id": row.index[k_extra],
        "twin_id": row.index[k_twin],
        "position_sigma_mm": math.nan,
        "in_view_mm": math.nan,
        "empty_mm": math.nan,
        "occupied_mm": math.nan,
        "no_depth_mm": math.nan,
        "hidden_mm": math.nan,
        "mask_mm": math.nan,
    }
    gap = abs(float(row.offsets[k_extra] - row.offsets[k_twin]))
    overlap = min(a.t1_mm, b.t1_mm) - max(a.t0_mm, b.t0_mm)
    shorter = min(a.t1_mm - a.t0_mm, b.t1_mm - b.t0_mm)
    what = f"bars {row.index[k_extra]} and {row.index[k_twin]}, {gap:.0f} mm apart on one design position"
    if overlap < prm.overlap_fraction * shorter or overlap < prm.min_evidence_mm:
        return {
            **base,
            "status": NOT_EXTRA,
            "reason": (
                f"{what}, side by side over {max(overlap, 0):.0f} mm only: a lap or a loose piece, not an extra bar"
            ),
        }
    weak = [(row.index[k], x) for x, k in ((a, k_extra), (b, k_twin)) if x.status != MEASURED]
    # two bars a good part of a spacing apart are two things, not one bar read twice (a sliver
    # beside a bar, a bar fitted twice lie within a bar's width or two of it)
    if weak and gap >= max(prm.distinct_fraction * row.spacing, 4.0 * row.radius):
        why = _why_open(row, k_extra, k_twin, a, b, gap, plane, intr, foot, mask, prm)
        if why:
            return {**base, "status": NOT_MEASURED, "reason": f"{what}: {why}"}
    if weak:
        # the position has its bar; the other is no evidence of an extra one
        return {
            **base,
            "status": NOT_EXTRA,
            "reason": (
                f"{what}: bar {weak[0][0]} is not a measured bar ({weak[0][1].reason[:80]}), so it is no "
                "evidence of an extra bar"
            ),
        }
    m_img = mask() if mask is not None else None
    if m_img is None:
        return {**base, "status": NOT_MEASURED, "reason": f"{what}: no colour mask to confirm an extra bar"}
    shares = [_mask_along(x, plane, intr, foot, row.index[k] + 1, m_img) for x, k in ((a, k_extra), (b, k_twin))]
    if all(math.isfinite(x) and x >= prm.min_share for x in shares):
        return {
            **base,
            "status": EXTRA,
            "reason": (
                f"{what}, both fitted to points at bar height over {overlap:.0f} mm, the colour mask along both "
                f"({shares[0]:.0%}, {shares[1]:.0%})"
            ),
        }
    return {
        **base,
        "status": NOT_MEASURED,
        "reason": (f"{what}: the colour mask runs along only {min(shares):.0%} of one of them"),
    }


def _why_open(row: _Row, k_extra: int, k_twin: int, a, b, gap: float, plane, intr, foot, mask, prm) -> str:
    """Why a pair of two distinct bars, one of them no measured bar, leaves the position "not
    measured" rather than showing no extra bar ("" where it shows none; docs/verdicts.md,
    "Extra bars").

    - The bar off the position measured, the one on it not: an extra bar, or this position's bar
      placed far off it beside something else; which, this capture cannot tell.
    - The bar off the position not measured: an extra one only on its own evidence, which it
      lacks; but where the colour mask runs along it, or it lies under nearer bars all along
      (where the mask cannot show it) over a position's length, it is no evidence of none
      either (a bar half-way between two positions lies under a higher bar of its direction
      where that lattice's bars sit there).
    """
    ke, kt = row.index[k_extra], row.index[k_twin]
    if a.status == MEASURED:
        return (
            f"bar {ke} is a measured bar {gap:.0f} mm off the position and bar {kt} beside it is not "
            f"({b.reason[:80]}): whether bar {ke} is an extra bar cannot be told from this capture"
        )
    m_img = mask() if mask is not None else None
    if m_img is None:
        return ""
    share = _mask_along(a, plane, intr, foot, ke + 1, m_img)
    if math.isfinite(share) and share >= prm.min_share:
        return (
            f"bar {ke} is seen in the colour mask along {share:.0%} of it but is not a measured bar "
            f"({a.reason[:80]}): whether it is an extra bar cannot be told from this capture"
        )
    if not math.isfinite(share) and a.t1_mm - a.t0_mm >= prm.min_evidence_mm:
        return (
            f"bar {ke}, found over {a.t1_mm - a.t0_mm:.0f} mm, is not a measured bar ({a.reason[:80]}) and lies "
            "under nearer bars all along, where the colour mask cannot show it: whether it is an extra bar cannot "
            "be told from this capture"
        )
    return ""
