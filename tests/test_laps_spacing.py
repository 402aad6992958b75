"""A lap seen in the point cloud: its spacings are taken from its middle (decision 071)."""

import numpy as np
import pytest

from rebarlib.geometry import BarAxis, measure_spacings
from rebarlib.geometry.bar_checks import _laps
from rebarlib.geometry.params import GeometryParams

R = 7.0  # the bars' radius (mm)
H = 30.0  # their axes' height
MIN_D = GeometryParams().lap_min_diameters  # the shortest lap seen, in diameters


def _surface(y_axis, x0, x1, *, h_axis=H, step=2.0):
    """Points on the upper half of a bar along x (what a camera above sees of it)."""
    x = np.arange(x0, x1, step)
    th = np.radians(np.arange(-70, 71, 10))
    xx, tt = np.meshgrid(x, th)
    return np.c_[xx.ravel(), y_axis + R * np.sin(tt.ravel()), h_axis + R * np.cos(tt.ravel())]


def _bar(y):
    return BarAxis("lower", np.array([1.0, 0.0]), y, 0.0, H, 0.0, 0.0, 600.0, R, 1000, 0.3, level="bottom")


def _shift(points, bar=None):
    (b,) = _laps([bar or _bar(0.0)], points[:, :2], points[:, 2], MIN_D)
    return b.lap_shift_mm


def test_a_bar_touching_the_fitted_one_alongside_is_a_lap():
    own = _surface(0.0, 0, 600)
    # the other bar of the lap touches it (axes two radii apart) over 400 mm, on either side
    for side in (1, -1):
        pts = np.r_[own, _surface(side * 2 * R, 100, 500)]
        assert _shift(pts) == pytest.approx(side * R, abs=0.5)


def test_a_lap_whose_other_bar_gives_a_third_of_the_points_is_still_a_lap():
    # the other bar's far flank seen edge-on, its points sparser: in a rendered capture they were
    # 35-40 % of the bar's own per station, and the lap had been missed (decision 073)
    pts = np.r_[_surface(0.0, 0, 600), _surface(2 * R, 100, 500)[::2]]
    assert _shift(pts) == pytest.approx(R, abs=0.5)


def test_a_line_fitted_through_both_pieces_of_a_lap_is_at_its_middle_already():
    # one piece at y = -R up to x = 400, the other at y = +R from x = 200, side by side between:
    # one straight line fitted through both lies at y = 0, the lap's middle, with a bar's points
    # touching it on each side over 200 mm; moved a radius either way it would be off by one
    pts = np.r_[_surface(-R, 0, 400), _surface(R, 200, 600)]
    assert _shift(pts) == 0.0


@pytest.mark.parametrize(
    "other",
    [
        # a bar alone
        np.zeros((0, 3)),
        # a crossing bar, tie or chair: one or two diameters beside it
        _surface(2 * R, 300, 325),
        # touching, but over less than the shortest lap seen (a short piece, not a lap)
        _surface(2 * R, 300, 300 + (MIN_D - 1) * 2 * R),
        # a strip beside it at ground level, as flying pixels at a bar's edge fall away
        _surface(2 * R, 0, 600, h_axis=H - 2 * R),
    ],
)
def test_nothing_else_beside_a_bar_is_a_lap(other):
    assert _shift(np.r_[_surface(0.0, 0, 600), other]) == 0.0


def test_a_lapped_bar_is_spaced_from_the_lap_s_middle():
    # design positions 200 mm apart; the lap's two bars straddle the middle position, touching:
    # the fit kept the one at 200 - R. Spaced to it, the spacings read 193 and 207 mm.
    pts = np.r_[_surface(0.0, 0, 600), _surface(200 - R, 0, 600), _surface(200 + R, 0, 600), _surface(400, 0, 600)]
    bars = _laps([_bar(0.0), _bar(200 - R), _bar(400.0)], pts[:, :2], pts[:, 2], MIN_D)
    assert [round(b.lap_shift_mm, 1) for b in bars] == [0.0, pytest.approx(R, abs=0.5), 0.0]
    t = measure_spacings(bars, design_spacing={("lower", "bottom"): 200.0})
    assert t.spacing_mm.tolist() == [pytest.approx(200.0, abs=0.5)] * 2
    assert (t.reason == "bar 1 lapped: taken at the middle of the lap").all()
    # without the lap seen, each spacing is off by a radius
    plain = measure_spacings([_bar(0.0), _bar(200 - R), _bar(400.0)], design_spacing={("lower", "bottom"): 200.0})
    assert plain.spacing_mm.tolist() == pytest.approx([200 - R, 200 + R])


def test_the_truth_spaces_a_lap_from_its_middle_too():
    from rebarlib.synth.truth import _spacings_truth

    def bar(i, off, partner=None):
        return {"id": i, "offset_mm": off, "lap_partner": partner, "visible": True}

    # positions at 0, 200, 400; the middle one lapped with Φ14 pieces (16.2 mm envelope) touching
    group = [bar(1, 0.0), bar(2, 200 - 8.1, 3), bar(3, 200 + 8.1, 2), bar(4, 400.0)]
    sp = _spacings_truth({("lower", "bottom"): group})
    assert [(s["bar_a"], s["bar_b"], s["spacing_mm"]) for s in sp] == [(1, 2, 200.0), (3, 4, 200.0)]


def test_the_truth_spaces_a_lone_piece_as_it_lies():
    """A capture that sees one piece of a lap and not the other (beyond the lap, or the other
    hidden) sees a bar where that piece lies: its truth spaces from that piece, on both sides,
    named by it (decision 071's definition; decision 076)."""
    from rebarlib.synth.truth import _spacings_truth

    def bar(i, off, partner=None, visible=True):
        return {"id": i, "offset_mm": off, "lap_partner": partner, "visible": visible}

    group = [bar(1, 0.0), bar(2, 200 - 8.1, 3), bar(3, 200 + 8.1, 2, visible=False), bar(4, 400.0)]
    sp = _spacings_truth({("lower", "bottom"): group})
    assert [(s["bar_a"], s["bar_b"], s["spacing_mm"]) for s in sp] == [(1, 2, 191.9), (2, 4, 208.1)]
    # neither piece seen: the position is still the lap's middle (and the spacings not visible)
    group = [bar(1, 0.0), bar(2, 200 - 8.1, 3, False), bar(3, 200 + 8.1, 2, False), bar(4, 400.0)]
    sp = _spacings_truth({("lower", "bottom"): group})
    assert [(s["bar_a"], s["bar_b"], s["spacing_mm"], s["visible"]) for s in sp] == [
        (1, 2, 200.0, False),
        (3, 4, 200.0, False),
    ]
