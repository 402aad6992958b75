"""A bar of which a nearer bar leaves only a strip, whose fixed-radius circle slid off the level
of the other bars of its direction, is "not measured" whatever arc its points cover
(rebarlib/geometry/bar_checks.py, ``_seen_in_parts``; docs/decisions/072)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from rebarlib.geometry.axis import BarAxis
from rebarlib.geometry.bar_checks import _seen_in_parts
from rebarlib.geometry.params import GeometryParams

R = 8.1  # a Φ14 bar's envelope radius


def _bar(offset, height, n_points, arc=120.0, *, t0=-300.0, t1=300.0, group=0):
    return BarAxis(
        "lower", np.array([1.0, 0.0]), offset, 0.0, height, 0.0, t0, t1, R, n_points, 1.0, group=group, arc_deg=arc
    )


def _row():
    # four bars seen whole: about 4 points per mm, axes at 43.6 ± 0.6 mm
    return [_bar(-400.0, 43.8, 2400), _bar(-200.0, 43.6, 2500), _bar(200.0, 44.2, 2300), _bar(400.0, 43.0, 2450)]


def test_a_strip_fitted_low_with_a_wide_arc_is_not_measured():
    # as on a rendered slab: a lower bar mostly under a parallel upper bar gave 626 points over
    # 950 mm (0.66 points/mm, typical 4.0), its circle 5.7 mm under the level with 160° of arc,
    # 12.6 mm off the bar across; its spacings then failed a clean slab's lot
    row, strip = _row(), _bar(0.0, 37.9, 400, arc=160.0)
    out = _seen_in_parts([*row, strip], 90.0, 200.0, GeometryParams())
    assert all(a is b for a, b in zip(out[:4], row))
    assert out[4].status == "not measured"
    assert "only a strip of the bar is seen" in out[4].reason and "-5.7 mm off" in out[4].reason


def test_a_strip_on_its_level_and_a_whole_bar_off_it_stay_measured():
    # a strip whose circle lies within half a radius of the level places its axis
    on_level = _bar(0.0, 41.0, 400, arc=150.0)
    assert _seen_in_parts([*_row(), on_level], 90.0, 200.0, GeometryParams())[4] is on_level
    # a bar seen whole (its points as dense as the others') 6 mm low is a finding, kept
    whole_low = _bar(0.0, 37.9, 2400, arc=120.0)
    assert _seen_in_parts([*_row(), whole_low], 90.0, 200.0, GeometryParams())[4] is whole_low
    # the level is that of the bar's own direction: a strip of the other direction at another
    # height, with no two other bars of its own, is not judged against this one
    other = _bar(0.0, 30.0, 400, arc=150.0, group=1)
    assert _seen_in_parts([*_row(), other], 90.0, 200.0, GeometryParams())[4] is other
    # the tolerance is a parameter
    strip = _bar(0.0, 37.9, 400, arc=160.0)
    loose = replace(GeometryParams(), sliver_level_radii=1.0)
    assert _seen_in_parts([*_row(), strip], 90.0, 200.0, loose)[4] is strip
