"""A bar beside a bar under it that has no depth (the projector's shadow): the mask runs on over
both, and the strip without depth reaches past the room the profile leaves beside the bar.

Seen on a verdict-benchmark capture (slab 715, ``C1_664``, Φ10 upper bar, 664 mm away): the
strip was not read as a sliver because its runs ran to the profile's end; the run was cut
where the bar's own grazing flank lost its depth, 1.6 px inside its edge, and the bar was
sized Φ8 at 0.98 (a false "wrong size"). docs/decisions/067-a-strip-past-the-profile-is-a-sliver.md
"""

from __future__ import annotations

import numpy as np

from rebarlib.diameter.params import DiameterParams
from rebarlib.diameter.runs import _holed_side

PRM = DiameterParams()
K = 41  # profile samples across the bar, ± one expected width
T = np.linspace(-11.6, 11.6, K)  # mm: a Φ10 bar's envelope (11.6 mm) each side of its axis
PX = np.full(30, 0.5)  # profile step in pixels (0.29 mm a sample at 1.18 mm a pixel)


def _runs(hi_strip_to_end: bool):
    """30 sections: the bar spans samples 10..30 (its edges at ± 5.8 mm); at the high side the
    mask goes on over a bar under it without depth, to the profile's end (K) or to sample 38."""
    n = len(PX)
    left = np.full(n, 9)  # the first non-bar sample below the run
    right = np.full(n, K if hi_strip_to_end else 38)
    left2 = left.copy()
    right2 = np.full(n, 28)  # cut where the depth ends: the bar's own flank lost 2 samples
    return left, right, left2, right2


def test_a_strip_without_depth_running_to_the_profile_end_is_a_sliver():
    left, right, left2, right2 = _runs(hi_strip_to_end=True)
    rows = np.ones(len(PX), bool)
    no_depth = np.ones((len(PX), K), bool)  # every rebar sample beside the bar without depth
    assert _holed_side(T, left, right, left2, right2, rows, PX, PRM, hollow=no_depth) == "hi"


def test_a_strip_with_depth_past_the_profile_keeps_its_depth_step_as_the_edge():
    # a lower bar beside the bar, seen with its depth: the depth step is the bar's edge
    left, right, left2, right2 = _runs(hi_strip_to_end=True)
    rows = np.ones(len(PX), bool)
    assert _holed_side(T, left, right, left2, right2, rows, PX, PRM, hollow=np.zeros((len(PX), K), bool)) == ""
    assert _holed_side(T, left, right, left2, right2, rows, PX, PRM) == ""


def test_a_strip_ending_inside_the_profile_is_a_sliver_as_before():
    left, right, left2, right2 = _runs(hi_strip_to_end=False)
    rows = np.ones(len(PX), bool)
    assert _holed_side(T, left, right, left2, right2, rows, PX, PRM) == "hi"


def test_a_bar_whose_edges_lose_a_pixel_on_both_sides_is_no_sliver():
    n = len(PX)
    left, right = np.full(n, 9), np.full(n, 31)
    left2, right2 = np.full(n, 11), np.full(n, 29)  # one pixel of each flank without depth
    assert _holed_side(T, left, right, left2, right2, np.ones(n, bool), PX, PRM) == ""


def test_a_run_over_the_whole_profile_is_not_read():
    n = len(PX)
    left, right = np.full(n, -1), np.full(n, K)  # a crossing bar: mask across the whole profile
    left2, right2 = np.full(n, 9), np.full(n, 28)
    hollow = np.ones((n, K), bool)
    assert _holed_side(T, left, right, left2, right2, np.ones(n, bool), PX, PRM, hollow=hollow) == ""
