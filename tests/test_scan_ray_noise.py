"""One range noise along the rays for a set of bars, held by each bar's streak fit (decision 045).

A bar seen from one side lets its streak fit trade the noise against the axis's place along the
rays: on the held-out synthetic scan below (σ 15 mm, sparse, no formwork, seed 12) the lower
bottom set's last bar, seen from its inner side over its cover blocks, fitted 7.0 mm of noise
where its set's bars fitted 9.4-10.9 mm, and the fit put it 2.5 mm inward: the pair's spacing
erred 5.48 mm against the issue's 5 mm. One noise for the whole scan fixed that pair but moved a
bar over the formwork of a training scan (σ 15 mm, sparse, seed 17) 2.5 mm: the noise in a bar's
section depends on the rays' angle to the bar, which a set shares and the other direction does
not. Ground truth: the synthetic scanner's layout."""

import math

import numpy as np
import pytest

from rebarlib import load_design
from rebarlib.scan import inspect_cloud
from rebarlib.scan._axes import _set_ray_noise
from rebarlib.scan._sides import seen_sides_centre
from rebarlib.synth_scan import ScannerModel, Station, ring_stations, score_scan, synth_scan

DESIGN = "examples/paper_slab/design.toml"


def _streak(rng, n, r, phi_deg, sigma):
    """Points of a bar (axis at 0, 0) seen along ``phi_deg`` from the vertical: the half circle
    facing the ray, sampled ∝ cos² of the incidence, range noise along the ray."""
    phi = math.radians(phi_deg)
    psi = []
    while len(psi) < n:
        x = rng.uniform(-math.pi / 2, math.pi / 2, 4 * n)
        psi.extend(x[rng.random(4 * n) < np.cos(x) ** 2])
    psi = np.asarray(psi[:n]) + phi
    u = np.array([math.sin(phi), math.cos(phi)])
    p = r * np.column_stack([np.sin(psi), np.cos(psi)]) + rng.normal(0, sigma, n)[:, None] * u
    return p[:, 0], p[:, 1]


def test_the_noise_held_is_the_one_given():
    rng = np.random.default_rng(4)
    r = 7.0
    a, h = _streak(rng, 600, r, 50.0, 15.0)
    kw = dict(centre0=(a.mean(), h.mean() - 2 * r / math.pi), half_mm=r + 2.5 * 15 + 2)
    centre, sig, _ = seen_sides_centre(a, h, r, sigma0_mm=15.0, sigma_fixed=True, **kw)
    assert sig == 15.0
    assert abs(centre[0]) < 1.0  # the axis, not the points' mean (about 4.5 mm to the side)
    _, sig_free, _ = seen_sides_centre(a, h, r, sigma0_mm=9.0, **kw)
    assert sig_free != 9.0


def test_the_sets_noise_is_the_median_of_its_bars():
    weights = np.full(18, 1 / 18)
    fits = [(0.0, 0.0, s, weights) for s in (7.0, 11.0, 12.0, 12.5, 30.0)]
    assert _set_ray_noise(fits) == 12.0  # one one-sided bar's 7 mm, one crowded bar's 30 mm: no pull


@pytest.mark.slow
@pytest.mark.parametrize(
    ("seed", "formwork", "before"),
    [(12, False, 5.48), (17, True, 2.95)],  # held out (decision 042's "Left"); training
)
def test_sparse_scans_at_15_mm_spacing_within_5_mm(seed, formwork, before):
    """Worst spacing |err| with each bar's own noise ``before`` (mm); the issue's target is 5 mm
    at σ 15 mm (one noise for the scan: 2.22 and 5.52 mm). No bar missed, no phantom."""
    design = load_design(DESIGN)
    scanner = ScannerModel(range_sigma_mm=15.0, step_az_deg=0.24, step_el_deg=0.06)
    stations = ring_stations(2) + [Station((4000.0, -1500.0, 1500.0))]
    pts, truth, _ = synth_scan(design, stations=stations, scanner=scanner, formwork=formwork, rng=seed)
    s = score_scan(inspect_cloud(pts, design), truth)
    assert s["missed"] == 0 and s["phantoms"] == 0
    assert s["spacing_max_abs_err_mm"] <= 5.0
