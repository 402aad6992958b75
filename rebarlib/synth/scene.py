"""The scene: a double-layer bar mesh laid out on formwork from a design, with its as-built
deviations (bars off their positions, missing, extra or of another size, bowed) and the
accessories around it (spacers, chairs, tie wire, edge boards).

The scene lives in a *world* frame: formwork top surface at z = 0, z up, mesh centred on the
origin. Bars are placed by their visible (rib) envelope: cover and layer distance are measured
to the envelope, like a tape would.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .._checks import RebarInputError
from .._design import Design
from ..diameter.barsizes import GB_RIBS as _GB_RIBS
from ..diameter.barsizes import rib_envelope_mm

__all__ = ["Deviations", "Bar", "SlabScene", "make_scene"]


@dataclass(frozen=True)
class Deviations:
    """As-built deviations of the mesh from its design (all mm / degrees).

    Attributes
    ----------
    position_sigma_mm : std dev of each bar's offset across its direction (spacing varies bar to bar)
    height_sigma_mm : std dev of each bar's height (local cover deviations)
    bow_mm : in-plan sagitta of each bar over its full length (random sign)
    mesh_yaw_deg : rotation of the whole mesh in plan
    stacked : each upper bar right above the lower bar of its direction (before the position
        jitter; where both sets have one spacing): the lower bars are then seen only as slivers
        beside the upper bars
    missing : number of bars left out (never the outermost of a set)
    wrong_size : number of bars of another standard size than designed
    ribs : deformed bars, drawn with their rib envelope (GB 1499.2 d1 + 2h)
    rib_relief : with ``ribs``, draw the ribs in relief instead of as a smooth envelope: a core of
        diameter d1, two longitudinal ribs and crescent transverse ribs of height h at GB 1499.2's
        spacing, each bar turned to a random roll and with a random shift between the ribs of its
        two sides (:func:`_relief_radius`). A silhouette then reaches the envelope d1 + 2h at most
        at the rib crests and is d1 wide between them, as on a real deformed bar; the truth's
        ``envelope_mm`` stays d1 + 2h. Off by default (renders are unchanged)
    spacers, chairs, ties : cover blocks under the lower lattice, chairs between the lattices,
        tie wire at crossings
    slab_size_mm : extent of the (square) mesh
    end_overhang_mm : None (the default, kept so that earlier renders stay identical): every bar
        runs the whole ``slab_size_mm``. A number: a finite mesh as tied on site: each bar ends
        this far beyond the outermost bar crossing it, so the mesh's edge is where the crossing
        bars end; captures aimed near the edge (``target_mm``) show formwork beyond the mesh
    edge_form : with ``end_overhang_mm``, boards standing at the slab's edges, 25 mm beyond the
        bar ends, as high as the slab (``design.thickness_mm``, or the mesh's top + 30 mm)
    missing_at_end : number of bars left out at the end of a row (the outermost of a set)
    extra : number of bars added half-way between two design positions (same size as designed)
    position_uniform_mm : each bar's offset also moves by a uniform draw in ± this (on top of
        ``position_sigma_mm``): spacings off their design value by up to twice it
    laps : number of inner bars made of two pieces joined by a lap, as bars shorter than the
        slab are on site: the pieces lie side by side and touching (axes one envelope apart,
        straddling the bar's position) over ``lap_length_mm``, centred at a random place along
        the bar; ``SlabScene.laps`` says where. No bar is missing there and neither piece is an
        extra bar
    lap_length_mm : the laps' length; None: 40 diameters, at least 300 mm (GB 50010's shortest)
    """

    position_sigma_mm: float = 2.0
    height_sigma_mm: float = 0.5
    bow_mm: float = 0.0
    mesh_yaw_deg: float = 0.0
    stacked: bool = False
    missing: int = 0
    wrong_size: int = 0
    ribs: bool = True
    rib_relief: bool = False
    spacers: bool = True
    chairs: bool = True
    ties: bool = True
    slab_size_mm: float = 2000.0
    end_overhang_mm: float | None = None
    edge_form: bool = False
    missing_at_end: int = 0
    extra: int = 0
    position_uniform_mm: float = 0.0
    laps: int = 0
    lap_length_mm: float | None = None

    def __post_init__(self):
        for name in ("missing", "wrong_size", "missing_at_end", "extra", "laps"):
            n = getattr(self, name)
            if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or n < 0:
                raise RebarInputError(f"{name}: expected a whole number of bars >= 0, got {n!r}")
        if self.lap_length_mm is not None and not self.lap_length_mm > 0:
            raise RebarInputError(f"lap_length_mm: expected a length > 0 mm or None, got {self.lap_length_mm!r}")

    @classmethod
    def none(cls) -> "Deviations":
        """A mesh exactly as designed (no jitter, no ribs, no accessories): for unit tests."""
        return cls(position_sigma_mm=0.0, height_sigma_mm=0.0, ribs=False, spacers=False, chairs=False, ties=False)


@dataclass(frozen=True)
class Bar:
    """One bar: a (bowed) polyline axis in the world frame and its envelope radius."""

    id: int
    layer: str  # "lower" | "upper"
    level: str  # "bottom" | "top" (within its lattice)
    index: int  # position across its direction, 0..n-1 in design order
    offset_mm: float  # centre-line offset across the direction (in the mesh frame)
    direction: np.ndarray  # unit in-plan axis direction (world)
    axis: np.ndarray  # (M, 3) polyline, world mm
    nominal_mm: float
    envelope_mm: float
    design_mm: float
    extra: bool = False  # a bar the design does not have (Deviations.extra)
    lap_partner: int = -1  # the id of the other piece where this bar is one of a lap's two (Deviations.laps)

    @property
    def radius_mm(self) -> float:
        """Half the envelope."""
        return self.envelope_mm / 2

    @property
    def underside_mm(self) -> float:
        """Height of the bar's underside above the formwork (its axis's mean height less the
        radius)."""
        return float(self.axis[:, 2].mean() - self.radius_mm)


@dataclass(frozen=True)
class SlabScene:
    """A mesh on formwork: bars, accessories (boxes and thin cylinders), the design it came from."""

    design: Design
    deviations: Deviations
    bars: tuple
    missing: tuple  # (layer, level, index) of design positions left empty
    boxes: tuple  # (centre (3,), half-size (3,), yaw rad, kind)
    rods: tuple  # (p0 (3,), p1 (3,), radius, kind)
    key: int = 0  # seeds what belongs to the slab, not the shot: formwork texture, which bars rust
    ghosts: tuple = ()  # a Bar where each missing bar would have been (same order as ``missing``)
    laps: tuple = ()  # (id of one piece, id of the other, world (3,) middle of the lap) per lap


def _sizes_near(size: float) -> list:
    """The GB 1499.2 sizes next to ``size`` (one smaller, one larger; 8 mm at least): what a
    wrong-size bar is drawn from."""
    std = sorted(_GB_RIBS)
    i = std.index(size) if size in std else int(np.argmin([abs(s - size) for s in std]))
    return [std[j] for j in (i - 1, i + 1) if 0 <= j < len(std) and std[j] >= 8]


def make_scene(design: Design, deviations: Deviations | None = None, *, rng=None) -> SlabScene:
    """Lay out the mesh of ``design`` with as-built ``deviations`` (random parts drawn from ``rng``).

    The bars of each of the four sets (lattice x direction) sit at their design spacing with a
    random phase; some inner positions are then left empty, given a bar of another size or an
    extra bar half-way to the next (:class:`Deviations`), and every bar is moved, raised and
    bowed by its own draws. Spacers, chairs, tie wire and edge boards follow from the bars.

    Examples
    --------
    >>> from rebarlib.data import paper_design
    >>> scene = make_scene(paper_design(), Deviations(missing=2), rng=0)
    >>> len(scene.missing), sorted({(b.layer, b.level) for b in scene.bars})[0]
    (2, ('lower', 'bottom'))
    """
    rng = np.random.default_rng(rng)
    dev = deviations or Deviations()
    half = dev.slab_size_mm / 2
    yaw = math.radians(dev.mesh_yaw_deg)
    ex = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    ey = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    sets = _design_positions(design, dev, half, rng)
    slots = _deviant_slots(sets, dev, rng)
    extent = _finite_extent(sets, dev)
    bars, missing, ghosts, laps = _place_bars(design, dev, sets, slots, extent, (ex, ey), half, rng)
    boxes, rods = _accessories(design, dev, bars, yaw)
    if dev.edge_form and extent:
        boxes.extend(_edge_forms(design, bars, extent, ex, ey, yaw))
    return SlabScene(
        design,
        dev,
        tuple(bars),
        tuple(missing),
        tuple(boxes),
        tuple(rods),
        key=int(rng.integers(2**31)),
        ghosts=tuple(ghosts),
        laps=tuple(laps),
    )


def _design_positions(design: Design, dev: Deviations, half: float, rng) -> list:
    """Design offsets across its direction (mesh frame, mm) of every bar of each set, as
    ``(layer, level, offsets)``: the design spacing with a random phase (the upper bars right
    above the lower ones with ``dev.stacked``), filling the slab less 25 mm at each edge."""
    sets, lower_phase = [], {}
    for layer in ("lower", "upper"):
        lat = design.lattice(layer)
        for level in ("bottom", "top"):
            s = lat.level(level).spacing_mm
            phase = rng.uniform(-s / 2, s / 2)
            below = lower_phase.get(level)
            if dev.stacked and layer == "upper" and below is not None and below[1] == s:
                phase = below[0]  # right above the lower bars of its direction
            if layer == "lower":
                lower_phase[level] = (phase, s)
            n = int((2 * half - 2 * 25) // s) + 1
            first = -(n - 1) * s / 2 + phase
            sets.append((layer, level, [first + k * s for k in range(n)]))
    return sets


def _deviant_slots(sets: list, dev: Deviations, rng) -> tuple[set, set, set, set]:
    """The ``(set index, position)`` slots left empty, given a bar of another size, followed
    by an extra bar, and whose bar is lapped. Missing and wrong-size bars are never the outermost
    of a set, except the ``missing_at_end`` ones; a lapped bar is an inner bar of its design size."""
    slots = [(si, k) for si, (_, _, offs) in enumerate(sets) for k in range(1, len(offs) - 1)]
    pick = rng.permutation(len(slots))
    missing_slots = {slots[i] for i in pick[: dev.missing]}
    wrong_slots = {slots[i] for i in pick[dev.missing : dev.missing + dev.wrong_size]}
    # the options below draw from ``rng`` only when set, so that earlier renders stay identical
    if dev.missing_at_end:
        ends = [(si, k) for si, (_, _, offs) in enumerate(sets) for k in (0, len(offs) - 1)]
        ends = [e for e in ends if e not in wrong_slots]
        missing_slots |= {ends[i] for i in rng.permutation(len(ends))[: dev.missing_at_end]}
    extra_slots = set()
    if dev.extra:
        gaps = [(si, k) for si, (_, _, offs) in enumerate(sets) for k in range(1, len(offs) - 2)]
        extra_slots = {gaps[i] for i in rng.permutation(len(gaps))[: dev.extra]}
    lap_slots = set()
    if dev.laps:
        free = [x for x in slots if x not in missing_slots | wrong_slots | extra_slots]
        lap_slots = {free[i] for i in rng.permutation(len(free))[: dev.laps]}
    return missing_slots, wrong_slots, extra_slots, lap_slots


def _finite_extent(sets: list, dev: Deviations) -> dict:
    """A finite mesh (``dev.end_overhang_mm``): (start, end) along each set's direction, the
    crossing set's extent plus the overhang; ``{}`` where every bar runs the whole slab."""
    extent = {}
    if dev.end_overhang_mm is not None:
        for layer in ("lower", "upper"):
            offs = {lv: o for (la, lv, o) in sets if la == layer}
            for level, other in (("bottom", "top"), ("top", "bottom")):
                extent[(layer, level)] = (
                    min(offs[other]) - dev.end_overhang_mm,
                    max(offs[other]) + dev.end_overhang_mm,
                )
    return extent


def _place_bars(
    design: Design, dev: Deviations, sets: list, slots: tuple, extent: dict, frame, half: float, rng
) -> tuple[list, list, list, list]:
    """The bars of every set where they lie (offset, height and bow drawn from ``rng``); the
    empty positions and a ghost bar at each (where it would have been, with no draw); the laps."""
    env = (lambda d: rib_envelope_mm(d)) if dev.ribs else (lambda d: float(d))
    missing_slots, wrong_slots, extra_slots, lap_slots = slots
    ex, ey = frame
    base = {"lower": design.cover_mm, "upper": design.cover_mm + design.layer_distance_mm}
    bars, missing, ghosts, laps = [], [], [], []
    for si, (layer, level, offsets) in enumerate(sets):
        lat = design.lattice(layer)
        d_design = lat.level(level).diameter_mm
        bottom_env = env(lat.bottom.diameter_mm)
        along, across = (ex, ey) if level == "bottom" else (ey, ex)
        s_lo, s_hi = extent.get((layer, level), (-half, half))
        s_mid, s_half = 0.5 * (s_lo + s_hi), 0.5 * (s_hi - s_lo)
        spacing = lat.level(level).spacing_mm
        placed = [(k, off, False) for k, off in enumerate(offsets)]
        placed += [(k, off + spacing / 2, True) for k, off in enumerate(offsets) if (si, k) in extra_slots]
        for k, off, is_extra in sorted(placed, key=lambda x: x[1]):
            if not is_extra and (si, k) in missing_slots:
                missing.append((layer, level, k))
                # where it would have been (design position and height; no random draw)
                e = env(d_design)
                zc = base[layer] + (e / 2 if level == "bottom" else bottom_env + e / 2)
                s = np.array([s_lo, s_hi])
                ghosts.append(
                    Bar(
                        -1 - len(ghosts),
                        layer,
                        level,
                        k,
                        float(off),
                        along.copy(),
                        s[:, None] * along + off * across + np.array([0, 0, zc]),
                        float(d_design),
                        float(e),
                        float(d_design),
                    )
                )
                continue
            nominal = d_design
            if not is_extra and (si, k) in wrong_slots:
                nominal = float(rng.choice(_sizes_near(d_design)))
            e = env(nominal)
            off_true = off + rng.normal(0, dev.position_sigma_mm) if dev.position_sigma_mm else off
            if dev.position_uniform_mm:
                off_true += rng.uniform(-dev.position_uniform_mm, dev.position_uniform_mm)
            z0 = base[layer] + rng.normal(0, dev.height_sigma_mm) if dev.height_sigma_mm else base[layer]
            # bottom bars rest on the spacers; top bars rest on the bottom bars of their lattice
            zc = z0 + e / 2 if level == "bottom" else z0 + bottom_env + e / 2
            n_seg = 12 if dev.bow_mm else 1
            sign = rng.choice([-1.0, 1.0]) if dev.bow_mm else 0.0

            def axis_over(a, b, shift=0.0):
                s = np.linspace(a, b, n_seg + 1)
                bow = dev.bow_mm * sign * (1 - ((s - s_mid) / s_half) ** 2) if dev.bow_mm else 0 * s
                return s[:, None] * along + (off_true + shift + bow)[:, None] * across + np.array([0, 0, zc])

            def bar(axis, offset, partner=-1):
                return Bar(
                    len(bars),
                    layer,
                    level,
                    k,
                    float(offset),
                    along.copy(),
                    axis,
                    float(nominal),
                    float(e),
                    float(d_design),
                    extra=is_extra,
                    lap_partner=partner,
                )

            if not is_extra and (si, k) in lap_slots:
                # two pieces side by side, touching, straddling the position over the lap
                lap = dev.lap_length_mm or max(40.0 * nominal, 300.0)
                mid = float(rng.uniform(s_lo + lap, s_hi - lap)) if s_hi - s_lo > 3 * lap else s_mid
                side = float(rng.choice([-1.0, 1.0]))
                i0 = len(bars)
                bars.append(bar(axis_over(s_lo, mid + lap / 2, -side * e / 2), off_true - side * e / 2, i0 + 1))
                bars.append(bar(axis_over(mid - lap / 2, s_hi, side * e / 2), off_true + side * e / 2, i0))
                laps.append((i0, i0 + 1, mid * along + off_true * across + np.array([0, 0, zc])))
                continue
            bars.append(bar(axis_over(s_lo, s_hi), off_true))
    return bars, missing, ghosts, laps


def _accessories(design: Design, dev: Deviations, bars: list, yaw: float) -> tuple[list, list]:
    """Cover blocks under the lower lattice, chairs between the lattices and tie wire at the
    crossings, as boxes ``(centre, half-size, yaw, kind)`` and rods ``(p0, p1, radius, kind)``."""
    boxes, rods = [], []
    lower_b = [b for b in bars if b.layer == "lower" and b.level == "bottom"]
    lower_t = [b for b in bars if b.layer == "lower" and b.level == "top"]
    if dev.spacers and lower_b:
        pitch = max(2, int(round(800 / design.lower.top.spacing_mm)))
        for b in lower_b[1::pitch]:
            for d_mm in np.arange(150.0, _length(b), 800.0):
                c = b.axis[0] + d_mm * b.direction
                c = np.array([c[0], c[1], (b.axis[:, 2].mean() - b.radius_mm) / 2])
                hs = np.array([25.0, 25.0, c[2]])
                boxes.append((c, hs, yaw, "spacer"))
    upper_b = [b for b in bars if b.layer == "upper" and b.level == "bottom"]
    if dev.chairs and upper_b and lower_t:
        top_of_lower = max(b.axis[:, 2].max() + b.radius_mm for b in lower_t)
        for b in upper_b[1::3]:
            for d_mm in np.arange(300.0, _length(b), 900.0):
                p = b.axis[0] + d_mm * b.direction
                z_top = b.axis[:, 2].mean() - b.radius_mm
                rods.append((np.array([p[0], p[1], top_of_lower]), np.array([p[0], p[1], z_top]), 5.0, "chair"))
    if dev.ties:
        rods.extend(_ties(bars))
    return boxes, rods


def _ties(bars: list) -> list:
    """A short wire across each crossing of a lattice's bars (every other bottom bar where a
    lattice has more than 6), just over the top bar."""
    rods = []
    for layer in ("lower", "upper"):
        bot = [b for b in bars if b.layer == layer and b.level == "bottom"]
        top = [b for b in bars if b.layer == layer and b.level == "top"]
        for tb in top:
            for bb in bot[::2] if len(bot) > 6 else bot:
                # crossing of the two chord lines in plan
                A = np.column_stack((bb.direction[:2], -tb.direction[:2]))
                st = np.linalg.solve(A, tb.axis[0, :2] - bb.axis[0, :2])
                if not (0 <= st[0] <= _length(bb) and 0 <= st[1] <= _length(tb)):
                    continue  # a lap's piece ends before this crossing
                xy = bb.axis[0, :2] + st[0] * bb.direction[:2]
                z = tb.axis[:, 2].mean() + tb.radius_mm + 0.7
                diag = (bb.direction + tb.direction) / math.sqrt(2) * (tb.radius_mm + 3)
                c = np.array([xy[0], xy[1], z])
                rods.append((c - diag, c + diag, 0.7, "tie"))
    return rods


def _length(bar: Bar) -> float:
    """Length of a bar's chord (mm)."""
    return float(np.linalg.norm(bar.axis[-1, :2] - bar.axis[0, :2]))


_EDGE_FORM_GAP_MM, _EDGE_FORM_THICKNESS_MM = 25.0, 18.0


def _edge_forms(design: Design, bars, extent: dict, ex, ey, yaw) -> list:
    """Four boards standing at the slab's edges, ``_EDGE_FORM_GAP_MM`` beyond the bar ends."""
    x_lo = min(extent[(la, "bottom")][0] for la in ("lower", "upper")) - _EDGE_FORM_GAP_MM
    x_hi = max(extent[(la, "bottom")][1] for la in ("lower", "upper")) + _EDGE_FORM_GAP_MM
    y_lo = min(extent[(la, "top")][0] for la in ("lower", "upper")) - _EDGE_FORM_GAP_MM
    y_hi = max(extent[(la, "top")][1] for la in ("lower", "upper")) + _EDGE_FORM_GAP_MM
    top = max(float(b.axis[:, 2].max()) + b.radius_mm for b in bars) + 30.0
    height = float(design.thickness_mm) if getattr(design, "thickness_mm", None) else top
    t = _EDGE_FORM_THICKNESS_MM / 2
    out = []
    for x in (x_lo - t, x_hi + t):  # boards across x, running along y
        c = x * ex + 0.5 * (y_lo + y_hi) * ey + np.array([0, 0, height / 2])
        out.append((c, np.array([t, 0.5 * (y_hi - y_lo) + 2 * t, height / 2]), yaw, "edge_form"))
    for y in (y_lo - t, y_hi + t):
        c = 0.5 * (x_lo + x_hi) * ex + y * ey + np.array([0, 0, height / 2])
        out.append((c, np.array([0.5 * (x_hi - x_lo), t, height / 2]), yaw, "edge_form"))
    return out
