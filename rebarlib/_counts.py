"""Bar counts from evidence: a bar is missing only where an empty position is seen.

Each row of bars (one lattice, one direction) is continued at its design spacing. Every
position where no bar was found is *examined*, never assumed:

1. **Inside the mesh?** Between two found bars it is. Beyond the outermost found bar it is only
   where the crossing bars (the other direction of the same lattice) run across it, to within a
   quarter spacing: where they end, the mesh ends (:func:`mesh_boundary`), and a position
   beyond is "outside the mesh", not missing.
2. **In view?** Its *core*, the nominal line ± (¼ spacing + the bar's radius), must project into
   the image over at least ``min_evidence_mm`` of the row's length; else it is "not in view" and
   is not counted at all (a bar within tolerance of its place lies inside the core).
3. **What the depth shows.** The *corridor* (± ½ spacing across, the neighbours' own pixels
   left out) is sampled at the height of the would-be bar's top, slice by slice along the row
   (every ``step_mm``). Each sample's pixel shows something at the bar's height, the support
   below it (formwork, or the level underneath), something above it (another bar, which hides
   the spot), or no depth. A slice is *occupied* when a stretch at least a radius wide anywhere
   in the corridor is at the bar's height, *empty* when it is not and the core shows no unseen
   stretch as wide as the bar (a bar within a quarter spacing of its place would show), and
   *unknown* otherwise (the cause is kept).
4. **What the colour shows.** The rebar mask (the colour model's) is sampled over the same
   slices, at the would-be bar's axis height, outside every found bar's pixels: a slice shows a
   bar when a stretch at least a radius wide is rebar.

Verdicts: **missing** when at least ``min_evidence_mm`` of slices are empty, at most
``max_share`` of the seen slices are occupied, and the mask shows a bar on at most
``max_share`` of the empty slices. **present, no depth** when the slices lack depth over at
least ``min_evidence_mm`` and the mask shows a bar on at least ``min_share`` of them with a
steady centre line: the bar is placed on that centre line at its level's height and counts as
found. Where that holds only with the slices at the image's border added (the core partly
outside the image, the bar's own width inside; a run of the mask the border cuts does not
count), the bar counts as found too, but its place is not stated to an accuracy and its
spacings are not measured (docs/decisions/060-a-bar-without-depth-at-the-image-s-border.md).
**present** when the slices are occupied (points at the bar's height along it) and the
mask agrees. Anything else is **not measured**, with the reason: no depth there, hidden under
another bar, something at the bar's height that the mask does not call a bar, or a mask that
contradicts the depth.

Extra bars need the same kind of evidence: two found bars on one lattice position (the row's
phase, :func:`_lattice_index`) make one extra only where both are measured bars that run side
by side over most of their length (not a lap or a loose piece) and the mask runs along both.

All lengths are in mm; the decisions are in ``docs/verdicts.md``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import pandas as pd

from ._camera import Intrinsics, project
from ._count_tables import count_table, off_the_row, settle_spacings
from ._evidence import (  # noqa: F401 (names tests and callers reach through this module)
    _footprints,
    _heights,
    _offset,
    _Row,
    _runs,
    _samples,
    mesh_boundary,
)
from ._extras import _lattice_index, _mask_along, _pairs  # noqa: F401 (reached through this module)
from ._position_verdict import _judge, _present, _t_range  # noqa: F401 (reached through this module)
from ._status import (  # noqa: F401 (the position words, reached through this module)
    EXTRA,
    MEASURED,
    MISSING,
    NOT_EXTRA,
    NOT_IN_VIEW,
    NOT_MEASURED,
    OUTSIDE,
    PRESENT,
    PRESENT_NO_DEPTH,
)
from .geometry import LAYERS, LEVELS, BarAxis, Plane, from_slab_frame, to_slab_frame

__all__ = [
    "CountParams",
    "examine_positions",
    "mesh_boundary",
    "count_table",
    "settle_spacings",
    "off_the_row",
    "POSITION_COLUMNS",
]


POSITION_COLUMNS = [
    "layer",
    "level",
    "kind",
    "offset_mm",
    "status",
    "reason",
    "in_view_mm",
    "empty_mm",
    "occupied_mm",
    "no_depth_mm",
    "hidden_mm",
    "mask_mm",
    "position_sigma_mm",
    "bar_id",
    "start_x_mm",
    "start_y_mm",
    "start_z_mm",
    "end_x_mm",
    "end_y_mm",
    "end_z_mm",
    "twin_id",
]


@dataclass(frozen=True)
class CountParams:
    """What it takes to call a position missing, present or extra (mm unless stated).

    step_mm : slice spacing along the row
    sample_mm : sample spacing across the corridor
    min_evidence_mm : length of slices a verdict needs (empty, no-depth or occupied ones)
    core_fraction : the core, ± this × spacing (+ radius), must be in the image
    inside_mm : beyond the outermost bar, the crossing bars must reach to within this of the
        position for it to be inside the mesh. Where a bar is missing at a row's end, its
        crossing bars still run on past its place by their overhang; where the mesh ends, they
        stop one spacing less their overhang short of the next position. The position itself is
        the last bar plus a spacing, good to the bars' placing tolerance on site (about 10-15
        mm), which is what this margin allows; a mesh whose crossing bars overhang its last bar
        by more than a spacing less twice this cannot be told from one missing its end bars
    max_share : at most this share of the seen slices occupied (missing), or of the empty
        slices showing a bar in the mask
    min_share : a mask that shows a bar on at least this share of the slices places it
    max_position_sigma_mm : a bar placed from the mask has its spacings measured when its
        position's standard uncertainty is under this; else they are "not measured"
    max_cut_share : ... and where the mask's band ends at a nearer bar's pixels on under this
        share of the slices it is placed from: beyond it the band is the part showing beside a
        bar over it, its middle not the bar's, and its place is not stated (docs/decisions/075)
    overlap_fraction : an extra bar runs beside its twin over at least this share of the
        shorter one's length (else it is a lap or a loose piece)
    distinct_fraction : two bars on one design position at least this share of a spacing (and
        two bar widths) apart are two things, not one bar read twice: where one of them is no
        measured bar, whether the other is an extra bar is "not measured", not "no extra"
    """

    step_mm: float = 5.0
    sample_mm: float = 2.0
    min_evidence_mm: float = 150.0
    core_fraction: float = 0.25
    inside_mm: float = 15.0
    max_share: float = 0.1
    min_share: float = 0.5
    max_position_sigma_mm: float = 1.5
    max_cut_share: float = 0.5
    overlap_fraction: float = 0.8
    distinct_fraction: float = 0.25


# ----------------------------------------------------------------------------------------------
# Rows and positions


def examine_positions(
    bars: list,
    *,
    design_spacing: dict,
    plane: Plane,
    depth_mm,
    intrinsics: Intrinsics,
    mask=None,
    noise_mm: float | None = None,
    params: CountParams | None = None,
):
    """Examine every empty design position and every close pair of bars of each row.

    Parameters
    ----------
    bars : list of BarAxis (slab frame), as found
    design_spacing : ``{(layer, level): spacing_mm}``
    plane, depth_mm, intrinsics : the formwork plane and the capture's depth (mm) and camera
    mask : callable returning the (H, W) bool rebar mask (the colour model's), called only when
        a verdict needs it; or None (then no position is called missing or extra)
    noise_mm : the depth noise on the formwork (default 1 mm)

    Returns
    -------
    positions : DataFrame, one row per examined position (:data:`POSITION_COLUMNS`): ``kind``
        "gap" | "end" | "pair", ``status`` missing / present / present (no depth) / extra /
        not measured / not counted / outside the mesh / not in view, with the reason and the
        lengths of evidence (mm)
    new_bars : list of BarAxis placed at positions found present (status "not measured"; their
        ``reason`` says how they were placed); ``positions.bar_id`` refers to ``bars + new_bars``
    boundary : :func:`mesh_boundary`
    """
    prm = params or CountParams()
    noise = float(noise_mm or 1.0)
    depth = np.asarray(depth_mm, float)
    intr = intrinsics
    foot = _footprints(bars, plane, intr)
    get_mask = _lazy_mask(mask)
    boundary = mesh_boundary(bars, plane=plane, depth_mm=depth, intrinsics=intr, noise_mm=noise)
    rows_out, new_bars, rows = [], [], {}
    for layer in LAYERS:
        for level in LEVELS:
            row = _row_of(bars, layer, level, design_spacing.get((layer, level)))
            if row is None:
                continue
            rows[(layer, level)] = row
            rows_out.extend(
                _examine_row(
                    row,
                    bars,
                    new_bars,
                    boundary,
                    plane=plane,
                    depth=depth,
                    intr=intr,
                    foot=foot,
                    mask=get_mask,
                    noise=noise,
                    prm=prm,
                )
            )
    rows_out, new_bars = _level_untold(rows_out, rows, len(bars), new_bars, plane)
    df = pd.DataFrame(rows_out, columns=POSITION_COLUMNS)
    return df, new_bars, boundary


def _carried(p: float, h: float, h2: float, c: float, zc: float) -> tuple:
    """``(x, k)``: where the line of sight from the camera's centre (offset ``c`` across, height
    ``zc``) through offset ``p`` at height ``h`` meets height ``h2``, ``x = c + (p - c) k`` with
    ``k = (zc - h2) / (zc - h)``; a bar of radius ``r`` at ``p`` looks as wide there as ``r k``.
    Two bars' silhouettes overlap where ``|x - q| < r2 + r k`` (``q``, ``r2``: the other bar at
    ``h2``)."""
    k = (zc - h2) / (zc - h)
    return c + (p - c) * k, k


# the positions that may hold a bar no depth places: a bar seen only in colour along a line of
# sight they share could be theirs
_OPEN = (MISSING, PRESENT_NO_DEPTH, NOT_MEASURED)


def _level_untold(recs: list, rows: dict, n_found: int, new_bars: list, plane: Plane) -> tuple:
    """``(recs, new_bars)`` with a bar placed from the colour mask alone taken back where its
    level cannot be told (docs/decisions/074).

    A bar without depth is placed on the mask's centre line at the height of the level whose
    position it stands on. The colour does not say that height. Where a position of a row of
    the same direction on another level — one where no bar with depth was found: missing,
    placed without depth, or not measured — lies on the same lines of sight (seen from the
    camera's centre, the two bars' silhouettes would overlap), the band of rebar could be
    either bar: a missing upper bar right over a lower bar in the projector's shadow would be
    counted present. Both positions are then "not measured", with the reason, and no bar is
    placed for either. The silhouettes overlap where the would-be axis at offset ``p`` and
    height ``h``, carried along the lines of sight to the other level's height ``h2`` (``c +
    (p - c) k``, ``k = (zc - h2) / (zc - h)``, ``c`` and ``zc`` the camera's offset across and
    height), lies within ``r2 + r k`` of that level's position, and their stretches along the
    row overlap."""
    placed = [i for i, o in enumerate(recs) if o["status"] == PRESENT_NO_DEPTH and o["kind"] in ("gap", "end")]
    if not placed:
        return recs, new_bars
    cam = to_slab_frame(np.zeros((1, 3)), plane)[0]
    rivals = [j for j, o in enumerate(recs) if o["status"] in _OPEN and o["kind"] in ("gap", "end")]
    plan = {}  # a record's axis ends in plan (slab frame), taken once, when first needed

    def stretch(i, row):
        if i not in plan:
            ends = np.array([[recs[i][f"{e}_{c}_mm"] for c in "xyz"] for e in ("start", "end")], float)
            plan[i] = to_slab_frame(ends, plane)[:, :2]
        t = plan[i] @ row.direction
        return float(t.min()), float(t.max())

    untold = {}
    for i in placed:
        rec = recs[i]
        row = rows[(rec["layer"], rec["level"])]
        c, zc = float(cam[:2] @ row.normal), float(cam[2])
        t0, t1 = stretch(i, row)
        for j in rivals:
            other = recs[j]
            row2 = rows[(other["layer"], other["level"])]
            if row2 is row or abs(float(row.direction @ row2.direction)) < 0.95:
                continue
            if zc <= max(row.height, row2.height) + 1.0:
                continue
            u0, u1 = stretch(j, row)
            if min(t1, u1) <= max(t0, u0):
                continue
            x, k = _carried(float(rec["offset_mm"]), row.height, row2.height, c, zc)
            q = float(np.sign(row.normal @ row2.normal)) * float(other["offset_mm"])
            if abs(x - q) < row2.radius + row.radius * k:
                untold.setdefault(i, j)
    if not untold:
        return recs, new_bars
    out, kept, renumber = [], [], {}
    for i, rec in enumerate(recs):
        bid = rec.get("bar_id")
        placed = bid is not None and not pd.isna(bid) and int(bid) >= n_found
        if i in untold:
            o = recs[untold[i]]
            rec = {
                **rec,
                "status": NOT_MEASURED,
                "bar_id": None,
                "reason": (
                    "the colour mask shows a bar along it without depth, but the "
                    f"{o['layer']} {o['level']} position at {float(o['offset_mm']):.0f} mm lies on the same "
                    "lines of sight: without depth the bar's height, and so which of the two it is, "
                    "cannot be told"
                ),
            }
        elif placed:
            renumber[int(bid)] = n_found + len(kept)
            kept.append(new_bars[int(bid) - n_found])
            rec = {**rec, "bar_id": renumber[int(bid)]}
        out.append(rec)
    return out, kept


def _lazy_mask(mask):
    """The rebar mask, computed once on first need.

    Parameters
    ----------
    mask : callable or None
        Returns the (H, W) rebar mask (or None) when called.

    Returns
    -------
    callable or None
        Returns the mask as a bool array (or None), calling ``mask`` at most once; None where
        ``mask`` is None.
    """
    if mask is None:
        return None
    cache = {}

    def get_mask():
        if "m" not in cache:
            m = mask()
            cache["m"] = None if m is None else np.asarray(m, bool)
        return cache["m"]

    return get_mask


def _row_of(bars: list, layer: str, level: str, spacing) -> _Row | None:
    """The row of one lattice's level: its found bars in order across, its height, height
    spread and radius from its measured bars.

    Parameters
    ----------
    bars : list of BarAxis
        All the found bars.
    layer, level : str
        The lattice and its level.
    spacing : float or None
        The row's design spacing (mm).

    Returns
    -------
    _Row or None
        None where the row has no design spacing, no bar or no measured bar.
    """
    idx = [i for i, b in enumerate(bars) if b.layer == layer and b.level == level]
    if not idx or not spacing:
        return None
    n2 = bars[idx[0]].normal2d
    order = sorted(idx, key=lambda i: _offset(bars[i], n2))
    meas = [bars[i] for i in order if bars[i].status == MEASURED]
    if not meas:
        return None
    hs = np.array([b.axis_height_mm for b in meas])
    return _Row(
        layer,
        level,
        [bars[i] for i in order],
        order,
        np.array([_offset(bars[i], n2) for i in order]),
        float(spacing),
        float(np.median(hs)),
        float(1.4826 * np.median(np.abs(hs - np.median(hs)))) if len(hs) > 2 else 1.0,
        float(np.median([b.radius_mm for b in meas])),
        bars[idx[0]].direction,
        n2,
    )


def _examine_row(row: _Row, bars: list, new_bars: list, boundary: dict, *, plane, depth, intr, foot, mask, noise, prm):
    """The ``positions`` rows of one row: each empty design position judged, then each pair of
    found bars on one position.

    Parameters
    ----------
    row : _Row
    bars : list of BarAxis
        All the found bars.
    new_bars : list of BarAxis
        The bars placed so far; a bar placed here is appended (``bar_id`` counts on from
        ``len(bars)``).
    boundary : dict
        :func:`mesh_boundary`.
    plane, depth, intr, foot : Plane, ndarray, Intrinsics, ndarray
        The formwork plane, the depth image (mm), the camera and the found bars' footprints.
    mask : callable or None
        Returns the rebar mask when called (:func:`_lazy_mask`).
    noise : float
        The depth noise on the formwork (mm).
    prm : CountParams

    Returns
    -------
    list of dict
        The rows, with their ``layer`` and ``level``.
    """
    layer, level, n2 = row.layer, row.level, row.normal
    reach = _reach(boundary, layer, level, row.normal)
    higher = [i + 1 for i, b in enumerate(bars) if b.axis_height_mm > row.height + row.radius]
    # the higher bars along this row (offset across, axis height, radius): where one
    # hides a position, they say from where it would show
    over = [
        (_offset(b, n2), b.axis_height_mm, b.radius_mm)
        for b in bars
        if b.axis_height_mm > row.height + row.radius and abs(float(b.direction @ row.direction)) > 0.95
    ]
    out = []
    for kind, p, nb in _candidates(row, reach, plane, intr, prm):
        rec = _judge(
            row,
            kind,
            p,
            nb,
            reach,
            plane=plane,
            depth=depth,
            intr=intr,
            foot=foot,
            higher=higher,
            mask=mask,
            noise=noise,
            prm=prm,
        )
        if rec["status"] == NOT_MEASURED and rec["reason"].startswith("hidden under"):
            rec["reason"] += _where_it_shows(row, p, over, plane, intr)
        if rec.pop("_bar", None) is not None:
            new_bars.append(rec.pop("_new"))
            rec["bar_id"] = len(bars) + len(new_bars) - 1
        rec.update(_line_ends(row, float(rec["offset_mm"]), _t_range(nb), plane))
        out.append({"layer": layer, "level": level, **rec})
    out.extend({"layer": layer, "level": level, **rec} for rec in _pairs(row, plane, intr, foot, mask, prm))
    return out


def _where_it_shows(row: _Row, p: float, over: list, plane: Plane, intr: Intrinsics | None = None) -> str:
    """Advice for a position hidden under a higher bar of its direction: how far to move the
    camera across the row for the bar to show beside that bar, and which way keeps it in view
    ("" where no such bar covers it).

    Seen from the camera's centre, a bar at height ``h`` and offset ``p`` across lies at
    ``c + (p - c) k`` on the higher bar's level (``c`` the camera's offset across, ``k = (zc -
    hu) / (zc - h)``); it clears the higher bar (offset ``q``, radius ``ru``) when that point is
    ``ru + r k`` or more from ``q``. Moving the camera by ``dc`` moves it by ``(1 - k) dc``; tilting
    the camera moves nothing (only its centre matters). The move advised clears it either way;
    moved towards the position (the side of the camera it lies on), the position also comes
    nearer the middle of the image, while moved away it goes towards the image's border and can
    leave the view (a position at a row's end near the border). The side is named by the image
    edge the camera moves towards (where ``intr`` is given)."""
    cam = to_slab_frame(np.zeros((1, 3)), plane)[0]
    c, zc = float(cam[:2] @ row.normal), float(cam[2])
    best = None
    for q, hu, ru in over:
        if zc <= hu + 1.0:
            continue
        x, k = _carried(p, row.height, hu, c, zc)
        d = x - q  # the position's place on that bar's level, from the bar
        if best is None or abs(d) < abs(best[0]):
            best = (d, k, ru)
    if best is None:
        return ""
    d, k, ru = best
    need = ru + row.radius * k
    if abs(d) >= need:
        return ""
    # one way it needs (need - |d|) / (1 - k), the other way (need + |d|) / (1 - k): the advice
    # holds either way
    move = 10.0 * math.ceil((need + abs(d)) / max(1.0 - k, 1e-6) / 10.0)
    return (
        f"; a capture taken with the camera about {move:.0f} mm or more to either side across these bars "
        "(moved, not tilted) would show it beside that bar" + _towards(row, p, c, plane, intr)
    )


def _towards(row: _Row, p: float, c: float, plane: Plane, intr: Intrinsics | None) -> str:
    """The side to move the camera to for a hidden position to stay in view: towards it, named
    by the image edge that way (the image direction of a step across the row from the position
    towards its side of the camera's centre); "" without a camera."""
    if intr is None:
        return ""
    sign = 1.0 if p >= c else -1.0
    t = float(np.mean([b.t_mid for b in row.bars]))
    plan = np.array([t * row.direction + p * row.normal, t * row.direction + (p + sign * 50.0) * row.normal])
    cam = from_slab_frame(np.column_stack((plan, np.full(2, row.height))), plane)
    if np.any(cam[:, 2] <= 1.0):
        return ""
    du, dv = np.diff(project(cam, intr), axis=0)[0]
    edge = ("right" if du > 0 else "left") if abs(du) >= abs(dv) else ("bottom" if dv > 0 else "top")
    return f"; moved towards it (towards the image's {edge} edge) it also stays in view"


def _reach(boundary: dict, layer: str, level: str, n2) -> dict | None:
    """The crossing bars' reach across a row: its own lattice's, or where that lattice's
    crossing bars were not found, the other lattice's bars of the crossing direction (the two
    meshes of a slab are tied over the same area), marked ``proxy``."""
    own = (boundary.get(layer) or {}).get(level)
    if own:
        return own
    other = "upper" if layer == "lower" else "lower"
    for lv in LEVELS:
        cand = (boundary.get(other) or {}).get(lv)
        if not cand:
            continue
        # a group of the other lattice whose own normal is parallel to this row's is crossed
        # by the same direction as this row
        cos = float(np.dot(np.array(cand["normal"]), n2))
        if abs(cos) > 0.9:
            flip = cos < 0
            lo, hi = cand["reach_minus_mm"], cand["reach_plus_mm"]
            el, eh = cand["edge_minus"], cand["edge_plus"]
            if flip:
                lo, hi, el, eh = -hi, -lo, eh, el
            return {
                **cand,
                "reach_minus_mm": lo,
                "reach_plus_mm": hi,
                "edge_minus": el,
                "edge_plus": eh,
                "proxy": f"the {other} lattice's crossing bars",
            }
    return None


def _candidates(row: _Row, reach, plane, intr, prm):
    """(kind, plan offset, the two nearest found bars) of each empty design position: inside
    the gaps of the row, and beyond its outermost bars while the would-be axis is in view."""
    offs, s = row.offsets, row.spacing
    for a, b, oa, ob in zip(row.bars[:-1], row.bars[1:], offs[:-1], offs[1:]):
        k = int(round((ob - oa) / s)) - 1
        for j in range(1, k + 1):
            yield "gap", oa + j * (ob - oa) / (k + 1), (a, b)
    for sign, start, nb in ((-1, offs[0], row.bars[:2]), (1, offs[-1], row.bars[-2:][::-1])):
        for j in range(1, 100):
            p = start + sign * j * s
            if not _line_in_view(row, p, nb[0], plane, intr, prm):
                break
            yield "end", p, tuple(nb)


def _line_in_view(row: _Row, p: float, b: BarAxis, plane, intr, prm) -> bool:
    t = np.arange(b.t0_mm, b.t1_mm + 1e-9, prm.step_mm)
    _, inside = _samples(row, p, t, np.array([0.0]), row.height + row.radius, plane, intr)
    return inside.sum() * prm.step_mm >= prm.min_evidence_mm


def _line_ends(row: _Row, p: float, t_range, plane: Plane) -> dict:
    """Camera-frame ends of the would-be axis at plan offset ``p`` (for drawing it)."""
    t = np.array(t_range, float)
    plan = t[:, None] * row.direction + p * row.normal
    cam = from_slab_frame(np.column_stack((plan, np.full(2, row.height))), plane)
    return {
        f"{end}_{c}_mm": round(float(cam[i, j]), 2)
        for i, end in enumerate(("start", "end"))
        for j, c in enumerate("xyz")
    }
