"""A scanned "bar" must be seen over ``min_length_mm``: the length its returns cover, not the ends of
a run of cells; and between the crossings its returns must cover its stretches about as its set's
do (decision 042). Ground truth: the lattices are laid out here, each point known to be a bar's, a
chair's or a stray return.

Phantoms of the synthetic scans were runs whose ends lay 100 mm apart or more but whose returns
covered far less: a chair's column and a crossing bar's points 100 mm apart joined by one stray
return (the gaps on either side of it under the 60 mm closed as shadows); a chair's and a crossing
bar's returns 41 mm long in all, in two cells of 38 mm that made a run one cell short of 100 mm,
which counted; a chair half-way between two crossing bars, whose line held 68-79 % of its points
in their bands (under the 80 % that marks a line of crossing points) and covered a third of its
stretches between them."""

import numpy as np
import pytest

from rebarlib.scan._bars import _longest_extent, _seen_length, lattice_bars

R, SIGMA = 7.0, 5.0  # bar radius and noise, mm
SPACING = 200.0


def _bar_points(rng, axis, at, lo, hi, per_mm, h):
    """Returns of a bar along x (axis 0, at y = ``at``) or y (axis 1, at x = ``at``): uniform along,
    on its upper half-circle across and in height, with the noise."""
    n = int(per_mm * (hi - lo))
    along = rng.uniform(lo, hi, n)
    ang = rng.uniform(0.0, np.pi, n)
    across = at + R * np.cos(ang) + rng.normal(0.0, SIGMA, n)
    z = h + R * np.sin(ang) + rng.normal(0.0, SIGMA, n)
    xy = np.c_[along, across] if axis == 0 else np.c_[across, along]
    return np.c_[xy, z]


def _lower_lattice_with_a_chair(seed):
    """A lower lattice (bottom bars along y at x = 0 ... 1000, top bars along x at y = 0 ... 1000,
    3 returns per mm), a chair (a 5 mm rod standing on the top bars' level) at (95, 100), half-way
    between two top bars and between two bottom bars, and one stray return between the chair and
    the bottom bar at x = 200."""
    rng = np.random.default_rng(seed)
    parts = [_bar_points(rng, 1, x, -100.0, 1100.0, 3.0, 20.0) for x in np.arange(0.0, 1001.0, SPACING)]
    parts += [_bar_points(rng, 0, y, -100.0, 1100.0, 3.0, 34.0) for y in np.arange(0.0, 1001.0, SPACING)]
    n = 75
    a = rng.uniform(0.0, 2 * np.pi, n)
    chair = np.c_[
        95.0 + 5.0 * np.cos(a) + rng.normal(0.0, SIGMA, n),
        100.0 + 5.0 * np.sin(a) + rng.normal(0.0, SIGMA, n),
        rng.uniform(41.0, 70.0, n),
    ]
    stray = np.array([[140.0, 85.0, 55.0]])
    return np.vstack(parts + [chair, stray])


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
@pytest.mark.parametrize("stray", [True, False])
def test_a_chair_between_crossing_bars_is_not_a_bar(seed, stray):
    # before decision 042 a "bar" ran through the chair in every one of these clouds
    q = _lower_lattice_with_a_chair(seed)
    if not stray:
        q = q[:-1]
    found = lattice_bars(q, radius_mm={0: R, 1: R}, spacing_mm=SPACING, noise_mm=SIGMA, rng=0)
    offsets = np.array([abs(b.centre) for _, b in found])
    # every "bar" lies on a real one (offsets 0, 200, ... 1000); none on the chair's line (100)
    off_grid = np.abs((offsets + 0.5 * SPACING) % SPACING - 0.5 * SPACING)
    assert off_grid.max() < 20.0, sorted(offsets.round())
    assert len(found) == 12  # the six bars of each direction, none missed


def test_returns_a_cell_short_of_the_length_are_not_seen_over_it():
    # a chair's 7 returns within 6 mm and a crossing bar's 16 within 15 mm, 20 mm apart: a sparse
    # band's cells of 38 mm hold them in two cells, a run 76 mm long, which counted against
    # ``min_length_mm - cell`` (62 mm)
    rng = np.random.default_rng(0)
    t = np.r_[-759.5 + rng.uniform(0.0, 6.0, 7), -734.0 + rng.uniform(0.0, 15.0, 16)]
    cell = 38.2
    t0, t1, seen = _longest_extent(t, cell_mm=cell, max_gap_mm=max(60.0, 2 * cell))
    assert t1 - t0 >= 100.0 - cell  # the run's ends passed the old test
    assert seen < 100.0


def test_a_sparse_real_bar_scanned_over_the_length_is_seen_over_it():
    # one return every 13 mm over 110 mm; the band's cells hold three returns (39 mm)
    t = np.arange(0.0, 110.0, 13.0)
    t0, t1, seen = _longest_extent(t, cell_mm=39.0, max_gap_mm=78.0)
    assert seen >= 100.0


def test_a_shadow_closed_in_the_run_is_not_counted_as_seen():
    # returns every mm over 0-79 and 130-169 mm, a 51 mm shadow between: one run of 5 mm cells,
    # 170 mm long; each return covers the cell about it, 84 + 44 mm
    t = np.r_[np.arange(0.0, 80.0, 1.0), np.arange(130.0, 170.0, 1.0)]
    t0, t1, seen = _longest_extent(t, cell_mm=5.0, max_gap_mm=60.0)
    assert (t0, t1) == (0.0, 170.0)
    assert seen == pytest.approx((79.0 + 5.0) + (39.0 + 5.0))
    assert _seen_length(np.array([]), 5.0) == 0.0


def test_returns_at_one_place_between_the_crossings_cover_little_of_the_stretches():
    from rebarlib.scan._bars import _cover_between

    crossings = np.array([0.0, 200.0, 400.0])
    half = 30.0
    # a bar's returns all along (one every 4 mm): its stretches between the bands are covered
    bar = np.arange(-50.0, 450.0, 4.0)
    assert _cover_between(bar, crossings, half, -50.0, 450.0, 12.0) > 0.95
    # a chair's returns within 20 mm half-way between two crossings, a line through both bands
    chair = 90.0 + np.arange(0.0, 20.0, 1.0)
    assert _cover_between(chair, crossings, half, -30.0, 230.0, 12.0) < 0.3
    # the bands cover the whole extent: nothing to show
    assert _cover_between(np.array([]), crossings, half, -20.0, 20.0, 12.0) == 1.0
