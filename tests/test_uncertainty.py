"""The uncertainty budget (rebarlib.uncertainty), device profiles (rebarlib.devices) and the
decision rules in the verdict (rebarlib._decision, acceptance.evaluate).

The sensitivity coefficients are checked against the depth error model itself: points are
moved by a known depth scale / offset / stereo error and the change of a length or height is
compared with the coefficient times the error.
"""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

from rebarlib import Measurement, RebarInputError, evaluate, load_tolerances
from rebarlib._results import InspectionResult
from rebarlib import uncertainty as U
from rebarlib.devices import device_for, list_devices, load_device
from rebarlib.uncertainty import (
    COVERAGE_K,
    Inputs,
    apply_budget,
    combine,
    height_terms,
    inputs_for,
    length_terms,
    width_terms,
)

Z = 600.0  # working depth, mm
F = 616.4  # focal length, px


def _inputs(**kw) -> Inputs:
    base = dict(
        source="test",
        name="test",
        u_scale=0.0,
        u_offset_mm=0.0,
        u_quad_mm_per_m2=0.0,
        u_focal=0.0,
        u_pp_px=0.0,
        u_registration_px=0.0,
    )
    return Inputs(**{**base, **kw})


def _term(terms, name):
    return next(t for t in terms if t.name.startswith(name))


def _depth_error(z, s=0.0, o=0.0, k=0.0):
    """The depth a camera with these systematic errors reads for a true depth z (mm)."""
    return (1 + s) * z + o + k * (z / 1000.0) ** 2


def _backproject(u, v, z, f=F, c=(640.0, 400.0)):
    return np.array([(u - c[0]) * z / f, (v - c[1]) * z / f, z])


# ------------------------------------------------------------------------------------------------
# Device profiles
# ------------------------------------------------------------------------------------------------


def test_every_shipped_profile_loads_with_a_source_and_positive_limits():
    devices = list_devices()
    assert {
        "gemini2",
        "femto",
        "azure_kinect",
        "realsense_d405",
        "realsense_d435",
        "realsense_d455",
        "zed",
        "phone_lidar",
        "unknown",
    } <= set(devices)
    for key, p in devices.items():
        assert p.depth_percent > 0 and p.focal_percent > 0 and p.depth_source, key
        lim = p.depth_limits()
        assert lim["scale"] > 0 or lim["quad_mm_per_m2"] > 0, key


@pytest.mark.parametrize(
    "device, key",
    [
        ("rebarlib synthetic (Gemini-2-like)", "gemini2"),
        ("Orbbec Gemini 2", "gemini2"),
        ("Intel RealSense D435I", "realsense_d435"),
        ("Intel(R) RealSense(TM) Depth Camera 455", "unknown"),
        ("RealSense D455", "realsense_d455"),
        ("Orbbec Femto Bolt", "femto"),
        ("Azure Kinect DK", "azure_kinect"),
        ("iPhone 13 Pro", "phone_lidar"),
        ("ZED 2i", "zed"),
        ("", "unknown"),
        (None, "unknown"),
    ],
)
def test_device_strings_pick_their_profile(device, key):
    prof, matched = device_for(device)
    assert prof.key == key and matched == (key != "unknown")


def test_stereo_profile_error_grows_with_distance_as_the_datasheet_says():
    # Gemini 2: 2 % of the distance at 2 m (k z²: 40 mm at 2 m), 0.5 % constant scale
    lim = load_device("gemini2").depth_limits()
    assert lim["quad_mm_per_m2"] * 2.0**2 == pytest.approx(0.02 * 2000)
    assert lim["scale"] == pytest.approx(0.005)
    # ToF: 0.1 % of the distance plus 11 mm
    tof = load_device("azure_kinect").depth_limits()
    assert tof == {"scale": pytest.approx(0.001), "offset_mm": 11.0, "quad_mm_per_m2": 0.0}


def test_unknown_device_name_is_an_error_only_when_asked_for_by_name():
    with pytest.raises(RebarInputError, match="no profile matches"):
        load_device("my own camera")
    assert inputs_for("my own camera").default_profile


def test_inputs_are_rectangular_standard_uncertainties_of_the_limits():
    i = inputs_for(profile="azure_kinect")
    assert i.u_offset_mm == pytest.approx(11.0 / math.sqrt(3))
    assert i.u_scale == pytest.approx(0.001 / math.sqrt(3))
    assert i.u_focal == pytest.approx(0.003 / math.sqrt(3))


# ------------------------------------------------------------------------------------------------
# Sensitivity coefficients against the error model
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("field, err", [("u_scale", 0.01), ("u_offset_mm", 5.0), ("u_quad_mm_per_m2", 20.0)])
def test_length_sensitivities_match_the_depth_error_model(field, err):
    # two points 200 mm apart across the line of sight at depth Z, read through the error
    L = 200.0
    a, b = np.array([-L / 2, 0, Z]), np.array([L / 2, 0, Z])
    kw = {"u_scale": "s", "u_offset_mm": "o", "u_quad_mm_per_m2": "k"}[field]
    za = _depth_error(Z, **{kw: err})
    moved = np.linalg.norm(b * za / Z - a * za / Z)  # each point slides along its ray
    terms = length_terms(L, 0.0, _inputs(**{field: err}), depth_mm=Z, tilt_deg=0.0, focal_px=F)
    assert combine(terms) == pytest.approx(abs(moved - L), rel=1e-6)


@pytest.mark.parametrize(
    "field, err, first_order", [("u_scale", 0.01, True), ("u_offset_mm", 5.0, True), ("u_quad_mm_per_m2", 20.0, False)]
)
def test_height_sensitivities_match_the_depth_error_model(field, err, first_order):
    # a height along the line of sight: two depths h apart, read through the error
    h = 85.0
    kw = {"u_scale": "s", "u_offset_mm": "o", "u_quad_mm_per_m2": "k"}[field]
    moved = _depth_error(Z, **{kw: err}) - _depth_error(Z - h, **{kw: err})
    terms = height_terms(h, 0.0, _inputs(**{field: err}), depth_mm=Z - h / 2, tilt_deg=0.0)
    # k z² is linearised at the middle of the height: exact for a quadratic
    assert combine(terms) == pytest.approx(abs(moved - h), rel=1e-6, abs=1e-9)


def _tilted_plane(tilt_deg: float, D: float):
    """A formwork plane seen from a camera D above it, tilted by ``tilt_deg`` about the x axis:
    its unit normal (towards the camera) and a function giving plane points at (x, y) offsets
    from the camera's foot."""
    t = math.radians(tilt_deg)
    n = np.array([0.0, math.sin(t), -math.cos(t)])
    e1, e2 = np.array([1.0, 0.0, 0.0]), np.cross(n, [1.0, 0.0, 0.0])
    return n, lambda x, y: -D * n + np.multiply.outer(x, e1) + np.multiply.outer(y, e2)


def _read_with_stereo_error(p, k):
    """Points read through a stereo error k (mm/m²): each depth z becomes z + k (z / 1 m)²,
    the point sliding along its ray."""
    z = p[..., 2:3]
    return p * (z + k * (z / 1000.0) ** 2) / z


@pytest.mark.parametrize("tilt", [0.0, 15.0])
@pytest.mark.parametrize("half", ["whole", "left", "far"])
def test_stereo_sensitivity_follows_the_refitted_formwork_plane(tilt, half):
    """A stereo error k z² read on the capture's own geometry: the formwork's points are read
    through it and the plane fitted again (over the whole view, or only part of it: a depth
    is linear over a plane, so the refitted plane does not depend on where its inliers lie);
    each bar's top is read through it too, and its height above the new plane changes by k
    times ``stereo_sensitivity``. The old slope ``2 z h`` at the bars' depth is off by up to
    10 %."""
    from rebarlib.geometry import fit_formwork

    D, k = 550.0, 2.0
    n, at = _tilted_plane(tilt, D)
    rng = np.random.default_rng(3)
    x, y = rng.uniform(-250, 250, 4000), rng.uniform(-180, 180, 4000)
    if half == "left":
        x = -np.abs(x)
    elif half == "far":
        y = np.abs(y) + 60
    formwork = at(x, y)
    # one bar per level (its axis at mid-extent, envelope radius r): lower bottom, upper bottom, upper top
    levels = [("lower", "bottom", 23.1, 8.1, (30.0, -40.0)), ("upper", "bottom", 106.95, 6.95, (-60.0, 20.0))]
    levels.append(("upper", "top", 120.85, 6.95, (10.0, 90.0)))
    axes = np.array([at(*xy) + h * n for *_, h, _, xy in levels])
    r = np.array([lv[3] for lv in levels])
    bars = pd.DataFrame(
        {
            "layer": [lv[0] for lv in levels],
            "level": [lv[1] for lv in levels],
            "status": ["measured"] * 3,
            "start_z_mm": axes[:, 2],
            "end_z_mm": axes[:, 2],
            "axis_height_mm": [lv[2] for lv in levels],
            "radius_mm": r,
            "underside_mm": [lv[2] - lv[3] for lv in levels],
        }
    )
    res = InspectionResult(
        "A",
        "refined",
        *[Measurement.not_measured("-")] * 4,
        bars,
        None,
        formwork={"normal": n.tolist(), "offset_mm": D, "found": True},
    )
    before, _ = fit_formwork(formwork, threshold_mm=5.0, rng=0)
    after, _ = fit_formwork(_read_with_stereo_error(formwork, k), threshold_mm=5.0, rng=0)
    tops = axes + r[:, None] * n
    moved = after.height(_read_with_stereo_error(tops, k)) - before.height(tops)
    got = {key: U.stereo_sensitivity(res, key) for key in ("cover", "layer_distance", "upper_top")}
    assert k * got["cover"] == pytest.approx(moved[0], rel=5e-3)
    assert k * got["layer_distance"] == pytest.approx(moved[1] - moved[0], rel=5e-3)
    assert k * got["upper_top"] == pytest.approx(moved[2], rel=5e-3)
    if tilt:  # the old slope at the bars' median depth: 2 z h, h the top's height
        old = 2 * np.median(tops[:, 2]) * (levels[0][2] + r[0]) / 1e6
        assert abs(old / got["cover"] - 1) > 0.04


def test_stereo_sensitivity_needs_the_formwork_and_the_bars(paper_design):
    """Without a formwork plane found, or without the bars' axes (the paper method, an older
    result), the budget takes the slope 2 z h at the working depth, and says which it used."""
    dev = "rebarlib synthetic (Gemini-2-like)"
    res = _fitted(paper_design, [20.0] * 3, [105.0] * 3, [132.0] * 4)
    res.bars["axis_height_mm"] = res.bars["underside_mm"] + res.bars["radius_mm"]
    assert U.stereo_sensitivity(res, "cover") is None  # no formwork in the result
    res.formwork = {"normal": [0.0, 0.0, -1.0], "offset_mm": 650.0, "found": True}
    derived = {key: U.stereo_sensitivity(res, key) for key in ("cover", "layer_distance", "upper_top")}
    assert all(v is not None and v > 0 for v in derived.values())
    apply_budget(res, paper_design, device=dev)
    for key, v in derived.items():
        m = res.extras["uncertainty"]["measurements"][key]
        assert m["stereo_sensitivity"] == "formwork plane and bar depths"
        stereo = next(t for t in m["terms"] if t["term"].startswith("depth non-linearity"))
        assert stereo["sensitivity"] == pytest.approx(v, rel=1e-5)
    old = apply_budget(_fitted(paper_design, [20.0] * 3, [105.0] * 3, [132.0] * 4), paper_design, device=dev)
    assert old.extras["uncertainty"]["measurements"]["cover"]["stereo_sensitivity"] == "2 z h at the working depth"
    res.method = "paper"
    assert U.stereo_sensitivity(res, "cover") is None


def test_focal_length_stretches_lengths_not_heights_seen_square_on():
    u_f = 0.004
    L = 200.0
    # a point pair imaged through a lens whose focal length is (1 + u_f) x the one written
    uv = [(640 - L / 2 * F * (1 + u_f) / Z, 400), (640 + L / 2 * F * (1 + u_f) / Z, 400)]
    a, b = (_backproject(u, v, Z) for u, v in uv)
    lt = length_terms(L, 0.0, _inputs(u_focal=u_f), depth_mm=Z, tilt_deg=0.0, focal_px=F)
    assert combine(lt) == pytest.approx(np.linalg.norm(b - a) - L, rel=1e-9)
    ht = height_terms(85.0, 0.0, _inputs(u_focal=u_f), depth_mm=Z, tilt_deg=0.0)
    assert combine(ht) == 0.0
    ht20 = height_terms(85.0, 0.0, _inputs(u_focal=u_f), depth_mm=Z, tilt_deg=20.0)
    assert combine(ht20) == pytest.approx(85.0 * u_f * math.sin(math.radians(20)) ** 2)


def test_combined_is_the_root_sum_of_squares_and_keeps_the_random_term():
    terms = height_terms(85.0, 0.3, _inputs(u_scale=0.004), depth_mm=Z, tilt_deg=0.0, envelope_mm=0.15)
    expected = math.sqrt(0.3**2 + (85 * 0.004) ** 2 + 0.15**2)
    assert combine(terms) == pytest.approx(expected)
    assert _term(terms, "fits").kind == "random" and _term(terms, "depth scale").kind == "systematic"


def test_registration_reaches_a_width_through_the_pixel_size():
    t = width_terms(13.9, 0.0, _inputs(), depth_mm=Z, tilt_deg=0.0, focal_px=F, registration_px=0.5)
    assert combine(t) == pytest.approx(0.5 / math.sqrt(3) * Z / F)


# ------------------------------------------------------------------------------------------------
# The budget applied to a result
# ------------------------------------------------------------------------------------------------


def _result(paper_design, device_bars_z=600.0) -> InspectionResult:
    bars = pd.DataFrame(
        {
            "bar_id": [0, 1, 2],
            "layer": ["lower"] * 3,
            "level": ["bottom"] * 3,
            "start_z_mm": [device_bars_z] * 3,
            "end_z_mm": [device_bars_z] * 3,
            "axis_se_mm": [0.1, 0.2, 0.1],
            "status": ["measured"] * 3,
            "width_used_mm": [16.1, 16.3, 13.8],
            "width_sigma_mm": [0.2, 0.2, 0.2],
        }
    )
    spacings = pd.DataFrame(
        {
            "layer": ["lower"] * 2,
            "level": ["bottom"] * 2,
            "bar_a": [0, 1],
            "bar_b": [1, 2],
            "spacing_mm": [199.0, 203.0],
            "design_spacing_mm": [200.0, 200.0],
            "deviation_mm": [-1.0, 3.0],
            "status": ["measured"] * 2,
            "reason": ["", ""],
        }
    )
    return InspectionResult(
        "A",
        "refined",
        Measurement(20.4, 0.05, 500),
        Measurement(85.3, 0.07, 900),
        Measurement(125.0, 0.06, 400),
        Measurement.not_measured("no thickness"),
        bars,
        spacings,
        camera={"height_mm": 650.0, "tilt_deg": 10.0},
    )


def test_apply_budget_keeps_every_value_and_records_every_term(paper_design):
    res = _result(paper_design)
    before = (
        res.cover.value_mm,
        res.layer_distance.value_mm,
        res.spacings["spacing_mm"].tolist(),
        res.bars["width_used_mm"].tolist(),
    )
    apply_budget(res, paper_design, device="rebarlib synthetic (Gemini-2-like)", intrinsics=None)
    assert (
        res.cover.value_mm,
        res.layer_distance.value_mm,
        res.spacings["spacing_mm"].tolist(),
        res.bars["width_used_mm"].tolist(),
    ) == before
    ub = res.extras["uncertainty"]
    assert ub["k"] == COVERAGE_K and ub["inputs"]["name"] == "Orbbec Gemini 2"
    cover = ub["measurements"]["cover"]
    assert {t["term"] for t in cover["terms"]} >= {
        "fits (random)",
        "depth scale",
        "focal length",
        "rib envelope (spread between mills)",
        "assumed bar shape",
    }
    assert res.cover.uncertainty_mm == pytest.approx(cover["u_mm"], abs=1e-4) and res.cover.uncertainty_mm > 0.05
    assert cover["U_mm"] == pytest.approx(2 * cover["u_mm"], abs=2e-4)
    # the depth errors act on what the camera sees: a lower bar's top (cover + its envelope,
    # Φ14: 16.2 mm), the upper bars' tops over the lower bars' (layer distance + 13.9 - 16.2)
    ld = {t["term"]: t["contribution_mm"] for t in ub["measurements"]["layer_distance"]["terms"]}
    cv = {t["term"]: t["contribution_mm"] for t in cover["terms"]}
    assert ld["depth scale"] == pytest.approx(cv["depth scale"] * (85.3 + 13.9 - 16.2) / (20.4 + 16.2), rel=1e-3)
    # the assumed shape moves both lattices' undersides alike: only the rib heights' difference
    # (Φ14 against Φ12) is left in the layer distance
    assert 0 < ld["assumed bar shape"] < 0.25 * cv["assumed bar shape"]
    # spacings: random from the two axes, plus the systematic terms
    u_sp = res.spacings["uncertainty_mm"].to_numpy()
    assert np.all(u_sp > math.hypot(0.1, 0.2))
    # widths: combined uncertainty and a confidence no higher than with the random term alone
    assert np.all(res.bars["width_uncertainty_mm"] > res.bars["width_sigma_mm"])
    assert res.bars["budget_confidence"].between(0, 1).all()
    assert not any("matches no device profile" in n for n in res.notes)


def test_unknown_device_uses_the_conservative_default_and_says_so(paper_design):
    known = apply_budget(_result(paper_design), paper_design, device="Orbbec Gemini 2")
    unknown = apply_budget(_result(paper_design), paper_design, device="a camera nobody knows")
    assert any("matches no device profile" in n for n in unknown.notes)
    assert unknown.extras["uncertainty"]["inputs"]["default_profile"]
    assert unknown.layer_distance.uncertainty_mm > known.layer_distance.uncertainty_mm


def _fitted(paper_design, lower, upper, tops, rms=0.8) -> InspectionResult:
    """A result whose bars table gives each level's measured bars (undersides) with their fits'
    residual RMS, and the stage's spread-based terms (0.9 mm: what the budget must not use)."""
    rows = [("lower", "bottom", u) for u in lower] + [("upper", "bottom", u) for u in upper]
    rows += [("upper", "top", t - 2 * 6.95) for t in tops]
    n = len(rows)
    bars = pd.DataFrame(
        {
            "bar_id": range(n),
            "layer": [r[0] for r in rows],
            "level": [r[1] for r in rows],
            "start_z_mm": [600.0] * n,
            "end_z_mm": [600.0] * n,
            "axis_se_mm": [0.02] * n,
            "underside_mm": [r[2] for r in rows],
            "radius_mm": [6.95] * n,
            "fit_rms_mm": [rms] * n,
            "status": ["measured"] * n,
        }
    )
    sp = pd.DataFrame(columns=["layer", "level", "bar_a", "bar_b", "spacing_mm", "status"])
    return InspectionResult(
        "A",
        "refined",
        Measurement(float(np.mean(lower)), 0.9, 500),
        Measurement(float(np.mean(upper) - np.mean(lower)), 0.9, 900),
        Measurement(float(np.mean(tops)), 0.9, 400),
        Measurement.not_measured("no thickness"),
        bars,
        sp,
        camera={"height_mm": 650.0, "tilt_deg": 10.0},
    )


def _random_terms(res, key):
    terms = {t["term"]: t for t in res.extras["uncertainty"]["measurements"][key]["terms"]}
    return terms["fits (random)"]["u_input"], terms["fits (common to a level)"]["u_input"]


def test_heights_random_term_is_the_fits_error_not_the_bars_spread(paper_design):
    """The measurand is the mean over the bars in view: their true height differences are no
    error of it. The random term is the fits' scatter over the square root of the count, plus
    the part common to a level, whatever the bars' spread."""
    share, common = U.BAR_FIT_SHARE_OF_RMS, U.LEVEL_FIT_COMMON_MM
    dev = "rebarlib synthetic (Gemini-2-like)"
    flat = apply_budget(_fitted(paper_design, [20.0] * 3, [105.0] * 3, [132.0] * 4), paper_design, device=dev)
    spread = apply_budget(
        _fitted(paper_design, [19.0, 20.0, 21.0], [103.5, 105.0, 106.5], [131.0, 132.0, 133.0, 132.0]),
        paper_design,
        device=dev,
    )
    for res in (flat, spread):
        assert _random_terms(res, "cover") == pytest.approx((share * 0.8 / math.sqrt(3), common), abs=1e-5)
        # the layer distance: both levels' scatter in quadrature, one common term
        assert _random_terms(res, "layer_distance") == pytest.approx((share * 0.8 * math.sqrt(2 / 3), common), abs=1e-5)
        assert _random_terms(res, "upper_top") == pytest.approx((share * 0.8 / 2, common), abs=1e-5)
    for key in ("cover", "layer_distance", "upper_top"):  # same means, spread or not: same u
        assert getattr(spread, key).uncertainty_mm == pytest.approx(getattr(flat, key).uncertainty_mm)
    # four times the fits' residual: four times their scatter, the common part unchanged
    noisy = apply_budget(_fitted(paper_design, [20.0] * 3, [105.0] * 3, [132.0] * 4, rms=3.2), paper_design, device=dev)
    assert _random_terms(noisy, "cover") == pytest.approx((share * 3.2 / math.sqrt(3), common), abs=1e-5)


def test_heights_keep_the_stages_term_without_the_bars_fits(paper_design):
    """Where the bars table does not give the fits' residuals (the paper method, scanned
    clouds) the stage's own random term is kept, and there is no common term."""
    res = apply_budget(_result(paper_design), paper_design, device="Orbbec Gemini 2")
    terms = {t["term"]: t for t in res.extras["uncertainty"]["measurements"]["cover"]["terms"]}
    assert terms["fits (random)"]["u_input"] == pytest.approx(0.05)
    assert "fits (common to a level)" not in terms


def test_derive_recovers_the_random_terms_constants(monkeypatch):
    """bench_coverage's estimator of the two constants, on errors drawn with known ones: bars
    scattering by 0.12 x their fit's RMS about a common error of 0.2 mm per level."""
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_coverage as bc

    rng = np.random.default_rng(5)
    bars, heights = [], []
    for c in range(400):
        n = int(rng.integers(2, 6))
        rms = rng.uniform(0.4, 1.2, n)
        e = rng.normal(0.0, 0.2) + rng.normal(0.0, 0.12 * rms)
        bars += [{"capture": c, "layer": "lower", "level": "bottom", "error": x, "fit_rms": r} for x, r in zip(e, rms)]
        u_bars = U.BAR_FIT_SHARE_OF_RMS * math.sqrt(float(np.sum(rms**2))) / n
        heights.append({"quantity": "cover", "residual": float(e.mean()), "u_bars": u_bars})
    d = bc.derive(pd.DataFrame(bars), pd.DataFrame(heights))
    assert d["share_of_rms"] == pytest.approx(0.12, rel=0.08)
    assert d["common_mm"] == pytest.approx(0.2, rel=0.12)


def test_coverage_interval_and_verdict(monkeypatch):
    """bench_coverage's per-set check: the share within 2u with its Clopper-Pearson interval (one
    value per capture), an effective n below n where several values share a capture, the
    verdict on the share as the issue states it, and the share a right budget predicts."""
    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_coverage as bc
    from scipy.stats import binomtest

    p, lo, hi, n_eff = bc.share_interval([True] * 36, range(36))
    assert (p, hi, n_eff) == (1.0, 1.0, 36.0)
    assert lo == pytest.approx(0.025 ** (1 / 36))  # 90.3 %: 36 of 36 cannot show <= 99.9 %
    p, lo, hi, _ = bc.share_interval([True] * 34 + [False] * 2, range(36))
    ci = binomtest(34, 36).proportion_ci(0.95, method="exact")
    assert (lo, hi) == (pytest.approx(ci.low), pytest.approx(ci.high))
    assert bc.verdict(p, lo, hi) == ("MISSED", "overlaps")  # 94.4 %
    # 10 values a capture, all within or all not together: as informative as the 20 captures
    # (19: the clusters' variance estimated with k - 1)
    w = [True] * 180 + [False] * 20
    _, _, _, n_eff = bc.share_interval(w, np.repeat(np.arange(20), 10))
    assert n_eff == pytest.approx(19.0)
    assert bc.verdict(0.97, 0.955, 0.985) == ("met", "inside")
    assert bc.verdict(1.0, 0.9995, 1.0) == ("too wide", "outside")
    # a normal error of u: 95.4 % within 2u; a rectangular one of u: all of it
    cols = {f"c {t}": 0.0 for t in bc.EXERCISED}
    df = pd.DataFrame([{"u": 1.0, "u_normal": 1.0, **cols}, {"u": 1.0, "u_normal": 0.0, **cols, "c depth scale": 1.0}])
    e = bc.expected_share(df, draws=20000)
    assert e[0] == pytest.approx(0.9545, abs=0.005) and e[1] == 1.0


def test_face_on_formwork_error(monkeypatch, capsys):
    """bench_coverage's face-on diagnostic: the plane's error is its depth on the optical axis
    less (1 + s)(h + k h²) + offset, only at tilt 0; a height read against the plane whose error
    is that plane error is explained by it, the layer distance is not read against it."""
    from types import SimpleNamespace

    monkeypatch.syspath_prepend(str(Path(__file__).resolve().parents[1] / "benchmarks"))
    import bench_coverage as bc

    errs = {"bias_mm_per_m2": 10.0, "depth_scale_error": 0.002, "depth_offset_mm": 0.0, "focal_error": 0.0}
    ideal = 1.002 * (600 + 10.0 * 0.36)
    res = SimpleNamespace(formwork={"found": True, "normal": [0.0, 0.0, -1.0], "offset_mm": ideal + 0.3})
    assert bc.formwork_error(res, ("d435-848", 15, 600, 0, 0.0, 0.0, 1, errs)) == pytest.approx(0.3)
    assert math.isnan(bc.formwork_error(res, ("d435-848", 15, 600, 5, 0.0, 0.0, 1, errs)))
    res.formwork["found"] = False
    assert math.isnan(bc.formwork_error(res, ("d435-848", 15, 600, 0, 0.0, 0.0, 1, errs)))

    rng = np.random.default_rng(3)
    rows = []
    for i in range(80):
        tilt = 0 if i % 2 else 10
        plane = rng.normal(0.0, 0.3) if tilt == 0 else math.nan
        x = {f"x {n}": rng.normal(0.0, 0.2) for n in bc.DRAWN.values()}
        e = sum(x.values()) + (plane if tilt == 0 else 0.0) + rng.normal(0.0, 0.05)
        rows.append({"quantity": "cover", "set": "s", "tilt": tilt, "error": e, "u": 0.4, "formwork_error": plane, **x})
        rows.append({**rows[-1], "quantity": "layer distance", "error": sum(x.values()) + rng.normal(0.0, 0.05)})
    t = bc.face_on(pd.DataFrame(rows)).set_index(["quantity", "set"])
    cover = t.loc[("cover", "all sets")]
    assert (cover["n face-on"], cover["n tilted"]) == (40, 40)
    assert cover["corr"] > 0.95 and cover["residual SD less plane"] < 0.08 < cover["residual SD face-on"]
    assert cover["stereo tilted"] == pytest.approx(1.0, abs=0.15)
    assert math.isnan(t.loc[("layer distance", "all sets")]["residual SD less plane"])
    assert "Face-on (tilt 0)" in capsys.readouterr().out


# ------------------------------------------------------------------------------------------------
# Decision rules
# ------------------------------------------------------------------------------------------------


def _meas(v, u):
    return {"value_mm": v, "uncertainty_mm": u, "n_points": 100, "status": "measured", "reason": ""}


def _slab(cover, u_cover, spacing=None, u_sp=None):
    r = {"capture": "A", "measurements": {"cover": _meas(cover, u_cover), "layer_distance": _meas(85.0, 0.3)}}
    if spacing is not None:
        r["spacings"] = [
            {
                "layer": "lower",
                "level": "bottom",
                "bar_a": 0,
                "bar_b": 1,
                "spacing_mm": spacing,
                "design_spacing_mm": 200.0,
                "deviation_mm": spacing - 200.0,
                "status": "measured",
                "reason": "",
                "uncertainty_mm": u_sp,
            }
        ]
    return r


def _cp(acc, item):
    return acc.checkpoints.set_index("item").loc[item]


def test_every_preset_names_simple_acceptance_and_design_can_override(paper_design):
    from dataclasses import replace

    for name in ("GB50204-2015", "ACI117-318", "EN13670-class1", "custom"):
        assert load_tolerances(name).decision_rule == "simple"
    d = replace(paper_design, tolerances={**paper_design.tolerances, "decision_rule": "guarded"})
    acc = evaluate([_slab(21.5, 0.3)], d)
    assert acc.tolerances.decision_rule == "guarded"
    with pytest.raises(RebarInputError, match="decision_rule"):
        evaluate([_slab(21.5, 0.3)], replace(paper_design, tolerances={"decision_rule": "lenient"}))


def test_simple_acceptance_marks_a_straddling_interval_but_keeps_the_verdict(paper_design):
    # GB 50204 slab cover ±3 mm on a 20 mm design (paper design): 22.6 is within, U = 0.8 straddles +3
    acc = evaluate([_slab(paper_design.cover_mm + 2.6, 0.4)], paper_design)
    c = _cp(acc, "cover")
    assert c["status"] == "within" and c["decision"] == "within, not proven"
    assert c["expanded_uncertainty"] == pytest.approx(0.8)
    # the chance it is out of tolerance: the normal tail beyond the limit, 0.4 / 0.4 = 1 sigma
    assert c["risk"] == pytest.approx(1 - 0.8413, abs=1e-3)
    assert acc.items.set_index("item").loc["cover", "not_proven"] == 1
    assert acc.items.set_index("item").loc["cover", "verdict"] == "pass"
    s = acc.decision_summary()
    assert s["rule"] == "simple" and s["within_not_proven"] == 1 and "50 %" in s["worst_case"]


def test_beyond_not_proven_and_a_clear_within(paper_design):
    acc = evaluate([_slab(paper_design.cover_mm + 3.3, 0.4)], paper_design)
    assert _cp(acc, "cover")["decision"] == "beyond, not proven" and _cp(acc, "cover")["status"] == "beyond"
    acc = evaluate([_slab(paper_design.cover_mm + 0.5, 0.4)], paper_design)
    assert _cp(acc, "cover")["decision"] == "within" and _cp(acc, "cover")["risk"] < 1e-6


def test_guarded_acceptance_narrows_the_limit_by_U(paper_design):
    from dataclasses import replace

    guarded = replace(paper_design, tolerances={**paper_design.tolerances, "decision_rule": "guarded"})
    # within by 0.4 mm < U = 0.8: accepted under simple acceptance, not under guarded acceptance
    simple = evaluate([_slab(paper_design.cover_mm + 2.6, 0.4)], paper_design)
    g = evaluate([_slab(paper_design.cover_mm + 2.6, 0.4)], guarded)
    assert _cp(simple, "cover")["status"] == "within" and _cp(g, "cover")["status"] == "beyond"
    assert _cp(g, "cover")["decision"] == "within, not proven"
    # its risk is now that of a false reject: the chance it is within after all
    assert _cp(g, "cover")["risk"] == pytest.approx(0.8413, abs=1e-3)
    # within by more than U: accepted under both
    g2 = evaluate([_slab(paper_design.cover_mm + 2.0, 0.4)], guarded)
    assert _cp(g2, "cover")["status"] == "within"


def test_proven_rule_rejects_only_beyond_the_limit_by_U(paper_design):
    from dataclasses import replace

    proven = replace(paper_design, tolerances={**paper_design.tolerances, "decision_rule": "proven"})
    # cover ±3 mm (GB 50204, slab): 3.3 mm beyond the design with U = 0.8 mm is beyond the limit by
    # 0.3 < U: rejected under simple acceptance, left open under "proven"
    s = evaluate([_slab(paper_design.cover_mm + 3.3, 0.4)], paper_design)
    p = evaluate([_slab(paper_design.cover_mm + 3.3, 0.4)], proven)
    assert s.items.set_index("item").loc["cover", "verdict"] == "fail" and s.verdict == "rejected"
    # simple acceptance rejects it on the measured side of the limit, and the sheet says it is not proven
    assert (
        "the checkpoint beyond lies beyond its limit by less than" in s.items.set_index("item").loc["cover", "reason"]
    )
    assert _cp(p, "cover")["status"] == "beyond" and _cp(p, "cover")["decision"] == "beyond, not proven"
    row = p.items.set_index("item").loc["cover"]
    assert row["verdict"] == "incomplete" and "not proven" in row["reason"] and "by hand" in row["reason"]
    assert p.verdict == "incomplete"
    # left open, so no false reject is expected of it (under simple acceptance: its 23 % chance of being within)
    assert p.decision_summary()["expected_false_rejects"] == 0.0
    assert s.decision_summary()["expected_false_rejects"] == pytest.approx(0.227, abs=0.01)
    # beyond by more than U (3.9 - 3 = 0.9 > 0.8): proven, rejected under both
    p2 = evaluate([_slab(paper_design.cover_mm + 3.9, 0.4)], proven)
    assert p2.items.set_index("item").loc["cover", "verdict"] == "fail" and p2.verdict == "rejected"
    assert "not proven" not in p2.items.set_index("item").loc["cover", "reason"]
    # within: accepted as under simple acceptance, also where it is within by less than U
    p3 = evaluate([_slab(paper_design.cover_mm + 2.6, 0.4)], proven)
    assert p3.items.set_index("item").loc["cover", "verdict"] == "pass"
    assert p3.decision_summary()["rule"] == "proven" and "left open" in p3.decision_summary()["worst_case"]


def test_proven_rule_judges_a_lot_on_its_proven_checkpoints(paper_design):
    from dataclasses import replace

    proven = replace(paper_design, tolerances={**paper_design.tolerances, "decision_rule": "proven"})

    def lot(values):
        r = _slab(20.0, 0.2, spacing=200.0, u_sp=1.0)
        one = r["spacings"][0]
        r["spacings"] = [
            {**one, "bar_a": k, "bar_b": k + 1, "spacing_mm": v, "deviation_mm": v - 200.0}
            for k, v in enumerate(values)
        ]
        return [r]

    def verdict(values, design):
        return evaluate(lot(values), design).items.set_index("item").loc["spacing_lower_bottom", "verdict"]

    # ±10 mm, at least 80 % within (GB 50204); U = 2 mm. 211 and 189 are beyond by 1 < U
    for values, simple, under_proven in (
        ([200, 201, 199, 211, 189], "fail", "incomplete"),  # 3/5; 5/5 with the two unproven
        ([200, 201, 199, 213, 189], "fail", "incomplete"),  # one proven beyond: 4/5 at most
        ([200, 201, 199, 213, 187], "fail", "fail"),  # both proven beyond: 3/5
        ([200, 201, 199, 200, 189], "pass", "pass"),  # 4/5 either way
    ):
        assert verdict(values, paper_design) == simple, values
        assert verdict(values, proven) == under_proven, values


def test_proven_rule_beyond_the_max_factor_only_where_proven():
    from rebarlib.acceptance import _judge_with_rule

    # ±10 mm, 1.5x = 15 mm: 15.5 mm with U = 2 is beyond the limit (proven) but not beyond 15 by U
    st, _, dec, _ = _judge_with_rule("spacing_lower_bottom", 15.5, 10.0, 10.0, 1.5, 2.0, None, "simple")
    assert st == "beyond max" and dec == "beyond"
    st, _, dec, _ = _judge_with_rule("spacing_lower_bottom", 15.5, 10.0, 10.0, 1.5, 2.0, None, "proven")
    assert st == "beyond" and dec == "beyond"
    st, _, _, _ = _judge_with_rule("spacing_lower_bottom", 17.5, 10.0, 10.0, 1.5, 2.0, None, "proven")
    assert st == "beyond max"
    from rebarlib._decision import check_rule

    assert check_rule(" Proven ", "design.toml") == "proven"


def test_spacing_uncertainty_reaches_the_checkpoints(paper_design):
    acc = evaluate([_slab(20.0, 0.2, spacing=208.5, u_sp=1.0)], paper_design)
    sp = acc.checkpoints[acc.checkpoints["item"] == "spacing_lower_bottom"].iloc[0]
    assert sp["uncertainty"] == 1.0 and sp["decision"] == "within, not proven"
