"""The formwork plane's depth-resolution term of the uncertainty budget
(rebarlib.uncertainty.plane_resolution, docs/decisions/037): the stored depth grid's rounding that
a plane fitted to a capture's depths keeps, pinned against planes quantised here."""

from __future__ import annotations

import math

import numpy as np
import pandas as pd
import pytest

from rebarlib import GEMINI2, Intrinsics, Measurement
from rebarlib._results import InspectionResult
from rebarlib.uncertainty import RESOLUTION_TERM, apply_budget, plane_resolution

#: a small image, so that every pixel's depth can be rounded here
SMALL = Intrinsics(fx=160.0, fy=160.0, cx=79.5, cy=49.5, width=160, height=100)


def _normal(tilt_deg: float, about_deg: float = 90.0) -> np.ndarray:
    """A formwork's normal towards the camera, tilted by ``tilt_deg`` towards the image's
    direction ``about_deg`` from its x axis."""
    t, a = math.radians(tilt_deg), math.radians(about_deg)
    return np.array([math.sin(t) * math.cos(a), math.sin(t) * math.sin(a), -math.cos(t)])


def _depths(normal, offset_mm: float, K: Intrinsics) -> np.ndarray:
    x = (np.arange(K.width) - K.cx) / K.fx
    y = (np.arange(K.height) - K.cy) / K.fy
    return (-offset_mm / (normal[0] * x[None, :] + normal[1] * y[:, None] + normal[2])).ravel()


def _mean_rounding_sd(z: np.ndarray, unit: float, phases: int = 400) -> float:
    """The SD, over the grid's place against the depths (a common shift c of every depth,
    uniform over one unit), of the mean rounding error of the depths stored on the grid."""
    out = []
    for c in (np.arange(phases) + 0.5) / phases * unit:
        zc = z + c
        out.append(float(np.mean(np.round(zc / unit) * unit - zc)))
    return float(np.sqrt(np.mean(np.square(out))))


@pytest.mark.parametrize("tilt", [0.0, 0.02, 0.05, 0.1, 0.3, 2.0])
@pytest.mark.parametrize("unit", [1.0, 0.25])
def test_term_is_the_mean_rounding_of_the_planes_stored_depths(tilt, unit):
    """The share times unit / sqrt(12) is the SD of the mean rounding of the plane's depths over
    the image, stored on the grid, over the grid's unknown place (the quantisation theorem's
    mean, summed over its harmonics). Tilted obliquely to the pixel grid: a plane tilted along
    the rows of so small an image has its depths on a comb of a hundred rows, whose harmonics
    beyond those summed are not the last one's."""
    n = _normal(tilt, about_deg=29.0)
    got = plane_resolution(n, 600.0, SMALL, unit) * unit / math.sqrt(12)
    want = _mean_rounding_sd(_depths(n, 600.0, SMALL), unit)
    assert got == pytest.approx(want, rel=0.03, abs=2e-4)


def test_face_on_keeps_the_whole_rounding_a_tilted_plane_averages_it_out():
    assert plane_resolution(_normal(0.0), 600.0, GEMINI2, 1.0) == pytest.approx(1.0)
    assert plane_resolution(_normal(0.0), 420.0, SMALL, 1.0) == pytest.approx(1.0)
    shares = [plane_resolution(_normal(t), 600.0, GEMINI2, 1.0) for t in (0.05, 0.2, 1.0, 5.0, 15.0)]
    assert shares[0] < 0.5 and max(shares[1:]) < 0.1
    # the view unknown: the bound; no grid: nothing
    assert plane_resolution(_normal(10.0), 600.0, None, 1.0) == 1.0
    assert plane_resolution(_normal(0.0), 600.0, GEMINI2, 0.0) == 0.0


def test_bound_holds_for_a_face_on_plane_through_disparity_steps():
    """A stereo camera's face-on plane: noisy disparities, rounded to 1/8 px, then the depth
    stored on a 1 mm grid (as rebarlib.synth's sensor does). The grid's rounding left in the
    mean of the stored depths, over planes at depths the grid meets anywhere, is within the
    face-on term (unit / sqrt(12)), and not averaged out as a tilted plane's is: the depths fall
    on a few levels, each rounded once (here about half the bound is left: three levels 1.5 mm
    apart carry most of the depths)."""
    rng = np.random.default_rng(3)
    fb = 616.0 * 50.0
    left = []
    for depth in rng.uniform(550.0, 650.0, 300):
        disp = fb / depth + 0.08 * rng.normal(size=4000)
        z = fb / (np.round(disp * 8) / 8)
        left.append(float(np.mean(np.round(z) - z)))
    sd = float(np.sqrt(np.mean(np.square(left))))
    term = plane_resolution(_normal(0.0), 600.0, GEMINI2, 1.0) / math.sqrt(12)
    assert 0.3 * term < sd <= term


def _result(tilt_deg: float, found: bool = True) -> InspectionResult:
    bars = pd.DataFrame(columns=["bar_id", "layer", "level", "status", "start_z_mm", "end_z_mm"])
    n = _normal(tilt_deg)
    return InspectionResult(
        "A",
        "refined",
        Measurement(20.4, 0.05, 500),
        Measurement(85.3, 0.07, 900),
        Measurement(125.0, 0.06, 400),
        Measurement.not_measured("no thickness"),
        bars,
        pd.DataFrame(columns=["bar_a", "bar_b", "spacing_mm"]),
        formwork={"normal": n.tolist(), "offset_mm": 600.0, "found": found},
        camera={"height_mm": 600.0, "tilt_deg": tilt_deg},
    )


def _resolution_term(res, key):
    terms = res.extras["uncertainty"]["measurements"][key]["terms"]
    return next((t for t in terms if t["term"] == RESOLUTION_TERM), None)


def test_budget_puts_the_term_on_heights_read_against_the_plane(paper_design):
    dev = "rebarlib synthetic (Gemini-2-like)"
    face_on = apply_budget(_result(0.0), paper_design, device=dev, intrinsics=GEMINI2, depth_unit_mm=1.0)
    for key in ("cover", "upper_top", "top_cover") if face_on.top_cover.ok else ("cover", "upper_top"):
        t = _resolution_term(face_on, key)
        assert t["contribution_mm"] == pytest.approx(1 / math.sqrt(12), abs=1e-4)
    # the layer distance, a difference of two levels of bars, is not read against the plane
    assert _resolution_term(face_on, "layer_distance") is None
    rec = face_on.extras["uncertainty"]["plane_resolution"]
    assert rec["share"] == pytest.approx(1.0) and rec["depth_unit_given"]
    # tilted: averaged out; a finer grid: proportionally less; no plane found: no term
    tilted = apply_budget(_result(10.0), paper_design, device=dev, intrinsics=GEMINI2, depth_unit_mm=1.0)
    assert _resolution_term(tilted, "cover")["contribution_mm"] < 0.01
    fine = apply_budget(_result(0.0), paper_design, device=dev, intrinsics=GEMINI2, depth_unit_mm=0.1)
    assert _resolution_term(fine, "cover")["contribution_mm"] == pytest.approx(0.1 / math.sqrt(12), abs=1e-5)
    none = apply_budget(_result(0.0, found=False), paper_design, device=dev, intrinsics=GEMINI2)
    assert _resolution_term(none, "cover") is None and "plane_resolution" not in none.extras["uncertainty"]
    # the unit not given: 1 mm, as a capture read without camera.json's depth_scale_mm
    assumed = apply_budget(_result(0.0), paper_design, device=dev, intrinsics=GEMINI2)
    assert not assumed.extras["uncertainty"]["plane_resolution"]["depth_unit_given"]
    want = math.hypot(tilted.cover.uncertainty_mm, 1 / math.sqrt(12))
    assert face_on.cover.uncertainty_mm == pytest.approx(want, rel=0.02)
