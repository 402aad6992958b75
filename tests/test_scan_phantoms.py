"""A "bar" made of what lies at the crossings (the crossing bars' points, a cover block under the
bar beneath) is dropped; a real bar of a direction scanned ten times more sparsely than the
crossing one, which also holds most of its points at the crossings, is kept. Ground truth: the
lattice is laid out here, each point known to be a bar's or the block's.

Where the bars of the phantom's direction are scanned ten times more sparsely than the crossing
ones, the block's points beyond the crossing bar's band are as many per mm as a quarter of
theirs, and the phantom is kept: a limit of the rule (docs/scanned_clouds.md, Limits)."""

import numpy as np
import pytest

from rebarlib.scan._bars import _Bar, _crossing_free, _drop_phantoms

R, SIGMA = 7.0, 7.0  # bar radius and noise across, mm
HALF = R + 2.5 * SIGMA + 2.0  # a bar's band (and the crossing bars' bands)


def _bar_points(rng, axis, at, lo, hi, per_mm):
    """Points of a bar along x (axis 0, at y = ``at``) or y (axis 1, at x = ``at``), uniform
    along with ``per_mm`` points per mm, spread across by the radius and the noise."""
    n = int(per_mm * (hi - lo))
    along = rng.uniform(lo, hi, n)
    across = at + rng.uniform(-R, R, n) + rng.normal(0, SIGMA, n)
    return np.c_[along, across] if axis == 0 else np.c_[across, along]


def _bar(plan, direction, centre, t0, t1):
    """A found bar of ``direction`` whose points are every point of its band over its extent."""
    d = np.asarray(direction, float)
    n2 = np.array([-d[1], d[0]])
    t, off = plan @ d, plan @ n2
    idx = np.flatnonzero((np.abs(off - centre) < HALF) & (t >= t0) & (t <= t1))
    return _Bar(d, centre, 0.0, t0, t1, 0.0, len(idx), SIGMA, SIGMA, idx, 10.0)


def _lattice(sparse_per_mm):
    rng = np.random.default_rng(3)
    sparse_y = [0.0, 200.0, 400.0, 600.0, 800.0, 1000.0]  # bars along x
    dense_x = [100.0, 300.0, 500.0, 700.0, 900.0]  # bars along y, 2 points per mm
    parts = [_bar_points(rng, 0, y, 0.0, 1000.0, sparse_per_mm) for y in sparse_y]
    # the dense bars run on past the last sparse bar, to the scan's edge at y = 1150
    parts += [_bar_points(rng, 1, x, -50.0, 1150.0, 2.0) for x in dense_x]
    # a cover block (50 x 50 mm) under the dense bar at x = 500, 100 mm beyond the last sparse bar
    parts.append(np.c_[rng.uniform(475, 525, 60), rng.uniform(1075, 1125, 60)] + rng.normal(0, SIGMA, (60, 2)))
    plan = np.vstack(parts)
    real = [(0, _bar(plan, (1.0, 0.0), y, 0.0, 1000.0)) for y in sparse_y]
    real += [(1, _bar(plan, (0.0, 1.0), -x, -50.0, 1150.0)) for x in dense_x]
    # the "bar" the offsets' peak there makes: parallel to the sparse bars, 120 mm long about
    # the block (the crossing bar's points and the block's)
    phantom = (0, _bar(plan, (1.0, 0.0), 1100.0, 440.0, 560.0))
    return plan, real, phantom


@pytest.fixture(scope="module")
def lattice():
    """The bars along x scanned 2.5 times more sparsely than those along y."""
    return _lattice(0.8)


@pytest.fixture(scope="module")
def lattice_10x():
    """The bars along x scanned 10 times more sparsely than those along y."""
    return _lattice(0.2)


def test_a_sparse_real_bar_holds_most_of_its_points_at_the_crossings(lattice_10x):
    plan, real, _ = lattice_10x
    g, b = real[2]
    cross = [-x.centre for gg, x in real if gg == 1]
    inside = 1.0 - _crossing_free(plan[b.idx] @ b.direction, cross, HALF).mean()
    # expected about (2·53 + 0.2·53) / (2·53 + 0.2·200) = 0.80 per crossing spacing
    assert 0.7 < inside < 0.9


def test_crossing_points_and_a_block_are_dropped_real_bars_kept(lattice):
    plan, real, phantom = lattice
    found = real[:6] + [phantom] + real[6:]
    kept = _drop_phantoms(plan, found, {0: R, 1: R}, SIGMA)
    ids = {id(b) for _, b in kept}
    assert id(phantom[1]) not in ids
    assert all(id(b) in ids for _, b in real)


def test_real_bars_ten_times_sparser_than_the_crossing_ones_are_kept(lattice_10x):
    plan, real, phantom = lattice_10x
    kept = _drop_phantoms(plan, real, {0: R, 1: R}, SIGMA)
    assert len(kept) == len(real)


def test_without_crossing_bars_nothing_is_dropped(lattice):
    plan, real, phantom = lattice
    found = [x for x in real if x[0] == 0] + [phantom]
    assert len(_drop_phantoms(plan, found, {0: R, 1: R}, SIGMA)) == len(found)
