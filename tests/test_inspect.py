"""inspect() and `rebar inspect` against the synthetic captures' ground truth.

Every capture is rendered once per module (half-resolution Gemini 2 to keep the file fast) and
scored with rebarlib.geometry.scoring (bar matching, the "measurable" rule, phantoms, spacing errors).
Tolerances below are for half-resolution captures up to 500 mm; the benchmark holds the
full-resolution targets (0.5 mm cover / layer distance, 2 mm spacing).
"""

from __future__ import annotations

import json
import math
from dataclasses import replace

import numpy as np
import pytest

from rebarlib import GEMINI2, RebarInputError, load_capture
from rebarlib._camera import project
from rebarlib._capture import Capture
from rebarlib.geometry.scoring import measurable_bars, score_result
from rebarlib._inspect import inspect
from rebarlib._results import MEASURED, NOT_MEASURED
from rebarlib.data import example_capture, example_slab, paper_design
from rebarlib.synth import CameraPose, Deviations, SensorModel, make_scene, misregister, render_capture, synth_capture

K_HALF = GEMINI2.scaled(0.5)
COVER_TOL_MM = 0.8  # cover, half resolution
LAYER_TOL_MM = 0.8  # layer distance, half resolution
UPPER_TOP_TOL_MM = 1.0
SPACING_TOL_MM = 3.0  # any single spacing, half resolution (position jitter 5 mm)
EXAMPLE_COVER_TOL_MM = 0.5  # full-resolution examples: the benchmark's target
EXAMPLE_SPACING_TOL_MM = 2.0
PAPER_COVER_TOL_MM = 1.5  # paper method at 500 mm (the paper reports 1.43 mm)
AXIS_OFFSET_TOL_MM = 3.0  # median distance of found axes from the true axes
SPARSE_KEEP_EVERY = 48  # the too-few-points case keeps 1 pixel in this many of one bar


def _visible_measurable(cap, **where):
    return [b for b in measurable_bars(cap) if all(b[k] == v for k, v in where.items())]


def _assert_bars_ok(res, cap, *, allow_missed=0):
    s = score_result(res, cap)
    measured = res.bars[res.bars["status"] == MEASURED]
    phantoms = [b for b in s["phantoms"] if b in set(measured["bar_id"])]
    assert phantoms == [], f"phantom bars {phantoms}"
    assert len(s["missed"]) <= allow_missed, f"visible bars not found: {s['missed']}"
    assert s["wrong_level"] == [], f"bars with the wrong level: {s['wrong_level']}"
    m = s["matches"]
    assert np.nanmedian(m.loc[~m["phantom"], "offset_mm"]) < AXIS_OFFSET_TOL_MM
    return s


# ------------------------------------------------------------------------------------------------
# Captures (rendered once per module)
# ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def hard():
    """Yawed mesh, 20° tilt, spacing varying bar to bar, one bar missing in view, bars cut by the
    image border, lower bars partly hidden under upper bars."""
    dev = Deviations(mesh_yaw_deg=37.0, position_sigma_mm=5.0, missing=1)
    design = paper_design()
    cap = synth_capture(
        design,
        height_mm=500,
        tilt_deg=20,
        yaw_deg=15,
        deviations=dev,
        intrinsics=K_HALF,
        seed=4,
        scene_seed=11,
        name="hard",
    )
    return cap, design, inspect(cap, design, rng=0)


@pytest.fixture(scope="module")
def one_lattice():
    """Only the lower lattice was placed (no upper bars, no chairs)."""
    design = paper_design()
    scene = make_scene(design, Deviations(mesh_yaw_deg=-23.0), rng=np.random.default_rng(3))
    scene = replace(scene, bars=tuple(b for b in scene.bars if b.layer == "lower"), rods=())
    pose = CameraPose.looking_down(450, tilt_deg=8)
    cap = render_capture(scene, pose, intrinsics=K_HALF, rng=np.random.default_rng(5), name="one")
    return cap, design, inspect(cap, design, rng=0)


def _with_depth(cap: Capture, depth, name: str) -> Capture:
    return replace(cap, depth_mm=depth, metadata={**cap.metadata, "name": name})


def _bare(cap: Capture) -> Capture:
    """The capture with everything but the bars removed (no formwork, no spacers or chairs)."""
    return _with_depth(cap, np.where(cap.labels > 0, cap.depth_mm, 0.0), cap.name + "_bare")


# ------------------------------------------------------------------------------------------------
# Hard cases
# ------------------------------------------------------------------------------------------------


def test_the_default_gives_the_same_result_in_every_run(hard):
    # without a seed, inspect seeds its random steps with 0 (as `rebar inspect --seed 0`): the
    # library gave borderline bars different reasons from run to run before (a width of 10.434
    # or 10.435 mm: "ambiguous" or "mask and cloud widths disagree")
    cap, design, seeded = hard
    assert (
        inspect(cap, design, diameters=False).to_dict()["bars"]
        == inspect(cap, design, rng=0, diameters=False).to_dict()["bars"]
    )


def test_yawed_tilted_mesh_cover_layer_distance_and_top(hard):
    cap, design, res = hard
    t = cap.truth
    assert res.cover.status == MEASURED and abs(res.cover.value_mm - t["cover_mm"]) <= COVER_TOL_MM
    assert abs(res.layer_distance.value_mm - t["layer_distance_mm"]) <= LAYER_TOL_MM
    assert abs(res.upper_top.value_mm - t["upper_top_mm"]) <= UPPER_TOP_TOL_MM
    true_top_cover = design.thickness_mm - t["upper_top_mm"]
    assert res.top_cover.ok and abs(res.top_cover.value_mm - true_top_cover) <= UPPER_TOP_TOL_MM
    for m in (res.cover, res.layer_distance, res.upper_top):
        assert m.n_points > 100 and 0 < m.uncertainty_mm < 1.0
    # the camera pose over the formwork
    assert abs(res.camera["tilt_deg"] - 20.0) < 0.5
    assert abs(res.camera["height_mm"] - t["camera"]["height_mm"]) < 2.0 if "height_mm" in t["camera"] else True
    assert abs(abs(np.dot(res.formwork["normal"], t["formwork_plane"]["normal"])) - 1) < 1e-4


def test_every_visible_bar_found_once_with_its_level(hard):
    cap, _, res = hard
    # preconditions of the hard case: bars cut by the image border, lower bars partly hidden
    cut = [
        b
        for b in _visible_measurable(cap)
        if b["visible_length_mm"] < 0.95 * np.linalg.norm(np.subtract(b["axis_end_mm"], b["axis_start_mm"]))
    ]
    assert len(cut) >= 10
    assert len(_visible_measurable(cap, layer="lower")) >= 6
    s = _assert_bars_ok(res, cap)
    assert s["found"] == s["measurable"] >= 15
    # plan angles of the two directions 90° apart
    ang = res.bars.groupby(["layer", "level"])["plan_angle_deg"].median()
    for layer in ("lower", "upper"):
        d = abs(ang[(layer, "bottom")] - ang[(layer, "top")]) % 180
        assert abs(d - 90) < 2.0


@pytest.mark.parametrize("mesh_yaw_deg,height_mm,tilt_deg", [(0.0, 400, 0.0), (45.0, 600, 12.0), (90.0, 500, 6.0)])
def test_any_yaw_straight_or_diagonal(mesh_yaw_deg, height_mm, tilt_deg):
    """Bars parallel to the image axes (0°, 90°, no tilt) and diagonal (45°) alike."""
    design = paper_design(cover_mm=25)
    cap = synth_capture(
        design,
        height_mm=height_mm,
        tilt_deg=tilt_deg,
        deviations=Deviations(mesh_yaw_deg=mesh_yaw_deg),
        intrinsics=K_HALF,
        seed=int(mesh_yaw_deg) + 7,
        name="yaw",
    )
    res = inspect(cap, design, diameters=False, rng=0)
    t = cap.truth
    assert abs(res.cover.value_mm - t["cover_mm"]) <= COVER_TOL_MM
    assert abs(res.layer_distance.value_mm - t["layer_distance_mm"]) <= LAYER_TOL_MM
    s = _assert_bars_ok(res, cap)
    assert s["found"] == s["measurable"]
    assert len(s["spacing_errors_mm"]) >= 4 and np.abs(s["spacing_errors_mm"]).max() <= SPACING_TOL_MM


def test_spacing_varying_bar_to_bar(hard):
    cap, _, res = hard
    s = score_result(res, cap)
    true_sp = np.array([x["spacing_mm"] for x in cap.truth["spacings"] if x["visible"]])
    assert true_sp.std() > 3.0  # precondition: spacings really vary
    err = s["spacing_errors_mm"]
    assert len(err) >= 8 and np.abs(err).max() <= SPACING_TOL_MM
    sp = res.spacings
    assert list(sp.columns[:9]) == [
        "layer",
        "level",
        "bar_a",
        "bar_b",
        "spacing_mm",
        "design_spacing_mm",
        "deviation_mm",
        "status",
        "reason",
    ]
    ok = sp[sp["status"] == MEASURED]
    assert np.allclose(ok["deviation_mm"], ok["spacing_mm"] - ok["design_spacing_mm"])
    assert (ok["design_spacing_mm"] == 200).all()


def test_no_spacing_measured_across_a_hidden_bar(hard):
    """A lower bar hidden under the parallel upper bar right above it is not missing (counts say
    so) — so the gap across it is not a spacing: every *measured* spacing must be between bars
    that are adjacent in the mesh."""
    cap, _, res = hard
    seen = {(b["layer"], b["level"], b["index"]) for b in measurable_bars(cap)}
    hidden = [
        b
        for b in cap.truth["bars"]
        if not b["visible"] and {(b["layer"], b["level"], b["index"] + k) for k in (-1, 1)} <= seen
    ]
    assert hidden  # precondition: a hidden bar between two measurable ones
    s = score_result(res, cap)
    assert s["spacings_unscored"] == 0


def test_spacings_in_order_across_the_bars(hard):
    _, _, res = hard
    bars = res.bars.set_index("bar_id")
    for (layer, level), g in res.spacings.groupby(["layer", "level"], sort=False):
        chain = list(g["bar_a"]) + [g["bar_b"].iloc[-1]]
        # consecutive rows share a bar: a chain across the set
        assert all(a == b for a, b in zip(g["bar_b"].iloc[:-1], g["bar_a"].iloc[1:]))
        assert len(set(chain)) == len(chain)
        assert set(bars.loc[chain, "layer"]) == {layer}


def test_missing_bar_counted(hard):
    cap, _, res = hard
    miss = cap.truth["missing"]
    assert len(miss) == 1
    key = (miss[0]["layer"], miss[0]["level"])
    c = res.counts.set_index(["layer", "level"])
    assert list(res.counts.columns) == [
        "layer",
        "level",
        "found",
        "expected",
        "missing",
        "extra",
        "not_measured",
        "outside",
        "evidence",
    ]
    # A bar is missing only on evidence of an empty position (docs/verdicts.md). Here the upper
    # bar of its direction lies over the empty position in the image: a bar within tolerance of
    # its place could hide under it, so the position is "not measured (hidden)", never accepted.
    pos = res.positions
    at = pos[(pos["layer"] == key[0]) & (pos["level"] == key[1]) & pos["status"].isin(["missing", "not measured"])]
    assert int(c.loc[key, "missing"]) == 1 or (
        int(c.loc[key, "not_measured"]) >= 1 and any("hidden" in r for r in at["reason"])
    )
    for k in c.index:
        if k != key:
            assert int(c.loc[k, "missing"]) == 0
        assert int(c.loc[k, "extra"]) == 0


# Captures of the geometry benchmark (full resolution, realistic sensor) with a bar the thinned
# cloud of the bar search misses: (cover, height, tilt, mesh yaw, camera yaw, seed, truth bar id)
SECOND_LOOK = {
    "lower bar seen as slivers beside the upper bar above it": (15, 600, 5, 157.4924, 76.7366, 278041, 7),
    "bar cut to 7 cm by the image corner": (25, 600, 15, 18.1010, 100.6264, 702891, 8),
}
SECOND_LOOK_AXIS_TOL_MM = 3.0  # plan offset of the found axis from the true axis


@pytest.mark.slow
@pytest.mark.parametrize("case", list(SECOND_LOOK))
def test_second_look_finds_the_bars_the_thinned_cloud_misses(case):
    cover, h, tilt, mesh_yaw, cam_yaw, seed, bar = SECOND_LOOK[case]
    design = paper_design(cover_mm=cover)
    cap = synth_capture(
        design,
        height_mm=h,
        tilt_deg=tilt,
        yaw_deg=cam_yaw,
        deviations=Deviations(mesh_yaw_deg=mesh_yaw),
        seed=seed,
        scene_seed=seed + 1,
    )
    res = inspect(cap, design, diameters=False, rng=seed)
    s = score_result(res, cap)
    m = s["matches"]
    assert s["phantoms"] == []
    hit = m[m["truth_id"] == bar]
    assert len(hit) == 1, f"truth bar {bar} not found"
    row = res.bars.set_index("bar_id").loc[int(hit["bar_id"].iloc[0])]
    # found by the second look: there, but its axis is not placed to the millimetre
    assert row["status"] == NOT_MEASURED and row["reason"].startswith("seen only at full resolution")
    assert float(hit["offset_mm"].iloc[0]) < SECOND_LOOK_AXIS_TOL_MM
    # its spacings are not measured (never one spacing twice the real one)
    sp = res.spacings
    near = sp[(sp["bar_a"] == row.name) | (sp["bar_b"] == row.name)]
    assert len(near) >= 1 and (near["status"] == NOT_MEASURED).all()


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 2])
def test_second_look_invents_no_bar_where_one_is_missing_under_an_upper_bar(seed):
    """Upper bars stacked right above the lower bars, several lower and upper bars left out: the
    flying pixels along the upper bars' edges and the empty positions under them give no bar."""
    design = paper_design(cover_mm=20)
    cap = synth_capture(
        design,
        height_mm=600,
        tilt_deg=5,
        yaw_deg=30.0 * seed,
        deviations=Deviations(stacked=True, missing=6, mesh_yaw_deg=17.0 * seed),
        seed=seed,
    )
    res = inspect(cap, design, diameters=False, rng=0)
    s = score_result(res, cap)
    assert s["phantoms"] == [], f"seed {seed}: phantom bars {s['phantoms']}"
    assert s["missed"] == []
    # precondition: an empty lower position in view, right under an upper bar
    assert _empty_lower_positions_in_view_under_upper_bars(cap) >= 1


@pytest.mark.slow
@pytest.mark.parametrize("k, h, tilt, stacked", [(1, 500, 15, True), (2, 600, 5, False)])
def test_second_look_ignores_flying_pixels(k, h, tilt, stacked):
    """A sensor with over three times the default flying pixels at depth edges (mixed depths
    between the two surfaces): their chance hits on a would-be bar's cylinder are sparser than a
    bar's stripe of pixels, so the second look places no bar on them. (Without its fill rule it
    placed one in each of these captures.)"""
    design = paper_design(cover_mm=20)
    sensor = SensorModel(edge_hole_prob=0.15, edge_fatten_prob=0.2, flying_pixel_prob=0.5)
    cap = synth_capture(
        design,
        sensor=sensor,
        height_mm=h,
        tilt_deg=tilt,
        yaw_deg=47.0 * k,
        deviations=Deviations(mesh_yaw_deg=31.0 * k, stacked=stacked, missing=6),
        seed=500 + k,
        scene_seed=600 + k,
    )
    res = inspect(cap, design, diameters=False, rng=0)
    s = score_result(res, cap)
    seen_later = res.bars["reason"].str.startswith("seen only at full resolution")
    second = set(res.bars.loc[seen_later, "bar_id"])
    assert not second & set(s["phantoms"]), f"second-look phantoms {second & set(s['phantoms'])}"


def _empty_lower_positions_in_view_under_upper_bars(cap) -> int:
    K = cap.intrinsics
    bars = {(b["layer"], b["level"], b["index"]): b for b in cap.truth["bars"]}
    n = 0
    for m in cap.truth["missing"]:
        lo, hi = (bars.get(("lower", m["level"], m["index"] - 1)), bars.get(("lower", m["level"], m["index"] + 1)))
        if m["layer"] != "lower" or lo is None or hi is None or ("upper", m["level"], m["index"]) not in bars:
            continue
        a = 0.5 * (np.array(lo["axis_start_mm"]) + np.array(hi["axis_start_mm"]))
        b = 0.5 * (np.array(lo["axis_end_mm"]) + np.array(hi["axis_end_mm"]))
        p = a + np.linspace(0, 1, 400)[:, None] * (b - a)
        u, v = project(p[p[:, 2] > 1], K).T
        n += int(np.sum((u >= 0) & (u < K.width) & (v >= 0) & (v < K.height)) > 20)
    return n


def test_bar_table_columns_and_axes_in_camera_frame(hard):
    cap, _, res = hard
    cols = [
        "bar_id",
        "layer",
        "level",
        "plan_angle_deg",
        "start_x_mm",
        "start_y_mm",
        "start_z_mm",
        "end_x_mm",
        "end_y_mm",
        "end_z_mm",
        "visible_length_mm",
        "n_points",
        "status",
        "reason",
    ]
    assert set(cols) <= set(res.bars.columns)
    # axis end points project into the image (visible extent), and bar_points carry the pixels
    K = cap.intrinsics
    for r in res.bars[res.bars["status"] == MEASURED].itertuples():
        for p in ((r.start_x_mm, r.start_y_mm, r.start_z_mm), (r.end_x_mm, r.end_y_mm, r.end_z_mm)):
            u, v = K.fx * p[0] / p[2] + K.cx, K.fy * p[1] / p[2] + K.cy
            assert -30 <= u <= K.width + 30 and -30 <= v <= K.height + 30
        pts = res.bar_points[r.bar_id]
        assert len(pts) >= r.n_points * 0.9
        ids = cap.bar_ids[pts.pixels[:, 1], pts.pixels[:, 0]]
        # the points given to a bar are (mostly) that bar's pixels
        assert np.mean(ids == np.bincount(ids[ids > 0]).argmax()) > 0.8


def test_formwork_a_disparity_step_above_its_plane_is_not_taken_for_bars():
    # An 848 x 480 stereo camera (a D435's focal length scaled) at 600 mm quantises depth in
    # steps of 2-3 mm: an eighth of the formwork sits 3.3 mm above its fitted plane, beyond the
    # plane's 4 robust σ. Taken as bars, it buried the lower lattice (none found, cover not
    # measured). Every bar of both lattices is found and the cover is measured.
    from rebarlib import Intrinsics

    k = Intrinsics(fx=638.0 * 848 / 1280, fy=638.0 * 848 / 1280, cx=423.5, cy=239.5, width=848, height=480)
    design = paper_design()
    cap = synth_capture(design, height_mm=600, tilt_deg=0, seed=1, sensor=SensorModel(), intrinsics=k)
    res = inspect(cap, design, diameters=False, rng=0)
    counts = res.counts.set_index(["layer", "level"])
    assert (counts.found > 0).all() and (counts.missing == 0).all()
    assert res.cover.status == MEASURED and abs(res.cover.value_mm - cap.truth["cover_mm"]) <= 1.0
    assert abs(res.layer_distance.value_mm - cap.truth["layer_distance_mm"]) <= 1.0


def test_one_lattice_only(one_lattice):
    cap, _, res = one_lattice
    t = cap.truth
    assert set(res.bars["layer"]) == {"lower"}
    assert abs(res.cover.value_mm - t["cover_mm"]) <= COVER_TOL_MM
    assert res.layer_distance.status == NOT_MEASURED and res.layer_distance.value_mm is None
    assert res.layer_distance.reason
    assert res.upper_top.status == NOT_MEASURED and res.top_cover.status == NOT_MEASURED
    _assert_bars_ok(res, cap)
    err = score_result(res, cap)["spacing_errors_mm"]
    assert len(err) >= 3 and np.abs(err).max() <= SPACING_TOL_MM


def test_no_formwork_visible(hard):
    cap, design, _ = hard
    bare = _bare(cap)
    res = inspect(bare, design, rng=0)
    t = cap.truth
    assert res.cover.status == NOT_MEASURED and res.cover.value_mm is None and "formwork" in res.cover.reason
    assert res.top_cover.status == NOT_MEASURED
    # layers and spacing are still measured (relative quantities)
    assert abs(res.layer_distance.value_mm - t["layer_distance_mm"]) <= LAYER_TOL_MM
    _assert_bars_ok(res, cap)
    err = score_result(res, cap)["spacing_errors_mm"]
    assert len(err) >= 8 and np.abs(err).max() <= SPACING_TOL_MM
    assert res.formwork.get("found") is False
    assert json.loads(res.to_json())["cover_mm"] is None


def test_bar_with_too_few_points_is_not_measured(hard):
    """A bar whose depth is almost all lost (here: 1 pixel in 48 of it kept, about 30 points after
    the stride) is reported as "not measured" with a reason, not dropped silently and not given a
    number."""
    cap, design, _ = hard
    target = max(_visible_measurable(cap, layer="upper", level="top"), key=lambda b: b["visible_length_mm"])
    mask = cap.bar_ids == target["id"] + 1
    vv, uu = np.nonzero(mask)
    drop = np.ones(len(vv), bool)
    drop[::SPARSE_KEEP_EVERY] = False
    depth = cap.depth_mm.copy()
    depth[vv[drop], uu[drop]] = 0.0
    res = inspect(_with_depth(cap, depth, "sparse"), design, rng=0)
    m = score_result(res, cap)["matches"]
    rows = m[m["truth_id"] == target["id"]]
    assert len(rows) == 1, "the sparse bar must be reported"
    row = res.bars.set_index("bar_id").loc[int(rows["bar_id"].iloc[0])]
    assert row["status"] == NOT_MEASURED and row["reason"]


# ------------------------------------------------------------------------------------------------
# Bad input
# ------------------------------------------------------------------------------------------------


def test_empty_capture_is_an_input_error(hard):
    cap, design, _ = hard
    with pytest.raises(RebarInputError, match="depth"):
        inspect(_with_depth(cap, np.zeros_like(cap.depth_mm), "empty"), design)


#: inspect() called wrongly: (the argument changed, the word the error names). "depth" stands
#: for the capture's depth array given in place of the capture.
WRONG_ARGUMENTS = [
    ({"method": "fast"}, "method"),
    ({"design": {"cover_mm": 20}}, "design"),
    ({"capture": "depth"}, "capture"),
    *[({"edge_trim_px": bad}, "edge_trim_px") for bad in (-1, 1.5, "1", True)],
]


@pytest.mark.parametrize(
    "change, names", WRONG_ARGUMENTS, ids=[f"{k}={v!r}" for (c, _) in WRONG_ARGUMENTS for k, v in c.items()]
)
def test_wrong_arguments_are_input_errors(hard, change, names):
    cap, design, _ = hard
    args = {"design": design, **change}
    capture = cap.depth_mm if args.pop("capture", None) == "depth" else cap
    with pytest.raises(RebarInputError, match=names):
        inspect(capture, args.pop("design"), **args)


def test_flat_formwork_only_measures_nothing(hard):
    """All points on one plane: no bars, so no cover, no layer distance, no spacing — and no
    made-up numbers."""
    cap, design, _ = hard
    K = cap.intrinsics
    v = np.mgrid[0 : K.height, 0 : K.width][0]
    # a tilted plane 500 mm away along the optical axis
    depth = 500.0 / (1.0 + 0.2 * (v - K.cy) / K.fy)
    res = inspect(_with_depth(cap, depth, "flat"), design, rng=0)
    for m in (res.cover, res.layer_distance, res.upper_top, res.top_cover):
        assert m.status == NOT_MEASURED and m.value_mm is None and m.reason
    assert (res.bars["status"] != MEASURED).all() if len(res.bars) else True
    assert len(res.spacings) == 0 or (res.spacings["status"] != MEASURED).all()


@pytest.mark.parametrize("absurd", [{"cover_mm": -5}, {"layer_distance_mm": 5}], ids=str)
def test_absurd_design_values_rejected(absurd):
    with pytest.raises(RebarInputError):
        paper_design(**absurd)


# ------------------------------------------------------------------------------------------------
# Shipped examples (full resolution), both methods
# ------------------------------------------------------------------------------------------------


@pytest.mark.parametrize("slab,name", [("paper_slab", "B_500"), ("site_slab", "P1_500")])
def test_examples_refined_accuracy(slab, name):
    _, design = example_slab(slab)
    cap = load_capture(example_capture(slab, name))
    res = inspect(cap, design, rng=0)
    t = cap.truth
    assert abs(res.cover.value_mm - t["cover_mm"]) <= EXAMPLE_COVER_TOL_MM
    assert abs(res.layer_distance.value_mm - t["layer_distance_mm"]) <= EXAMPLE_COVER_TOL_MM
    s = _assert_bars_ok(res, cap)
    assert np.abs(s["spacing_errors_mm"]).max() <= EXAMPLE_SPACING_TOL_MM
    assert res.method == "refined" and res.capture == name


def test_paper_method_on_example():
    _, design = example_slab("paper_slab")
    cap = load_capture(example_capture("paper_slab", "B_500"))
    res = inspect(cap, design, method="paper", rng=0)
    assert res.method == "paper"
    assert abs(res.cover.value_mm - cap.truth["cover_mm"]) <= PAPER_COVER_TOL_MM
    assert res.layer_distance.ok and len(res.bars) > 0
    assert {"lower", "upper"} == set(res.bars["layer"])


def test_same_seed_same_result(hard):
    cap, design, res = hard
    again = inspect(cap, design, rng=0)
    assert again.to_json() != "" and json.loads(again.to_json())["bars"] == json.loads(res.to_json())["bars"]


# ------------------------------------------------------------------------------------------------
# rebar inspect
# ------------------------------------------------------------------------------------------------


def test_cli_writes_result_and_tables(tmp_path, capsys):
    from rebarlib.cli import main

    folder, _ = example_slab("paper_slab")
    out = tmp_path / "results"
    rc = main(
        [
            "inspect",
            str(example_capture("paper_slab", "A_400")),
            "--design",
            str(folder / "design.toml"),
            "--out",
            str(out),
        ]
    )
    assert rc == 0
    d = out / "A_400"
    data = json.loads((d / "result.json").read_text())
    for key in (
        "capture",
        "method",
        "cover_mm",
        "layer_distance_mm",
        "upper_top_mm",
        "top_cover_mm",
        "measurements",
        "formwork",
        "camera",
        "bars",
        "spacings",
        "counts",
        "timings_s",
        "notes",
    ):
        assert key in data
    assert data["capture"] == "A_400" and data["method"] == "refined"
    assert math.isfinite(data["cover_mm"]) and data["measurements"]["cover"]["status"] == MEASURED
    import pandas as pd

    bars = pd.read_csv(d / "bars.csv")
    assert len(bars) == len(data["bars"]) and "start_x_mm" in bars
    assert "nominal_mm" in bars  # the diameter stage's columns by default
    assert len(pd.read_csv(d / "spacings.csv")) == len(data["spacings"])
    assert (d / "counts.csv").exists()
    line = capsys.readouterr().out
    assert "A_400: cover" in line and "layer distance" in line


def test_cli_geometry_only(tmp_path, capsys):
    import pandas as pd

    from rebarlib.cli import main

    folder, _ = example_slab("site_slab")
    out = tmp_path / "r"
    rc = main(
        [
            "inspect",
            str(example_capture("site_slab", "P1_500")),
            "--design",
            str(folder / "design.toml"),
            "--out",
            str(out),
            "--no-diameters",
            "--method",
            "refined",
            "--seed",
            "3",
        ]
    )
    assert rc == 0
    bars = pd.read_csv(out / "P1_500" / "bars.csv")
    assert "nominal_mm" not in bars and len(bars) >= 20
    assert "P1_500: cover" in capsys.readouterr().out


def test_cli_never_writes_into_a_capture(tmp_path, capsys):
    from rebarlib.cli import main

    folder, _ = example_slab("paper_slab")
    cap = example_capture("paper_slab", "A_400")
    before = sorted(p.name for p in cap.iterdir())
    rc = main(["inspect", str(cap), "--design", str(folder / "design.toml"), "--out", str(cap.parent)])
    assert rc == 2 and "capture folder" in capsys.readouterr().err
    assert sorted(p.name for p in cap.iterdir()) == before


def test_cli_duplicate_names_and_missing_capture(tmp_path, capsys):
    from rebarlib.cli import main

    folder, _ = example_slab("paper_slab")
    (tmp_path / "x" / "A_400").mkdir(parents=True)
    (tmp_path / "y" / "A_400").mkdir(parents=True)
    rc = main(
        [
            "inspect",
            str(tmp_path / "x" / "A_400"),
            str(tmp_path / "y" / "A_400"),
            "--design",
            str(folder / "design.toml"),
            "--out",
            str(tmp_path / "out"),
        ]
    )
    assert rc == 2 and "overwrite" in capsys.readouterr().err
    rc = main(
        ["inspect", str(tmp_path / "nope"), "--design", str(folder / "design.toml"), "--out", str(tmp_path / "out")]
    )
    assert rc == 2 and "nope" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()


def test_widest_bar_px_is_the_widest_envelope_at_the_nearest_depth(paper_design):
    from rebarlib import Capture, Intrinsics
    from rebarlib._inspect import widest_bar_px

    K = Intrinsics(500.0, 500.0, 50.0, 40.0, 100, 80)
    depth = np.full((80, 100), 600.0)
    depth[:, :50] = 0.0  # no depth on half the image: not counted
    depth[:10, 50:] = 400.0  # the nearest 12.5 % of the valid pixels
    cap = Capture(np.zeros((80, 100, 3), np.uint8), depth, K)
    # the paper slab's widest bar is Φ14 (rib envelope 16.2 mm): 16.2 x 500 / 400 px
    assert widest_bar_px(cap, paper_design) == pytest.approx(16.2 * 500 / 400)
    assert np.isnan(widest_bar_px(Capture(cap.color, np.zeros((80, 100)), K), paper_design))


# ------------------------------------------------------------------------------------------------
# Colour-depth misregistration
# ------------------------------------------------------------------------------------------------


@pytest.fixture(scope="module")
def example_b500():
    _, design = example_slab("paper_slab")
    return load_capture(example_capture("paper_slab", "B_500")), design


def _diameters(res):
    b = res.bars
    measured = b[b.diameter_status == MEASURED]
    return len(measured), int((measured.matches_design == False).sum())  # noqa: E712 - object column


@pytest.mark.slow
def test_colour_depth_misregistration_is_undone_before_the_diameters(example_b500, monkeypatch):
    # Measured on this capture: 14 of its 15 bars sized as aligned (registration estimated
    # (0.06, 0.05) px, not applied), 14 with the depth 2 px right and 1 px up and the registration
    # undone (estimated (2.06, -0.98) px), 6 without undoing it. No bar of the example is of another size
    # than designed, so a size that does not match the design is a wrong one.
    import rebarlib._masks as M  # where the mask step reads its registration threshold

    cap, design = example_b500
    aligned = inspect(cap, design, rng=0)
    assert aligned.extras["registration"]["applied"] is False  # it estimates < 0.5 px here
    n_aligned, wrong = _diameters(aligned)
    assert wrong == 0
    moved = misregister(cap, 2, -1)  # depth 2 px right, 1 px up: what an alignment can leave
    colour = moved.color.copy()
    res = inspect(moved, design, rng=0)
    reg = res.extras["registration"]
    assert reg["applied"] and math.hypot(reg["shift_px"][0] - 2, reg["shift_px"][1] + 1) <= 0.3
    assert any("px from the colour image" in n for n in res.notes)
    assert np.array_equal(moved.color, colour)  # the capture given is not changed
    n_moved, wrong = _diameters(res)
    assert wrong == 0 and n_moved >= n_aligned - 1
    monkeypatch.setattr(M, "REGISTRATION_MIN_PX", math.inf)  # the same without undoing it
    n_left, _ = _diameters(inspect(moved, design, rng=0))
    assert n_left < n_aligned - 3
    assert json.loads(res.to_json())["extras"]["registration"]["applied"] is True


# ------------------------------------------------------------------------------------------------
# Edge fattening
# ------------------------------------------------------------------------------------------------


@pytest.mark.slow
def test_edge_fattening_is_left_out_before_the_bars_are_fitted(paper_design):
    # 3 px of stereo fattening (the benchmarks' "fattened" sensor): a bar's depth reaches past its
    # flank, and a bar seen from one side only slides towards it. Measured on this capture: the
    # mask step finds 1 px of over-reach; with it left out the largest spacing error is 0.06 mm
    sensor = SensorModel(edge_fatten_px=3, edge_fatten_prob=0.6, edge_hole_prob=0.2)
    cap = synth_capture(paper_design, sensor=sensor, height_mm=400, tilt_deg=15, seed=1)
    res = inspect(cap, paper_design, rng=0)
    trim = res.extras["edge_trim_px"]
    assert trim >= 1 and trim == res.extras["registration"]["depth_overreach_px"]
    assert any("edge fattening" in n and "before the bars were fitted" in n for n in res.notes)
    err = score_result(res, cap)["spacing_errors_mm"]
    assert len(err) >= 6 and np.abs(err).max() <= EXAMPLE_SPACING_TOL_MM
    # the geometry alone takes the depth as it comes (no colour mask measures the over-reach).
    # Before decision 055 it read a spacing 7.9 mm off here (a bar seen from one side, 8.8 mm
    # off); leaving a half-covered bar's clear flank edge out of its fit now keeps it at 0.11 mm
    kept = inspect(cap, paper_design, diameters=False, rng=0)
    assert "edge_trim_px" not in kept.extras
    assert np.abs(score_result(kept, cap)["spacing_errors_mm"]).max() <= EXAMPLE_SPACING_TOL_MM
    # given: the same fit as inspect's own second one (the same random draws)
    given = inspect(cap, paper_design, diameters=False, edge_trim_px=trim, rng=0)
    cols = ["start_x_mm", "start_y_mm", "start_z_mm", "end_x_mm", "end_y_mm", "end_z_mm"]
    assert np.array_equal(given.bars[cols].to_numpy(), res.bars[cols].to_numpy())
    assert given.extras["edge_trim_px"] == trim
    # the default sensor's fattening now and then is no over-reach: nothing is trimmed
    plain = synth_capture(paper_design, height_mm=400, tilt_deg=15, seed=1)
    plain = inspect(plain, paper_design, rng=0)
    assert "edge_trim_px" not in plain.extras
    assert plain.extras["registration"]["depth_overreach_px"] == 0


def test_a_trimmed_depth_fits_half_covered_bars_with_every_point(paper_design, monkeypatch):
    # Decision 055 leaves a half-covered bar's clear flank edge out only on the depth as it
    # comes: a depth already trimmed at every occluding edge (edge_trim_px, or the over-reach
    # inspect measures) has lost that flank's fattening and kept the covered flank's fringe, so
    # the edge flags are not even computed
    import rebarlib._refined as RF

    cap = synth_capture(paper_design, height_mm=450, tilt_deg=10, seed=2)
    calls = []
    flags = RF.edge_flags
    monkeypatch.setattr(RF, "edge_flags", lambda *a, **k: calls.append(1) or flags(*a, **k))
    inspect(cap, paper_design, diameters=False, edge_trim_px=1, rng=0)
    assert calls == []
    inspect(cap, paper_design, diameters=False, edge_trim_px=0, rng=0)
    assert calls == [1]
