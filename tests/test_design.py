"""Design files: the documented format loads; every bad value is named."""

import pytest

from rebarlib import RebarInputError, design_from_dict, load_design

from rebarlib.data import _PAPER as PAPER_DESIGN

DOC_EXAMPLE = """
[slab]
id = "S-101"
element = "slab"
location = "Floor 3, grid A-B/1-2"
standard = "GB50204-2015"      # name of a tolerance preset

[design]
cover_mm = 20
layer_distance_mm = 85         # bottom to bottom, see method.md
thickness_mm = 180             # optional

[design.lower]
diameter_mm = 14
spacing_mm = 200               # same in both directions of the lattice

[design.upper]
diameter_mm = 12
spacing_mm = 200
"""


def test_the_documented_design_file_loads(tmp_path):
    (tmp_path / "design.toml").write_text(DOC_EXAMPLE)
    d = load_design(tmp_path)  # a slab folder works too
    assert d.slab_id == "S-101" and d.standard == "GB50204-2015"
    assert (d.cover_mm, d.layer_distance_mm, d.thickness_mm) == (20, 85, 180)
    assert d.lower.bottom.diameter_mm == d.lower.top.diameter_mm == 14
    assert d.upper.top.spacing_mm == 200
    assert d.upper_top_mm == 20 + 85 + 24 and d.top_cover_mm == 180 - 129


def test_per_direction_overrides():
    data = {
        **PAPER_DESIGN,
        "design": {
            **PAPER_DESIGN["design"],
            "lower": {"diameter_mm": 14, "spacing_mm": 200, "top": {"spacing_mm": 150}},
        },
    }
    d = design_from_dict(data)
    assert d.lower.bottom.spacing_mm == 200 and d.lower.top.spacing_mm == 150


@pytest.mark.parametrize(
    "path, value, match",
    [
        (("design", "cover_mm"), None, "missing required key 'cover_mm'"),
        (("design", "cover_mm"), -3, "cover_mm: -3 mm is outside"),
        (("design", "cover_mm"), "twenty", "cover_mm: expected a number"),
        (("design", "layer_distance_mm"), 20, "lattices would intersect"),
        (("design", "thickness_mm"), 120, "leaves no top cover"),
        (("design", "lower"), None, r"missing table \[design.lower\]"),
        (("slab", "id"), None, "needs an 'id'"),
    ],
)
def test_bad_values_are_named(path, value, match):
    import copy

    data = copy.deepcopy(PAPER_DESIGN)
    table = data[path[0]]
    if value is None:
        table.pop(path[1])
    else:
        table[path[1]] = value
    with pytest.raises(RebarInputError, match=match):
        design_from_dict(data)


def test_missing_and_broken_files(tmp_path):
    with pytest.raises(RebarInputError, match="design file not found"):
        load_design(tmp_path / "x.toml")
    (tmp_path / "d.toml").write_text("[design\ncover_mm = ")
    with pytest.raises(RebarInputError, match="d.toml: not a valid TOML"):
        load_design(tmp_path / "d.toml")
