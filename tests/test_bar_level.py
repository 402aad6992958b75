"""A bar far off its direction's level is no bar of it: the level is the median of the bars'
axis heights weighted by the length each is seen over (rebarlib/geometry/bar_checks.py,
``_off_their_level``; docs/decisions/064)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from rebarlib.geometry.axis import BarAxis
from rebarlib.geometry.bar_checks import _off_their_level, _weighted_median
from rebarlib.geometry.params import GeometryParams


def _bar(height, t0, t1, offset, *, group=0):
    return BarAxis("lower", np.array([1.0, 0.0]), offset, 0.0, height, 0.0, t0, t1, 9.2, 500, 1.0, group=group)


def test_weighted_median():
    assert _weighted_median([1.0, 2.0, 3.0], [1, 1, 1]) == 2.0
    assert _weighted_median([39.7, 20.5], [460, 55]) == 39.7
    assert _weighted_median([39.7, 20.5], [55, 460]) == 20.5
    assert _weighted_median([10.0, 20.0], [1, 1]) == 10.0  # a tie: the lower one


def test_a_short_stretch_fitted_low_beside_a_long_bar_is_left_out():
    # as seen on a D435-like noisy capture from 390 mm: the mixed pixels along a lower bar's
    # silhouette fitted as a 55 mm bar 19 mm under the 460 mm bar of its direction. The plain
    # median of the two (30.1 mm) kept both (1.5 radii: 13.8 mm); weighted by length it is 39.7 mm
    long_bar, stretch = _bar(39.74, -230.0, 230.0, 0.0), _bar(20.5, 100.0, 155.0, 400.0)
    kept = _off_their_level([long_bar, stretch], {0: 9.2}, 9.2, GeometryParams())
    assert kept == [long_bar]
    # a bar of the other direction is judged against its own direction's bars only
    other = _bar(20.5, 100.0, 155.0, 400.0, group=1)
    assert _off_their_level([long_bar, other], {0: 9.2, 1: 9.2}, 9.2, GeometryParams()) == [long_bar, other]


def test_bars_within_the_tolerance_of_the_level_are_kept_and_a_sliver_above_is_not_measured():
    bars = [_bar(40.0, -200, 200, 0.0), _bar(43.0, -200, 200, 200.0), _bar(38.0, -50, 50, 400.0)]
    assert _off_their_level(bars, {0: 9.2}, 9.2, GeometryParams()) == bars
    sliver = _bar(60.0, -60, 60, 600.0)  # 17 mm above the level, 43 mm (tolerance 13.8 mm): a sliver
    out = _off_their_level([*bars, sliver], {0: 9.2}, 9.2, GeometryParams())
    assert out[:3] == bars and out[3].status == "not measured" and "above the other bars" in out[3].reason


def test_a_direction_with_no_bar_measured_keeps_a_level_of_its_own():
    """With no bar of a direction measured, its level comes from its bars' approximate heights;
    before, it was named "bottom" beside the other direction's bottom bars, and the lattice's two
    directions were counted as one row (a D435-like capture from 696 mm: "15 found" on the
    lower bottom level, the top level "no bar found")."""
    from rebarlib.geometry.levels import assign_levels

    top_dir = [replace(_bar(48.0 + k, -200.0, 200.0, 200.0 * k), status="not measured") for k in range(3)]
    bottom_dir = [
        replace(_bar(36.0, -200.0, 200.0, 200.0 * k, group=1), direction=np.array([0.0, 1.0])) for k in range(3)
    ]
    for bars in (top_dir + bottom_dir, top_dir + [replace(b, status="not measured") for b in bottom_dir]):
        levels = {(b.group, b.level) for b in assign_levels(bars)}
        assert levels == {(0, "top"), (1, "bottom")}
    # one direction alone is the bottom level, measured or not
    assert {b.level for b in assign_levels(top_dir)} == {"bottom"}
