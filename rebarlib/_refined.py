"""The refined method's geometry of one capture (``inspect(..., method="refined")``), step by
step: the formwork plane, the points of the lattices and their split, the bars of each lattice,
the heights read off them (cover, layer distance, top), and the bar positions judged on evidence
with the spacings and counts that follow.

Each step is a function of what the one before it gave; :func:`inspect_refined` times them
(``result.timings_s``: cloud, plane, layers, bars, measure).
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np

from . import _counts as C
from . import geometry as G
from ._camera import Cloud
from ._capture import Capture
from ._checks import RebarInputError
from ._design import Design
from ._inspect import (
    MIN_BAR_LENGTH_MM,
    MIN_LATTICE_POINTS,
    STRIDE,
    _camera_pose,
    _check_camera_height,
    _design_spacing,
    _formwork_found,
    _mean_measure,
    _radii,
    _top_cover,
    edge_flags,
    facing_up,
    prepare_cloud,
    registered_mask,
)
from ._results import InspectionResult, Measurement
from ._status import MEASURED

__all__ = ["inspect_refined"]


@dataclass
class _Ground:
    """The formwork plane (or, without formwork, a reference plane under every point) and the
    points' heights above it."""

    plane: G.Plane
    h: np.ndarray
    sigma: float  # the plane's noise σ (1 mm where unknown)
    thr: float  # the plane's RANSAC band, mm
    found: bool  # a formwork plane with nothing beneath it


@dataclass
class _Lattices:
    """The points above the formwork, in the slab frame, and which lattice each belongs to."""

    sel: np.ndarray  # indices into the cloud
    q: np.ndarray  # (n, 3) slab-frame points
    split: float | None
    layer_of: np.ndarray
    names: list


def inspect_refined(
    capture: Capture, design: Design, rng, mask_cache: dict | None = None, *, trimmed: bool = False
) -> InspectionResult:
    """The refined method's result for one capture (no diameters: :func:`rebarlib.inspect`
    adds them). ``mask_cache``: a dict the colour mask is kept in between calls. ``trimmed``:
    the capture's depth has had the nearer surface's last pixels left out at every occluding
    edge (``trim_edge_fattening``); a bar seen from one flank is then fitted with every point
    (that trim already took the clear flank's edge effects, and gave the covered flank its
    fringe back, docs/decisions/055)."""
    T, notes = {}, []
    t = time.perf_counter()
    cloud = prepare_cloud(capture)
    T["cloud"] = time.perf_counter() - t
    if len(cloud) < 100:
        raise RebarInputError(f"capture {capture.name!r}: only {len(cloud)} valid depth points")
    t = time.perf_counter()
    ground = _ground(capture, design, cloud, rng, notes)
    T["plane"] = time.perf_counter() - t
    t = time.perf_counter()
    lat = _lattices(capture, design, cloud, ground, notes)
    T["layers"] = time.perf_counter() - t
    t = time.perf_counter()
    bars, bar_clouds = _bars(capture, design, cloud, ground.plane, lat, rng, one_sided=not trimmed)
    T["bars"] = time.perf_counter() - t
    t = time.perf_counter()
    cover, layer_distance, upper_top, top_cover = _heights(bars, ground, design)
    positions, placed, boundary = _positions(capture, design, bars, ground.plane, mask_cache)
    bars = bars + placed
    bar_clouds = bar_clouds + [Cloud(np.zeros((0, 3)), np.zeros((0, 2), np.int32)) for _ in placed]
    spacings = G.measure_spacings(bars, design_spacing=_design_spacing(design), skip=C.off_the_row(positions, bars))
    spacings = C.settle_spacings(spacings, bars, positions)
    counts = C.count_table(bars, positions, _design_spacing(design))
    T["measure"] = time.perf_counter() - t

    plane = ground.plane
    table = G.bars_table(bars, plane, points=[c.points for c in bar_clouds])
    res = InspectionResult(
        capture=capture.name,
        method="refined",
        cover=cover,
        layer_distance=layer_distance,
        upper_top=upper_top,
        top_cover=top_cover,
        bars=table,
        spacings=spacings,
        counts=counts,
        formwork={**plane.to_dict(), "found": bool(ground.found)},
        camera=_camera_pose(plane) if ground.found else {},
        timings_s=T,
        notes=notes,
        extras={"layer_split_mm": lat.split, "n_points": int(len(cloud)), "mesh_boundary": boundary},
    )
    res.positions = positions
    res.bar_points = {i: c for i, c in enumerate(bar_clouds)}
    return res


def _ground(capture: Capture, design: Design, cloud, rng, notes: list) -> _Ground:
    """The formwork plane, checked for the camera's height; without formwork, a reference plane
    parallel to the lattice under every point (noted)."""
    thr = max(3.0, min(0.4 * design.cover_mm, 10.0))
    plane, inl = G.fit_formwork(cloud.points, threshold_mm=thr, rng=rng)
    h = plane.height(cloud.points)
    sigma = plane.noise_mm or 1.0
    has_formwork, below = _formwork_found(plane, h, inl)
    _check_camera_height(
        capture,
        design,
        plane.offset_mm if has_formwork else float(np.median(cloud.points[:, 2])),
        formwork=has_formwork,
    )
    if not has_formwork:
        notes.append(
            f"no formwork plane: {below:.0%} of the points lie under the best plane; cover not measured, "
            "heights are relative to the lowest bars"
        )
        # a reference plane parallel to the lattice, under every point
        lowest = float(np.percentile(h, 0.5))
        plane = G.Plane(plane.normal, plane.offset_mm - lowest, 0, None)
        h = plane.height(cloud.points)
    return _Ground(plane, h, sigma, thr, has_formwork)


def _above_formwork(design: Design, ground: _Ground, notes: list) -> np.ndarray:
    """Indices of the points that stand above the formwork and not far above the mesh's design
    top."""
    h, sigma, thr = ground.h, ground.sigma, ground.thr
    # What stands above the formwork: beyond 4 noise σ of the plane, at least 3 mm, and above
    # the formwork's own points. The last matters on a stereo camera that quantises depth in
    # disparity: at 600 mm a step is 1.5 mm on a 1280 × 800 unit and 2.1 mm at 848 × 480; the
    # plane's robust σ sees the level it lies on, not the next level up, where a tenth of the
    # formwork can sit (3.3 mm over a D435-like capture's plane). Those points, counted as bars,
    # filled the lower lattice with a layer of clutter in which no bar run stood out. The
    # formwork's extent is the 99th percentile of the heights in the plane's RANSAC band
    # (|h| < thr, at most 0.4 × the design cover, so bars resting at their cover are not in it).
    band = h[np.abs(h) < thr]
    top_of_formwork = float(np.percentile(band, 99)) if len(band) else 0.0
    above_thr = max(4 * sigma, 3.0, top_of_formwork + sigma) if ground.found else -1.0
    bar_sel = np.where(h > above_thr)[0] if ground.found else np.arange(len(h))
    if ground.found:
        # Nothing of the mesh stands far above its design top: what does (an edge form's top, a
        # tool, a boot) is not rebar. The margin, a quarter of the design top and at least 30 mm,
        # keeps a mesh placed centimetres too high (itself a cover or layer-distance defect).
        top_limit = design.upper_top_mm + max(30.0, 0.25 * design.upper_top_mm)
        high = h[bar_sel] > top_limit
        if high.any():
            if high.mean() > 0.01:
                notes.append(
                    f"{high.mean():.0%} of the points above the formwork lie more than "
                    f"{top_limit - design.upper_top_mm:.0f} mm above the design's top of the mesh "
                    f"({design.upper_top_mm:.0f} mm): left out as not rebar (an edge form, an object)"
                )
            bar_sel = bar_sel[~high]
    return bar_sel


def _lattices(capture: Capture, design: Design, cloud, ground: _Ground, notes: list) -> _Lattices:
    """The points above the formwork split into the lower and upper lattice (or one lattice, or
    none), by the empty band between them in the heights."""
    plane, has_formwork = ground.plane, ground.found
    bar_sel = _above_formwork(design, ground, notes)
    q = G.to_slab_frame(cloud.points[bar_sel], plane)
    split = G.find_layer_split(q[:, 2])
    if split is None and len(q) >= MIN_LATTICE_POINTS and has_formwork:
        # A vertical surface (an edge form at the slab's edge, a wall, a column's side) puts
        # points at every height and fills the band between the lattices; the lattices' bars
        # are seen mostly from above. Try again on the points whose surface faces up.
        up = facing_up(capture, cloud.pixels[bar_sel], plane)
        if up.sum() >= MIN_LATTICE_POINTS:
            # the tops of one lattice's two levels leave a gap of about a bar's diameter in
            # these heights; the band between the lattices is the design's clear distance
            clear = design.layer_distance_mm - design.lower.thickness_mm
            split = G.find_layer_split(q[up, 2], min_gap_mm=max(6.0, 0.5 * clear))
            if split is not None:
                notes.append(
                    f"layer split at {split:.0f} mm found on the upward-facing points only: vertical "
                    "surfaces (an edge form, a wall) fill the band between the lattices"
                )
    layer_of = G.split_layers(q[:, 2], split_mm=split)
    layer_names = ["lower", "upper"]
    if len(q) < MIN_LATTICE_POINTS:
        # nothing stands above the plane (a capture of bare formwork): no lattice, no bars
        layer_names = []
        notes.append(f"no lattice: only {len(q)} points stand above the formwork plane")
    elif split is None:
        # one lattice: which one, from the design heights (only meaningful over formwork)
        lo = float(np.percentile(q[:, 2], 2))
        is_upper = has_formwork and abs(lo - (design.cover_mm + design.layer_distance_mm)) < abs(lo - design.cover_mm)
        layer_names = ["upper" if is_upper else "lower"]
        notes.append(f"one lattice only ({layer_names[0]}): no empty band between lattices in the heights")
    return _Lattices(bar_sel, q, split, layer_of, layer_names)


def _bars(capture: Capture, design: Design, cloud, plane: G.Plane, lat: _Lattices, rng, one_sided=True) -> tuple:
    """The bars of each lattice (cylinders fitted with the design radii), then a second look at
    full resolution at the positions of each row where none was found: (bars, their clouds).
    ``one_sided``: a bar seen from one flank under a nearer bar is fitted without its clear
    flank's edge pixels (docs/decisions/055)."""
    bars, bar_clouds = [], []
    K = capture.intrinsics
    camera = G.to_slab_frame(np.zeros((1, 3)), plane)[0]  # where the bars' visible sides face
    # which points are a nearer surface's last pixel, or lie beside a nearer surface (the
    # fit of a bar half under a nearer bar leaves its clear flank's last pixel out)
    flags = edge_flags(capture.depth_mm, cloud.pixels[lat.sel]) if one_sided else None
    for li, lname in enumerate(lat.names):
        sel = np.where(lat.layer_of == li)[0]
        if len(sel) == 0:
            continue
        # sample pitch on this lattice: STRIDE pixels at its median depth
        pitch = STRIDE * float(np.median(cloud.points[lat.sel[sel], 2])) / (0.5 * (K.fx + K.fy))
        radii = _radii(design, lname)
        edges = None if flags is None else tuple(f[sel] for f in flags)
        # direction groups do not know their level yet: fit with the larger radius first, then
        # refit each group with its level's radius once the levels are known
        found = G.find_bars(
            lat.q[sel],
            layer=lname,
            radius_mm=max(radii.values()),
            min_length_mm=MIN_BAR_LENGTH_MM,
            pitch_mm=pitch,
            camera=camera,
            rng=rng,
            noise_mm=plane.noise_mm,
            edges=edges,
        )
        found = G.assign_levels(found)
        if radii["bottom"] != radii["top"]:
            rad_by_group = {b.group: radii[b.level] for b in found}
            found = G.assign_levels(
                G.find_bars(
                    lat.q[sel],
                    layer=lname,
                    radius_mm=rad_by_group,
                    min_length_mm=MIN_BAR_LENGTH_MM,
                    pitch_mm=pitch,
                    camera=camera,
                    rng=rng,
                    noise_mm=plane.noise_mm,
                    edges=edges,
                )
            )
        found = G.flag_border_cut(found, lat.q[sel], plane=plane, intrinsics=K)
        for b in found:
            bar_clouds.append(cloud.subset(lat.sel[sel[b.point_index]]))
        bars.extend(found)
    # a second look, at full resolution, at the positions of each row where no bar was found
    more, more_clouds = G.find_missed_bars(
        bars,
        depth_mm=capture.depth_mm,
        intrinsics=K,
        plane=plane,
        design_spacing=_design_spacing(design),
        noise_mm=plane.noise_mm,
        min_length_mm=MIN_BAR_LENGTH_MM,
    )
    return bars + more, bar_clouds + more_clouds


def _heights(bars: list, ground: _Ground, design: Design) -> tuple:
    """Cover, layer distance, top of the upper lattice and top cover, from the measured bars'
    undersides and tops (each "not measured" with its reason where it cannot be read)."""
    plane, has_formwork, sigma = ground.plane, ground.found, ground.sigma

    def undersides(layer, level):
        return [b.underside_mm for b in bars if b.layer == layer and b.level == level and b.status == MEASURED]

    def npts(layer, level):
        return sum(b.n_points for b in bars if b.layer == layer and b.level == level)

    plane_var = (sigma / math.sqrt(max(plane.n_inliers, 1))) ** 2 if has_formwork else 0.0
    unclear = {la: _levels_unclear(bars, la) for la in G.LAYERS}
    lower_u = undersides("lower", "bottom")
    if not has_formwork:
        cover = Measurement.not_measured("no formwork visible in the capture (no plane with nothing beneath it)")
    elif unclear["lower"]:
        cover = Measurement.not_measured(unclear["lower"], npts("lower", "bottom"))
    elif not lower_u:
        cover = Measurement.not_measured(
            "no bar of the lower lattice's bottom level was measured", npts("lower", "bottom")
        )
    else:
        cover = _mean_measure(lower_u, what="lower bar", extra_var=plane_var, n_points=npts("lower", "bottom"))
    upper_u = undersides("upper", "bottom")
    if unclear["lower"] or unclear["upper"]:
        layer_distance = Measurement.not_measured(unclear["lower"] or unclear["upper"])
    elif lower_u and upper_u:
        lm = _mean_measure(lower_u, what="lower bar")
        um = _mean_measure(upper_u, what="upper bar")
        layer_distance = Measurement(
            um.value_mm - lm.value_mm,
            math.hypot(lm.uncertainty_mm, um.uncertainty_mm),
            npts("lower", "bottom") + npts("upper", "bottom"),
        )
    else:
        which = "upper" if not upper_u else "lower"
        layer_distance = Measurement.not_measured(f"no bar of the {which} lattice's bottom level was measured")
    tops = [b.top_mm for b in bars if b.layer == "upper" and b.level == "top" and b.status == MEASURED]
    if not has_formwork:
        upper_top = Measurement.not_measured("no formwork visible: heights have no reference")
    elif unclear["upper"]:
        upper_top = Measurement.not_measured(unclear["upper"], npts("upper", "top"))
    else:
        upper_top = (
            _mean_measure(tops, what="upper top bar", extra_var=plane_var, n_points=npts("upper", "top"))
            if tops
            else Measurement.not_measured("no bar of the upper lattice's top level was measured")
        )
    return cover, layer_distance, upper_top, _top_cover(design, upper_top)


def _positions(capture: Capture, design: Design, bars: list, plane: G.Plane, mask_cache: dict | None) -> tuple:
    """Every empty design position and every close pair examined on evidence (docs/verdicts.md):
    (positions, the bars placed where only the colour shows one, the mesh's boundary). The
    colour mask is computed only when a verdict needs it, and kept in ``mask_cache``."""

    def count_mask():
        if mask_cache is not None and "model" in mask_cache:
            return mask_cache["model"]
        m = registered_mask(capture, source="model", plane=(plane.normal, plane.offset_mm))[0]
        if mask_cache is not None:
            mask_cache["model"] = m
        return m

    return C.examine_positions(
        bars,
        design_spacing=_design_spacing(design),
        plane=plane,
        depth_mm=capture.depth_mm,
        intrinsics=capture.intrinsics,
        mask=count_mask,
        noise_mm=plane.noise_mm,
    )


def _levels_unclear(bars: list, layer: str) -> str:
    """Why the two levels of a lattice cannot be told apart on this capture, or "".

    A lattice's levels are named by the order of its two direction groups' heights
    (``geometry.assign_levels``): with measured bars in one direction only, that one is called
    "bottom" whether it is or not. Where depth is sparse (wet, black or sunlit steel) the crossing
    bars resting on top are the ones found, and their undersides, one bar diameter up, were
    taken for the cover. Only a lattice with measured bars in both directions supports the
    heights read off one level.
    """
    levels = {b.level for b in bars if b.layer == layer and b.status == MEASURED}
    if not levels or levels == {"bottom", "top"}:
        return ""
    return (
        f"bars of the {layer} lattice were measured in one direction only: whether they are its "
        "bottom or its top level cannot be told (too few depth points on the other direction's bars)"
    )
