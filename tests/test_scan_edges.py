"""A scanned bar at the scan's edge: its position is "not measured" unless the cloud shows that it
goes on beyond the bar's cross-section (rebarlib/scan/_edges.py, decision 032)."""

from __future__ import annotations

import numpy as np
import pytest

from rebarlib import load_design
from rebarlib.scan import inspect_cloud
from rebarlib.scan._edges import EDGE_MARGIN_SIGMA, edge_beyond
from rebarlib.synth import Deviations, make_scene
from rebarlib.synth_scan import ScannerModel, Station, ring_stations, scan_scene, score_scan, synth_scan

DESIGN = "examples/paper_slab/design.toml"


@pytest.fixture(scope="module")
def design():
    return load_design(DESIGN)


def _cloud(g, edge_mm, sigma=10.0, n=40_000, strays=0):
    """Offsets across a bar (outward positive) of a cloud of uniform density from -300 mm out to
    ``edge_mm``, smeared by ``sigma``, with ``strays`` points scattered over ±400 mm."""
    u = g.uniform(-300.0, edge_mm, n) + g.normal(0.0, sigma, n)
    return np.r_[u, g.uniform(-400.0, 400.0, strays)]


@pytest.mark.parametrize("edge", [40.0, 60.0, 90.0])
def test_the_edge_is_found_where_the_cloud_ends(edge):
    g = np.random.default_rng(1)
    est, n_out, n_in = edge_beyond(_cloud(g, edge, strays=200), 7.0, 10.0, 120.0)
    assert abs(est - edge) < 4.0 and n_in > n_out > 0


def test_a_cloud_that_goes_on_and_one_that_ends_inside_the_section():
    g = np.random.default_rng(2)
    r, sig = 7.0, 10.0
    on, *_ = edge_beyond(_cloud(g, 600.0), r, sig, 120.0)
    assert on >= r + 2.5 * sig + 2.0 + 120.0  # beyond the windows: the cloud goes on
    for edge in (-3.0, 3.0, 7.0):  # the section cut (the edge inside the bar's radius)
        est, *_ = edge_beyond(_cloud(g, edge, strays=300), r, sig, 120.0)
        assert est < r + EDGE_MARGIN_SIGMA * sig, (edge, est)
    # no density to compare with on the inner side
    assert edge_beyond(np.full(10, 100.0), r, sig, 120.0) is None


@pytest.mark.slow
def test_a_bar_half_cut_by_the_scan_s_edge_is_not_measured(design):
    # the scan benchmark's sparse case at sigma 15 mm, seed 8: the lower lattice's last top bar
    # lies 2.8 mm inside the scanned square (radius 8.1 mm), so its cross-section beyond the
    # edge sends no returns; its axis was placed 4.6 mm inward and the spacing to it 5.2 mm off
    stations = ring_stations(2) + [Station((4000.0, -1500.0, 1500.0))]
    scanner = ScannerModel(range_sigma_mm=15.0, step_az_deg=0.24, step_el_deg=0.06)
    pts, truth, _ = synth_scan(design, stations=stations, scanner=scanner, rng=8)
    res = inspect_cloud(pts, design)
    bars = res.bars
    cut = bars[bars["status"] != "measured"]
    assert len(cut) == 1 and "scan's edge" in cut["reason"].iloc[0]
    row = cut.iloc[0]
    assert (row["layer"], row["level"]) == ("lower", "top")
    assert abs(0.5 * (row["start_x_mm"] + row["end_x_mm"]) + res.extras["cloud"]["offset_mm"][0] - 997.2) < 10
    sp = res.spacings
    not_measured = sp[sp["status"] != "measured"]
    assert len(not_measured) == 1 and "scan's edge" in not_measured["reason"].iloc[0]
    s = score_scan(res, truth)
    assert s["missed"] == 0 and s["phantoms"] == 0 and s["spacing_max_abs_err_mm"] <= 5.0, s


@pytest.mark.slow
def test_a_scan_cut_through_one_bar_and_clear_of_another(design):
    # the scan stops at x1 1.5 mm outside a bar running along y (its section cut) and at y1
    # 60 mm beyond the last bar running along x: only the first is not measured
    scene = make_scene(design, Deviations(), rng=np.random.default_rng(5))
    along_y = sorted((b for b in scene.bars if (b.layer, b.level) == ("upper", "top")), key=lambda b: b.offset_mm)
    along_x = sorted((b for b in scene.bars if (b.layer, b.level) == ("upper", "bottom")), key=lambda b: b.offset_mm)
    assert abs(along_y[0].direction[1]) > 0.99 and abs(along_x[0].direction[0]) > 0.99
    x_cut = along_y[5].offset_mm + 1.5
    y_cut = along_x[6].offset_mm + 60.0
    scanner = ScannerModel(range_sigma_mm=15.0, step_az_deg=0.1, step_el_deg=0.1)
    pts, truth, _ = scan_scene(scene, ring_stations(3), scanner, region=(-1000.0, x_cut, -1000.0, y_cut), rng=5)
    res = inspect_cloud(pts, design)
    off = np.asarray(res.extras["cloud"]["offset_mm"])
    bars = res.bars
    mid_x = 0.5 * (bars["start_x_mm"] + bars["end_x_mm"]) + off[0]
    mid_y = 0.5 * (bars["start_y_mm"] + bars["end_y_mm"]) + off[1]
    at_x = bars[(bars["layer"] == "upper") & (bars["level"] == "top") & (np.abs(mid_x - along_y[5].offset_mm) < 50)]
    at_y = bars[(bars["layer"] == "upper") & (bars["level"] == "bottom") & (np.abs(mid_y - along_x[6].offset_mm) < 50)]
    assert len(at_x) == 1 and at_x["status"].iloc[0] == "not measured", at_x
    assert len(at_y) == 1 and at_y["status"].iloc[0] == "measured", at_y
    s = score_scan(res, truth)
    assert s["missed"] == 0 and s["phantoms"] == 0 and s["spacing_max_abs_err_mm"] <= 5.0, s
