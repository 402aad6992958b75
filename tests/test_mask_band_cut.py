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


def _band_scene(band_height_mm):
    """A capture 600 mm over the formwork, looking down: the rebar mask is one band along the
    row's position 0 at the level's axis height; the band's pixels have depth at
    ``band_height_mm`` above the formwork (None: no depth), every other pixel the formwork."""
    from rebarlib._camera import project
    from rebarlib.geometry import from_slab_frame

    depth = np.full((INTR.height, INTR.width), 600.0)
    mask = np.zeros((INTR.height, INTR.width), bool)
    t, c = np.meshgrid(np.arange(-200.0, 200.0, 0.5), np.arange(-7.0, 7.01, 0.5))
    plan = t.ravel()[:, None] * ALONG + c.ravel()[:, None] * ACROSS
    cam = from_slab_frame(np.column_stack((plan, np.full(len(plan), ROW.height))), PLANE)
    uv = np.round(project(cam, INTR)).astype(int)
    mask[uv[:, 1], uv[:, 0]] = True
    depth[mask] = 0.0 if band_height_mm is None else 600.0 - band_height_mm
    return depth, mask


@pytest.mark.parametrize("band_height_mm, shows", [(None, True), (ROW.height + 7.0, True), (130.0, False)])
def test_the_mask_is_read_outside_a_nearer_surface_with_depth(band_height_mm, shows):
    # rebar in the mask over pixels whose depth shows something well above the bar's top is a
    # nearer bar the fit did not take (a lap's second piece over a lower position), not a bar at
    # this level; a band without depth, or at the bar's height, is read as before
    from rebarlib._evidence import _add_mask, _examine

    depth, mask = _band_scene(band_height_mm)
    foot = np.zeros(depth.shape, np.int32)
    ev = _examine(
        ROW,
        0.0,
        (-150.0, 150.0),
        plane=PLANE,
        depth=depth,
        intr=INTR,
        foot=foot,
        row_ids=[1],
        higher=[],
        noise=0.5,
        prm=CountParams(),
    )
    ev = _add_mask(ev, ROW, 0.0, mask, plane=PLANE, intr=INTR, foot=foot, prm=CountParams(), depth=depth, noise=0.5)
    assert bool(ev["_shows"][ev["_in_view"]].mean() > 0.9) is shows
    # without the depth the band is read as rebar wherever the mask has it
    ev = _add_mask(ev, ROW, 0.0, mask, plane=PLANE, intr=INTR, foot=foot, prm=CountParams())
    assert ev["_shows"][ev["_in_view"]].mean() > 0.9
