"""A bar seen only in colour, on lines of sight that a position of another level shares, is not
placed: without depth its height, and so which position it stands on, cannot be told
(rebarlib/_counts.py, ``_level_untold``; docs/decisions/074)."""

from __future__ import annotations

import numpy as np

from rebarlib._counts import _level_untold, _line_ends
from rebarlib._evidence import _Row
from rebarlib._status import MISSING, NOT_MEASURED, PRESENT_NO_DEPTH
from rebarlib.geometry import Plane, to_slab_frame

PLANE = Plane(np.array([0.0, 0.0, -1.0]), 600.0)  # the camera 600 mm over the formwork, looking down
ALONG, ACROSS = np.array([1.0, 0.0]), np.array([0.0, 1.0])


def _row(layer, height, radius):
    return _Row(layer, "top", [], [], np.zeros(0), 200.0, height, 0.5, radius, ALONG, ACROSS)


LOWER, UPPER = _row("lower", 40.0, 7.0), _row("upper", 140.0, 6.0)
ROWS = {("lower", "top"): LOWER, ("upper", "top"): UPPER}
N_FOUND = 20  # bars found with depth; a bar placed from the mask is numbered after them


def _rec(row, p, status, bar_id=None):
    return {
        "layer": row.layer,
        "level": row.level,
        "kind": "gap",
        "offset_mm": p,
        "status": status,
        "reason": "",
        "bar_id": bar_id,
        **_line_ends(row, p, (-300.0, 300.0), PLANE),
    }


def _on_upper_level(p):
    """Where the line of sight through the lower level's offset ``p`` meets the upper level."""
    cam = to_slab_frame(np.zeros((1, 3)), PLANE)[0]
    c, zc = float(cam[:2] @ ACROSS), float(cam[2])
    return c + (p - c) * (zc - UPPER.height) / (zc - LOWER.height)


def test_a_bar_without_depth_under_an_empty_upper_position_is_not_placed():
    # a lower bar in the projector's shadow (placed from the mask) right under a missing upper
    # bar: the mask's band could be either, and both had been counted present
    q = _on_upper_level(100.0)
    recs = [
        _rec(LOWER, 100.0, PRESENT_NO_DEPTH, N_FOUND),
        _rec(LOWER, 300.0, PRESENT_NO_DEPTH, N_FOUND + 1),  # another, with no position over it
        _rec(UPPER, q, PRESENT_NO_DEPTH, N_FOUND + 2),
    ]
    out, kept = _level_untold(recs, ROWS, N_FOUND, ["bar a", "bar b", "bar c"], PLANE)
    assert [r["status"] for r in out] == [NOT_MEASURED, PRESENT_NO_DEPTH, NOT_MEASURED]
    assert "which of the two it is, cannot be told" in out[0]["reason"] and out[0]["bar_id"] is None
    assert "lower top position" in out[2]["reason"]
    # the bar kept is numbered on from the bars found
    assert kept == ["bar b"] and out[1]["bar_id"] == N_FOUND


def test_an_empty_position_on_the_same_line_makes_it_untold_and_a_position_beside_does_not():
    q = _on_upper_level(100.0)
    # an upper position judged missing or not measured on the same lines of sight: untold
    for status in (MISSING, NOT_MEASURED):
        recs = [_rec(LOWER, 100.0, PRESENT_NO_DEPTH, N_FOUND), _rec(UPPER, q, status)]
        out, kept = _level_untold(recs, ROWS, N_FOUND, ["bar a"], PLANE)
        assert out[0]["status"] == NOT_MEASURED and out[1]["status"] == status and kept == []
    # the silhouettes apart (more than 6 + 7 k mm on the upper level): the bar is placed
    recs = [_rec(LOWER, 100.0, PRESENT_NO_DEPTH, N_FOUND), _rec(UPPER, q + 13.0, MISSING)]
    out, kept = _level_untold(recs, ROWS, N_FOUND, ["bar a"], PLANE)
    assert out[0]["status"] == PRESENT_NO_DEPTH and kept == ["bar a"]
    # nor does a position of the same row, or one whose stretch along the row is elsewhere
    far = {**_rec(UPPER, q, MISSING), **_line_ends(UPPER, q, (400.0, 700.0), PLANE)}
    recs = [_rec(LOWER, 100.0, PRESENT_NO_DEPTH, N_FOUND), _rec(LOWER, 100.0, MISSING), far]
    out, kept = _level_untold(recs, ROWS, N_FOUND, ["bar a"], PLANE)
    assert out[0]["status"] == PRESENT_NO_DEPTH and kept == ["bar a"]
