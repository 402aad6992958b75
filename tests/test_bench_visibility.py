"""The benchmarks' line between the bars whose width the image shows and the others, drawn on a
hand-built image of bar ids (benchmarks/_visibility.py)."""

from types import SimpleNamespace

import numpy as np

from benchmarks._visibility import shows_width, width_sections

F, CX, CY, W, H, Z = 1000.0, 320.0, 240.0, 640, 480, 500.0  # 1 px = 0.5 mm at Z


def _bar(i, layer, level, v_or_u, along="u", half_px=10, z=Z, extent=(40, 600)):
    """A bar of 20 px (10 mm at Z: 'diameter' 10) along the image's rows (along="u") or columns."""
    a, b = extent
    if along == "u":
        p0, p1 = (a, v_or_u), (b, v_or_u)
    else:
        p0, p1 = (v_or_u, a), (v_or_u, b)
    to3d = lambda p: [(p[0] - CX) * z / F, (p[1] - CY) * z / F, z]  # noqa: E731
    return {
        "id": i,
        "layer": layer,
        "level": level,
        "visible": True,
        "diameter_mm": 10.0,
        "envelope_mm": 10.0,
        "visible_start_mm": to3d(p0),
        "visible_end_mm": to3d(p1),
        "_px": (p0, p1, half_px, along),
    }


def _capture(bars, order):
    """Draw the bars' ids, nearest last (``order``: ids from the formwork up)."""
    ids = np.zeros((H, W), np.int32)
    by = {b["id"]: b for b in bars}
    for i in order:
        (u0, v0), (u1, v1), r, along = by[i]["_px"]
        if along == "u":
            ids[max(v0 - r, 0) : v0 + r + 1, u0 : u1 + 1] = i + 1
        else:
            ids[v0 : v1 + 1, max(u0 - r, 0) : u0 + r + 1] = i + 1
    intr = SimpleNamespace(fx=F, fy=F, cx=CX, cy=CY, width=W, height=H)
    return SimpleNamespace(bar_ids=ids, intrinsics=intr, truth={"bars": bars})


def test_whole_bars_show_their_width_slivers_and_border_bars_do_not():
    bars = [
        _bar(0, "lower", "bottom", 100),  # alone on the formwork: whole width in view
        _bar(1, "lower", "bottom", 300),  # under bar 2, which covers all but 4 px of it: a sliver
        _bar(2, "upper", "bottom", 306),
        _bar(3, "lower", "bottom", 475),  # along the bottom border: half the bar is outside
        _bar(4, "upper", "top", 200, along="v", extent=(20, 460)),  # crosses 0 and 2 above them
    ]
    cap = _capture(bars, order=[0, 1, 3, 2, 4])
    sec = width_sections(cap)
    assert sec[1][0] == 0 and sec[3][0] == 0  # never both edges
    assert sec[0][0] > 100 and sec[2][0] > 100 and sec[4][0] > 100
    # bar 0 is cut only where bar 4 crosses it: 20 px of 560, a few sections
    assert 240 < sec[0][1] < 281
    assert shows_width(cap) == {0, 2, 4}
    # a stretch shorter than the asked diameters does not count: bar 2 shows 560 px = 280 mm
    assert 2 not in shows_width(cap, min_length_d=30)


def test_a_bar_further_from_the_camera_beside_the_edge_does_not_hide_it():
    # bar 1 (lower) runs along bar 0's edge (upper), touching: bar 0's edges both stay its own,
    # bar 1 loses the edge bar 0 covers
    bars = [_bar(0, "upper", "bottom", 200), _bar(1, "lower", "bottom", 220)]
    cap = _capture(bars, order=[1, 0])
    assert shows_width(cap) == {0}
