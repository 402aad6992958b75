"""The verdict on one empty design position of a row (:mod:`rebarlib._counts`): outside the
mesh, not in view, present (placed from the colour mask), missing or not measured, from the
evidence :mod:`rebarlib._evidence` gathers along the would-be bar.

The tests run in a fixed order (:func:`_judge`): beyond the crossing bars' reach, too little of
it in view, occupied at the bar's height, seen empty, without depth but shown by the mask, and
otherwise not measured with the reason. All lengths are in mm; the rules are in
``docs/verdicts.md``.
"""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np

from ._evidence import _add_mask, _examine, _place_from_mask, _Row
from ._status import MISSING, NOT_IN_VIEW, NOT_MEASURED, OUTSIDE, PRESENT, PRESENT_NO_DEPTH
from .geometry import BarAxis

__all__: list = []

#: the evidence lengths a ``positions`` row carries (mm)
EVIDENCE_KEYS = ("in_view_mm", "empty_mm", "occupied_mm", "no_depth_mm", "hidden_mm", "mask_mm")


def _t_range(nb) -> tuple:
    """The span along the row of the bars ``nb``.

    Parameters
    ----------
    nb : sequence of BarAxis

    Returns
    -------
    tuple of float
        ``(t0_mm, t1_mm)``: the least start and the greatest end.
    """
    return min(b.t0_mm for b in nb), max(b.t1_mm for b in nb)


def _judge(row: _Row, kind: str, p: float, nb, reach, *, plane, depth, intr, foot, higher, mask, noise, prm) -> dict:
    """The verdict on one empty position, in the order of tests of the module docstring.

    Parameters
    ----------
    row : _Row
        The row the position belongs to.
    kind : str
        ``"gap"`` (between two found bars) or ``"end"`` (beyond the outermost one).
    p : float
        The position's plan offset across the row (mm).
    nb : tuple of BarAxis
        The two nearest found bars (their span along the row bounds the slices).
    reach : dict or None
        The crossing bars' reach across the row (``_counts._reach``).
    plane, depth, intr, foot : Plane, ndarray, Intrinsics, ndarray
        The formwork plane, the depth image (mm), the camera and the found bars' footprints.
    higher : list of int
        1 + index of each found bar above the row's bars.
    mask : callable or None
        Returns the (H, W) bool rebar mask when called; None where there is none.
    noise : float
        The depth noise on the formwork (mm).
    prm : CountParams

    Returns
    -------
    dict
        A ``positions`` row without its ``layer`` and ``level``; with ``_bar``/``_new`` (the
        placed :class:`BarAxis`) where a bar is found present there.
    """
    base = {"kind": kind, "offset_mm": round(p, 1), "bar_id": None, "position_sigma_mm": math.nan}
    if kind == "end":
        rec = _beyond_the_mesh(row, p, reach, base, prm)
        if rec is not None:
            return rec
    ev = _evidence_at(
        row, p, nb, plane=plane, depth=depth, intr=intr, foot=foot, higher=higher, mask=mask, noise=noise, prm=prm
    )
    rec = {**base, **{k: round(ev[k], 1) for k in EVIDENCE_KEYS}}
    E = prm.min_evidence_mm
    if ev["in_view_mm"] < E:
        return {**rec, "status": NOT_IN_VIEW, "reason": f"only {ev['in_view_mm']:.0f} mm of it in view (needs {E:.0f})"}
    return _verdict(row, p, ev, rec, plane, intr, prm)


def _beyond_the_mesh(row: _Row, p: float, reach, base: dict, prm) -> dict | None:
    """The verdict on a position beyond the row's outermost bar where the mesh's extent decides
    it: not measured where no crossing bar tells where the mesh ends, outside the mesh where
    the crossing bars end more than ``prm.inside_mm`` before it.

    Parameters
    ----------
    row : _Row
    p : float
        The position's plan offset (mm).
    reach : dict or None
        The crossing bars' reach across the row.
    base : dict
        The row's fields common to every verdict.
    prm : CountParams

    Returns
    -------
    dict or None
        The ``positions`` row, or None where the position is inside the mesh (judged on).
    """
    side = "plus" if p > row.offsets[-1] else "minus"
    if reach is None:
        return {
            **base,
            "status": NOT_MEASURED,
            "reason": "no crossing bar found: where the mesh ends cannot be "
            "told, so this position beyond the outermost bar is not judged",
        }
    r_edge = reach[f"reach_{side}_mm"]
    beyond = (p - r_edge) if side == "plus" else (r_edge - p)
    if beyond > prm.inside_mm:
        edge = reach[f"edge_{side}"]
        return {
            **base,
            "status": OUTSIDE,
            "reason": (
                f"the crossing bars end {beyond:.0f} mm before it"
                + (" (the mesh's edge is in view)" if edge else " (where they leave the view or are hidden)")
            ),
        }
    return None


def _evidence_at(row: _Row, p: float, nb, *, plane, depth, intr, foot, higher, mask, noise, prm) -> dict:
    """What the depth shows along the would-be bar at ``p``, and the colour mask where the depth
    leaves a verdict that needs it (the mask is read only then).

    Parameters
    ----------
    row, p, nb, plane, depth, intr, foot, higher, mask, noise, prm
        As for :func:`_judge`.

    Returns
    -------
    dict
        The evidence of :func:`rebarlib._evidence._examine`, with the mask's
        (:func:`rebarlib._evidence._add_mask`) where it was read.
    """
    row_ids = [i + 1 for i in row.index]
    ev = _examine(
        row,
        p,
        _t_range(nb),
        plane=plane,
        depth=depth,
        intr=intr,
        foot=foot,
        row_ids=row_ids,
        higher=higher,
        noise=noise,
        prm=prm,
    )
    E = prm.min_evidence_mm
    nd_mm = ev["no_depth_mm"] + float(ev["_nd_edge"].sum()) * prm.step_mm
    needs = ev["in_view_mm"] >= E and (ev["occupied_mm"] >= E or ev["empty_mm"] >= E or nd_mm >= E)
    m = mask() if (mask is not None and needs) else None
    if m is not None:
        ev = _add_mask(ev, row, p, m, plane=plane, intr=intr, foot=foot, prm=prm, depth=depth, noise=noise)
    return ev


def _verdict(row: _Row, p: float, ev: dict, rec: dict, plane, intr, prm) -> dict:
    """The verdict on a position in view, from its evidence: occupied, empty, placed without
    depth, or not measured, tested in that order.

    Parameters
    ----------
    row, p : _Row, float
        The row and the position's plan offset (mm).
    ev : dict
        The evidence (:func:`_evidence_at`).
    rec : dict
        The ``positions`` row so far (its evidence lengths).
    plane, intr, prm : Plane, Intrinsics, CountParams

    Returns
    -------
    dict
        The ``positions`` row (see :func:`_judge`).
    """
    E = prm.min_evidence_mm
    seen = ev["empty_mm"] + ev["occupied_mm"]
    if ev["occupied_mm"] >= E and ev["occupied_mm"] >= 0.5 * seen:
        return _occupied(row, p, ev, rec, plane, intr, prm)
    if ev["empty_mm"] >= E and ev["occupied_mm"] <= prm.max_share * seen:
        return _empty(row, ev, rec, prm)
    if ev["no_depth_mm"] >= E and "_shows" in ev:
        share = ev["mask_nodepth_share"]
        sel = ev["_nd"] & ev["_shows"]
        if share >= prm.min_share and sel.sum() * prm.step_mm >= E:
            return _present(row, p, ev, sel, plane, intr, prm, rec, PRESENT_NO_DEPTH, "")
    # the same with the slices at the image's border, where only the bar's own width is in view:
    # the bar is there, but its place is not stated to an accuracy (decision 060)
    nd = ev["_nd"] | ev["_nd_edge"]
    if ev["_nd_edge"].any() and nd.sum() * prm.step_mm >= E and "_shows" in ev:
        share = float(ev["_shows"][nd].mean())
        sel = nd & ev["_shows"]
        if share >= prm.min_share and sel.sum() * prm.step_mm >= E:
            return _present(row, p, ev, sel, plane, intr, prm, rec, PRESENT_NO_DEPTH, "", border=True)
    return _not_measured(ev, rec, prm)


def _occupied(row: _Row, p: float, ev: dict, rec: dict, plane, intr, prm) -> dict:
    """A position with points at the bar's height along it: present where the colour mask
    agrees, else not measured (another object, or no mask).

    Parameters
    ----------
    row, p, ev, rec, plane, intr, prm
        As for :func:`_verdict`.

    Returns
    -------
    dict
        The ``positions`` row.
    """
    has_mask = "_shows" in ev
    if has_mask and ev["mask_occupied_share"] >= prm.min_share:
        why = (
            f"points at the bar's height along {ev['occupied_mm']:.0f} mm and the colour mask "
            "along it: a bar the fit did not take"
        )
        return _present(row, p, ev, ev["_state"] == 2, plane, intr, prm, rec, PRESENT, why)
    return {
        **rec,
        "status": NOT_MEASURED,
        "reason": (
            f"points at the bar's height along {ev['occupied_mm']:.0f} mm, but "
            + ("the colour mask does not show a bar there (another object?)" if has_mask else "no colour mask")
        ),
    }


def _empty(row: _Row, ev: dict, rec: dict, prm) -> dict:
    """A position whose corridor the depth shows empty: missing where the colour mask shows no
    bar there either, else not measured (no mask, or a mask that contradicts the depth).

    Parameters
    ----------
    row, ev, rec, prm
        As for :func:`_verdict`.

    Returns
    -------
    dict
        The ``positions`` row.
    """
    if "_shows" not in ev:
        return {
            **rec,
            "status": NOT_MEASURED,
            "reason": (
                f"the depth shows the support and nothing at the bar's height along {ev['empty_mm']:.0f} mm, "
                "but no colour mask was available to confirm it"
            ),
        }
    share = ev["mask_empty_share"]
    if share <= prm.max_share:
        support = "formwork" if row.level == "bottom" and row.layer == "lower" else "support"
        return {
            **rec,
            "status": MISSING,
            "reason": (
                f"empty: the {support} "
                f"is seen with depth and nothing at the bar's height along {ev['empty_mm']:.0f} mm of the "
                f"corridor (± {row.spacing / 2:.0f} mm), and the colour mask shows no bar there"
            ),
        }
    return {
        **rec,
        "status": NOT_MEASURED,
        "reason": (
            f"the depth shows the corridor empty along {ev['empty_mm']:.0f} mm, but the colour mask shows a bar "
            f"on {share:.0%} of it"
        ),
    }


def _not_measured(ev: dict, rec: dict, prm) -> dict:
    """A position in view that no test decided: not measured, with the main cause (no depth,
    hidden under another bar, or too little evidence of any kind).

    Parameters
    ----------
    ev, rec, prm
        As for :func:`_verdict`.

    Returns
    -------
    dict
        The ``positions`` row.
    """
    E = prm.min_evidence_mm
    has_mask = "_shows" in ev
    if ev["no_depth_mm"] >= E and ev["no_depth_mm"] >= ev["hidden_mm"]:
        share = ev["mask_nodepth_share"]
        if not has_mask:
            tail = " and no colour mask"
        elif math.isfinite(share):
            tail = f", and the colour mask shows a bar on only {share:.0%} of that"
        else:
            tail = ""
        return {**rec, "status": NOT_MEASURED, "reason": f"no depth along {ev['no_depth_mm']:.0f} mm of it" + tail}
    if ev["hidden_mm"] >= ev["no_depth_mm"] and ev["hidden_mm"] > 0:
        return {
            **rec,
            "status": NOT_MEASURED,
            "reason": (
                f"hidden under another bar along {ev['hidden_mm']:.0f} mm; only {ev['empty_mm']:.0f} mm seen empty"
            ),
        }
    return {
        **rec,
        "status": NOT_MEASURED,
        "reason": (
            f"too little evidence: {ev['empty_mm']:.0f} mm seen empty, {ev['occupied_mm']:.0f} mm occupied, "
            f"{ev['no_depth_mm']:.0f} mm without depth (needs {E:.0f} mm of one)"
        ),
    }


def _present(
    row: _Row,
    p: float,
    ev: dict,
    sel: np.ndarray,
    plane,
    intr,
    prm,
    rec: dict,
    status: str,
    why: str,
    border: bool = False,
) -> dict:
    """A position found holding a bar: the bar placed on the mask's centre line over the slices
    ``sel`` at its level's height, status "not measured" (its axis is not fitted to points).

    Parameters
    ----------
    row, p, ev : _Row, float, dict
        The row, the position's plan offset (mm) and its evidence.
    sel : ndarray of bool
        The slices the bar is placed from.
    plane, intr, prm : Plane, Intrinsics, CountParams
    rec : dict
        The ``positions`` row so far.
    status : str
        ``PRESENT`` or ``PRESENT_NO_DEPTH``.
    why : str
        The reason's first part (for ``PRESENT``).
    border : bool
        Whether ``sel`` takes slices at the image's border (decision 060): the bar counts as
        found, its place is not stated to an accuracy (``position_sigma_mm`` NaN), so its
        spacings are not measured.

    Returns
    -------
    dict
        The ``positions`` row, with ``_bar`` True and ``_new`` the placed :class:`BarAxis`.
    """
    placed = sel & np.isfinite(ev["_centre"])
    off, sd, t0, t1 = _place_from_mask(row, p, ev, placed, plane, intr, prm)
    # the share of those slices whose band ends at a found bar's pixels (decision 075)
    cut = float(ev["_cut"][placed].mean()) if placed.any() else 0.0
    if border:
        at = float((sel & ev["_nd_edge"]).sum()) * prm.step_mm
        how = (
            f"the colour mask shows it over {sel.sum() * prm.step_mm:.0f} mm, {at:.0f} mm of that where the "
            "image's border cuts its corridor: placed from the mask's centre line at its level's height, its "
            "place not stated to an accuracy, so its spacings are not measured"
        )
        sd = math.nan
    elif cut >= prm.max_cut_share:
        how = (
            "placed from the colour mask's centre line at its level's height; along "
            f"{cut:.0%} of it the mask's band ends at a nearer bar's pixels, so its centre line is that "
            "of the part showing beside that bar, not the bar's: its place not stated to an accuracy, "
            "so its spacings are not measured"
        )
        sd = math.nan
    else:
        ok = sd <= prm.max_position_sigma_mm
        how = (
            f"placed from the colour mask's centre line at its level's height (± {sd:.1f} mm across"
            + ("" if ok else f"; over {prm.max_position_sigma_mm:g} mm, so its spacings are not measured")
            + ")"
        )
    reason = ("no depth on it: " if status == PRESENT_NO_DEPTH else why + "; ") + how
    ref = row.bars[0]
    bar = BarAxis(
        layer=row.layer,
        direction=ref.direction.copy(),
        offset_mm=float(off),
        slope=0.0,
        centre_h_mm=row.height,
        h_slope=0.0,
        t0_mm=t0,
        t1_mm=t1,
        radius_mm=row.radius,
        n_points=0,
        rms_mm=math.nan,
        point_index=np.zeros(0, int),
        group=ref.group,
        level=row.level,
        status=NOT_MEASURED,
        reason=reason,
    )
    bar = replace(bar, axis_se_mm=float(sd))
    return {
        **rec,
        "status": status,
        "reason": reason,
        "position_sigma_mm": round(sd, 2),
        "offset_mm": round(off, 1),
        "_bar": True,
        "_new": bar,
    }
