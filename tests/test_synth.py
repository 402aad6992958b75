"""Synthetic captures against geometry derived here independently of the renderer."""

import hashlib

import cv2
import numpy as np
import pytest

from rebarlib import GEMINI2, save_capture
from rebarlib._camera import ray_directions
from rebarlib.synth import Appearance, CameraPose, Deviations, SensorModel, make_scene, rib_envelope_mm, synth_capture

IDEAL_DEPTH_TOL_MM = 0.01  # the bound for the ideal sensor
NOISE_STD_REL_TOL = 0.10  # measured noise std within 10 % of the model
BIAS_TOL_MM = 0.05


def _ray_cylinder_depth(dirs, p0, p1, r):
    """z-depth where rays from the origin with direction ``dirs`` (z = 1) meet an infinite cylinder."""
    a = (p1 - p0) / np.linalg.norm(p1 - p0)
    dp = dirs - np.outer(dirs @ a, a)
    wp = -p0 - np.dot(-p0, a) * a
    A = (dp * dp).sum(1)
    B = dp @ wp
    C = wp @ wp - r * r
    disc = B * B - A * C
    return (-B - np.sqrt(np.maximum(disc, 0))) / A, disc


@pytest.fixture(scope="module")
def ideal(paper_design):
    return synth_capture(
        paper_design,
        height_mm=520,
        tilt_deg=12,
        yaw_deg=20,
        deviations=Deviations(
            position_sigma_mm=3, height_sigma_mm=1, mesh_yaw_deg=33, spacers=False, chairs=False, ties=False
        ),
        sensor=SensorModel.ideal(),
        intrinsics=GEMINI2.scaled(0.5),
        seed=5,
    )


def test_ideal_depth_on_bars_is_the_analytic_cylinder(ideal):
    K = ideal.intrinsics
    dirs = ray_directions(K)
    checked = 0
    for bar in ideal.truth["bars"]:
        if not bar["visible"]:
            continue
        px = np.flatnonzero(ideal.bar_ids.ravel() == bar["id"] + 1)
        p0, p1 = np.array(bar["axis_start_mm"]), np.array(bar["axis_end_mm"])
        z, disc = _ray_cylinder_depth(dirs[px], p0, p1, bar["envelope_mm"] / 2)
        # stay off the silhouette, where the depth's sensitivity to the truth's 4-decimal axis explodes
        face = disc > 0.2 * (bar["envelope_mm"] / 2) ** 2 * (dirs[px] ** 2).sum(1)
        assert face.sum() > 20
        err = np.abs(ideal.depth_mm.ravel()[px][face] - z[face])
        assert err.max() < IDEAL_DEPTH_TOL_MM, bar["id"]
        checked += 1
    assert checked >= 10


def test_ideal_depth_on_formwork_is_the_plane(ideal):
    n = np.array(ideal.truth["formwork_plane"]["normal"])
    d = ideal.truth["formwork_plane"]["offset_mm"]
    dirs = ray_directions(ideal.intrinsics)
    form = ideal.labels.ravel() == 0
    z_plane = -d / (dirs[form] @ n)
    assert np.abs(ideal.depth_mm.ravel()[form] - z_plane).max() < IDEAL_DEPTH_TOL_MM


def test_truth_heights_follow_the_design(paper_design):
    cap = synth_capture(
        paper_design,
        height_mm=450,
        tilt_deg=0,
        deviations=Deviations.none(),
        sensor=SensorModel.ideal(),
        intrinsics=GEMINI2.scaled(0.25),
        seed=1,
    )
    t = cap.truth
    assert t["cover_mm"] == pytest.approx(20) and t["layer_distance_mm"] == pytest.approx(85)
    assert t["upper_top_mm"] == pytest.approx(20 + 85 + 24)
    assert t["camera"]["height_mm"] == pytest.approx(450)
    assert all(s["spacing_mm"] == pytest.approx(200) for s in t["spacings"])
    by_level = {(b["layer"], b["level"]): b for b in t["bars"]}
    assert by_level[("lower", "top")]["underside_mm"] == pytest.approx(20 + 14)


def test_rib_envelope_table():
    assert rib_envelope_mm(12) == 13.9 and rib_envelope_mm(8) == 9.3 and rib_envelope_mm(14) == 16.2


def test_missing_and_wrong_size_bars(paper_design):
    scene = make_scene(paper_design, Deviations(missing=2, wrong_size=1), rng=4)
    assert len(scene.missing) == 2
    wrong = [b for b in scene.bars if b.nominal_mm != b.design_mm]
    assert len(wrong) == 1 and wrong[0].nominal_mm in (10, 12, 14, 16)


def test_camera_pose_height_tilt_and_target():
    pose = CameraPose.looking_down(500, tilt_deg=15, yaw_deg=40, target_mm=(100, -50))
    assert pose.centre[2] == pytest.approx(500)
    axis = pose.rotation.T @ [0, 0, 1]
    assert np.degrees(np.arccos(-axis[2])) == pytest.approx(15)
    hit = pose.centre + axis * (500 / -axis[2])
    assert hit[:2] == pytest.approx([100, -50])
    assert np.allclose(pose.rotation @ pose.rotation.T, np.eye(3)) and np.linalg.det(pose.rotation) == pytest.approx(1)


@pytest.mark.parametrize("bias", [0.0, 8.0])
def test_realistic_noise_matches_the_model(paper_design, bias):
    sensor = SensorModel(edge_hole_prob=0, flying_pixel_prob=0, edge_fatten_prob=0, bias_mm_per_m2=bias, quantize=False)
    ideal = SensorModel.ideal()
    kw = dict(height_mm=550, tilt_deg=0, deviations=Deviations.none(), intrinsics=GEMINI2.scaled(0.5), seed=2)
    real = synth_capture(paper_design, sensor=sensor, **kw)
    exact = synth_capture(paper_design, sensor=ideal, **kw)
    form = cv2.erode((exact.labels == 0).astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    form &= real.depth_mm > 0
    z_true, z = exact.depth_mm[form], real.depth_mm[form]
    z = z - bias * (z_true / 1000) ** 2
    f = real.intrinsics.fx
    # in disparity, the model is N(0, sigma_d) plus uniform rounding to the sub-pixel step
    ddisp = f * sensor.baseline_mm / z - f * sensor.baseline_mm / z_true
    expected = np.hypot(sensor.disparity_sigma_px, sensor.subpixel_px / np.sqrt(12))
    assert np.std(ddisp) == pytest.approx(expected, rel=NOISE_STD_REL_TOL)
    assert abs(np.mean(z - z_true)) < BIAS_TOL_MM + 0.02 * sensor.sigma_z_mm(550, f)
    # and sigma_z grows with z^2 as the model says
    assert sensor.sigma_z_mm(1000, 616.4) == pytest.approx(4 * sensor.sigma_z_mm(500, 616.4))


def test_realistic_sensor_makes_holes_at_bar_edges(paper_design):
    cap = synth_capture(paper_design, height_mm=500, intrinsics=GEMINI2.scaled(0.5), seed=3)
    holes = cap.depth_mm == 0
    assert 0.01 < holes.mean() < 0.2
    edges = cv2.morphologyEx((cap.labels > 0).astype(np.uint8), cv2.MORPH_GRADIENT, np.ones((3, 3), np.uint8)) > 0
    assert holes[edges].mean() > 5 * holes[~edges].mean()


def test_wider_edge_fattening_gives_the_background_the_nearer_depth_further_out(paper_design):
    # the share of the formwork pixels 2 and 3 px from a bar's silhouette that read nearer than
    # they are (by more than the 5 mm edge step): measured 0.58 and 0.31 with 3 px of fattening
    # (probability 0.6, 0.4, 0.2 at 1, 2, 3 px), 0.23 and 0.003 with the default 1 px (the 2 px
    # ones: the pixel positions' jitter)
    kw = dict(height_mm=500, tilt_deg=5, intrinsics=GEMINI2.scaled(0.5), seed=4)
    ideal = synth_capture(paper_design, sensor=SensorModel.ideal(), **kw).depth_mm.astype(float)
    fat = SensorModel(edge_fatten_px=3, edge_fatten_prob=0.6, edge_hole_prob=0.2)

    def nearer(sensor):
        cap = synth_capture(paper_design, sensor=sensor, **kw)
        dist = cv2.distanceTransform((cap.labels == 0).astype(np.uint8), cv2.DIST_L2, 5)
        ok = (cap.depth_mm > 0) & (ideal > 0)
        near = ideal - cap.depth_mm > 5
        return [near[ok & (dist > j - 0.5) & (dist <= j + 0.5)].mean() for j in (2, 3)]

    (f2, f3), (d2, d3) = nearer(fat), nearer(SensorModel())
    assert f2 > d2 + 0.2 and f3 > 0.2 > 0.02 > d3


def test_same_seed_same_bytes(paper_design, tmp_path):
    kw = dict(height_mm=480, tilt_deg=7, intrinsics=GEMINI2.scaled(0.25), appearance=Appearance(rust_fraction=0.5))

    def digest(folder):
        return {p.name: hashlib.sha256(p.read_bytes()).hexdigest() for p in sorted(folder.iterdir())}

    a = save_capture(synth_capture(paper_design, seed=9, **kw), tmp_path / "a")
    b = save_capture(synth_capture(paper_design, seed=9, **kw), tmp_path / "b")
    c = save_capture(synth_capture(paper_design, seed=10, **kw), tmp_path / "c")
    assert digest(a) == digest(b)
    assert digest(a)["depth.png"] != digest(c)["depth.png"]


def test_cli_synth(tmp_path, capsys):
    from rebarlib.cli import main

    design = tmp_path / "design.toml"
    design.write_text(
        '[slab]\nid="X"\n[design]\ncover_mm=15\nlayer_distance_mm=54\n'
        "[design.lower]\ndiameter_mm=8\nspacing_mm=150\n[design.upper]\ndiameter_mm=8\nspacing_mm=150\n"
    )
    assert main(["synth", "--design", str(design), "--height", "450", "--seed", "1", str(tmp_path / "cap")]) == 0
    assert "cover 1" in capsys.readouterr().out
    assert (tmp_path / "cap" / "truth.json").is_file()
    assert main(["synth", "--design", str(design), str(tmp_path / "cap")]) == 2  # never overwrites
    assert "not empty" in capsys.readouterr().err


def test_pixel_samples_mix_colours_at_edges_only(paper_design, tmp_path):
    # a camera's pixel integrates the light over its area: with several rays per pixel the
    # pixels an edge crosses take a mixed colour, the rest keep theirs, and the depth, labels
    # and truth (about pixel centres) stay those of the one-ray render
    kw = dict(height_mm=480, tilt_deg=7, intrinsics=GEMINI2.scaled(0.25), seed=4)
    one = synth_capture(paper_design, appearance=Appearance(noise_sigma=0.0), **kw)
    many = synth_capture(paper_design, appearance=Appearance(noise_sigma=0.0, pixel_samples=3), **kw)
    a = save_capture(one, tmp_path / "a")
    b = save_capture(many, tmp_path / "b")
    for name in ("depth.png", "labels.png", "bar_ids.png"):
        assert (a / name).read_bytes() == (b / name).read_bytes(), name
    ta, tb = one.metadata["truth"], many.metadata["truth"]
    assert tb["appearance"].pop("pixel_samples") == 3 and ta["appearance"].pop("pixel_samples") == 1
    assert ta == tb
    lab = one.labels.astype(np.int16)
    k3 = np.ones((3, 3), np.uint8)
    edge = cv2.dilate(lab.astype(np.uint8), k3) != cv2.erode(lab.astype(np.uint8), k3)
    diff = np.abs(one.color.astype(int) - many.color.astype(int)).max(axis=2)
    inner = ~cv2.dilate(edge.astype(np.uint8), k3).astype(bool)
    assert np.median(diff[inner]) <= 2
    # away from bar edges, shadow edges, wood grain and ribs mix too (measured: 6.5 % of those
    # pixels change by 8 grey levels or more, 37 % of the pixels at bar edges)
    assert np.mean(diff[edge] >= 8) >= 4 * np.mean(diff[inner] >= 8)
    # light is neither made nor lost: the image's mean stays within 1 %
    assert abs(many.color.mean() - one.color.mean()) <= 0.01 * one.color.mean()


@pytest.mark.parametrize("bad", [0, 9, 2.5, "3", True])
def test_pixel_samples_must_be_a_small_whole_number(bad):
    from rebarlib import RebarInputError

    with pytest.raises(RebarInputError, match="pixel_samples"):
        Appearance(pixel_samples=bad)


def test_ribs_in_relief_reach_the_envelope_only_at_their_crests():
    """Rays straight down on a bar along x drawn in relief (GB Φ12: core 11.5, ribs 1.2 high,
    8 mm apart), turned so that its longitudinal ribs lie on top and underneath: the transverse
    ribs form its silhouette. Hand-computed: the top is the longitudinal rib, r1 + h above the
    axis, facing up; beside the axis a ray at r1 + h/2 meets the bar at a rib's middle and
    misses it half-way between two ribs; a ray just inside the core meets it anywhere."""
    from rebarlib.synth.raycast import _ray_relief, _relief_params

    r1, h, pitch = _relief_params(12)
    assert (2 * r1, h, pitch) == pytest.approx((11.5, 1.2, 8.0))
    z0 = 100.0
    # u = a x z = -y, so psi = phi - pi/2 is pi/2 on the +y side (its ribs at s = k * pitch) and
    # -pi/2 on the -y side (shifted by shift * pitch); the longitudinal ribs (psi 0, pi) lie at ±z
    shift = 0.5
    rib = np.array([r1, h, pitch, shift, np.pi / 2, 0.0])

    def cast(x, y):
        o = np.array([[x, y, z0 + 50.0]])
        t, n, hit = _ray_relief(
            o, np.array([[0.0, 0.0, -1.0]]), np.array([[-96.0, 0, z0]]), np.array([[100.0, 0, z0]]), rib[None]
        )
        return t[0], n[0], bool(hit[0])

    t, n, hit = cast(3.0, 0.0)
    assert hit and 50.0 - t == pytest.approx(r1 + h, abs=1e-3)
    assert n == pytest.approx([0, 0, 1], abs=1e-2)
    # x = -100 + s: the +y side's ribs at x = 0, 8, ..., the -y side's at x = 4, 12, ...
    assert cast(0.0, r1 + h / 2)[2] and not cast(pitch / 2, r1 + h / 2)[2]
    assert cast(pitch / 2, -(r1 + h / 2))[2] and not cast(0.0, -(r1 + h / 2))[2]
    assert all(cast(x, y)[2] for x in np.linspace(0, pitch, 9) for y in (r1 - 0.05, -(r1 - 0.05)))
    assert not cast(0.0, r1 + h + 0.05)[2]


def test_ribs_in_relief_leave_smooth_renders_alone_and_narrow_the_silhouette(paper_design):
    """rib_relief draws the same scene (same bars, same truth) with a silhouette between the core
    and the envelope; without it the render is the envelope's, as before."""
    kw = dict(height_mm=450, tilt_deg=0, sensor=SensorModel.ideal(), intrinsics=GEMINI2.scaled(0.5), seed=3)
    smooth = synth_capture(paper_design, deviations=Deviations(spacers=False, chairs=False, ties=False), **kw)
    relief = synth_capture(
        paper_design, deviations=Deviations(spacers=False, chairs=False, ties=False, rib_relief=True), **kw
    )
    same = ("id", "axis_start_mm", "axis_end_mm", "envelope_mm", "underside_mm")
    assert [[b[k] for k in same] for b in relief.truth["bars"]] == [[b[k] for k in same] for b in smooth.truth["bars"]]
    a_s, a_r = (smooth.labels > 0).sum(), (relief.labels > 0).sum()
    # the bars' image area shrinks by about the share of the silhouette between ribs, which is
    # below the envelope: between the core's (d1 / (d1 + 2h), 0.83 for Φ12) and 1
    assert 0.83 * a_s < a_r < 0.99 * a_s


@pytest.mark.parametrize("formwork", ["plywood", "film", "plastic"])
def test_every_capture_of_a_slab_shows_the_same_board_whatever_rusts(paper_design, formwork):
    """The formwork's texture belongs to the slab: a capture with rusty bars shows the same board
    as one without (once, the rust was drawn first and moved the board's noise fields)."""
    shots = []
    for rust in (0.0, 0.5):
        app = Appearance(rust_fraction=rust, formwork=formwork)
        cap = synth_capture(
            paper_design, seed=3, scene_seed=11, appearance=app, intrinsics=GEMINI2.scaled(0.25), tilt_deg=5
        )
        shots.append(cap)
    board = (shots[0].labels == 0) & (shots[1].labels == 0)
    assert board.mean() > 0.3
    assert np.array_equal(shots[0].color[board], shots[1].color[board])


def test_ribs_in_relief_are_marched_a_bounded_number_of_rays_at_a_time(paper_design, monkeypatch):
    # the rays that reach a bar drawn in relief are marched through its ribs in chunks, so that a
    # supersampled image with many bars in view holds a bounded amount at once (a D435-like
    # image at 3 x 3 samples a pixel once held ~10 GB); each ray's hit is its own, so the image is
    # the same to the bit whatever the chunk
    import rebarlib.synth.raycast as rc

    kw = dict(
        height_mm=450,
        tilt_deg=15,
        seed=4,
        intrinsics=GEMINI2.scaled(0.25),
        deviations=Deviations(rib_relief=True),
        appearance=Appearance(pixel_samples=2),
    )
    whole = synth_capture(paper_design, **kw)
    calls = []
    march = rc._ray_relief

    def counted(o, *a, **k):
        calls.append(len(o))
        return march(o, *a, **k)

    monkeypatch.setattr(rc, "RELIEF_CHUNK", 500)
    monkeypatch.setattr(rc, "_ray_relief", counted)
    chunked = synth_capture(paper_design, **kw)
    assert max(c for c in calls if c <= 500) == 500 and any(c > 500 for c in calls)  # split, not just small
    for name in ("color", "depth_mm", "labels"):
        assert np.array_equal(getattr(whole, name), getattr(chunked, name)), name
