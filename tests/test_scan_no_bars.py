"""A scan with no bar mesh in it (a formwork and clutter): no bars, every measurement "not
measured" with its reason, a note that says so, and no spread across bars that were never seen.
Ground truth: the cloud is laid out here with no bar in it."""

import numpy as np

from rebarlib.data import paper_design
from rebarlib.scan import inspect_cloud


def _formwork_and_clutter(seed=3):
    rng = np.random.default_rng(seed)
    board = np.c_[rng.uniform(-600, 600, (20000, 2)), rng.normal(0.0, 1.0, 20000)]
    clutter = np.c_[rng.uniform(-600, 600, (300, 2)), rng.uniform(10, 200, 300)]
    return np.r_[board, clutter]


def test_a_scan_without_a_mesh_says_no_bar_found_and_measures_nothing():
    res = inspect_cloud(_formwork_and_clutter(), paper_design())
    assert len(res.bars) == 0
    assert any(n.startswith("no bar found") for n in res.notes)
    # the formwork's noise is measured; a spread across bars is not claimed
    assert any("across the formwork" in n for n in res.notes)
    assert not any("across the bars" in n for n in res.notes)
    m = res.to_dict()["measurements"]
    assert m["cover"]["status"] == "not measured" and m["cover"]["reason"]
    assert m["layer_distance"]["status"] == "not measured" and m["layer_distance"]["reason"]
