"""benchmarks/study_one_sided_axes.py: a fitted axis is matched to the parallel true bar nearest
to it, and its offsets are split across the bar and along the line of sight."""

from types import SimpleNamespace

import pandas as pd

from benchmarks.study_one_sided_axes import _truth_match


def _true_bar(c, z, *, along="x", envelope=16.2, visible=True):
    a, b = ([-300.0, c, z], [300.0, c, z]) if along == "x" else ([c, -300.0, z], [c, 300.0, z])
    return {"visible": visible, "axis_start_mm": a, "axis_end_mm": b, "envelope_mm": envelope}


def _fitted(p0, p1):
    return {f"{end}_{k}_mm": v for end, p in (("start", p0), ("end", p1)) for k, v in zip("xyz", p)}


def test_an_axis_is_matched_to_the_nearest_parallel_bar_and_its_offsets_split():
    # a camera looking straight down the z axis; a true bar along x right under it (y = 0), one
    # crossing it (along y), a parallel one 200 mm away and a hidden one 0.2 mm away
    cap = SimpleNamespace(
        truth={
            "bars": [
                _true_bar(0.0, 500.0),
                _true_bar(50.0, 500.0, along="y"),
                _true_bar(200.0, 500.0),
                _true_bar(0.4, 500.0, visible=False),
            ]
        }
    )
    bars = pd.DataFrame(
        [
            # 0.6 mm beside the first bar (across) and 0.3 mm nearer the camera (along the ray)
            _fitted([-250.0, 0.6, 499.7], [250.0, 0.6, 499.7]),
            # along y, 30 mm from the crossing bar's axis: too far for a match
            _fitted([20.0, -290.0, 450.0], [20.0, 290.0, 450.0]),
        ]
    )
    first, far = _truth_match(cap, bars)
    assert far is None
    across, ray, env = first
    assert env == 16.2
    assert abs(abs(across) - 0.6) < 1e-3  # (the line of sight to the bar leans 0.07°)
    assert abs(ray + 0.3) < 1e-3  # nearer the camera: against the line of sight
