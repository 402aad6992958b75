"""Rendering: the camera's pose, how the colour image looks, and one RGB-D capture of a scene
with its labels and ground truth (:func:`render_capture`, :func:`synth_capture`)."""

from __future__ import annotations

import math
from dataclasses import dataclass, replace
from typing import NamedTuple

import numpy as np

from .._camera import GEMINI2, Intrinsics, ray_directions
from .._capture import Capture
from .._checks import RebarInputError, check_positive
from .._design import Design
from .raycast import K_BAR, K_CHAIR, K_FORMWORK, K_SPACER, K_TIE, _build_geometry, _Caster
from .scene import Deviations, SlabScene, make_scene
from .sensor import SensorModel, _remove_bar_depth, _sensor_depth
from .truth import _truth

__all__ = [
    "Appearance",
    "CameraPose",
    "render_capture",
    "synth_capture",
    "misregister",
    "FORMWORKS",
    "LABEL_BACKGROUND",
    "LABEL_LOWER",
    "LABEL_UPPER",
]

LABEL_BACKGROUND, LABEL_LOWER, LABEL_UPPER = 0, 1, 2
FORMWORKS = ("plywood", "film", "plastic")


@dataclass(frozen=True)
class Appearance:
    """How the colour image looks. ``None`` fields are drawn at random from the seed.

    Attributes
    ----------
    formwork : "plywood", "film" (black film-faced board) or "plastic"
    rust_fraction : fraction of bars that are rusty
    sun_elevation_deg, sun_azimuth_deg : direction of the light casting shadows
    ambient : share of light that reaches shadowed surfaces
    exposure : overall gain; noise_sigma : colour sensor noise (8-bit units)
    blur_px : Gaussian blur sigma; jpeg_quality : JPEG round trip of the colour image
    pixel_samples : the colour of a pixel is the mean of ``pixel_samples`` x ``pixel_samples``
        rays spread over its area (in linear light), as a camera's pixel integrates the light
        falling on it: an edge crossing a pixel gives it a mixed colour. 1: one ray through the
        pixel's centre, so every edge is a hard step placed to the nearest pixel (aliased), and
        a bar along the pixel rows shows a width rounded to whole pixels whatever its true width
    cast_shadows : False renders no cast shadows (surfaces facing away from the sun stay dark);
        used only to tell cast from attached shadow when evaluating
    """

    formwork: str | None = None
    rust_fraction: float = 0.0
    sun_elevation_deg: float | None = None
    sun_azimuth_deg: float | None = None
    ambient: float = 0.35
    exposure: float = 1.0
    noise_sigma: float = 2.5
    blur_px: float = 0.0
    jpeg_quality: int | None = None
    cast_shadows: bool = True
    pixel_samples: int = 1

    def __post_init__(self):
        if self.formwork is not None and self.formwork not in FORMWORKS:
            raise RebarInputError(f"formwork: expected one of {FORMWORKS}, got {self.formwork!r}")
        if (
            isinstance(self.pixel_samples, bool)
            or not isinstance(self.pixel_samples, (int, np.integer))
            or not 1 <= self.pixel_samples <= 8
        ):
            raise RebarInputError(
                f"pixel_samples: expected a whole number of rays per pixel side from 1 to 8, got {self.pixel_samples!r}"
            )


@dataclass(frozen=True)
class CameraPose:
    """World-to-camera pose: ``X_cam = rotation @ (X_world - centre)`` (OpenCV camera frame)."""

    rotation: np.ndarray
    centre: np.ndarray

    @classmethod
    def looking_down(
        cls, height_mm: float, *, tilt_deg: float = 0.0, yaw_deg: float = 0.0, target_mm=(0.0, 0.0)
    ) -> "CameraPose":
        """Camera ``height_mm`` above the formwork, optical axis tilted ``tilt_deg`` from the
        vertical (the image's top edge raised), turned ``yaw_deg`` about the vertical, with the
        optical axis meeting the formwork at ``target_mm`` (world x, y)."""
        check_positive(height_mm, "height_mm", lo=50, hi=5000)
        if not 0 <= tilt_deg < 60:
            raise RebarInputError(f"tilt_deg: expected 0..60 degrees, got {tilt_deg!r}")
        t, y = math.radians(tilt_deg), math.radians(yaw_deg)
        # Looking straight down: camera x = world x, camera y = -world y, camera z = -world z.
        down = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])
        cy, sy = math.cos(y), math.sin(y)
        yaw = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1.0]])
        ct, st = math.cos(t), math.sin(t)
        pitch = np.array([[1.0, 0, 0], [0, ct, -st], [0, st, ct]])  # about the camera x axis
        rotation = pitch @ down @ yaw.T
        axis_world = rotation.T @ np.array([0, 0, 1.0])
        centre = np.array([target_mm[0], target_mm[1], 0.0]) - axis_world * (height_mm / -axis_world[2])
        return cls(rotation, centre)

    @property
    def extrinsic(self) -> np.ndarray:
        """4x4 world-to-camera matrix."""
        e = np.eye(4)
        e[:3, :3] = self.rotation
        e[:3, 3] = -self.rotation @ self.centre
        return e

    def to_camera(self, points_world) -> np.ndarray:
        """World points (N, 3) in the camera frame."""
        return (np.asarray(points_world, float) - self.centre) @ self.rotation.T


def _value_noise(rng, shape, octaves=3):
    """Smooth random field on a grid, values about 0..1 (sum of up-sampled random grids)."""
    import cv2

    h, w = shape
    out = np.zeros(shape, np.float32)
    amp, tot = 1.0, 0.0
    for o in range(octaves):
        gh, gw = max(2, h >> (octaves - o + 1)), max(2, w >> (octaves - o + 1))
        g = rng.random((gh, gw)).astype(np.float32)
        out += amp * cv2.resize(g, (w, h), interpolation=cv2.INTER_CUBIC)
        tot += amp
        amp *= 0.5
    return np.clip(out / tot, 0, 1)


def _sample(field_img, x, y, extent, cell):
    """Bilinear sample of ``field_img`` (covering [-extent, extent]^2 at ``cell`` mm) at world x, y."""
    import cv2

    n = len(x)
    if n == 0:  # nothing of this kind in view (a capture of bare formwork has no bar pixels)
        return np.zeros((0,) + field_img.shape[2:], np.float32)
    cols = 1024  # remap wants maps under 32767 px a side: lay the samples out in rows
    pad = (-n) % cols
    mx = np.pad(((x + extent) / cell).astype(np.float32), (0, pad)).reshape(-1, cols)
    my = np.pad(((y + extent) / cell).astype(np.float32), (0, pad)).reshape(-1, cols)
    out = cv2.remap(field_img, mx, my, cv2.INTER_LINEAR, borderMode=cv2.BORDER_REFLECT)
    return out.ravel()[:n]


def _formwork_texture(kind, rng):
    """What the formwork's colour is drawn with (its noise fields and the kind's parameters),
    drawn from ``rng``: the slab's own stream, before anything a capture may vary (which bars
    rust), so that every capture of one slab shows the same board."""
    tex = {"kind": kind, "n1": _value_noise(rng, (512, 512)), "n2": _value_noise(rng, (1024, 1024), 2)}
    if kind == "plywood":
        tex["base"] = np.array([0.78, 0.60, 0.40]) * rng.uniform(0.85, 1.1)
        tex["grain_mm"] = rng.uniform(6, 12)
    elif kind == "film":
        tex["base"] = np.array([0.20, 0.14, 0.11]) * rng.uniform(0.8, 1.2)
    else:  # plastic
        tex["base"] = [np.array([0.25, 0.45, 0.75]), np.array([0.55, 0.57, 0.58]), np.array([0.3, 0.6, 0.35])][
            rng.integers(3)
        ]
    return tex


def _formwork_albedo(tex, p, extent):
    """Colour (linear, 0..1) of the formwork at world points ``p``: plywood with grain and sheet
    seams, dusty black film-faced board, or coloured plastic panels (``tex``:
    :func:`_formwork_texture`)."""
    x, y = p[:, 0], p[:, 1]
    n1 = _sample(tex["n1"], x, y, extent, 2 * extent / 512)
    n2 = _sample(tex["n2"], x, y, extent, 2 * extent / 1024)
    kind, base = tex["kind"], tex["base"]
    if kind == "plywood":
        grain = 0.5 + 0.5 * np.sin(2 * np.pi * (x + 60 * n1) / tex["grain_mm"])
        shade = 0.82 + 0.12 * grain + 0.18 * (n2 - 0.5)
        seams = (np.abs(((y + extent) % 1220) - 610) > 608) | (np.abs(((x + extent) % 2440) - 1220) > 1218)
        shade = np.where(seams, 0.45, shade)
    elif kind == "film":
        shade = 0.85 + 0.3 * (n1 - 0.5) + 0.15 * (n2 - 0.5)
        dust = n2 > 0.72
        shade = np.where(dust, shade * 1.8, shade)
    else:  # plastic
        shade = 0.92 + 0.1 * (n2 - 0.5)
        seams = (np.abs(((y + extent) % 500) - 250) > 247) | (np.abs(((x + extent) % 500) - 250) > 247)
        shade = np.where(seams, 0.6, shade)
    return np.clip(shade[:, None] * base, 0, 1)


def _bar_albedo(scene, bar_of_px, p, rust_of_bar, rng):
    """Colour (linear, 0..1) of bar ``bar_of_px`` at world points ``p``: steel, rust patches
    on rusty bars, and the ribs' shading where they are drawn as an envelope."""
    axis0 = np.array([b.axis[0] for b in scene.bars])
    dirs = np.array([b.direction for b in scene.bars])
    radius = np.array([b.radius_mm for b in scene.bars])
    s = ((p - axis0[bar_of_px]) * dirs[bar_of_px]).sum(1)  # position along the bar
    steel = np.array([0.36, 0.35, 0.34])
    rust = np.array([0.55, 0.27, 0.12])
    pitch = 0.7 * 2 * radius[bar_of_px]
    # ribs drawn as an envelope are hinted at by their shading; in relief they shade themselves
    drawn = scene.deviations.ribs and not scene.deviations.rib_relief
    ribs = 0.85 + 0.15 * np.abs(np.sin(np.pi * s / pitch)) if drawn else 1.0
    field_img = _value_noise(rng, (64, 2048), 3)
    patch = _sample(field_img, s, bar_of_px * 40.0, 2048 / 2, 1.0)
    amount = np.clip((patch - (1 - rust_of_bar[bar_of_px])) * 4, 0, 1)[:, None]
    col = (1 - amount) * steel + amount * rust
    return np.clip(col * (ribs * (0.9 + 0.2 * patch))[:, None], 0, 1)


class _Hits(NamedTuple):
    """What the rays through a set of pixels hit (one row per ray)."""

    d_world: np.ndarray  # world ray directions, scaled so that t is the z-depth
    t: np.ndarray  # z-depth of the hit (inf on a miss)
    normal: np.ndarray
    hit: np.ndarray
    p: np.ndarray  # world point hit
    kind: np.ndarray  # object kind (``K_*``; -1 on a miss)
    bar_of: np.ndarray  # bar index (-1: none)
    leave: tuple  # (lift, own): how a shadow ray leaves the surface (``_cast``)


def _cast(geo, caster, lens: Intrinsics, pose: CameraPose, pixels=None) -> _Hits:
    """What the rays through ``pixels`` (default: every pixel's centre) of a camera with ``lens``
    at ``pose`` hit."""
    d_world = ray_directions(lens, pixels) @ pose.rotation  # rows: R^T d; z = 1: t is the z-depth
    origins = np.broadcast_to(pose.centre, d_world.shape).copy()
    t, obj, normal = caster.first_hit(origins, d_world)
    hit = np.isfinite(t)
    p = origins + d_world * np.where(hit, t, 0)[:, None]
    o = np.maximum(obj, 0)
    kind = np.where(hit, geo.obj_kind[o], -1)
    bar_of = np.where(kind == K_BAR, geo.obj_bar[o], -1)
    # How shadow rays leave the surface: they start just off it; on bars, outside the
    # circumscribing prism (up to 2 % of the radius beyond the true cylinder), or a bar would
    # shadow itself; a point on a bar in relief lies inside its own prism: its rays pass
    # through that first (Caster.occluded's ``own``).
    lift = 0.05 + np.where(kind == K_BAR, 0.03 * geo.seg_r[o], 0.0)
    own = np.where(hit & (kind == K_BAR) & np.isfinite(geo.seg_rib[o, 0]), o, -1)
    return _Hits(d_world, t, normal, hit, p, kind, bar_of, (lift, own))


def render_capture(
    scene: SlabScene,
    pose: CameraPose,
    *,
    intrinsics: Intrinsics = GEMINI2,
    sensor: SensorModel | None = None,
    appearance: Appearance | None = None,
    rng=None,
    name: str = "synthetic",
) -> Capture:
    """Render one RGB-D capture of ``scene`` seen from ``pose``, with ground truth.

    Returns a :class:`~rebarlib.Capture` with ``labels``, ``bar_ids`` and ``metadata["truth"]``
    (docs/formats.md, "truth.json", lists the keys). Deterministic for a given ``rng`` seed.
    """
    rng = np.random.default_rng(rng)
    sensor = sensor or SensorModel()
    app = appearance or Appearance()
    H, W = intrinsics.height, intrinsics.width
    lens = sensor.true_intrinsics(intrinsics)  # the capture is saved with ``intrinsics``
    geo = _build_geometry(scene)
    caster = _Caster(geo)
    hits = _cast(geo, caster, lens, pose)
    z_true = np.where(hits.hit, hits.t, 0.0).reshape(H, W)
    layer_of_bar = np.array([LABEL_LOWER if b.layer == "lower" else LABEL_UPPER for b in scene.bars] + [0])
    labels = layer_of_bar[hits.bar_of].astype(np.uint8).reshape(H, W)
    bar_ids = (hits.bar_of + 1).astype(np.int32).reshape(H, W)
    depth = _sensor_depth(z_true, hits.p, hits.normal, hits.hit, pose, intrinsics, sensor, caster, rng, hits.leave)
    img, formwork, light, rust_of_bar = _colour(scene, pose, lens, app, geo, caster, hits, rng)
    # the truth is about the pixel centres
    truth = _truth(scene, pose, intrinsics, bar_ids, hits.p, formwork, light, rust_of_bar, sensor, app)
    no_depth = _remove_bar_depth(depth, bar_ids, truth, sensor.bars_without_depth, rng)
    for tb in truth["bars"]:
        tb["no_depth"] = tb["id"] in no_depth
    meta = {
        "depth_scale_mm": sensor.depth_scale_mm,
        "device": "rebarlib synthetic (Gemini-2-like)",
        "name": name,
        "truth": truth,
    }
    return Capture(img, depth, intrinsics, meta, labels, bar_ids)


def _colour(
    scene: SlabScene, pose: CameraPose, lens: Intrinsics, app: Appearance, geo, caster, hits: _Hits, rng
) -> tuple:
    """The colour image (H, W, 3 uint8) and what it was drawn with: the formwork's kind, the
    light's direction (world) and each bar's rust (0..1, one more entry for "no bar").

    What belongs to the slab (formwork kind and texture, which bars rust) is drawn from its key,
    so every capture of one slab agrees; the sun and the sensor noise from ``rng``."""
    slab_rng = np.random.default_rng([scene.key, 1])
    formwork = app.formwork or FORMWORKS[slab_rng.integers(len(FORMWORKS))]
    elev = math.radians(app.sun_elevation_deg if app.sun_elevation_deg is not None else rng.uniform(35, 75))
    azim = math.radians(app.sun_azimuth_deg if app.sun_azimuth_deg is not None else rng.uniform(0, 360))
    light = np.array([math.cos(elev) * math.cos(azim), math.cos(elev) * math.sin(azim), math.sin(elev)])
    # the board's texture before the rust: a capture's rust fraction must not change the board
    texture = _formwork_texture(formwork, slab_rng)
    rust_of_bar = np.zeros(len(scene.bars) + 1)
    n_rusty = int(round(app.rust_fraction * len(scene.bars)))
    if n_rusty:
        rust_of_bar[slab_rng.permutation(len(scene.bars))[:n_rusty]] = slab_rng.uniform(0.5, 1.0, n_rusty)
    n_s = int(app.pixel_samples)
    if n_s > 1:  # the colour pass casts n_s² rays spread over each pixel (see Appearance)
        hits = _cast(geo, caster, lens, pose, _subpixels(lens.height, lens.width, n_s))
    albedo = _albedo(scene, texture, hits, rust_of_bar, slab_rng)
    rgb = _shade(app, caster, hits, albedo, light, rust_of_bar, formwork)
    img = _to_image(rgb, n_s, lens.height, lens.width, app, rng)
    return img, formwork, light, rust_of_bar


def _subpixels(H: int, W: int, n_s: int) -> np.ndarray:
    """(n_s² H W, 2) pixel positions: an n_s x n_s grid over each pixel, one grid point of every
    pixel after another."""
    off = (np.arange(n_s) + 0.5) / n_s - 0.5
    oy, ox = np.meshgrid(off, off, indexing="ij")
    v, u = np.mgrid[0:H, 0:W]
    px = np.stack([np.column_stack(((u + dx).ravel(), (v + dy).ravel())) for dx, dy in zip(ox.ravel(), oy.ravel())])
    return px.reshape(-1, 2)


def _albedo(scene: SlabScene, texture: dict, hits: _Hits, rust_of_bar, slab_rng) -> np.ndarray:
    """(N, 3) surface colour (linear, 0..1) of each ray's hit (``texture``: the formwork's,
    :func:`_formwork_texture`); black on a miss."""
    kind, p = hits.kind, hits.p
    albedo = np.zeros((len(hits.t), 3))
    extent = scene.deviations.slab_size_mm * 2
    fw = kind == K_FORMWORK
    albedo[fw] = _formwork_albedo(texture, p[fw], extent)
    bars_px = kind == K_BAR
    albedo[bars_px] = _bar_albedo(scene, hits.bar_of[bars_px], p[bars_px], rust_of_bar, slab_rng)
    albedo[kind == K_SPACER] = [0.62, 0.61, 0.58]
    albedo[kind == K_CHAIR] = [0.35, 0.34, 0.33]
    albedo[kind == K_TIE] = [0.18, 0.18, 0.19]
    return albedo


def _shade(app: Appearance, caster, hits: _Hits, albedo, light, rust_of_bar, formwork: str):
    """(N, 3) linear light from each ray's hit: ambient, direct sun where no object casts a
    shadow, and a specular sheen on steel and film-faced board; 0 on a miss."""
    d_world, t, normal, hit, p, kind, bar_of, leave = hits
    lambert = np.clip(normal @ light, 0, None)
    lit = hit & (lambert > 0)
    idx = np.flatnonzero(lit)
    shadow = np.zeros(len(t), bool)
    if app.cast_shadows:
        shadow[idx] = caster.occluded(
            p[idx] + normal[idx] * leave[0][idx, None],
            np.broadcast_to(light, (len(idx), 3)).copy(),
            1e5,
            own=leave[1][idx],
        )
    direct = np.where(shadow, 0.0, lambert)
    view = -d_world / np.linalg.norm(d_world, axis=1, keepdims=True)
    half_v = (view + light) / np.linalg.norm(view + light, axis=1, keepdims=True)
    fw = kind == K_FORMWORK
    spec_k = np.where(
        kind == K_BAR, 0.25 * (1 - rust_of_bar[bar_of]), np.where(fw & (formwork != "plywood"), 0.15, 0.0)
    )
    spec = spec_k * np.clip((normal * half_v).sum(1), 0, 1) ** 30 * (~shadow)
    shade = app.ambient + (1 - app.ambient) * 1.25 * direct
    rgb = albedo * shade[:, None] + spec[:, None]
    return np.where(hit[:, None], rgb, 0.0)


def _to_image(rgb, n_s: int, H: int, W: int, app: Appearance, rng) -> np.ndarray:
    """The camera's 8-bit image of the rays' light: each pixel's n_s² rays averaged, exposure,
    blur, gamma, sensor noise (drawn from ``rng``) and the JPEG round trip."""
    import cv2

    rgb = rgb.reshape(n_s * n_s, H * W, 3).mean(axis=0) if n_s > 1 else rgb
    rgb = rgb.reshape(H, W, 3) * app.exposure
    if app.blur_px > 0:
        rgb = cv2.GaussianBlur(rgb, (0, 0), app.blur_px)
    noisy = rgb ** (1 / 1.8) * 255 + rng.normal(0, app.noise_sigma, rgb.shape)
    img = np.clip(noisy, 0, 255).astype(np.uint8)
    if app.jpeg_quality:
        ok, buf = cv2.imencode(".jpg", img[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(app.jpeg_quality)])
        img = cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1].copy()
    return img


def synth_capture(
    design: Design,
    *,
    height_mm: float = 500.0,
    tilt_deg: float = 10.0,
    yaw_deg: float = 0.0,
    target_mm=(0.0, 0.0),
    deviations: Deviations | None = None,
    sensor: SensorModel | None = None,
    appearance: Appearance | None = None,
    intrinsics: Intrinsics = GEMINI2,
    seed: int = 0,
    scene_seed: int | None = None,
    name: str = "synthetic",
) -> Capture:
    """Lay out and render one capture of ``design`` in one call (see :func:`make_scene`,
    :func:`render_capture`). ``scene_seed`` fixes the mesh so several captures show one slab.

    Examples
    --------
    >>> from rebarlib import design_from_dict
    >>> d = design_from_dict({"slab": {"id": "S"}, "design": {"cover_mm": 20,
    ...     "layer_distance_mm": 85, "lower": {"diameter_mm": 14, "spacing_mm": 200},
    ...     "upper": {"diameter_mm": 12, "spacing_mm": 200}}})
    >>> cap = synth_capture(d, height_mm=500, tilt_deg=0, sensor=SensorModel.ideal(),
    ...                     deviations=Deviations.none(), intrinsics=GEMINI2.scaled(0.25))
    >>> round(cap.truth["cover_mm"], 6), round(cap.truth["layer_distance_mm"], 6)
    (20.0, 85.0)
    """
    ss = np.random.SeedSequence(seed)
    scene_rng, render_rng = ss.spawn(2)
    if scene_seed is not None:
        scene_rng = np.random.SeedSequence(scene_seed)
    scene = make_scene(design, deviations, rng=np.random.default_rng(scene_rng))
    pose = CameraPose.looking_down(height_mm, tilt_deg=tilt_deg, yaw_deg=yaw_deg, target_mm=target_mm)
    return render_capture(
        scene,
        pose,
        intrinsics=intrinsics,
        sensor=sensor,
        appearance=appearance,
        rng=np.random.default_rng(render_rng),
        name=name,
    )


def misregister(capture: Capture, du: int, dv: int) -> Capture:
    """A copy of ``capture`` whose depth image's content lies ``du`` pixels right and ``dv``
    down of where it was against the colour image (whole pixels; no depth where it would come
    from beyond the border): the misregistration a camera's depth-to-colour alignment can leave.
    Colour, labels and truth stay the colour image's. The capture given is not changed.

    Examples
    --------
    >>> from rebarlib import Intrinsics
    >>> cap = Capture(np.zeros((2, 4, 3), np.uint8), np.array([[1.0, 2, 3, 4], [5, 6, 7, 8]]),
    ...               Intrinsics(10.0, 10.0, 2.0, 1.0, 4, 2))
    >>> misregister(cap, 1, -1).depth_mm.tolist()
    [[0.0, 5.0, 6.0, 7.0], [0.0, 0.0, 0.0, 0.0]]
    """
    du, dv = int(du), int(dv)
    h, w = capture.depth_mm.shape
    depth = np.zeros_like(capture.depth_mm)
    depth[max(dv, 0) : h + min(dv, 0), max(du, 0) : w + min(du, 0)] = capture.depth_mm[
        max(-dv, 0) : h + min(-dv, 0), max(-du, 0) : w + min(-du, 0)
    ]
    return replace(capture, depth_mm=depth)
