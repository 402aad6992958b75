"""A slab's captures judged together: where two captures of one slab overlap, a bar position
that one of them could not judge (hidden under a bar of the upper lattice, without depth, only
partly in view) is judged by the other (docs/decisions/028-captures-of-one-slab-together.md).

The captures are registered **from their bars alone**, so it works on ``result.json`` files
without the images: each capture's bars, in its own slab frame (the formwork plane's), are
lines in plan. Between two captures of one slab the plan frames differ by a rotation and a
translation. The rotation comes from the bars' directions (one per set of bars; all must
agree), up to a half turn. Each translation component comes from matching the bars' offsets
across one direction; a mesh is periodic, so a shift by whole spacings fits almost as well as
the right one — the bars' own irregular placing (hand-tied bars lie millimetres off their
nominal places, each differently) is what tells them apart. A registration is accepted only
when one placing pairs enough bars of both directions within the measurement's scatter,
contradicts neither capture's view, and is 1000 times more likely than every rival (another
shift, the half turn, no overlap at all); a mesh too regular to tell is left unregistered and
its open positions stay "not measured". A wrong registration would turn a hidden missing bar
into a present one, so the test errs on refusing.

A capture taken because another capture's sheet asked for it, aimed at one of that capture's
bars (its ``aim.json``, carried into its result as ``extras["aimed_at"]``), says which bar it shows
at its image's middle. Where its pair is refused as too regular, that aim chooses among the
placings that fit: only those putting the bar aimed at on the aimed capture's bar at its aim point
compete (docs/decisions/043-a-capture-placed-where-it-was-aimed.md). A pair the bars alone cannot
place is placed through a third capture placed on both, where the composed placing contradicts
neither's bars (docs/decisions/044-two-captures-placed-through-a-third.md).
"""

from __future__ import annotations

import copy
import math
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

from ._counts import CountParams
from ._status import HIDDEN, MEASURED, MISSING, NOT_IN_VIEW, NOT_MEASURED, PRESENT
from .geometry.plane import Plane, to_slab_frame

#: a registration needs at least this many bars matched across each of the two directions
MIN_MATCHED = 3
#: the bars' offsets are taken as measured no better than this (mm) when the odds of a placing
#: are weighed, however tightly it fits
SIGMA_FLOOR_MM = 0.3
#: shifts kept per direction before the joint test of both
SHORTLIST = 6
#: two bars are compared where their seen stretches overlap, or lie apart along the bar by at most
#: this (mm), at the middle of what they share or of the gap between them. Two captures of a bar
#: often see different stretches of it (a capture taken from closer, aimed at it, shows its middle;
#: the first showed one end); the same line of a lattice is one bar across a gap shorter than the
#: shortest lap (EN 1992-1-1 8.7.3: l0 >= max(0.3 a6 lb,rqd, 15 phi, 200 mm); GB 50010: 300 mm): a
#: second bar joined to it by a lap would lie beside it over at least that length, in view in one
#: of the stretches (docs/decisions/041)
MAX_GAP_MM = 200.0
#: a bar with at least this much (mm) in the other capture's view must be matched there: the
#: length a bar position's verdict needs in one capture
MIN_CONFLICT_MM = CountParams.min_evidence_mm
#: a registration needs odds of at least e^LOG_ODDS (1000 : 1) over every other shift
LOG_ODDS = math.log(1000.0)
#: the matched bars' RMS misfit may not exceed this (mm): a bar measured to a millimetre
MAX_RMS_MM = 1.5
#: the bars' directions of the sets must agree to within this (degrees) after the rotation
MAX_ANGLE_SPREAD_DEG = 2.0
#: a person aiming a capture at a bar's middle ("aimed at its middle", the sheet's advice) puts the
#: image's middle within this share of the bar's design spacing of the bar, across it. The bar
#: nearest the aim point is taken as the bar aimed at only where it lies within that and every
#: other bar of its set at least a spacing less twice that (half a spacing) farther: a bar
#: within a quarter spacing of the aim and its neighbours a spacing from that bar (decision 043)
AIM_ERROR_SPACINGS = 0.25
#: along the bar, "its middle" is the middle of the stretch the asking capture saw, found on the
#: slab among its crossing bars: the aim is taken to lie within this share of the crossing bars'
#: design spacing of it (more than across: the middle of a stretch is judged, a bar is seen). A
#: placing is chosen along only where it puts the aim within that and every other placing that
#: fits at least a crossing spacing less twice that (a quarter spacing) farther (decision 043)
AIM_ALONG_SPACINGS = 0.375
#: a bar sized from one edge over this share of its sections or more has its axis fitted to the
#: side it shows (the diameter stage's ``hidden_fraction``, decision 024)
_ONE_SIDED_SHARE = 0.5

# the refusals of a pair (_register); which of them a placing through a third capture may settle:
# _chainable (decision 044)
_NO_FIT = f"no placing fits {MIN_MATCHED} or more bars of each direction to within {MAX_RMS_MM} mm"
_TOO_REGULAR = "the mesh is too regular to tell which bars are the same (two placings fit alike)"
_AIM_DENIED = "no placing that fits puts that bar on bar"
_BARS_AGAINST_AIM = "the bars favour another placing 1000 : 1"


@dataclass
class _Set:
    key: tuple  # (layer, level)
    direction: np.ndarray  # plan unit direction (2,), sign fixed
    mids: np.ndarray  # (N, 2) mid points in plan
    bar_ids: list
    segs: np.ndarray  # (N, 2, 2) the bars' ends in plan
    open_mids: np.ndarray  # (M, 2) mid points of the positions not found (not measured, missing, not in view)
    #: (N,) whether each bar's axis is a fit to both its sides (:func:`_well_placed`); None: all are
    fitted: np.ndarray | None = None

    def __post_init__(self):
        if self.fitted is None:
            self.fitted = np.ones(len(self.mids), bool)


class _Placing(NamedTuple):
    """One placing of capture a in capture b's frame, per bar direction (two): the pairs of two
    fitted axes (their RMS and count), the rotation and shift, and the other pairs
    (``(RMS, count)``: a bar placed otherwise than by a fit to both its sides, :func:`_well_placed`)."""

    rms: list  # per direction, mm, of the pairs of fitted axes
    n: list  # per direction, the pairs of fitted axes
    theta: float
    R: np.ndarray
    t: np.ndarray
    shifts: tuple  # the shift across each direction it was built from, mm
    other: list  # per direction, (RMS mm, count) of the other pairs


def _plane(r: dict) -> Plane | None:
    fw = r.get("formwork") or {}
    if not fw.get("found", True) or fw.get("normal") is None or fw.get("offset_mm") is None:
        return None
    return Plane(np.asarray(fw["normal"], float), float(fw["offset_mm"]))


def _ends(rec: dict) -> np.ndarray | None:
    keys = ("start_x_mm", "start_y_mm", "start_z_mm", "end_x_mm", "end_y_mm", "end_z_mm")
    vals = [rec.get(k) for k in keys]
    if any(v is None or (isinstance(v, float) and math.isnan(v)) for v in vals):
        return None
    return np.asarray(vals, float).reshape(2, 3)


def _well_placed(b: dict) -> bool:
    """Whether a bar's axis is a cylinder fitted to points on both its sides: a measured bar not
    seen from one edge over most of its sections (``one_sided_share`` below the diameter stage's
    ``hidden_fraction``, decision 024). A bar placed from the colour mask (no depth), or whose
    axis was fitted to the one side it shows beside nearer bars, lies where it is by an error of
    its own (millimetres, not the tenths of a fitted axis): it may pair with the same bar of
    another capture, but it says nothing about which placing is the right one."""
    if b.get("status", MEASURED) != MEASURED:
        return False
    one = b.get("one_sided_share")
    if one is None or (isinstance(one, float) and math.isnan(one)):
        return True
    return float(one) < _ONE_SIDED_SHARE


def plan_sets(r: dict) -> dict:
    """The found bars of a result as plan lines, per ``(layer, level)``: ``{key: _Set}``."""
    plane = _plane(r)
    if plane is None:
        return {}
    groups: dict = {}
    for b in r.get("bars") or []:
        e = _ends(b)
        if e is None or b.get("layer") is None:
            continue
        p = to_slab_frame(e, plane)[:, :2]
        groups.setdefault((b["layer"], b["level"]), []).append((p, b.get("bar_id"), _well_placed(b)))
    out = {}
    for key, items in groups.items():
        d0 = items[0][0][1] - items[0][0][0]
        dirs = []
        for p, _, _ in items:
            d = p[1] - p[0]
            dirs.append(d if d @ d0 >= 0 else -d)
        d = np.sum([x / max(np.linalg.norm(x), 1e-9) for x in dirs], axis=0)
        d /= max(np.linalg.norm(d), 1e-9)
        segs = np.array([p for p, _, _ in items])
        fitted = np.array([f for _, _, f in items], bool)
        out[key] = _Set(key, d, segs.mean(axis=1), [i for _, i, _ in items], segs, np.zeros((0, 2)), fitted)
    for p in r.get("positions") or []:
        key = (p.get("layer"), p.get("level"))
        e = _ends(p)
        # a position the capture could not see (not measured, or its core out of the image) may
        # hold a bar the other capture shows; a missing one is compared as such
        if key in out and e is not None and p.get("status") in (NOT_MEASURED, MISSING, NOT_IN_VIEW):
            mid = to_slab_frame(e, plane)[:, :2].mean(axis=0)
            out[key].open_mids = np.vstack([out[key].open_mids, mid])
    return out


@dataclass
class _Aim:
    """A capture of a pair aimed at a bar of the other (``aim.json``): which of the two was aimed
    (``"a"`` or ``"b"`` of :func:`_register`), the bar's set, the bar aimed at as a plan segment in
    the other (asking) capture's frame, and the bar of the aimed capture's set nearest its aim
    point (None where that is ambiguous: ``why``)."""

    aimed: str
    key: tuple
    seg: np.ndarray
    target: object
    why: str = ""
    text: str = ""  # "capture Z (aimed at bar K of capture C)"
    xy: np.ndarray | None = None  # the aim point in the aimed capture's plan frame
    spacing: dict | None = None  # the design spacings, {(layer, level): mm}


def _aim_point(r: dict, height_mm: float) -> np.ndarray | None:
    """Where the optical axis of capture ``r`` (the camera frame's z axis: the image's middle)
    meets the height ``height_mm`` above its formwork plane, in its plan frame; None where it
    does not (no plane, an axis along the plane)."""
    plane = _plane(r)
    if plane is None:
        return None
    q = to_slab_frame(np.array([[0.0, 0.0, 500.0], [0.0, 0.0, 1500.0]]), plane)
    dh = q[1, 2] - q[0, 2]
    if abs(dh) < 1e-6:
        return None
    return q[0, :2] + (height_mm - q[0, 2]) / dh * (q[1, :2] - q[0, :2])


def _aim_of(r_aimed: dict, r_asking: dict, s_aimed: dict, s_asking: dict, spacing: dict) -> tuple | None:
    """``(key, segment, target bar id or None, why, aim point or None)`` of the aim record of
    ``r_aimed`` at a bar of ``r_asking`` (key and segment None where that bar is not placed in
    plan); None where ``r_aimed`` holds no record naming ``r_asking``."""
    aim = (r_aimed.get("extras") or {}).get("aimed_at") or {}
    if not aim or str(aim.get("capture")) != str(r_asking.get("capture")):
        return None
    bid = aim.get("bar_id")
    rec = next((b for b in r_asking.get("bars") or [] if b.get("bar_id") == bid), None)
    plane = _plane(r_asking)
    e = None if rec is None else _ends(rec)
    key = None if rec is None else (rec.get("layer"), rec.get("level"))
    if e is None or plane is None or key not in s_asking or bid not in s_asking[key].bar_ids:
        why = f"bar {bid} of capture {r_asking.get('capture')} is not a bar placed in plan there"
        return None, None, None, why, None
    seg = s_asking[key].segs[s_asking[key].bar_ids.index(bid)]
    st = s_aimed.get(key)
    xy = _aim_point(r_aimed, float(to_slab_frame(e, plane)[:, 2].mean()))
    if st is None or xy is None or not len(st.mids):
        return key, seg, None, f"capture {r_aimed.get('capture')} shows no {key[0]} {key[1]} bar at its aim", None
    d, n = st.direction, _perp(st.direction)
    off = np.array([abs(_offset_at(o, float(xy @ d), d, n) - float(xy @ n)) for o in st.segs])
    dist = np.sort(off)
    sp = spacing.get(key, min(spacing.values()))
    err = AIM_ERROR_SPACINGS * sp
    if dist[0] > err:
        return (
            key,
            seg,
            None,
            (
                f"its nearest {key[0]} {key[1]} bar lies {dist[0]:.0f} mm from its aim point, more than a hand's aim "
                f"error ({err:.0f} mm, a quarter of the {sp:.0f} mm spacing)"
            ),
            None,
        )
    if len(dist) > 1 and dist[1] - dist[0] < sp - 2 * err:
        return (
            key,
            seg,
            None,
            (
                f"two of its {key[0]} {key[1]} bars lie {dist[0]:.0f} and {dist[1]:.0f} mm from its aim point: which "
                f"one it was aimed at is ambiguous (needs {sp - 2 * err:.0f} mm between them)"
            ),
            None,
        )
    return key, seg, st.bar_ids[int(np.argmin(off))], "", xy


def _along(h, aim: _Aim, sa: dict, sb: dict) -> float:
    """How far along the bar aimed at placing ``h`` puts the aim point from the middle of that
    bar's stretch seen in the asking capture (mm)."""
    m = aim.seg.mean(axis=0)
    if aim.aimed == "b":
        return float((aim.xy - (m @ h.R.T + h.t)) @ sb[aim.key].direction)
    return float((aim.xy - (m - h.t) @ h.R) @ sa[aim.key].direction)


def _puts_on(h, aim: _Aim, sa: dict, sb: dict, gate: float) -> bool:
    """Whether placing ``h`` (capture a in b's frame) puts the bar aimed at on the aimed capture's
    bar at its aim point."""
    if aim.aimed == "b":
        return _same_bar(aim.seg @ h.R.T + h.t, sb[aim.key], gate) == aim.target
    return _same_bar((aim.seg - h.t) @ h.R, sa[aim.key], gate) == aim.target


def _rot(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s], [s, c]])


def _perp(d: np.ndarray) -> np.ndarray:
    return np.array([-d[1], d[0]])


def _fit_shift(pairs: list, gate: float, fitted: list | None = None) -> list:
    """Candidate shifts across one direction. ``pairs`` holds, per set, the first capture's
    offsets (found bars, open positions; moved by the rotation) and the second's; ``fitted``,
    per set, which bars of each are fitted axes (:func:`_well_placed`; None: all). Returns
    ``[(rms, n, tau)]``, one per distinct shift that contradicts neither capture, best first.
    The shift is refined, and its RMS taken, on the pairs of two fitted axes where there are
    any (a bar placed otherwise would pull it by its own error); ``n`` counts every pair.

    A shift contradicts a capture where it puts a found bar of the other inside the span of the
    capture's own row (its found bars and open positions, widened by the gate) with neither a
    found bar nor an open position of its own within the gate."""
    if fitted is None:
        fitted = [(np.ones(len(u), bool), np.ones(len(o), bool)) for u, _, o, _ in pairs]
    cands = np.unique(np.round(np.concatenate([(o[None, :] - u[:, None]).ravel() for u, _, o, _ in pairs]), 1))
    seen = []
    for tau in cands:
        if any(abs(tau - t2) < gate for _, _, t2 in seen):
            continue
        for _ in range(2):  # refine: the mean residual of the matched bars, twice
            res, res_f = [], []
            for (u, _, o, _), (fu, fo) in zip(pairs, fitted):
                if not len(u) or not len(o):
                    continue
                x = u + tau
                j = np.argmin(np.abs(o[None, :] - x[:, None]), axis=1)
                r = o[j] - x
                hit = np.abs(r) < gate
                res += list(r[hit])
                res_f += list(r[hit & fu & fo[j]])
            if not res:
                break
            tau = tau + float(np.mean(res_f or res))
        if not res or any(abs(tau - t2) < gate for _, _, t2 in seen):
            continue
        if _conflicts(pairs, tau, gate):
            continue
        r = np.asarray(res_f or res)
        seen.append((float(np.sqrt(np.mean(r**2))), len(res), float(tau)))
    # most matched bars first; among equal counts, the better fit
    seen.sort(key=lambda x: (-x[1], x[0]))
    return seen


def _conflicts(pairs: list, tau: float, gate: float) -> int:
    n = 0
    for u, uo, o, oo in pairs:
        for mine, mine_open, other in ((o, oo, u + tau), (u + tau, uo + tau, o)):
            allx = np.concatenate([mine, mine_open])
            if not len(allx):
                continue
            lo, hi = allx.min() - gate, allx.max() + gate
            x = other[(other > lo) & (other < hi)]
            n += int(np.count_nonzero(~np.any(np.abs(allx[None, :] - x[:, None]) < gate, axis=1)))
    return n


@dataclass
class Registration:
    """How capture ``b``'s plan frame sees capture ``a``'s: ``x_b = R x_a + t``."""

    a: str
    b: str
    R: np.ndarray
    t: np.ndarray
    n_matched: int
    rms_mm: float
    log_odds: float  # over the likeliest rival placing (no overlap included)
    aimed: str = ""  # where the placing was chosen by a capture's aim: which aim (decision 043)
    through: str = ""  # where composed of two placings on a third capture: its name (decision 044)

    def to_b(self, xy) -> np.ndarray:
        return np.asarray(xy, float) @ self.R.T + self.t


def register(ra: dict, rb: dict, gate_mm: float) -> tuple[Registration | None, str]:
    """Register two captures' results from their bars; ``(registration, "")`` or ``(None,
    why not)``. ``gate_mm``: a bar is matched to another within this (a quarter spacing). Where one
    was aimed at a bar of the other (its ``extras["aimed_at"]``), that aim is used as
    :func:`resolve_across` uses it."""
    sa, sb = plan_sets(ra), plan_sets(rb)
    aim, _ = _pair_aim([ra, rb], [sa, sb], 0, 1, _design_spacings([ra, rb]))
    return _register(sa, sb, gate_mm, str(ra.get("capture")), str(rb.get("capture")), aim)


def _design_spacings(results: list) -> dict:
    """``{(layer, level): design spacing (mm)}`` from the results' spacings."""
    spacing = {}
    for r in results:
        for s in r.get("spacings") or []:
            if s.get("design_spacing_mm"):
                spacing[(s["layer"], s["level"])] = float(s["design_spacing_mm"])
    return spacing


def _pair_aim(results: list, sets: list, i: int, j: int, spacing: dict) -> tuple:
    """``(_Aim or None, note or "")``: the aim of capture ``j`` at a bar of capture ``i`` (or of
    ``i`` at one of ``j``), as :func:`_register` of ``(i, j)`` takes it; the note says why a record
    naming the other capture is not used."""
    names = [str(r.get("capture")) for r in results]
    for side, (x, y) in (("b", (j, i)), ("a", (i, j))):
        got = _aim_of(results[x], results[y], sets[x], sets[y], spacing) if spacing else None
        if got is None:
            continue
        if got[0] is None:
            return None, f"Capture {names[x]}'s aim is not used: {got[3]}."
        bid = ((results[x].get("extras") or {}).get("aimed_at") or {}).get("bar_id")
        text = f"capture {names[x]} was aimed at bar {bid} of capture {names[y]}"
        return _Aim(side, *got[:4], text, got[4], spacing), ""
    return None, ""


def _register(
    sa: dict, sb: dict, gate_mm: float, name_a: str, name_b: str, aim: _Aim | None = None
) -> tuple[Registration | None, str]:
    """:func:`register` on the captures' plan sets (:func:`plan_sets`). ``aim``: one capture was
    aimed at a bar of the other; where the placings that fit are too alike to tell, only those that
    put that bar on the aimed capture's bar at its aim point compete (never a placing that does not
    fit; a placing found without the aim is kept as it is)."""
    keys = [k for k in sa if k in sb]
    if len(keys) < 2:
        return None, "fewer than two sets of bars seen in both"
    # the rotation: every set's direction turns by the same angle (mod a half turn)
    ang = np.array(
        [
            math.atan2(sb[k].direction[1], sb[k].direction[0]) - math.atan2(sa[k].direction[1], sa[k].direction[0])
            for k in keys
        ]
    )
    z = np.exp(2j * ang).mean()
    theta0 = 0.5 * math.atan2(z.imag, z.real)
    spread = np.degrees(np.abs(np.angle(np.exp(2j * (ang - theta0))) / 2)).max()
    if spread > MAX_ANGLE_SPREAD_DEG:
        return None, f"the bars' directions turn by different angles ({spread:.1f}° apart)"
    groups = _two_directions(sb, keys)
    if groups is None:
        return None, "the bars seen in both captures do not run in two directions"
    # the part of the mesh each capture saw, per lattice (a lower bar shows at another place in
    # the image than an upper bar right above it)
    hull_a, hull_b = _layer_hulls(sa), _layer_hulls(sb)
    sw = [_irregularity([sa[k] for k in ks] + [sb[k] for k in ks]) for _, ks in groups]
    hyps = []  # _Placing
    for theta in (theta0, theta0 + math.pi):
        R = _rot(theta)
        shortlists, normals = [], []
        for d, ks in groups:
            n = _perp(d)
            pairs = [
                ((sa[k].mids @ R.T) @ n, (sa[k].open_mids @ R.T) @ n, sb[k].mids @ n, sb[k].open_mids @ n) for k in ks
            ]
            cands = _fit_shift(pairs, gate_mm, [(sa[k].fitted, sb[k].fitted) for k in ks])
            # the best fits of three or more bars, and the shifts that pair the most bars
            keep = sorted((c for c in cands if c[1] >= MIN_MATCHED), key=lambda c: c[0])[:SHORTLIST] + cands[:3]
            shortlists.append(list(dict.fromkeys(tau for _, _, tau in keep)))
            normals.append(n)
        N = np.array(normals)
        if abs(np.linalg.det(N)) < 0.2:
            return None, "the two directions are too close to parallel"
        shifts = [(t1, t2) for t1 in shortlists[0] for t2 in shortlists[1]]
        ts = [np.linalg.solve(N, np.array(sh)) for sh in shifts]
        fits = _joint_fits(sa, sb, groups, R, np.array(ts).reshape(-1, 2), hull_a, hull_b, gate_mm) if ts else []
        for sh, t, fit in zip(shifts, ts, fits):
            if fit is not None:
                hyps.append(_Placing(fit[0], fit[1], theta, R, t, sh, fit[2]))
    # enough bars paired in each direction (of fitted axes or not), the pairs of fitted axes within the RMS
    strong = [
        h for h in hyps if min(n + m for n, (_, m) in zip(h.n, h.other)) >= MIN_MATCHED and max(h.rms) <= MAX_RMS_MM
    ]
    if not strong:
        return None, _NO_FIT
    h1, lr = _best(strong, hyps, sw, gate_mm)
    aimed = ""
    if lr < LOG_ODDS:
        why = _TOO_REGULAR
        if aim is None:
            return None, why
        if aim.target is None:
            return None, f"{why}; {aim.text}, but {aim.why}"
        pool = [h for h in hyps if _puts_on(h, aim, sa, sb, gate_mm)]
        fits = [h for h in strong if any(h is x for x in pool)]
        if not fits:
            return None, f"{why}; {aim.text}, but {_AIM_DENIED} {aim.target} at its aim"
        # across the bar aimed at, the aim pairs it: the captures overlap there, and only another
        # placing that also puts it at the aim (turned) competes; across the other direction the
        # bars must tell the placing as without an aim
        g_aim = next(g for g, (_, ks) in enumerate(groups) if aim.key in ks)
        h1, lr = _best(fits, pool, sw, gate_mm, aimed_dir=g_aim)
        aimed = f"chosen by the aim of {aim.text} (bar {aim.target} there)"
        if lr < LOG_ODDS:
            # along the bar too: the placings that fit differ by crossing spacings there
            h1, why_along = _along_choice(fits, pool, aim, groups[1 - g_aim][1], sa, sb, gate_mm, 1 - g_aim)
            if h1 is not None:
                # the aim chooses among placings the bars cannot tell apart, never against them
                rivals = [h for h in pool if h is not h1]
                if _evidence_against(h1, rivals, sw, 1 - g_aim, against_none=False) < -LOG_ODDS:
                    h1, why_along = None, _BARS_AGAINST_AIM
            if h1 is None:
                still = "placings that put that bar at its aim still fit alike"
                return None, f"{why}; {aim.text}, and {still} ({why_along})"
            aimed += f", across and along it ({why_along})"
            lr = min(_evidence_against(h1, [], sw, g) for g in range(2))  # the bars' own, over no overlap
    n_pairs = int(sum(h1.n) + sum(m for _, m in h1.other))
    reg = Registration(name_a, name_b, h1.R, h1.t, n_pairs, float(max(h1.rms)), float(lr), aimed)
    return reg, ""


def _along_choice(fits: list, pool: list, aim: _Aim, cross_keys: list, sa: dict, sb: dict, gate: float, g: int):
    """``(placing, what)`` of the placings that fit and put the bar aimed at on the bar at the aim
    (``fits``; ``pool``: every such placing), the one that puts the aim point nearest the middle
    of that bar's stretch seen in the asking capture, along it: where it does so within a hand's
    error along (``AIM_ALONG_SPACINGS`` of the crossing bars' design spacing) and every other
    placing of the pool, at another shift across the crossing bars, lies a crossing spacing less
    twice that farther; else ``(None, why)``."""
    if aim.xy is None or not aim.spacing:
        return None, "no aim point"
    sc = min((aim.spacing[k] for k in cross_keys if k in aim.spacing), default=min(aim.spacing.values()))
    err = AIM_ALONG_SPACINGS * sc
    best = min(fits, key=lambda h: abs(_along(h, aim, sa, sb)))
    d1 = abs(_along(best, aim, sa, sb))
    others = [
        abs(_along(h, aim, sa, sb))
        for h in pool
        if h is not best
        and h.n[g] + h.other[g][1] >= 2
        and (h.theta != best.theta or abs(h.shifts[g] - best.shifts[g]) > gate)
    ]
    d2 = min(others, default=math.inf)
    if d1 > err:
        return None, f"the nearest puts the aim {d1:.0f} mm along the bar from its seen middle, more than {err:.0f} mm"
    if d2 - d1 < sc - 2 * err:
        return None, (
            f"the nearest that fits puts the aim {d1:.0f} mm along the bar from its seen middle, another placing "
            f"{d2:.0f} mm (the other must lie {sc - 2 * err:.0f} mm farther)"
        )
    nxt = f"the next placing {d2:.0f} mm" if math.isfinite(d2) else "no other placing"
    return best, f"the aim {d1:.0f} mm along the bar from its seen middle, {nxt}"


def _best(strong: list, hyps: list, sw: list, gate_mm: float, aimed_dir: int | None = None) -> tuple:
    """The placing of ``strong`` with the most evidence over a chance alignment in both directions
    (not the smallest RMS: one or two pairs of fitted axes fit as tightly as the shift was refined
    on them), and its least log-odds over every placing of ``hyps`` that pairs a direction's bars
    otherwise (another shift, or turned) and over no overlap at all. Across direction
    ``aimed_dir`` (the bars of one a capture was aimed at) no overlap is no rival: the aim pairs
    that bar."""
    h1 = max(strong, key=lambda h: sum(_evidence_against(h, [], sw, g) for g in range(2)))
    lr = math.inf
    for g in range(2):
        rivals = [
            h
            for h in hyps
            if h is not h1
            and h.n[g] + h.other[g][1] >= 2
            and (h.theta != h1.theta or abs(h.shifts[g] - h1.shifts[g]) > gate_mm)
        ]
        lr = min(lr, _evidence_against(h1, rivals, sw, g, g != aimed_dir))
    return h1, lr


def _two_directions(sb: dict, keys: list) -> list | None:
    """The sets grouped by direction (in the second capture's frame): ``[(direction, keys)]``,
    exactly two groups, or None."""
    groups: list = []
    for k in keys:
        d = sb[k].direction
        for g in groups:
            if abs(g[0] @ d) > math.cos(math.radians(10)):
                g[1].append(k)
                break
        else:
            groups.append((d, [k]))
    return groups if len(groups) == 2 else None


def _layer_hulls(sets: dict) -> dict:
    """``{layer: hull}`` of a capture's plan sets: the part of the mesh it saw, per lattice (a
    lower bar shows at another place in the image than an upper bar right above it)."""
    return {la: _hull({k: v for k, v in sets.items() if k[0] == la}) for la in {k[0] for k in sets}}


def _hull(sets: dict) -> np.ndarray:
    """The convex hull (counter-clockwise) of every bar end of a capture in plan: the part of the
    mesh it saw."""
    import cv2

    pts = np.vstack([s.segs.reshape(-1, 2) for s in sets.values()]).astype(np.float32)
    if len(pts) < 3:
        return None
    h = cv2.convexHull(pts).reshape(-1, 2).astype(float)
    area = 0.5 * np.sum(h[:, 0] * np.roll(h[:, 1], -1) - np.roll(h[:, 0], -1) * h[:, 1])
    return h if area > 0 else h[::-1]


def _inside(pts: np.ndarray, hull: np.ndarray) -> np.ndarray:
    """Which points (N, 2) lie inside a counter-clockwise convex polygon."""
    a, b = hull, np.roll(hull, -1, axis=0)
    cross = (b[None, :, 0] - a[None, :, 0]) * (pts[:, None, 1] - a[None, :, 1]) - (b[None, :, 1] - a[None, :, 1]) * (
        pts[:, None, 0] - a[None, :, 0]
    )
    return np.all(cross >= 0, axis=1)


def _offset_at(seg: np.ndarray, s: float, d: np.ndarray, n: np.ndarray) -> float:
    """The across offset (along ``n``) of the line through ``seg`` where it is at ``s`` along ``d``."""
    p0, p1 = seg
    ds = float((p1 - p0) @ d)
    if abs(ds) < 1e-6:
        return float(p0 @ n)
    return float((p0 + (s - p0 @ d) / ds * (p1 - p0)) @ n)


def _dots(x: np.ndarray, v: np.ndarray) -> np.ndarray:
    """Each 2-vector of ``x`` (..., 2) dotted with ``v``, every one computed as NumPy computes one
    such product alone (a stack of (1, 2) @ (2,) products): the same bits as ``x[i] @ v``, which a
    single matrix product over the rows does not give (it may fuse the multiply and add otherwise)."""
    x = np.ascontiguousarray(x, dtype=float)
    return (x.reshape(-1, 1, 2) @ v).reshape(x.shape[:-1])


def _offsets_at(segs: np.ndarray, s: np.ndarray, d: np.ndarray, n: np.ndarray) -> np.ndarray:
    """:func:`_offset_at` of segment ``segs[..., k, :, :]`` at ``s[..., m, k]`` along ``d``, for
    whole arrays at once, to the bit: ``segs`` (..., K, 2, 2), ``s`` (..., M, K), leading axes
    broadcast."""
    p0, p1 = segs[..., 0, :], segs[..., 1, :]
    ds, p0d, p0n = (v[..., None, :] for v in (_dots(p1 - p0, d), _dots(p0, d), _dots(p0, n)))
    flat = np.abs(ds) < 1e-6
    q = p0[..., None, :, :] + ((s - p0d) / np.where(flat, 1.0, ds))[..., None] * (p1 - p0)[..., None, :, :]
    return np.where(flat, p0n, _dots(q, n))


def _pairs(mine: np.ndarray, other: np.ndarray, d: np.ndarray, n: np.ndarray) -> tuple:
    """For each bar of ``mine`` (segments, (..., M, 2, 2)), its nearest bar of ``other`` ((..., K, 2,
    2); leading axes broadcast: one set of segments per placing) across ``d``: ``(r, j)``, each
    (..., M), the offset of bar ``j`` of ``other`` from it (mm, signed) and ``j``; ``(nan, -1)``
    where no bar of ``other`` may pair with it. Two bars are compared at ``s`` along ``d``, the
    middle of what their stretches share (or of the gap between them, at most ``MAX_GAP_MM``), with
    :func:`_offset_at`'s arithmetic; of equal offsets the first bar is taken."""
    lead = np.broadcast_shapes(mine.shape[:-3], other.shape[:-3])
    m = mine.shape[-3]
    if not m or not other.shape[-3]:
        return np.full((*lead, m), np.nan), np.full((*lead, m), -1)
    sm, so = np.sort(mine @ d, axis=-1), np.sort(other @ d, axis=-1)
    a0 = np.maximum(sm[..., :, None, 0], so[..., None, :, 0])
    a1 = np.minimum(sm[..., :, None, 1], so[..., None, :, 1])
    near = a1 - a0 >= -MAX_GAP_MM
    s = 0.5 * (a0 + a1)
    r = _offsets_at(other, s, d, n) - np.swapaxes(_offsets_at(mine, np.swapaxes(s, -1, -2), d, n), -1, -2)
    j = np.argmin(np.where(near, np.abs(r), np.inf), axis=-1)[..., None]
    ok = np.take_along_axis(near, j, -1)[..., 0]
    return np.where(ok, np.take_along_axis(r, j, -1)[..., 0], np.nan), np.where(ok, j[..., 0], -1)


def _joint_fit(sa, sb, groups, R, t, hull_a, hull_b, gate):
    """Residuals of one placing of capture a in capture b's frame: per direction, the RMS and the
    count of the pairs of two fitted axes, and ``(RMS, count)`` of the other pairs (a bar placed
    otherwise than by a fit to both its sides, :func:`_well_placed`), the bars compared at the
    middle of what their seen stretches share, or of the gap between them where it is at most
    ``MAX_GAP_MM`` (a bar is not straight: two captures see different stretches of it, and a line
    is extrapolated no farther than half that gap). None where the placing puts a bar of either
    capture in the other's view with no bar (or open position) of its own there."""
    return _joint_fits(sa, sb, groups, R, np.asarray(t, float)[None], hull_a, hull_b, gate)[0]


def _joint_fits(sa, sb, groups, R, ts, hull_a, hull_b, gate) -> list:
    """:func:`_joint_fit` of the placings ``x_b = R x_a + t`` for each row ``t`` of ``ts`` (P, 2),
    all at once: a list of P fits (or None), each the same to the bit as one placing alone."""
    P = len(ts)
    alive = np.ones(P, bool)
    fits = [([], [], []) for _ in range(P)]
    for d, ks in groups:
        n = _perp(d)
        res = [[] for _ in range(P)]
        res_u = [[] for _ in range(P)]
        for k in ks:
            A = (sa[k].segs @ R.T)[None] + ts[:, None, None, :]
            B = sb[k].segs
            open_b = sb[k].open_mids @ n
            open_a = ((sa[k].open_mids @ R.T)[None] + ts[:, None, :]) @ n
            h_b, h_a = hull_b.get(k[0]), hull_a.get(k[0])
            h_a = None if h_a is None else (h_a @ R.T)[None] + ts[:, None, :]
            fa, fb = sa[k].fitted, sb[k].fitted
            for a_side in (True, False):
                mine, other = (A, B[None]) if a_side else (B[None], A)
                best, j_best = _pairs(mine, other, d, n)
                paired = np.abs(best) < gate
                if a_side:
                    # a pair of two fitted axes (_well_placed), or one with a bar placed otherwise
                    both = paired & fa[None, :] & (fb[np.maximum(j_best, 0)] if len(fb) else False)
                    for p in range(P):
                        res[p].extend(best[p][both[p]])
                        res_u[p].extend(best[p][paired[p] & ~both[p]])
                hull = h_b if a_side else h_a
                if hull is None:
                    continue
                for p in np.flatnonzero(alive & ~paired.all(axis=1)):
                    segs = (mine[p] if a_side else B)[~paired[p]]
                    if _unpaired_in_view(segs, hull if a_side else hull[p], open_b if a_side else open_a[p], n, gate):
                        alive[p] = False
        for p in range(P):
            rms, cnt, unfitted = fits[p]
            rms.append(float(np.sqrt(np.mean(np.square(res[p])))) if res[p] else math.inf)
            cnt.append(len(res[p]))
            unfitted.append((float(np.sqrt(np.mean(np.square(res_u[p])))) if res_u[p] else math.inf, len(res_u[p])))
    return [fit if ok else None for fit, ok in zip(fits, alive)]


def _unpaired_in_view(segs: np.ndarray, hull: np.ndarray, opens: np.ndarray, n: np.ndarray, gate: float) -> bool:
    """Whether any of these bars (segments, unpaired) lies in the other capture's view (``hull``)
    over ``MIN_CONFLICT_MM`` or more (41 points along it), with no open position of that capture
    within ``gate`` across: a bar the other capture would have shown."""
    samples = segs[:, :1] + np.linspace(0, 1, 41)[None, :, None] * (segs[:, 1:] - segs[:, :1])
    share = _inside(samples.reshape(-1, 2), hull).reshape(len(segs), 41).mean(axis=1)
    for i in np.flatnonzero(share > 0):  # a bar wholly outside the view: nothing seen (MIN_CONFLICT_MM > 0)
        seg = segs[i]
        seen = share[i] * np.linalg.norm(seg[1] - seg[0])
        if seen >= MIN_CONFLICT_MM and not np.any(np.abs(opens - float(seg.mean(axis=0) @ n)) < gate):
            return True
    return False


def _irregularity(sets: list) -> float:
    """How far the bars' spacings deviate from their set's median (mm, an RMS), over the sets
    given: how far a pairing of each bar with its neighbour misfits. A gap of two spacings (a bar
    not found) and a spacing off by more than a tenth of the spacing (a misplaced bar, a defect of
    its own) are left out. 0 where fewer than three spacings are left."""
    dev = []
    for st in sets:
        o = np.sort(st.mids @ _perp(st.direction))
        d = np.diff(o)
        if len(d) < 2:
            continue
        m = float(np.median(d))
        d = d[(d > 0.5 * m) & (d < 1.5 * m)]
        if not len(d):
            continue
        dv = d - np.median(d)
        dev += list(dv[np.abs(dv) < 0.1 * m])
    return float(np.sqrt(np.mean(np.square(dev)))) if len(dev) >= 3 else 0.0


def _evidence_against(h1: _Placing, rivals: list, sw: list, g: int, against_none: bool = True) -> float:
    """The smallest log-odds, from direction ``g``'s bar pairs, of placing ``h1`` over any rival
    placing and (``against_none``) over no overlap at all; ``inf`` where neither is asked.

    A placing pairs bars of the two captures. Pairs of the same bar differ by the measurement's
    scatter ``sm`` (``h1``'s RMS, at least ``SIGMA_FLOOR_MM``); pairs of different bars by the
    bars' irregular placing ``sw`` (:func:`_irregularity`, measured on the captures' own
    spacings). Each pair a placing explains as one bar gains it ``log(sw/sm) - r²/2sm² +
    r²/2sw²`` (r the RMS) over a chance alignment; a mesh placed as regularly as it is measured
    (``sw ≈ sm``) gives no evidence either way. The captures not overlapping at all (no pair) is a
    rival too: ``h1``'s own gain must clear the odds, so that a few bars aligned by chance, with
    the true overlap too small to pair any, do not place the captures.

    Pairs of two fitted axes (``rms``, ``n``) and pairs with a bar placed otherwise (``other``:
    from the colour mask, or fitted to the one side it shows, :func:`_well_placed`) scatter
    differently: each kind gains with its own ``sm`` (``h1``'s RMS of that kind), so that one bar
    off by its own millimetres neither widens the scatter the fitted pairs are judged by nor adds
    evidence it does not carry."""

    def kind_gain(r, n, sm) -> float:
        w = max(sw[g], sm)
        return n * (math.log(w / sm) - r**2 / (2 * sm**2) + r**2 / (2 * w**2)) if n else 0.0

    sm = max(h1.rms[g], SIGMA_FLOOR_MM)
    sm_u = max(h1.other[g][0], SIGMA_FLOOR_MM) if h1.other[g][1] else math.inf

    def gain(h: _Placing) -> float:
        out = kind_gain(h.rms[g], h.n[g], sm)
        if h.other[g][1] and math.isfinite(sm_u):
            out += kind_gain(*h.other[g], sm_u)
        return out

    g1 = gain(h1)
    return min(([g1] if against_none else []) + [g1 - gain(h) for h in rivals], default=math.inf)


def _position_line(p: dict, plane: Plane) -> np.ndarray | None:
    e = _ends(p)
    if e is None:
        return None
    return to_slab_frame(e, plane)[:, :2]


def resolve_across(
    results: list, gate_fraction: float = 0.25, min_overlap_mm: float = CountParams.min_evidence_mm
) -> tuple[list, list]:
    """Copies of a slab's result dicts in which every position "not measured" in one capture
    that a registered other capture shows — a bar found there, or its place evidenced empty — is
    judged by that capture; and the notes saying what was done. Results are never changed in
    place; a position is judged only where both captures' views of it overlap along the bar by
    ``min_overlap_mm`` (the length a position's verdict needs in one capture)."""
    if len(results) < 2:
        return list(results), []
    out = [copy.deepcopy(r) for r in results]
    notes = []
    spacing = _design_spacings(results)
    if not spacing:
        return out, notes  # no spacing measured: nothing a lot could count twice
    gate = gate_fraction * min(spacing.values())
    sets = [plan_sets(r) for r in results]
    regs, refused = {}, {}
    names = [str(r.get("capture")) for r in results]
    for i, r in enumerate(results):
        named = str(((r.get("extras") or {}).get("aimed_at") or {}).get("capture") or "")
        if named and named not in names:
            notes.append(f"Capture {names[i]} was aimed at a bar of capture {named}, not among this slab's captures.")
    for i, ra in enumerate(results):
        for j, rb in enumerate(results):
            if j <= i:
                continue
            aim, why = _pair_aim(results, sets, i, j, spacing)
            if why:
                notes.append(why)
            # (with no aim, called as before: a caller may stand in its own _register)
            args = (sets[i], sets[j], gate, names[i], names[j])
            reg, why = _register(*args) if aim is None else _register(*args, aim=aim)
            if reg is None:
                refused[(i, j)] = why
                if aim is not None:
                    notes.append(f"Captures {names[i]} and {names[j]} are not placed on each other: {why}.")
                continue
            regs[(i, j)] = reg
            odds = f"10^{min(reg.log_odds, 99.0) / math.log(10):.0f} : 1"
            how = f"{reg.aimed}, the bars' own odds {odds}" if reg.aimed else f"odds over any other placing {odds}"
            notes.append(
                f"Captures {reg.a} and {reg.b} overlap: placed on each other from their bars ({reg.n_matched} "
                f"matched, {reg.rms_mm:.1f} mm RMS; {how})."
            )
    _through_a_third(regs, refused, sets, names, gate, notes)
    _sizes_across(out, results, sets, regs, gate)
    _spacings_across(out, results, sets, regs, gate, notes)
    # the captures not placed on each other: whether they show the same bars is unknown, and a
    # lot rule over their spacings must not depend on it (docs/decisions/039-a-lot-over-captures-not-placed.md)
    for i, r in enumerate(out):
        apart = [
            str(rb.get("capture")) for j, rb in enumerate(results) if j != i and (min(i, j), max(i, j)) not in regs
        ]
        if apart:
            r.setdefault("extras", {})["not_placed_on"] = apart
    for i, r in enumerate(out):
        plane = _plane(r)
        if plane is None:
            continue
        changed = False
        for p in r.get("positions") or []:
            if p.get("status") != NOT_MEASURED:
                continue
            line = _position_line(p, plane)
            if line is None:
                continue
            for j, rb in enumerate(results):
                if j == i:
                    continue
                reg = regs.get((i, j))
                if reg is not None:
                    xy = reg.to_b(line)
                else:
                    rev = regs.get((j, i))
                    if rev is None:
                        continue
                    xy = (line - rev.t) @ rev.R  # inverse: x_a = R^T (x_b - t)
                verdict = _judge_in(p, xy, sets[j].get((p.get("layer"), p.get("level"))), rb, gate, min_overlap_mm)
                if verdict is None:
                    continue
                status, bar_id, off = verdict
                here = p.get("reason", "")
                p["status"] = status
                p["reason"] = (
                    f"judged in capture {rb.get('capture')}: bar {bar_id} found there, {off:.1f} mm from this place"
                    if status == PRESENT
                    else f"judged in capture {rb.get('capture')}: its place seen empty there"
                ) + f" (in this capture: {here})"
                p["judged_in"] = str(rb.get("capture"))
                changed = True
                _recount(r, p, status)
                notes.append(
                    f"Capture {r.get('capture')}: the {p['layer']} {p['level']} bar position at "
                    f"{float(p.get('offset_mm') or 0):.0f} mm, not judged there, is {status} in capture "
                    f"{rb.get('capture')}."
                )
                break
        if changed:
            r.setdefault("extras", {})["judged_across"] = True
    return out, notes


def _chainable(why: str) -> bool:
    """Whether a pair refused for ``why`` (:func:`_register`) may be placed through a third
    capture: where its bars could not choose a placing (too few matched, or too regular to tell),
    not where they chose against something (their directions turn apart, an aim no placing that
    fits meets, the bars against the aim) or cannot check a placing in two directions."""
    if why == _NO_FIT:
        return True
    return why.startswith(_TOO_REGULAR) and _AIM_DENIED not in why and _BARS_AGAINST_AIM not in why


def _leg(regs: dict, a: int, b: int):
    """``(R, t)`` with ``x_b = R x_a + t`` from the placing of the pair (a, b), in either
    orientation, or None."""
    reg = regs.get((a, b))
    if reg is not None:
        return reg.R, reg.t
    reg = regs.get((b, a))
    if reg is None:
        return None
    return reg.R.T, -reg.t @ reg.R  # x_a = R^T (x_b - t)


def _fits_pair(sa: dict, sb: dict, R: np.ndarray, t: np.ndarray, gate: float) -> tuple | None:
    """``(fit, why)``: whether a placing found otherwise is consistent with the two captures' own
    bars: every set seen in both turns onto its twin within ``MAX_ANGLE_SPREAD_DEG``, no bar of
    either lies in the other's view without a counterpart (:func:`_joint_fit`), and the pairs of
    fitted axes it matches lie within ``MAX_RMS_MM`` RMS per direction (the test of a placing
    from the bars; others are within the gate by construction). ``fit`` is None where it fails;
    where the pair's sets do not run in two directions it cannot be checked: None too."""
    keys = [k for k in sa if k in sb]
    groups = _two_directions(sb, keys) if len(keys) >= 2 else None
    if groups is None:
        return None, "their bars seen in both do not run in two directions to check it against"
    for k in keys:
        da = sa[k].direction @ R.T
        cos = abs(float(da @ sb[k].direction)) / (np.linalg.norm(da) * np.linalg.norm(sb[k].direction))
        if math.degrees(math.acos(min(1.0, cos))) > MAX_ANGLE_SPREAD_DEG:
            return None, f"it turns their {k[0]} {k[1]} bars apart"
    hull_a, hull_b = _layer_hulls(sa), _layer_hulls(sb)
    fit = _joint_fit(sa, sb, groups, R, t, hull_a, hull_b, gate)
    if fit is None:
        return None, "it puts a bar of one in the other's view where that shows no bar"
    worst = max([r for r, c in zip(fit[0], fit[1]) if c] or [0.0])
    if worst > MAX_RMS_MM:
        return None, f"their own bars misfit under it by {worst:.1f} mm RMS, over {MAX_RMS_MM} mm"
    return fit, ""


def _through_a_third(regs: dict, refused: dict, sets: list, names: list, gate: float, notes: list) -> None:
    """Place each pair the bars alone could not (:func:`_chainable` refusals) through a capture
    placed on both, one step (the placings found from bars only compose): the placing of i on k
    and of k on j, composed, is taken where it is consistent with i and j's own bars
    (:func:`_fits_pair`) and every such capture gives the same (within the gate at i's bar ends).
    Adds the placings to ``regs`` (decision 044)."""
    found = {}
    for (i, j), why in sorted(refused.items()):
        if not _chainable(why):
            continue
        comps, bad = [], []
        for k in range(len(sets)):
            if k in (i, j):
                continue
            ik, kj = _leg(regs, i, k), _leg(regs, k, j)
            if ik is None or kj is None:
                continue
            R, t = kj[0] @ ik[0], ik[1] @ kj[0].T + kj[1]
            fit, why_not = _fits_pair(sets[i], sets[j], R, t, gate)
            (comps if fit is not None else bad).append((k, R, t, fit, why_not))
        if not comps and not bad:
            continue
        pair = f"Captures {names[i]} and {names[j]}"
        if bad:
            k, *_, why_not = bad[0]
            notes.append(f"{pair} are not placed through capture {names[k]}: {why_not}.")
            continue
        ends = np.vstack([st.segs.reshape(-1, 2) for st in sets[i].values()])
        k0, R0, t0, fit, _ = comps[0]
        apart = max(float(np.abs((ends @ R.T + t) - (ends @ R0.T + t0)).max()) for _, R, t, _, _ in comps)
        if apart > gate:
            notes.append(
                f"{pair} are not placed through a third capture: capture {names[comps[1][0]]} places them "
                f"{apart:.0f} mm otherwise than capture {names[k0]}."
            )
            continue
        n = int(sum(fit[1]) + sum(m for _, m in fit[2]))
        rms = max([r for r, c in zip(fit[0], fit[1]) if c] or [0.0])
        odds = min(regs[(min(i, k0), max(i, k0))].log_odds, regs[(min(j, k0), max(j, k0))].log_odds)
        found[(i, j)] = Registration(names[i], names[j], R0, t0, n, float(rms), float(odds), through=names[k0])
        own = (
            f"{n} of their own bars matched under it, {rms:.1f} mm RMS"
            if n
            else "their views do not overlap under it: they show different bars"
        )
        notes.append(
            f"{pair} are placed on each other through capture {names[k0]}, placed on both ({own}; alone: {why})."
        )
    regs.update(found)


def unplaced_pairs(results: list) -> set:
    """The pairs of captures (``frozenset`` of two names) of a slab's judged results
    (:func:`resolve_across`'s) that were not placed on each other: whether they show the same
    bars is not known."""
    out = set()
    for r in results:
        for other in (r.get("extras") or {}).get("not_placed_on") or []:
            out.add(frozenset((str(r.get("capture")), str(other))))
    return out


def spans_missing(r: dict) -> dict:
    """The spacings of a result that span a bar position evidenced missing in the same capture:
    ``{(layer, level, bar_a, bar_b): offset of the missing position (mm)}``. Such a gap is the
    missing bar's doing, and is judged under the bar count."""
    plane = _plane(r)
    if plane is None:
        return {}
    sets = plan_sets(r)
    out = {}
    for p in r.get("positions") or []:
        key = (p.get("layer"), p.get("level"))
        e = _ends(p)
        if p.get("status") != MISSING or key not in sets or e is None:
            continue
        st = sets[key]
        n = _perp(st.direction)
        at = float(to_slab_frame(e, plane)[:, :2].mean(axis=0) @ n)
        offs = dict(zip(st.bar_ids, st.mids @ n))
        for sp in r.get("spacings") or []:
            if (sp.get("layer"), sp.get("level")) != key:
                continue
            a, b = offs.get(sp.get("bar_a")), offs.get(sp.get("bar_b"))
            if a is not None and b is not None and min(a, b) < at < max(a, b):
                out[(*key, sp.get("bar_a"), sp.get("bar_b"))] = float(p.get("offset_mm") or at)
    return out


def _sizes_across(out: list, results: list, sets: list, regs: dict, gate: float) -> None:
    """Mark every bar a capture could not size (not hidden: that is excluded anyway) that a
    registered capture shows and sized, with ``sized_in`` = "capture (bar id, size)": the
    acceptance then checks its size there, once."""
    for (i, j), reg in regs.items():
        for ia, ib, inv in ((i, j, False), (j, i, True)):
            sa, sb = sets[ia], sets[ib]
            bars_a = {b.get("bar_id"): b for b in out[ia].get("bars") or []}
            bars_b = {b.get("bar_id"): b for b in results[ib].get("bars") or []}
            for key, st in sa.items():
                if key not in sb:
                    continue
                for k, bid in enumerate(st.bar_ids):
                    rec = bars_a.get(bid)
                    if rec is None or rec.get("diameter_status") in (None, MEASURED, HIDDEN) or rec.get("hidden"):
                        continue
                    seg = st.segs[k] @ reg.R.T + reg.t if not inv else (st.segs[k] - reg.t) @ reg.R
                    other = _same_bar(seg, sb[key], gate)
                    if other is None:
                        continue
                    ob = bars_b.get(other)
                    if ob is None or ob.get("diameter_status") != MEASURED or ob.get("nominal_mm") is None:
                        continue
                    if rec.get("sized_in"):
                        continue
                    # (the checkpoint's reason names it; the sheet's notes count them)
                    rec["sized_in"] = f"{results[ib].get('capture')} (bar {other}, Φ{float(ob['nominal_mm']):g})"


def _spacings_across(out: list, results: list, sets: list, regs: dict, gate: float, notes: list) -> None:
    """Mark every spacing a later capture measured between the same two bars as an earlier
    registered capture did with ``also_in`` = "capture (bars a-b)": a lot rule counts each
    spacing of the slab once (in the earliest capture that measured it)."""
    n = 0
    for (i, j), reg in sorted(regs.items()):
        sa, sb = sets[i], sets[j]
        measured_a = {
            (s["layer"], s["level"], frozenset((s.get("bar_a"), s.get("bar_b")))): s
            for s in results[i].get("spacings") or []
            if s.get("status") == MEASURED
        }
        for key, st in sb.items():
            if key not in sa:
                continue
            # each of b's bars of the set, as the bar of a it is
            to_a = {}
            for k, bid in enumerate(st.bar_ids):
                seg = (st.segs[k] - reg.t) @ reg.R
                same = _same_bar(seg, sa[key], gate)
                if same is not None:
                    to_a[bid] = same
            for sp in out[j].get("spacings") or []:
                if (sp.get("layer"), sp.get("level")) != key or sp.get("status") != MEASURED or sp.get("also_in"):
                    continue
                pair = (to_a.get(sp.get("bar_a")), to_a.get(sp.get("bar_b")))
                if None in pair:
                    continue
                twin = measured_a.get((*key, frozenset(pair)))
                if twin is not None:
                    sp["also_in"] = f"{results[i].get('capture')} (bars {twin.get('bar_a')}-{twin.get('bar_b')})"
                    n += 1
    if n:
        notes.append(f"{n} spacing(s) measured in two captures are counted once, in the first that measured them.")


def _same_bar(seg: np.ndarray, sb: _Set, gate: float):
    """The bar id of ``sb`` that is the bar along ``seg`` (within ``gate`` across, compared where
    their seen stretches overlap or in the middle of a gap of at most ``MAX_GAP_MM`` between
    them), or None."""
    d = sb.direction
    n = _perp(d)
    lo, hi = sorted(seg @ d)
    best, best_r = None, gate
    for k, o in enumerate(sb.segs):
        olo, ohi = sorted(o @ d)
        a0, a1 = max(lo, olo), min(hi, ohi)
        if a1 - a0 < -MAX_GAP_MM:
            continue
        sm = 0.5 * (a0 + a1)
        r = abs(_offset_at(o, sm, d, n) - _offset_at(seg, sm, d, n))
        if r < best_r:
            best, best_r = sb.bar_ids[k], r
    return best


def _judge_in(p: dict, xy: np.ndarray, sb: _Set | None, rb: dict, gate: float, min_overlap: float):
    """``(status, bar id, offset)`` of the line ``xy`` (2, 2; in capture b's plan frame) in
    capture b (``sb`` its set of the position's layer and level): a found bar within ``gate``
    across and overlapping it by ``min_overlap`` along, or an evidenced missing position there;
    else None."""
    key = (p.get("layer"), p.get("level"))
    d = xy[1] - xy[0]
    if np.linalg.norm(d) < 1e-6:
        return None
    d = d / np.linalg.norm(d)
    n = _perp(d)
    off = float(xy.mean(axis=0) @ n)
    lo, hi = sorted((float(xy[0] @ d), float(xy[1] @ d)))
    if sb is not None:
        spans = [np.sort(seg @ d) for seg in sb.segs]  # each bar's seen stretch along the position
        for k, t in enumerate(spans):
            across = float(sb.mids[k] @ n) - off
            overlap = min(hi, t[1]) - max(lo, t[0])
            if abs(across) < gate and overlap >= min_overlap:
                return PRESENT, sb.bar_ids[k], abs(across)
        # the same line further along: a bar seen over a verdict's length, overlapping the
        # position by less or lying beyond it by at most a lap's shortest length, is the bar there
        # (docs/decisions/059-a-hidden-position-on-a-bar-seen-further-along.md)
        for k, t in enumerate(spans):
            a0, a1 = max(lo, float(t[0])), min(hi, float(t[1]))
            if a1 - a0 >= min_overlap or a1 - a0 < -MAX_GAP_MM or t[1] - t[0] < min_overlap:
                continue
            sm = 0.5 * (a0 + a1)
            across = _offset_at(sb.segs[k], sm, d, n) - _offset_at(xy, sm, d, n)
            if abs(across) < gate:
                return PRESENT, sb.bar_ids[k], abs(across)
    plane = _plane(rb)
    for q in rb.get("positions") or []:
        if q.get("status") != MISSING or (q.get("layer"), q.get("level")) != key:
            continue
        ql = _position_line(q, plane)
        if ql is None:
            continue
        across = float(ql.mean(axis=0) @ n) - off
        t = np.sort(ql @ d)
        if abs(across) < gate and min(hi, t[1]) - max(lo, t[0]) >= min_overlap:
            return MISSING, None, abs(across)
    return None


def _recount(r: dict, p: dict, status: str) -> None:
    for c in r.get("counts") or []:
        if (c.get("layer"), c.get("level")) != (p.get("layer"), p.get("level")):
            continue
        c["not_measured"] = max(0, int(c.get("not_measured") or 0) - 1)
        c["expected"] = int(c.get("expected") or 0) + 1
        if status == PRESENT:
            c["found"] = int(c.get("found") or 0) + 1
        else:
            c["missing"] = int(c.get("missing") or 0) + 1
        c["evidence"] = (str(c.get("evidence") or "") + f"; 1 judged in capture {p.get('judged_in')}").lstrip("; ")
