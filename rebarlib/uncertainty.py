"""The uncertainty budget of an inspection: every measured length's standard uncertainty,
term by term, in the GUM's way (docs/uncertainty.md).

The measurement stages give each value and its *random* standard uncertainty (the spread of
the fits); for cover, layer distance and top of the upper bars, the mean over the bars in view,
the budget takes the random term from the bars' fits instead (docs/decisions/022: the bars' true
height differences are not an error of that mean). :func:`apply_budget` adds the *systematic*
terms that no fit can see — the depth camera's depth scale, offset and non-linearity, its
focal length and principal point, the colour-depth registration, the spread of bars' rib
envelopes between mills and the assumed bar shape — each as a standard uncertainty ``u(x)`` of
an input, a sensitivity coefficient ``c`` and a contribution ``|c| u(x)``; the combined
standard uncertainty is the root sum of squares (the inputs taken as uncorrelated). The values
themselves are not changed.

The inputs come from a calibration file (``rebar calibrate``) where one is given, else from the
device profile that ``camera.json``'s ``device`` picks (``rebarlib/devices``); a datasheet limit
``a`` is read as a rectangular distribution, ``u = a / sqrt(3)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from .diameter.barsizes import ENVELOPE_SIGMA_MM, observed_width_mm, rib_height_mm, snap_diameter
from ._design import DEFAULT_BAR_SYSTEM
from ._results import InspectionResult, Measurement
from ._status import MEASURED
from .devices import device_for, load_device

__all__ = [
    "COVERAGE_K",
    "Inputs",
    "Term",
    "inputs_for",
    "height_terms",
    "length_terms",
    "width_terms",
    "stereo_sensitivity",
    "plane_resolution",
    "combine",
    "apply_budget",
]

#: Coverage factor of every expanded uncertainty U = k u printed (about 95 % for a normal error).
COVERAGE_K = 2.0
_SQRT3 = math.sqrt(3.0)
#: Half-width of the assumed-shape term, as a share of the rib height h: a cylinder of the rib
#: envelope fitted to a ribbed bar's visible top (crests and the core between them). Set from
#: the cover errors seen on captures rendered with ribs in relief (+0.06 to +0.17 mm on Φ12-Φ14,
#: h = 1.2-1.4 mm), not from a model.
SHAPE_SHARE_OF_RIB = 0.125
#: The fits' random term of a mean height (docs/decisions/022): a bar's fitted axis height is off
#: by more than the fit's formal standard error (its points' errors are not independent, and the
#: cross-section is not a perfect circle of the assumed radius). Per bar, the standard deviation
#: of the fitted height about its level's common error, as a share of the fit's residual RMS;
#: pooled over the bars of the training captures (``benchmarks/bench_coverage.py --derive``, seeds
#: 59 and 7: 0.148 over 1 192 bars in 285 levels of 72 captures; the held-out seed 2026 not used).
BAR_FIT_SHARE_OF_RMS = 0.15
#: The part of the fits' error common to every bar of a level (mm): what is left of a mean
#: height's error on the training captures once the drawn systematic errors (times the budget's
#: sensitivities) and the bars' own scatter are taken out (the noise bias left after the
#: cylinder fit's correction, the plane's fit, the edges). Same training captures: 0.142 mm over
#: 216 mean heights (cover, layer distance, top of the upper bars).
LEVEL_FIT_COMMON_MM = 0.14
#: The bar levels each mean height is read from (its difference, for the layer distance).
_HEIGHT_LEVELS = {
    "cover": (("lower", "bottom"),),
    "layer_distance": (("lower", "bottom"), ("upper", "bottom")),
    "upper_top": (("upper", "top"),),
}
#: Harmonics of the stored depth grid's rounding summed in :func:`plane_resolution` (the k-th
#: adds 1/k² of the face-on variance; those beyond are taken at the last one's size).
RESOLUTION_HARMONICS = 50
#: The name of the plane's depth-resolution term in a budget.
RESOLUTION_TERM = "depth resolution (formwork plane)"
#: Phase bins (per depth unit) of the plane's depths in :func:`plane_resolution`: a bin's width
#: lowers the 50th harmonic by 0.4 %.
_PHASE_BINS = 1024
#: Residual colour-depth misregistration (px) after ``inspect`` has estimated it: the estimate's
#: own error where the shift was undone, else the largest shift it leaves (REGISTRATION_MIN_PX).
REGISTRATION_RESIDUAL_PX = (0.4, 0.5)


@dataclass(frozen=True)
class Inputs:
    """Standard uncertainties of the systematic inputs, and where they come from."""

    source: str  # "device profile" | "calibration"
    name: str  # the profile's name or the calibration file
    u_scale: float  # relative
    u_offset_mm: float
    u_quad_mm_per_m2: float  # k of the stereo error k (z / 1 m)²
    u_focal: float  # relative
    u_pp_px: float
    u_registration_px: float
    default_profile: bool = False

    def to_dict(self) -> dict:
        return {k: (round(v, 6) if isinstance(v, float) else v) for k, v in self.__dict__.items()}


@dataclass(frozen=True)
class Term:
    """One line of a budget: input, its standard uncertainty (in ``unit``), sensitivity, contribution (mm)."""

    name: str
    kind: str  # "random" | "systematic"
    u_input: float
    unit: str
    sensitivity: float
    contribution_mm: float

    def to_dict(self) -> dict:
        return {
            "term": self.name,
            "kind": self.kind,
            "u_input": _r(self.u_input),
            "unit": self.unit,
            "sensitivity": _r(self.sensitivity),
            "contribution_mm": _r(self.contribution_mm),
        }


def _r(x, nd=6):
    return None if x is None or not math.isfinite(x) else round(float(x), nd)


def inputs_for(device: str | None = None, *, profile=None, calibration=None) -> Inputs:
    """The systematic inputs: from ``calibration`` (a ``Calibration``) where given, else from
    ``profile`` (a ``DeviceProfile`` or its key) or the profile ``device`` matches.

    Examples
    --------
    >>> i = inputs_for("rebarlib synthetic (Gemini-2-like)")
    >>> i.name, round(i.u_quad_mm_per_m2, 3), round(i.u_focal, 5)
    ('Orbbec Gemini 2', 5.774, 0.00289)
    """
    prof, matched = (load_device(profile), True) if profile is not None else device_for(device)
    reg = prof.registration_px / _SQRT3
    if calibration is not None:
        c = calibration
        K = c.intrinsics
        return Inputs(
            "calibration",
            c.source or "calibration",
            c.u_depth_scale,
            c.u_depth_offset_mm,
            0.0,
            max(c.u_intrinsics[0] / K.fx, c.u_intrinsics[1] / K.fy),
            max(c.u_intrinsics[2:4]),
            reg,
        )
    lim = prof.depth_limits()
    return Inputs(
        "device profile",
        prof.name,
        lim["scale"] / _SQRT3,
        lim["offset_mm"] / _SQRT3,
        lim["quad_mm_per_m2"] / _SQRT3,
        prof.focal_percent / 100 / _SQRT3,
        prof.principal_point_px / _SQRT3,
        reg,
        default_profile=not matched or prof.is_default,
    )


def _t(name, u, unit, c, kind="systematic") -> Term:
    return Term(name, kind, float(u), unit, float(c), abs(float(c) * float(u)))


def height_terms(
    h_mm: float,
    u_random_mm: float,
    inp: Inputs,
    *,
    depth_mm: float,
    tilt_deg: float,
    envelope_mm=0.0,
    rib_mm=0.0,
    common_mm=0.0,
    stereo_mm=None,
    resolution=None,
) -> list:
    """Budget of a height above the formwork (or a difference of two) whose seen part, the
    depth difference the camera measures, is ``h_mm`` (for an underside, the bar's top: the
    value plus the assumed envelope, which :func:`apply_budget` passes).

    A height is a depth difference: a depth scale error s changes it by ``s h``, an offset not
    at all. The stereo error ``k z²`` changes it by ``stereo_mm`` per mm/m² of k where given
    (:func:`stereo_sensitivity`: derived from the capture's formwork plane and its bars'
    depths), else by ``2 k z h``, its slope at the working depth ``depth_mm``. A focal-length
    error stretches the image's directions, so only the part of ``h`` across the line of
    sight, ``sin² tilt``, changes. ``envelope_mm``: standard uncertainty of
    the rib envelopes the height depends on (the underside = fitted axis minus the assumed
    envelope radius: sensitivity 1 on the envelope's diameter); ``rib_mm``: the rib height of
    the bars whose assumed shape the height depends on; ``common_mm``: the part of the fits'
    error common to the bars of a level (:data:`LEVEL_FIT_COMMON_MM`), where ``u_random_mm`` is
    the bars' own scatter only (:func:`apply_budget`); ``resolution``: ``(depth unit / sqrt(12),
    share)`` of a height read against the fitted formwork plane, the stored depth grid's rounding
    left in the plane's position (:func:`plane_resolution`; sensitivity 1 on the plane, the share
    on the grid's rounding of one depth).
    """
    h = abs(float(h_mm))
    z_m = depth_mm / 1000.0
    s2 = math.sin(math.radians(tilt_deg or 0.0)) ** 2
    return [
        _t("fits (random)", u_random_mm, "mm", 1.0, "random"),
        *([_t("fits (common to a level)", common_mm, "mm", 1.0, "random")] if common_mm else []),
        _t("depth scale", inp.u_scale, "1", h),
        _t("depth offset", inp.u_offset_mm, "mm", 0.0),
        _t(
            "depth non-linearity (stereo k z²)",
            inp.u_quad_mm_per_m2,
            "mm/m²",
            2 * z_m * h / 1000.0 if stereo_mm is None else stereo_mm,
        ),
        _t("focal length", inp.u_focal, "1", h * s2),
        _t("principal point", inp.u_pp_px, "px", 0.0),
        _t("rib envelope (spread between mills)", envelope_mm, "mm", 1.0 if envelope_mm else 0.0),
        _t("assumed bar shape", SHAPE_SHARE_OF_RIB * rib_mm / _SQRT3, "mm", 1.0 if rib_mm else 0.0),
        *([_t(RESOLUTION_TERM, resolution[0], "mm", resolution[1])] if resolution else []),
    ]


def length_terms(
    L_mm: float, u_random_mm: float, inp: Inputs, *, depth_mm: float, tilt_deg: float, focal_px: float
) -> list:
    """Budget of a length across the line of sight (a spacing), ``L_mm`` long, at ``depth_mm``.

    Lateral coordinates are ``z (u - c) / f``: a depth scale error s changes a length by ``s L``,
    an offset o by ``o L / z``, the stereo error ``k z²`` by ``k z L``, the focal length by
    ``L`` per unit; an error of the principal point shears the view by ``dc / f``, which
    changes a length in the tilted formwork plane by ``L sin(tilt) cos(tilt) dc / f``.
    """
    L = abs(float(L_mm))
    z = float(depth_mm)
    t = math.radians(tilt_deg or 0.0)
    return [
        _t("fits (random)", u_random_mm, "mm", 1.0, "random"),
        _t("depth scale", inp.u_scale, "1", L),
        _t("depth offset", inp.u_offset_mm, "mm", L / z),
        _t("depth non-linearity (stereo k z²)", inp.u_quad_mm_per_m2, "mm/m²", z / 1000.0 * L / 1000.0),
        _t("focal length", inp.u_focal, "1", L),
        _t("principal point", inp.u_pp_px, "px", L * math.sin(t) * math.cos(t) / focal_px),
    ]


def width_terms(
    w_mm: float,
    u_random_mm: float,
    inp: Inputs,
    *,
    depth_mm: float,
    tilt_deg: float,
    focal_px: float,
    registration_px: float,
) -> list:
    """Budget of a bar's width: a length (:func:`length_terms`) plus the colour-depth
    registration: the mask's edges come from the colour image and its extent from the depth, so
    a residual shift of ``registration_px`` widens or narrows the mask on one side by up to that
    (sensitivity: the pixel's size at ``depth_mm``)."""
    terms = length_terms(w_mm, u_random_mm, inp, depth_mm=depth_mm, tilt_deg=tilt_deg, focal_px=focal_px)
    return terms + [_t("colour-depth registration", registration_px / _SQRT3, "px", depth_mm / focal_px)]


def combine(terms) -> float:
    """Combined standard uncertainty: root sum of squares of the contributions (mm).

    Examples
    --------
    >>> combine([_t("a", 0.3, "mm", 1.0), _t("b", 0.004, "1", 100.0)])
    0.5
    """
    return float(math.sqrt(sum(t.contribution_mm**2 for t in terms)))


def _budget_dict(terms, value) -> dict:
    u = combine(terms)
    return {
        "value_mm": _r(value, 3),
        "u_mm": _r(u, 4),
        "k": COVERAGE_K,
        "U_mm": _r(COVERAGE_K * u, 4),
        "terms": [t.to_dict() for t in terms],
    }


def _working_depth(res: InspectionResult) -> float:
    bars = res.bars
    if bars is not None and len(bars) and "start_z_mm" in bars:
        z = np.concatenate([bars["start_z_mm"].to_numpy(float), bars["end_z_mm"].to_numpy(float)])
        z = z[np.isfinite(z)]
        if len(z):
            return float(np.median(z))
    return float((res.camera or {}).get("height_mm") or 600.0)


def _registration_residual(res: InspectionResult, inp: Inputs) -> float:
    reg = res.extras.get("registration")
    if not reg or reg.get("shift_px") is None:
        return inp.u_registration_px * _SQRT3  # not estimated: the device's limit
    if reg.get("applied"):
        return REGISTRATION_RESIDUAL_PX[0]
    return min(math.hypot(*reg["shift_px"]), REGISTRATION_RESIDUAL_PX[1])


def _level_fits_u(bars, key: str) -> float | None:
    """The fits' random term of mean height ``key`` ("cover", "layer_distance", "upper_top"),
    the mean over a level's measured bars in view (a difference of two for the layer distance):
    each bar's fitted height scatters by :data:`BAR_FIT_SHARE_OF_RMS` times its fit's residual
    RMS, so the mean of n bars by the root sum of squares over n. The bars' *true* height
    differences are not part of it: they are the measurand's, not an error of it. None where
    ``bars`` does not give every level's measured bars with their fits' residual (the paper
    method, scanned clouds): the stage's own term is kept there.

    Examples
    --------
    >>> import pandas as pd
    >>> bars = pd.DataFrame({"layer": ["lower"] * 4, "level": ["bottom"] * 4, "status": ["measured"] * 4,
    ...                      "underside_mm": [20.0, 20.5, 19.6, float("nan")], "fit_rms_mm": [0.8, 0.8, 0.8, 0.8]})
    >>> round(_level_fits_u(bars, "cover") / BAR_FIT_SHARE_OF_RMS, 4)  # 0.8 / sqrt(3)
    0.4619
    >>> _level_fits_u(bars, "upper_top") is None
    True
    """
    need = {"layer", "level", "status", "underside_mm", "fit_rms_mm"}
    if bars is None or not len(bars) or not need <= set(bars.columns):
        return None
    var = 0.0
    for layer, level in _HEIGHT_LEVELS[key]:
        g = bars[(bars["layer"] == layer) & (bars["level"] == level) & (bars["status"] == MEASURED)]
        rms = g["fit_rms_mm"].to_numpy(float)[np.isfinite(g["underside_mm"].to_numpy(float))]
        if not len(rms) or not np.isfinite(rms).all():
            return None
        var += float(np.sum((BAR_FIT_SHARE_OF_RMS * rms) ** 2)) / len(rms) ** 2
    return math.sqrt(var)


def _level_stereo(bars, layer: str, level: str, normal, z0: float) -> float | None:
    """Mean over a level's measured bars of d(axis height)/dk (mm per mm/m²), the first-order
    change of a bar's top, ``h (z + z0) / 10⁶``, at its top's height h above the formwork and
    depth z (:func:`stereo_sensitivity`); None where no bar of the level gives it."""
    g = bars[(bars["layer"] == layer) & (bars["level"] == level) & (bars["status"] == MEASURED)]
    g = g[np.isfinite(g["underside_mm"].to_numpy(float))]
    if not len(g):
        return None
    mid = (g["start_z_mm"].to_numpy(float) + g["end_z_mm"].to_numpy(float)) / 2
    r = g["radius_mm"].to_numpy(float)
    h = g["axis_height_mm"].to_numpy(float) + r  # the bar's top above the formwork
    z = mid + r * float(normal[2])  # its depth (the normal points at the camera)
    s = h * (z + z0) / 1e6
    return float(np.mean(s)) if np.isfinite(s).all() else None


def stereo_sensitivity(res: InspectionResult, key: str) -> float | None:
    """The change of mean height ``key`` ("cover", "layer_distance", "upper_top") per mm/m² of
    a stereo camera's depth error ``k z²``, derived from the capture's own geometry: its
    formwork plane and its bars' depths (docs/uncertainty.md, docs/decisions/033).

    The error ``k z²`` moves a point along its ray by the factor ``1 + k z / 10⁶`` (z in mm), so
    a point h above the plane (normal n towards the camera, the camera D above it) rises by
    ``k z (h - D) / 10⁶``. On the formwork (h = 0) that is ``-k D z / 10⁶``, and a depth z is
    linear over a plane: the formwork stays a plane, and the plane refitted to it (whatever its
    inliers) lies lower by ``k D z_f / 10⁶`` under each point, z_f the depth of the point's foot
    on the plane, ``z + h cos(tilt)``. A height above the refitted plane therefore changes by
    ``k h (z + D cos(tilt)) / 10⁶``: ``D cos(tilt)`` is the depth of the camera's foot on the
    plane. A bar's axis, fitted with a fixed radius, moves as the top it is fitted to; the mean
    height is the mean over its level's bars (the layer distance: the difference of two).

    None where the result does not give it (no formwork plane found, the paper method, no
    bars' axes and heights): :func:`apply_budget` then takes the slope ``2 z h`` at the working
    depth.

    Examples
    --------
    >>> import pandas as pd
    >>> bars = pd.DataFrame({"layer": ["lower"], "level": ["bottom"], "status": ["measured"],
    ...                      "start_z_mm": [584.0], "end_z_mm": [584.0], "axis_height_mm": [24.0],
    ...                      "radius_mm": [8.0], "underside_mm": [16.0]})
    >>> res = InspectionResult("A", "refined", *[Measurement.not_measured("-")] * 4, bars, None,
    ...                        formwork={"normal": [0.0, 0.0, -1.0], "offset_mm": 600.0, "found": True})
    >>> round(stereo_sensitivity(res, "cover") * 1e6)  # h = 32 mm, z = 576 mm: 32 (576 + 600)
    37632
    """
    fw, bars = res.formwork or {}, res.bars
    need = {"layer", "level", "status", "underside_mm", "start_z_mm", "end_z_mm", "axis_height_mm", "radius_mm"}
    if res.method != "refined" or not fw.get("found") or "normal" not in fw or bars is None:
        return None
    if not len(bars) or not need <= set(bars.columns):
        return None
    n = np.asarray(fw["normal"], float)
    z0 = float(fw["offset_mm"]) * abs(float(n[2]))
    each = [_level_stereo(bars, layer, level, n, z0) for layer, level in _HEIGHT_LEVELS[key]]
    if any(s is None for s in each):
        return None
    return each[1] - each[0] if key == "layer_distance" else each[0]  # layer distance: upper - lower


def plane_resolution(normal, offset_mm: float, intrinsics, depth_unit_mm: float) -> float:
    """The share of the stored depth grid's rounding left in a formwork plane fitted to a
    capture's depths: the plane's standard uncertainty from the depth's resolution is this share
    times ``depth_unit_mm / sqrt(12)`` (docs/uncertainty.md, docs/decisions/037).

    A depth image stores each depth on a grid of ``depth_unit_mm`` (``camera.json``'s
    ``depth_scale_mm``): a depth z is read as z + e(z), e the rounding, a sawtooth of period Δ =
    ``depth_unit_mm``, e(z) = sum over k >= 1 of (Δ / π k) (-1)^k sin(2π k z / Δ). The plane
    fitted to many depths moves by their mean rounding, which for depths whose phase on the grid
    is unknown (the grid's place against the true depths: a depth scale or offset error of a
    fraction of a unit moves it) has the variance ::

        u² = sum over k of (Δ / π k)² |φ(2π k / Δ)|² / 2

    with φ the characteristic function of the depths the plane's points are stored from (the
    quantisation theorem's mean, Widrow): ``|φ| = 1`` for a plane seen face-on, whose depths are all
    one and the same, and u is the rounding's own Δ / sqrt(12); a tilted plane spans many units
    over the image and its rounding averages out (``|φ|`` small). The share returned is u over
    Δ / sqrt(12), ``sqrt(6 / π² sum |φ_k|² / k²)`` over :data:`RESOLUTION_HARMONICS` harmonics
    (the rest at the last one's ``|φ|``).

    The depths taken are the plane's own over every pixel of the image (``intrinsics``) that
    sees it, with no noise: a stereo camera stores disparity steps, and noise that dithers the
    disparity before its step does not dither the depth grid after it, so the depths before
    the grid can be as few as the levels a plane seen face-on falls on. The disparity step is not
    in the device profiles; without it this is the bound, 1 face-on (fewer levels than one cannot
    be). Returns 1 where ``intrinsics`` is None (the view unknown: the bound).

    Examples
    --------
    >>> from rebarlib import GEMINI2
    >>> plane_resolution([0.0, 0.0, -1.0], 600.0, GEMINI2, 1.0)  # face-on: all depths one
    1.0
    >>> t = np.radians(10.0)  # tilted by 10°: about 200 mm of depths over the image
    >>> plane_resolution([0.0, np.sin(t), -np.cos(t)], 600.0, GEMINI2, 1.0) < 0.02
    True
    """
    unit = float(depth_unit_mm)
    if not unit > 0:
        return 0.0
    if intrinsics is None:
        return 1.0
    n = np.asarray(normal, float)
    K = intrinsics
    x = (np.arange(K.width) - K.cx) / K.fx
    y = (np.arange(K.height) - K.cy) / K.fy
    dot = n[0] * x[None, :] + n[1] * y[:, None] + n[2]  # normal · ray (z = 1)
    seen = dot < 0
    if not seen.any():
        return 1.0
    z = -float(offset_mm) / dot[seen]  # the plane's depth along each pixel's ray
    phase = np.floor(np.mod(z / unit, 1.0) * _PHASE_BINS).astype(np.int64)
    hist = np.bincount(np.clip(phase, 0, _PHASE_BINS - 1), minlength=_PHASE_BINS) / len(z)
    phi = np.abs(np.fft.fft(hist)[1 : RESOLUTION_HARMONICS + 1])
    k = np.arange(1, RESOLUTION_HARMONICS + 1)
    # the harmonics beyond the last taken at its |φ| (all of them 1 face-on)
    tail = math.pi**2 / 6 - float(np.sum(1.0 / k**2))
    return float(min(1.0, math.sqrt(6.0 / math.pi**2 * (float(np.sum(phi**2 / k**2)) + phi[-1] ** 2 * tail))))


def _with_u(m: Measurement, u: float) -> Measurement:
    return replace(m, uncertainty_mm=u) if m.ok else m


def apply_budget(
    res: InspectionResult,
    design,
    *,
    device: str | None = None,
    calibration=None,
    intrinsics=None,
    depth_unit_mm: float | None = None,
) -> InspectionResult:
    """Put the systematic terms into ``res``'s uncertainties (in place; returns ``res``).

    - cover, layer distance, top of the upper bars and top cover: ``uncertainty_mm`` becomes the
      combined standard uncertainty; its random terms are the bars' fits' scatter over their
      count and the part common to a level (:func:`_level_fits_u`), or the stage's own term
      where the bars table gives no fit residuals;
    - spacings: a new ``uncertainty_mm`` column (the two axes' standard errors and the
      systematic terms);
    - bars with a width: ``width_uncertainty_mm`` (combined) and ``budget_confidence``, the
      size's posterior with that uncertainty and the envelope table's spread
      (``snap_diameter``); the diameter stage's own ``confidence`` still decides whether a size
      is given;
    - cover and top of the upper bars (and top cover), read against the fitted formwork plane:
      the plane's depth resolution, the stored depth grid's rounding left in its position
      (:func:`plane_resolution`; ``depth_unit_mm``: ``camera.json``'s ``depth_scale_mm``, 1 mm
      where not given, as a capture read without it assumes); not the layer distance, a
      difference of two levels of bars;
    - ``res.extras["uncertainty"]``: the inputs, every measurement's terms, k;
    - a note where the device is unknown and the conservative profile was used.
    """
    inp = inputs_for(device, calibration=calibration)
    z = _working_depth(res)
    tilt = float((res.camera or {}).get("tilt_deg") or 0.0)
    f = float(intrinsics.fx) if intrinsics is not None else 616.0
    system = getattr(design, "bar_system", DEFAULT_BAR_SYSTEM)

    def deformed(layer):
        return getattr(design.lattice(layer).bottom, "surface", "deformed") != "plain"

    def env(layer):  # a plain bar has no rib envelope to spread
        return ENVELOPE_SIGMA_MM if deformed(layer) else 0.0

    def envelope(layer):  # the width a camera sees of the layer's bottom bars
        d = design.lattice(layer).bottom.diameter_mm
        return float(observed_width_mm(d, system=system, deformed=deformed(layer)))

    def rib(layer):
        if not deformed(layer):
            return 0.0
        d = design.lattice(layer).bottom.diameter_mm
        return rib_height_mm(observed_width_mm(d, system=system), system=system)

    geo = {"depth_mm": z, "tilt_deg": tilt}
    resolution = _plane_resolution(res, intrinsics, depth_unit_mm)
    out = {
        "k": COVERAGE_K,
        "inputs": inp.to_dict(),
        "working_depth_mm": round(z, 1),
        "tilt_deg": round(tilt, 2),
        "measurements": {},
    }
    specs = {
        "cover": dict(envelope_mm=env("lower"), rib_mm=rib("lower")),
        # the assumed shape moves both lattices' undersides the same way, in proportion to
        # their rib heights: in their difference only the difference of the rib heights is left
        "layer_distance": dict(
            envelope_mm=math.hypot(env("lower"), env("upper")), rib_mm=abs(rib("lower") - rib("upper"))
        ),
        "upper_top": {},
    }
    if resolution is not None:  # the heights read against the plane; the layer distance is not
        for key in ("cover", "upper_top"):
            specs[key]["resolution"] = (resolution["u_unit_mm"], resolution["share"])
    # what the camera sees of an underside is the bar's top: the depth errors act on the height
    # of that top, the assumed envelope is subtracted after (upper top: seen as it is)
    seen = {"cover": envelope("lower"), "layer_distance": envelope("upper") - envelope("lower"), "upper_top": 0.0}
    for key, extra in specs.items():
        m = getattr(res, key)
        if not m.ok:
            continue
        # the measurand is the mean over the bars in view: the fits' errors, not the bars' spread
        u_fits = _level_fits_u(res.bars, key)
        if u_fits is None:  # no per-bar fits to read (paper method, scanned clouds): the stage's term
            u_fits, common = m.uncertainty_mm or 0.0, 0.0
        else:
            common = LEVEL_FIT_COMMON_MM
        # the stereo term's sensitivity from this capture's plane and bars' depths, where it has them
        stereo = stereo_sensitivity(res, key)
        terms = height_terms(m.value_mm + seen[key], u_fits, inp, **geo, **extra, common_mm=common, stereo_mm=stereo)
        out["measurements"][key] = {
            **_budget_dict(terms, m.value_mm),
            "stereo_sensitivity": "2 z h at the working depth" if stereo is None else "formwork plane and bar depths",
        }
        setattr(res, key, _with_u(m, combine(terms)))
    if res.top_cover.ok and res.upper_top.ok:
        # top cover = design thickness - top of the upper bars: the same budget
        res.top_cover = _with_u(res.top_cover, res.upper_top.uncertainty_mm)
        out["measurements"]["top_cover"] = {
            **out["measurements"]["upper_top"],
            "value_mm": _r(res.top_cover.value_mm, 3),
        }
    if resolution is not None:
        out["plane_resolution"] = {k: _r(v) if isinstance(v, float) else v for k, v in resolution.items()}
    res.spacings = _spacing_budget(res, inp, z, tilt, f, out)
    res.bars = _width_budget(res, inp, z, tilt, f, system, out)
    res.extras["uncertainty"] = out
    if inp.default_profile:
        res.notes.append(
            f"device {device or '(none named)'!r} matches no device profile: the uncertainty budget "
            "uses the conservative default (3 % depth scale, 1 % focal length); calibrate the "
            "camera (rebar calibrate) for smaller uncertainties"
        )
    return res


def _plane_resolution(res: InspectionResult, intrinsics, depth_unit_mm) -> dict | None:
    """The formwork plane's depth-resolution term (:func:`plane_resolution`) as the budget records
    it, or None where the result has no fitted formwork plane."""
    fw = res.formwork or {}
    if not fw.get("found") or "normal" not in fw or "offset_mm" not in fw:
        return None
    unit = 1.0 if depth_unit_mm is None else float(depth_unit_mm)
    share = plane_resolution(fw["normal"], float(fw["offset_mm"]), intrinsics, unit)
    return {
        "depth_unit_mm": unit,
        "depth_unit_given": depth_unit_mm is not None,
        "u_unit_mm": unit / math.sqrt(12.0),
        "share": share,
        "u_mm": share * unit / math.sqrt(12.0),
        "disparity_step": "not in the device profile: the depths before the grid taken without noise (the bound)",
        "view": "the plane over the image" if intrinsics is not None else "unknown (no intrinsics): the bound",
    }


def _bar_depth(bars, i) -> float:
    row = bars.loc[bars["bar_id"] == i]
    if not len(row):
        return math.nan
    return float((row["start_z_mm"].iloc[0] + row["end_z_mm"].iloc[0]) / 2)


def _spacing_budget(res, inp, z, tilt, f, out):
    sp = res.spacings
    if sp is None:
        return sp
    sp = sp.copy()
    bars = res.bars
    se = dict(zip(bars["bar_id"], bars["axis_se_mm"])) if len(bars) and "axis_se_mm" in bars else {}
    us, rows = [], []
    for rec in sp.to_dict(orient="records"):
        v = rec.get("spacing_mm")
        if v is None or not np.isfinite(v):
            us.append(math.nan)
            continue
        a, b = (se.get(rec["bar_a"], math.nan), se.get(rec["bar_b"], math.nan))
        u_rand = math.hypot(*(x if np.isfinite(x) else 0.5 for x in (a, b)))
        zz = np.nanmean([_bar_depth(bars, rec["bar_a"]), _bar_depth(bars, rec["bar_b"])]) if len(bars) else z
        terms = length_terms(v, u_rand, inp, depth_mm=zz if np.isfinite(zz) else z, tilt_deg=tilt, focal_px=f)
        us.append(combine(terms))
        rows.append({"bar_a": int(rec["bar_a"]), "bar_b": int(rec["bar_b"]), **_budget_dict(terms, v)})
    sp["uncertainty_mm"] = np.asarray(us, float)
    out["spacings"] = rows
    return sp


def _width_budget(res, inp, z, tilt, f, system, out):
    bars = res.bars
    if bars is None or not len(bars) or "width_sigma_mm" not in bars:
        return bars
    bars = bars.copy()
    reg = _registration_residual(res, inp)
    wcol = "width_used_mm" if "width_used_mm" in bars else "width_mm"
    us, confs, rows = [], [], []
    for rec in bars.to_dict(orient="records"):
        w, u0 = rec.get(wcol), rec.get("width_sigma_mm")
        if w is None or not np.isfinite(w) or u0 is None or not np.isfinite(u0):
            us.append(math.nan)
            confs.append(math.nan)
            continue
        zb = (rec["start_z_mm"] + rec["end_z_mm"]) / 2
        terms = width_terms(
            w, u0, inp, depth_mm=zb if np.isfinite(zb) else z, tilt_deg=tilt, focal_px=f, registration_px=reg
        )
        u = combine(terms)
        us.append(u)
        confs.append(snap_diameter(w, system=system, sigma_mm=u)[1])
        rows.append({"bar_id": int(rec["bar_id"]), **_budget_dict(terms, w)})
    bars["width_uncertainty_mm"] = np.asarray(us, float)
    bars["budget_confidence"] = np.asarray(confs, float)
    out["widths"] = rows
    return bars


def profile_text(inp: Inputs) -> str:
    """How the systematic inputs were set, for the report: "factory calibration, device profile
    ..." or "calibrated: FILE"."""
    if inp.source == "calibration":
        return f"calibrated ({inp.name})"
    return f"factory calibration, device profile {inp.name}" + (" (no profile matched)" if inp.default_profile else "")
