"""A bar placed from the colour mask whose band ends at a nearer bar's pixels along most of its
length is placed, but not stated to an accuracy: the band's middle is the middle of the part
showing beside that bar, not the bar's (rebarlib/_position_verdict.py, ``_present``;
docs/decisions/075)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from rebarlib._camera import Intrinsics
from rebarlib._counts import CountParams
from rebarlib._evidence import _Row
from rebarlib._position_verdict import _present
from rebarlib._status import PRESENT_NO_DEPTH
from rebarlib.geometry import BarAxis, Plane

PLANE = Plane(np.array([0.0, 0.0, -1.0]), 600.0)
INTR = Intrinsics(616.0, 616.0, 640.0, 400.0, 1280, 800)
ALONG, ACROSS = np.array([1.0, 0.0]), np.array([0.0, 1.0])
NEIGHBOUR = BarAxis("lower", ALONG, -200.0, 0.0, 30.0, 0.0, -300.0, 300.0, 7.0, 900, 0.5, level="top")
ROW = _Row("lower", "top", [NEIGHBOUR], [0], np.array([-200.0]), 200.0, 30.0, 0.5, 7.0, ALONG, ACROSS)


def _evidence(cut_every: int):
    """60 slices 5 mm apart showing the band, its centre line steady 0.3 mm off the position;
    the band's end meets a found bar's pixels on every ``cut_every``-th slice (0: none)."""
    t = np.arange(-150.0, 150.0, 5.0)
    cut = np.zeros(len(t), bool)
    if cut_every:
        cut[::cut_every] = True
    return {"_t": t, "_centre": np.full(len(t), 0.3), "_nd_edge": np.zeros(len(t), bool), "_cut": cut}


@pytest.mark.parametrize("cut_every, stated", [(0, True), (3, True), (1, False)])
def test_a_band_cut_by_a_nearer_bar_over_most_of_it_places_the_bar_without_a_stated_place(cut_every, stated):
    ev = _evidence(cut_every)
    sel = np.ones(len(ev["_t"]), bool)
    rec = _present(ROW, 0.0, ev, sel, PLANE, INTR, CountParams(), {}, PRESENT_NO_DEPTH, "")
    assert rec["status"] == PRESENT_NO_DEPTH and rec["_bar"]  # it counts as found either way
    if stated:  # a third of the slices cut (crossing bars): placed to a stated accuracy
        assert rec["position_sigma_mm"] < 1.5 and rec["offset_mm"] == pytest.approx(0.3)
    else:
        assert math.isnan(rec["position_sigma_mm"]) and math.isnan(rec["_new"].axis_se_mm)
        assert "ends at a nearer bar's pixels" in rec["reason"]
        assert "spacings are not measured" in rec["reason"]
