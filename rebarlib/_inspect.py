"""``inspect(capture, design)``: the whole geometry of one capture, composed from ``geometry``.

Both methods return the same :class:`~rebarlib.InspectionResult`, so they can be compared row by
row. Each stage is timed (``result.timings_s``).
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time

import numpy as np

from . import geometry as G
from ._camera import backproject, depth_to_points
from ._capture import Capture
from ._checks import RebarInputError
from ._design import Design
from ._masks import (  # noqa: F401 (the mask's names are reached through this module too)
    EDGE_MM,
    MASK_SOURCES,
    MODEL_THREADS,
    REGISTRATION_MIN_PX,
    REGISTRATION_WARN_PX,
    _farthest_within,
    _mask,
    _nearest_within,
    rebar_mask,
    registered_mask,
    trim_edge_fattening,
    widest_bar_px,
)
from ._results import InspectionResult, Measurement

__all__ = [
    "inspect",
    "prepare_cloud",
    "rebar_mask",
    "registered_mask",
    "trim_edge_fattening",
    "METHODS",
    "MASK_SOURCES",
]

METHODS = ("refined", "paper")

#: Refined: keep every ``STRIDE``-th pixel in each direction. At 400–600 mm a pixel covers
#: 0.65–1 mm, so a stride of 2 still puts 5+ samples across the thinnest (Φ8) bar, and the
#: cloud is 4× smaller.
STRIDE = 2
#: Paper: voxel grid (mm) and Open3D statistical outlier filter, as in method.md stage 0.
PAPER_VOXEL_MM, PAPER_NB, PAPER_STD = 2.0, 20, 2.0
#: Paper constants (method.md): t₁ = 0.8 × cover, k = 170; t₂ = 50 mm; 1.2·d; 1000 points; k = 460.
PAPER_T1_FACTOR, PAPER_PLANE_TRIALS, PAPER_T2_MM, PAPER_COVER_FACTOR = 0.8, 170, 50.0, 1.2
PAPER_SAMPLE, PAPER_LINE_TRIALS = 1000, 460
#: A formwork plane is rejected when more than this fraction of the points lie more than
#: 5 noise std below it (a plane through bar tops has bars' sides and the formwork under it).
MAX_BELOW_FRACTION = 0.02
#: Fewer points than this above the formwork: no lattice in the capture.
MIN_LATTICE_POINTS = 30
#: Bars shorter than this (mm of visible axis) are not reported: too short to fit an axis.
MIN_BAR_LENGTH_MM = 50.0
#: Nearest plausible distance (mm) from the camera to the formwork: depth cameras of this kind
#: see nothing nearer than about 150 mm. A nearer formwork means the depth is in another unit
#: than ``camera.json``'s ``depth_scale_mm`` says (0.1 given for depth stored in mm: 10x too near).
MIN_CAMERA_HEIGHT_MM = 150.0
#: The farthest plausible distance is where the design's thinnest bar would span this many
#: pixels (``fx · d / MIN_BAR_PX``): no bar can be fitted from farther, and a depth 10x too far
#: (``depth_scale_mm`` 10 for depth stored in mm) lands there.
MIN_BAR_PX = 2.0


def facing_up(capture: Capture, pixels, plane: G.Plane, *, step_px: int = 2, min_cos: float = 0.5) -> np.ndarray:
    """Which of ``pixels`` (N, 2) see a surface facing up, away from the formwork: the normal
    from the depth image (cross product of the neighbours ``step_px`` away) makes an angle under
    60° (``min_cos``) with the plane's normal. Pixels without the neighbours' depth: False."""
    depth = np.asarray(capture.depth_mm, float)
    H, W = depth.shape
    u = np.asarray(pixels)[:, 0].astype(int)
    v = np.asarray(pixels)[:, 1].astype(int)
    K = capture.intrinsics

    def point(uu, vv):
        uu, vv = np.clip(uu, 0, W - 1), np.clip(vv, 0, H - 1)
        z = depth[vv, uu]
        return backproject(np.column_stack((uu, vv)), z, K), z > 0

    (pu, ok1), (pl, ok2) = point(u + step_px, v), point(u - step_px, v)
    (pd, ok3), (pt, ok4) = point(u, v + step_px), point(u, v - step_px)
    n = np.cross(pu - pl, pd - pt)
    norm = np.linalg.norm(n, axis=1)
    ok = ok1 & ok2 & ok3 & ok4 & (norm > 0)
    cos = np.abs(n @ np.asarray(plane.normal, float)) / np.where(norm > 0, norm, 1.0)
    return ok & (cos >= min_cos)


def prepare_cloud(capture: Capture, *, stride: int = STRIDE, edge_mm: float | None = EDGE_MM):
    """Camera-frame cloud of a capture, every ``stride``-th pixel (pixel links kept).

    ``edge_mm``: a pixel whose 3×3 neighbourhood holds a depth more than ``edge_mm`` nearer the
    camera is dropped: it lies just behind an occluding edge, where stereo depth is a mix of the
    two surfaces (flying pixels, edge fattening). Bars keep their own points (they are the near
    side of the edge); what is lost is a 1-pixel fringe of the surface behind. ``None`` keeps all.
    """
    depth = capture.depth_mm
    if edge_mm is not None:
        d = depth.astype(np.float32)
        depth = np.where(d - _nearest_within(d, 1) > edge_mm, 0.0, depth)
    if stride > 1:
        sub = np.zeros_like(depth)
        sub[::stride, ::stride] = depth[::stride, ::stride]
        depth = sub
    return depth_to_points(depth, capture.intrinsics)


def edge_flags(depth_mm, pixels, *, edge_mm: float = EDGE_MM, beside_px: int = 3) -> tuple:
    """Per point (its ``(u, v)`` pixel): ``(silhouette, beside_nearer)``, two bool arrays.

    ``silhouette``: the pixel is the nearer surface's last at an occluding edge (a pixel of its
    3×3 neighbourhood has depth more than ``edge_mm`` farther; the pixels
    ``trim_edge_fattening(depth, 1)`` leaves out). ``beside_nearer``: a pixel within
    ``beside_px`` (a square) has depth more than ``edge_mm`` nearer: the point lies at the edge of
    what a nearer surface leaves of its own (``prepare_cloud`` drops the fringe pixel itself; the
    thinned cloud's next points lie up to ``STRIDE + 1`` pixels from the nearer surface, hence 3).
    Pixels without depth are neither farther nor nearer. The refined bar search uses both
    (``geometry.find_bars(edges=...)``, docs/decisions/055).

    Examples
    --------
    >>> depth = np.full((1, 9), 500.0); depth[0, 3:6] = 470.0
    >>> sil, beside = edge_flags(depth, np.array([[u, 0] for u in range(9)]))
    >>> sil.astype(int).tolist(), beside.astype(int).tolist()
    ([0, 0, 0, 1, 0, 1, 0, 0, 0], [1, 1, 1, 0, 0, 0, 1, 1, 1])
    """
    d = np.asarray(depth_mm).astype(np.float32)
    farthest, nearest = _farthest_within(d, 1), _nearest_within(d, beside_px)
    # (compared at the points' pixels only)
    u, v = np.asarray(pixels)[:, 0], np.asarray(pixels)[:, 1]
    dp = d[v, u]
    valid = dp > 0
    return valid & (farthest[v, u] - dp > edge_mm), valid & (dp - nearest[v, u] > edge_mm)


def _check(capture, design, method):
    if not isinstance(capture, Capture):
        raise RebarInputError(
            f"capture: expected a rebarlib.Capture (use rebarlib.load_capture), got {type(capture).__name__}"
        )
    if not isinstance(design, Design):
        raise RebarInputError(
            f"design: expected a rebarlib.Design (use rebarlib.load_design), got {type(design).__name__}"
        )
    if method not in METHODS:
        raise RebarInputError(f"method: expected one of {METHODS}, got {method!r}")
    if not np.any(capture.depth_mm > 0):
        raise RebarInputError(f"capture {capture.name!r}: the depth image has no valid pixel")


def _check_camera_height(capture: Capture, design: Design, height_mm: float, *, formwork: bool) -> None:
    """Refuse a capture whose formwork (else its median depth) lies nearer or farther from the
    camera than any capture could be measured from: its depth unit is almost surely wrong."""
    thinnest = min(design.lattice(la).level(lv).diameter_mm for la in G.LAYERS for lv in G.LEVELS)
    far = capture.intrinsics.fx * thinnest / MIN_BAR_PX
    if MIN_CAMERA_HEIGHT_MM <= height_mm <= far:
        return
    src = capture.metadata.get("source")
    where = f"{src}/camera.json" if src else f"capture {capture.name!r}"
    what = "the formwork" if formwork else "the scene (median depth)"
    raise RebarInputError(
        f"{where}: depth_scale_mm looks wrong: {what} would be {height_mm:.0f} mm from the camera "
        f"(depth_scale_mm = {capture.depth_scale_mm:g}; plausible: {MIN_CAMERA_HEIGHT_MM:.0f} to {far:.0f} mm, "
        f"where the thinnest bar, {thinnest:g} mm, still spans {MIN_BAR_PX:g} px)"
    )


def _formwork_found(plane: G.Plane, h: np.ndarray, inliers: np.ndarray) -> tuple[bool, float]:
    """Whether ``plane`` is the formwork: it holds at least 5 % of the points and no more than
    :data:`MAX_BELOW_FRACTION` of them lie beneath it by more than 5 robust noise σ of its
    inliers (at least 3 mm); a plane through bar tops has the bars' sides and whatever lies
    under them below it. Returns ``(found, fraction below)``."""
    sigma = plane.noise_mm
    if sigma is None:
        hi = h[inliers]
        sigma = 1.4826 * float(np.median(np.abs(hi))) if len(hi) else 1.0
    below = float(np.mean(h < -max(5 * (sigma or 1.0), 3.0)))
    return below <= MAX_BELOW_FRACTION and int(inliers.sum()) >= 0.05 * len(h), below


def _formwork_of(capture: Capture, design: Design, rng) -> tuple[G.Plane, bool, float]:
    """The refined method's formwork test on a capture (its cloud, :func:`prepare_cloud`):
    ``(plane, found, fraction of points beneath it)``; also refuses a capture whose formwork,
    else its median depth, is at an implausible distance (:func:`_check_camera_height`)."""
    points = prepare_cloud(capture).points
    thr = max(3.0, min(0.4 * design.cover_mm, 10.0))
    ref, inl = G.fit_formwork(points, threshold_mm=thr, rng=rng)
    found, below = _formwork_found(ref, ref.height(points), inl)
    _check_camera_height(capture, design, ref.offset_mm if found else float(np.median(points[:, 2])), formwork=found)
    return ref, found, below


def _same_plane(a: G.Plane, b: G.Plane, band_mm: float) -> bool:
    """Normals within 2° and offsets within ``band_mm``."""
    return float(np.dot(a.normal, b.normal)) > math.cos(math.radians(2.0)) and abs(a.offset_mm - b.offset_mm) < band_mm


def _camera_pose(plane: G.Plane) -> dict:
    tilt = math.degrees(math.acos(min(1.0, abs(float(plane.normal[2])))))
    return {"height_mm": round(float(plane.offset_mm), 2), "tilt_deg": round(tilt, 2)}


def _design_spacing(design: Design) -> dict:
    return {(la, lv): design.lattice(la).level(lv).spacing_mm for la in G.LAYERS for lv in G.LEVELS}


def _radii(design: Design, layer: str) -> dict:
    lat = design.lattice(layer)
    from .diameter.barsizes import barset_width_mm  # a plain bar (surface = "plain") is seen at its diameter

    return {lv: barset_width_mm(lat.level(lv), design.bar_system) / 2 for lv in G.LEVELS}


def _mean_measure(values, *, what: str, extra_var: float = 0.0, n_points: int = 0) -> Measurement:
    v = np.asarray([x for x in values if np.isfinite(x)], float)
    if len(v) == 0:
        return Measurement.not_measured(f"no {what} measured", n_points)
    se = float(v.std(ddof=1) / math.sqrt(len(v))) if len(v) > 1 else float("nan")
    unc = math.sqrt((se if np.isfinite(se) else 0.5) ** 2 + extra_var)
    return Measurement(float(v.mean()), unc, int(n_points))


def inspect(
    capture: Capture,
    design: Design,
    *,
    method: str = "refined",
    diameters: bool = True,
    mask=None,
    mask_source: str | None = None,
    register: bool = True,
    edge_trim_px=None,
    rng=0,
    calibration=None,
) -> InspectionResult:
    """Measure cover, layer distance, top of the upper lattice, every bar and every spacing.

    Parameters
    ----------
    capture : Capture (``load_capture``)
    design : Design (``load_design``) — gives the bar sizes (envelope radii), spacings for counts
        and the paper's design-derived thresholds
    method : "refined" (default) or "paper"
    diameters : also measure every bar's nominal diameter (method.md stage 3); the bar table then
        has the diameter columns of ``measure_diameters``
    mask : (H, W) rebar mask to use for the diameters: bool, or a float rebar probability in 0..1
        (edges at 0.5, to a fraction of a pixel) (default: computed, see mask_source)
    mask_source : "fused" (refined default), "model" (paper default) or "depth"
    register : refined, mask computed here: undo a colour-depth misregistration of
        :data:`REGISTRATION_MIN_PX` or more before the diameters (:func:`registered_mask`; the
        estimate is in ``result.extras["registration"]``, a note says when it was applied). The
        paper's method takes the images as they come.
    edge_trim_px : refined: pixels of the nearer surface left out at every occluding edge before
        the bars are fitted (:func:`trim_edge_fattening`, a depth camera's edge fattening).
        None (default): the depth's over-reach beyond the colour's bars where the mask step
        measures it (diameters with a computed "fused" mask, or ``register``;
        ``segmentation.depth_overreach_px``), the geometry then fitted again on the trimmed
        depth; else 0. The number used is in ``result.extras["edge_trim_px"]``, with a note.
        The paper's method takes the depth as it comes.
    rng : seed or Generator for the random parts (RANSAC, sampling); the default seed 0 (as
        ``rebar inspect --seed``) gives the same result in every run; None draws a fresh seed
    calibration : a ``rebarlib.calibration.Calibration`` or the path of a calibration file
        (``rebar calibrate``): its intrinsics and depth correction are applied to the capture
        first, and its uncertainties replace the device profile's in the budget. Either way the
        uncertainties carry the camera's systematic terms (``rebarlib.uncertainty``; the terms
        in ``result.extras["uncertainty"]``).

    Returns
    -------
    InspectionResult; bars carry their fitted points in ``result.bar_points`` (bar_id -> Cloud).
    """
    _check(capture, design, method)
    if edge_trim_px is not None and (
        isinstance(edge_trim_px, bool) or not isinstance(edge_trim_px, int) or edge_trim_px < 0
    ):
        raise RebarInputError(f"edge_trim_px: expected None or a whole number of pixels >= 0, got {edge_trim_px!r}")
    rng = np.random.default_rng(rng)
    capture, cal = _calibrated(capture, calibration)
    if method == "paper":
        res = _inspect_paper(capture, design, rng)
        if diameters:
            _add_diameters(
                res,
                capture,
                design,
                method=method,
                mask=mask,
                mask_source=mask_source or "model",
                register=False,
                rng=rng,
            )
        return _budget(_note_inputs(res, capture), capture, design, cal)
    # the geometry may be fitted again on a trimmed depth: it then draws the same random numbers
    rng_again = copy.deepcopy(rng)
    trim = edge_trim_px or 0
    mask_cache = {}  # the colour model's mask, computed once if the counts need it
    from ._refined import inspect_refined  # the refined steps (they use this module's helpers)

    res = inspect_refined(_trimmed(capture, trim), design, rng, mask_cache, trimmed=trim > 0)
    if diameters:
        first = res

        def refit(reach):
            # the mask step found the depth's bars reaching beyond the colour's: the edge
            # fattening that drew the bars' axes towards it is left out and the bars fitted again
            nonlocal trim
            trim = reach
            again = inspect_refined(_trimmed(capture, reach), design, rng_again, mask_cache, trimmed=True)
            again.timings_s["first_fit"] = round(sum(first.timings_s.values()), 6)
            return again

        res = _add_diameters(
            res,
            capture,
            design,
            method=method,
            mask=mask,
            mask_source=mask_source or "fused",
            register=register,
            rng=rng,
            refit=refit if edge_trim_px is None else None,
        )
    if trim:
        res.extras["edge_trim_px"] = trim
        res.notes.append(
            f"edge fattening: the nearer surface's last {trim} px at every "
            "occluding edge of the depth image left out before the bars were fitted"
        )
    return _budget(_note_inputs(res, capture), capture, design, cal)


def _calibrated(capture: Capture, calibration):
    """``(capture, calibration)``: the capture with the calibration applied, or as it is."""
    if calibration is None:
        return capture, None
    from .calibration import apply_calibration, load_calibration

    cal = load_calibration(calibration)
    return apply_calibration(capture, cal), cal


def _budget(res: InspectionResult, capture: Capture, design: Design, cal) -> InspectionResult:
    """The uncertainty budget's systematic terms (``rebarlib.uncertainty``), and the calibration."""
    from .uncertainty import apply_budget

    if cal is not None:
        res.extras["calibration"] = {**cal.to_dict(), "file": cal.source, "summary": cal.summary()}
    return apply_budget(
        res,
        design,
        device=capture.metadata.get("device"),
        calibration=cal,
        intrinsics=capture.intrinsics,
        depth_unit_mm=capture.depth_scale_mm,
    )


def _note_inputs(res: InspectionResult, capture: Capture) -> InspectionResult:
    """Notes on what the capture's files left to a default; the bar the capture was aimed at
    (``aim.json``), which the placing of a slab's captures uses (``_across``, decision 043)."""
    if capture.metadata.get("aimed_at"):
        res.extras["aimed_at"] = dict(capture.metadata["aimed_at"])
    if capture.metadata.get("depth_scale_assumed"):
        res.notes.append(
            f"camera.json gives no depth_scale_mm: {capture.depth_scale_mm:g} mm per depth unit was assumed"
        )
    return res


def _trimmed(capture: Capture, px: int) -> Capture:
    if not px:
        return capture
    return dataclasses.replace(capture, depth_mm=trim_edge_fattening(capture.depth_mm, px))


def _add_diameters(
    res: InspectionResult, capture: Capture, design: Design, *, method, mask, mask_source, register, rng, refit=None
) -> InspectionResult:
    """``res`` with the diameter columns; ``refit(px)``: ``res`` fitted again on the depth
    trimmed by ``px`` (:func:`trim_edge_fattening`), called where the mask step measures an
    over-reach of the depth's bars beyond the colour's."""
    from .diameter import measure_diameters

    t = time.perf_counter()
    reg, given = None, mask is not None
    if not given:
        plane = None
        if res.formwork.get("found"):
            plane = (np.asarray(res.formwork["normal"], float), float(res.formwork["offset_mm"]))
        # the refined stage finds edges to a fraction of a pixel on the soft mask; the paper's
        # takes boundary pixels of the binary one
        refined = method == "refined"
        # the refined method also undoes a colour-depth misregistration (registered_mask); the
        # paper's takes the images as they come
        mask, capture, reg = _mask(
            capture,
            source=mask_source,
            plane=plane,
            model=None,
            rng=rng,
            soft=refined,
            tiled=refined,
            bar_width_px=widest_bar_px(capture, design) if refined else None,
            register=register,
        )
    else:
        mask = np.asarray(mask)
        if mask.shape != capture.depth_mm.shape:
            raise RebarInputError(f"mask: expected shape {capture.depth_mm.shape} (the capture's), got {mask.shape}")
    t_mask = time.perf_counter() - t
    reach = (reg or {}).get("depth_overreach_px") or 0
    if refit is not None and reach:
        res = refit(reach)
    res.extras["mask_source"] = "given" if given else mask_source
    if reg is not None:
        res.extras["registration"] = reg
        _note_registration(res, reg)
    res.timings_s["mask"] = t_mask
    t = time.perf_counter()
    if len(res.bars):
        dia = measure_diameters(capture, res.bars, mask, design=design, method=method)
        new = [c for c in dia.columns if c not in res.bars.columns or c == "bar_id"]
        res.bars = res.bars.merge(dia[new], on="bar_id", how="left")
        if method == "refined":
            _note_pixels_for_sizes(res, capture, design)
    res.timings_s["diameter"] = time.perf_counter() - t
    return res


def _note_pixels_for_sizes(res: InspectionResult, capture: Capture, design: Design) -> None:
    """One note for the bars left unsized by their widths where the capture's pixels put two
    neighbouring sizes too close (``rebarlib.diameter.closer.pixels_for_sizes``); its figures in
    ``res.extras["pixels_for_sizes"]``."""
    from .diameter.closer import pixels_for_sizes

    adv = pixels_for_sizes(res.bars, capture.intrinsics, system=design.bar_system, design=design)
    if adv is not None:
        res.extras["pixels_for_sizes"] = {k: v for k, v in adv.items() if k != "note"}
        res.notes.append(adv["note"])


def _note_registration(res: InspectionResult, reg: dict) -> None:
    if reg.get("depth_overreach_px"):
        res.notes.append(
            f"the depth image's bars reach {reg['depth_overreach_px']} px beyond "
            "the colour image's on every side (edge fattening): left out of the mask "
            "the diameters are read on"
        )
    if reg["shift_px"] is None:
        res.notes.append(
            "colour-depth registration could not be estimated (too few bars seen by both): "
            "the colour image was taken as aligned to the depth image"
        )
        return
    du, dv = reg["shift_px"]
    size = math.hypot(du, dv)
    if reg["applied"]:
        res.notes.append(
            f"the depth image lies ({du:+.1f}, {dv:+.1f}) px from the colour image: the colour "
            "image was moved onto it before the bars' diameters were measured"
        )
    if size > REGISTRATION_WARN_PX:
        res.notes.append(
            f"colour and depth misregistered by {size:.1f} px: check the camera's depth-to-colour alignment"
        )


def _top_cover(design: Design, upper_top: Measurement) -> Measurement:
    """The top cover predicted from the design's thickness and the measured top of the upper
    lattice (both methods)."""
    if design.thickness_mm is None:
        return Measurement.not_measured("the design gives no slab thickness")
    if not upper_top.ok:
        return Measurement.not_measured(f"top of the upper lattice not measured ({upper_top.reason})")
    return Measurement(design.thickness_mm - upper_top.value_mm, upper_top.uncertainty_mm, upper_top.n_points)


def _inspect_paper(capture: Capture, design: Design, rng) -> InspectionResult:
    from ._cloud import remove_outliers, voxel_downsample

    T = {}
    t = time.perf_counter()
    # not in the published procedure: is the formwork in view (and at a plausible distance)? The
    # paper's plane, with its wide RANSAC band (0.8 x cover), also takes a lattice for a plane,
    # so the test is the refined method's, on its own random stream (the paper's numbers stay
    # as they were); the paper's plane must then be that one
    ref_plane, ref_found, below = _formwork_of(capture, design, copy.deepcopy(rng))
    cloud = depth_to_points(capture.depth_mm, capture.intrinsics)
    cloud = voxel_downsample(cloud, PAPER_VOXEL_MM)
    cloud = remove_outliers(cloud, nb_neighbors=PAPER_NB, std_ratio=PAPER_STD)
    T["cloud"] = time.perf_counter() - t

    t = time.perf_counter()
    plane, inl = G.paper_fit_formwork(
        cloud.points, threshold_mm=PAPER_T1_FACTOR * design.cover_mm, max_trials=PAPER_PLANE_TRIALS, rng=rng
    )
    has_formwork = ref_found and _same_plane(ref_plane, plane, PAPER_T1_FACTOR * design.cover_mm)
    T["plane"] = time.perf_counter() - t

    t = time.perf_counter()
    rest = np.where(~inl)[0]
    q = G.to_slab_frame(cloud.points[rest], plane)
    keep = q[:, 2] > 0  # points under the formwork are noise
    rest, q = rest[keep], q[keep]
    lower = q[:, 2] < PAPER_T2_MM
    T["layers"] = time.perf_counter() - t

    t = time.perf_counter()
    notes = ["paper method: cover = m1 - 1.2 d_lower, layer distance = m2 - m1 (method.md stage 1)"]
    cover, layer_distance, upper_top = _paper_heights(q, lower, design, rng, notes)
    if not has_formwork:
        why = (
            f"no formwork visible in the capture: {below:.0%} of the points lie under the best plane "
            "(heights above it would be heights above the bars)"
        )
        cover = Measurement.not_measured(why)
        layer_distance = Measurement.not_measured(why + "; the paper's layer split t2 is a height above the formwork")
        upper_top = Measurement.not_measured(why)
        notes.append(why)
    T["cover"] = time.perf_counter() - t

    t = time.perf_counter()
    bars, clouds = _paper_bars(q, lower, rest, cloud, design, rng)
    T["bars"] = time.perf_counter() - t

    t = time.perf_counter()
    pts_by_layer = {"lower": q[lower], "upper": q[~lower]}
    spacings = G.paper_spacings(bars, pts_by_layer, design_spacing=_design_spacing(design), rng=rng)
    counts = G.count_bars(bars, design_spacing=_design_spacing(design))
    T["spacing"] = time.perf_counter() - t

    res = InspectionResult(
        capture=capture.name,
        method="paper",
        cover=cover,
        layer_distance=layer_distance,
        upper_top=upper_top,
        top_cover=_top_cover(design, upper_top),
        bars=G.bars_table(bars, plane),
        spacings=spacings,
        counts=counts,
        formwork={**plane.to_dict(), "found": bool(has_formwork)},
        camera=_camera_pose(plane) if has_formwork else {},
        timings_s=T,
        notes=notes,
        extras={"layer_split_mm": PAPER_T2_MM, "n_points": int(len(cloud))},
    )
    res.bar_points = {i: c for i, c in enumerate(clouds)}
    return res


def _paper_heights(q, lower, design: Design, rng, notes: list) -> tuple:
    """The paper's cover and layer distance from the mean heights of random samples of each
    lattice's points (cover = m1 - 1.2 d), and the top of the upper lattice (its heights' 99th
    percentile, which the paper does not measure)."""
    d_low = design.lower.bottom.diameter_mm
    ql, qu = q[lower], q[~lower]
    if len(ql) == 0:
        m1 = None
        cover = Measurement.not_measured("no point of the lower lattice (heights under t2 = 50 mm)")
    else:
        s1 = ql[rng.choice(len(ql), min(PAPER_SAMPLE, len(ql)), replace=False), 2]
        m1 = float(s1.mean())
        cover = Measurement(m1 - PAPER_COVER_FACTOR * d_low, float(s1.std() / math.sqrt(len(s1))), len(s1))
    if len(qu) == 0 or m1 is None:
        layer_distance = Measurement.not_measured("no point of one of the lattices")
        upper_top = Measurement.not_measured("no point of the upper lattice")
    else:
        s2 = qu[rng.choice(len(qu), min(PAPER_SAMPLE, len(qu)), replace=False), 2]
        layer_distance = Measurement(
            float(s2.mean()) - m1,
            float(math.hypot(s1.std() / math.sqrt(len(s1)), s2.std() / math.sqrt(len(s2)))),
            len(s1) + len(s2),
        )
        upper_top = Measurement(float(np.percentile(qu[:, 2], 99)), None, len(qu))
        notes.append(
            "paper method: top of the upper lattice is the 99th percentile of the upper heights "
            "(the paper does not measure it)"
        )
    return cover, layer_distance, upper_top


def _paper_bars(q, lower, rest, cloud, design: Design, rng) -> tuple:
    """The paper's bars of each lattice: sequential RANSAC lines, K-means directions, levels;
    (bars, the cloud of each)."""
    bars, clouds = [], []
    for lname, sel in (("lower", lower), ("upper", ~lower)):
        idx = np.where(sel)[0]
        if len(idx) < 10:
            continue
        d = design.lattice(lname).bottom.diameter_mm
        # t4: slightly more than half the design diameter (method.md): 0.5 d + 1 mm
        found = G.paper_find_bars(
            q[idx], layer=lname, threshold_mm=0.5 * d + 1.0, max_trials=PAPER_LINE_TRIALS, rng=rng
        )
        found = G.group_directions(found, rng=rng)
        found = G.assign_levels(found)
        for b in found:
            clouds.append(cloud.subset(rest[idx[b.point_index]]))
        bars.extend(found)
    return bars, clouds
