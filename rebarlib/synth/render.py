"""Synthetic RGB-D captures of a double-layer bar mesh on formwork, with exact ground truth.

The scene lives in a *world* frame: formwork top surface at z = 0, z up, mesh centred on the
origin. Bars are exact cylinders: Open3D's ``RaycastingScene`` finds which object a ray meets
first (on slightly over-sized prisms), then the hit is refined analytically against the true
cylinder, so depths on bars are exact to floating-point precision with the ideal sensor.

Ground truth (``Capture.metadata["truth"]``) follows the definitions of docs/method.md:
cover = formwork top to the underside of the lower lattice's lowest bars; layer distance =
underside of the lower lattice's lowest bars to underside of the upper lattice's lowest bars;
spacing = centre-to-centre distance between adjacent parallel bars. Bars are placed by their
visible (rib) envelope: cover and layer distance are measured to the envelope, like a tape would.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, replace

import numpy as np

from ._camera import GEMINI2, Intrinsics, ray_directions
from ._capture import Capture
from ._checks import RebarInputError, check_positive
from ._design import Design
from ._ribs import _GB_RIB_PITCH, _GB_RIBS, rib_envelope_mm

__all__ = ["Deviations", "SensorModel", "Appearance", "CameraPose", "Bar", "SlabScene",
           "make_scene", "render_capture", "synth_capture", "rib_envelope_mm", "misregister", "dropout_mask"]

LABEL_BACKGROUND, LABEL_LOWER, LABEL_UPPER = 0, 1, 2

# --------------------------------------------------------------------------------------------
# Parameters


@dataclass(frozen=True)
class Deviations:
    """As-built deviations of the mesh from its design (all mm / degrees).

    Attributes
    ----------
    position_sigma_mm : std dev of each bar's offset across its direction (spacing varies bar to bar)
    height_sigma_mm : std dev of each bar's height (local cover deviations)
    bow_mm : in-plan sagitta of each bar over its full length (random sign)
    mesh_yaw_deg : rotation of the whole mesh in plan
    stacked : each upper bar right above the lower bar of its direction (before the position
        jitter; where both sets have one spacing): the lower bars are then seen only as slivers
        beside the upper bars
    missing : number of bars left out (never the outermost of a set)
    wrong_size : number of bars of another standard size than designed
    ribs : deformed bars, drawn with their rib envelope (GB 1499.2 d1 + 2h)
    rib_relief : with ``ribs``, draw the ribs in relief instead of as a smooth envelope: a core of
        diameter d1, two longitudinal ribs and crescent transverse ribs of height h at GB 1499.2's
        spacing, each bar turned to a random roll and with a random shift between the ribs of its
        two sides (:func:`_relief_radius`). A silhouette then reaches the envelope d1 + 2h at most
        at the rib crests and is d1 wide between them, as on a real deformed bar; the truth's
        ``envelope_mm`` stays d1 + 2h. Off by default (renders are unchanged)
    spacers, chairs, ties : cover blocks under the lower lattice, chairs between the lattices,
        tie wire at crossings
    slab_size_mm : extent of the (square) mesh
    end_overhang_mm : None (the default, kept so that earlier renders stay identical): every bar
        runs the whole ``slab_size_mm``. A number: a finite mesh as tied on site: each bar ends
        this far beyond the outermost bar crossing it, so the mesh's edge is where the crossing
        bars end; captures aimed near the edge (``target_mm``) show formwork beyond the mesh
    edge_form : with ``end_overhang_mm``, boards standing at the slab's edges, 25 mm beyond the
        bar ends, as high as the slab (``design.thickness_mm``, or the mesh's top + 30 mm)
    missing_at_end : number of bars left out at the end of a row (the outermost of a set)
    extra : number of bars added half-way between two design positions (same size as designed)
    position_uniform_mm : each bar's offset also moves by a uniform draw in ± this (on top of
        ``position_sigma_mm``): spacings off their design value by up to twice it
    """

    position_sigma_mm: float = 2.0
    height_sigma_mm: float = 0.5
    bow_mm: float = 0.0
    mesh_yaw_deg: float = 0.0
    stacked: bool = False
    missing: int = 0
    wrong_size: int = 0
    ribs: bool = True
    rib_relief: bool = False
    spacers: bool = True
    chairs: bool = True
    ties: bool = True
    slab_size_mm: float = 2000.0
    end_overhang_mm: float | None = None
    edge_form: bool = False
    missing_at_end: int = 0
    extra: int = 0
    position_uniform_mm: float = 0.0

    @classmethod
    def none(cls) -> "Deviations":
        """A mesh exactly as designed (no jitter, no ribs, no accessories): for unit tests."""
        return cls(position_sigma_mm=0.0, height_sigma_mm=0.0, ribs=False, spacers=False,
                   chairs=False, ties=False)


@dataclass(frozen=True)
class SensorModel:
    """Active-stereo depth sensor (docs/sensors.md). The default is a realistic Gemini-2-like unit.

    Attributes
    ----------
    baseline_mm, disparity_sigma_px : axial noise sigma_z = z^2 sigma_d / (f B)
    noise_correlation_px : the noise is smoothed over this many px (stereo matching windows
        correlate neighbouring pixels); 0 = independent pixels
    subpixel_px : disparity quantisation step (1/8 px); 0 = none
    lateral_jitter_px : sigma of the pixel position jitter (simkinect)
    edge_jump_mm : a depth step above this between neighbours is a discontinuity
    edge_hole_prob, edge_fatten_prob, flying_pixel_prob : what happens to pixels next to a
        discontinuity: no depth, foreground depth (edge fattening), or a mixed depth
    edge_fatten_px : how far the nearer surface bleeds over an edge. 1: the pixels right next to
        it only; k > 1: a pixel d px from the nearer surface (2 <= d <= k) also takes its depth,
        with probability edge_fatten_prob * (k - d + 1) / k (a stereo matcher's window, 2k+1 px,
        straddles the edge and its disparity is the nearer surface's; docs/sensors.md: "a few
        pixels")
    projector_shadow : no depth where the projector cannot see; it sits ``projector_offset_mm``
        from the camera along x (between the two IR cameras on most active-stereo units)
    bias_mm_per_m2 : distance-dependent bias b = k z^2 (z in m), positive = too far (too low)
    depth_scale_mm : mm per unit of the stored 16-bit depth
    quantize : store depth on the depth_scale_mm grid (as read back from a file)
    depth_scale_error, depth_offset_mm : systematic depth error of an uncalibrated unit: the
        stored depth is ``(1 + depth_scale_error) * z + depth_offset_mm`` (0.015: 1.5 % too far)
    focal_error : the lens's true focal lengths are ``(1 + focal_error)`` times the intrinsics
        written with the capture (a factory calibration that is off); the rays are cast through
        the true ones
    bars_without_depth : number of lower-lattice bars in view (at least 400 mm of them seen) that
        have no depth at all, as where a bar lies in the projector's shadow of the bar above it
        or is too dark for the matcher; they stay in the colour image (truth: ``no_depth``)
    dropout : fraction of the pixels with depth that lose it (0..1): wet, black or sunlit
        surfaces the matcher finds nothing on
    dropout_patch_px : 0 = each pixel drops out on its own (at random); k > 0 = the lost pixels
        come in blobs about k px across (a wet patch, a glare spot), placed at random
    """

    baseline_mm: float = 50.0
    disparity_sigma_px: float = 0.08
    noise_correlation_px: float = 1.0
    subpixel_px: float = 1.0 / 8.0
    lateral_jitter_px: float = 0.5
    edge_jump_mm: float = 5.0
    edge_hole_prob: float = 0.35
    edge_fatten_prob: float = 0.35
    edge_fatten_px: int = 1
    flying_pixel_prob: float = 0.15
    projector_shadow: bool = True
    projector_offset_mm: float = 25.0
    bias_mm_per_m2: float = 0.0
    depth_scale_mm: float = 1.0
    max_depth_mm: float = 10_000.0
    quantize: bool = True
    depth_scale_error: float = 0.0
    depth_offset_mm: float = 0.0
    focal_error: float = 0.0
    dropout: float = 0.0
    dropout_patch_px: float = 0.0
    bars_without_depth: int = 0

    def __post_init__(self):
        if not (0.0 <= self.dropout <= 1.0) or not self.dropout_patch_px >= 0:
            raise RebarInputError(f"SensorModel: dropout must be in 0..1 and dropout_patch_px >= 0, got "
                                  f"{self.dropout!r} and {self.dropout_patch_px!r}")

    @classmethod
    def ideal(cls) -> "SensorModel":
        """Exact depth: no noise, holes, jitter or quantisation (depth_scale_mm for saving only)."""
        return cls(disparity_sigma_px=0.0, noise_correlation_px=0.0, subpixel_px=0.0,
                   lateral_jitter_px=0.0, edge_hole_prob=0.0, edge_fatten_prob=0.0,
                   flying_pixel_prob=0.0, projector_shadow=False, depth_scale_mm=0.02,
                   quantize=False)

    def sigma_z_mm(self, z_mm, focal_px: float):
        """Model axial noise (mm) at depth ``z_mm``."""
        return np.asarray(z_mm, float) ** 2 * self.disparity_sigma_px / (focal_px * self.baseline_mm)

    def true_intrinsics(self, written: Intrinsics) -> Intrinsics:
        """The intrinsics the rays are cast through, where ``written`` are those saved with the
        capture (they differ by ``focal_error``)."""
        if not self.focal_error:
            return written
        k = 1.0 + self.focal_error
        return replace(written, fx=written.fx * k, fy=written.fy * k)


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
        if (isinstance(self.pixel_samples, bool) or not isinstance(self.pixel_samples, (int, np.integer))
                or not 1 <= self.pixel_samples <= 8):
            raise RebarInputError(f"pixel_samples: expected a whole number of rays per pixel side "
                                  f"from 1 to 8, got {self.pixel_samples!r}")


@dataclass(frozen=True)
class CameraPose:
    """World-to-camera pose: ``X_cam = rotation @ (X_world - centre)`` (OpenCV camera frame)."""

    rotation: np.ndarray
    centre: np.ndarray

    @classmethod
    def looking_down(cls, height_mm: float, *, tilt_deg: float = 0.0, yaw_deg: float = 0.0,
                     target_mm=(0.0, 0.0)) -> "CameraPose":
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
        return (np.asarray(points_world, float) - self.centre) @ self.rotation.T


# --------------------------------------------------------------------------------------------
# Scene


@dataclass(frozen=True)
class Bar:
    """One bar: a (bowed) polyline axis in the world frame and its envelope radius."""

    id: int
    layer: str  # "lower" | "upper"
    level: str  # "bottom" | "top" (within its lattice)
    index: int  # position across its direction, 0..n-1 in design order
    offset_mm: float  # centre-line offset across the direction (in the mesh frame)
    direction: np.ndarray  # unit in-plan axis direction (world)
    axis: np.ndarray  # (M, 3) polyline, world mm
    nominal_mm: float
    envelope_mm: float
    design_mm: float
    extra: bool = False  # a bar the design does not have (Deviations.extra)

    @property
    def radius_mm(self) -> float:
        return self.envelope_mm / 2

    @property
    def underside_mm(self) -> float:
        return float(self.axis[:, 2].mean() - self.radius_mm)


@dataclass(frozen=True)
class SlabScene:
    """A mesh on formwork: bars, accessories (boxes and thin cylinders), the design it came from."""

    design: Design
    deviations: Deviations
    bars: tuple
    missing: tuple  # (layer, level, index) of design positions left empty
    boxes: tuple  # (centre (3,), half-size (3,), yaw rad, kind)
    rods: tuple  # (p0 (3,), p1 (3,), radius, kind)
    key: int = 0  # seeds what belongs to the slab, not the shot: formwork texture, which bars rust
    ghosts: tuple = ()  # a Bar where each missing bar would have been (same order as ``missing``)


def _sizes_near(size: float) -> list:
    std = sorted(_GB_RIBS)
    i = std.index(size) if size in std else int(np.argmin([abs(s - size) for s in std]))
    return [std[j] for j in (i - 1, i + 1) if 0 <= j < len(std) and std[j] >= 8]


def make_scene(design: Design, deviations: Deviations | None = None, *, rng=None) -> SlabScene:
    """Lay out the mesh of ``design`` with as-built ``deviations`` (random parts drawn from ``rng``)."""
    rng = np.random.default_rng(rng)
    dev = deviations or Deviations()
    half = dev.slab_size_mm / 2
    yaw = math.radians(dev.mesh_yaw_deg)
    ex = np.array([math.cos(yaw), math.sin(yaw), 0.0])
    ey = np.array([-math.sin(yaw), math.cos(yaw), 0.0])
    env = (lambda d: rib_envelope_mm(d)) if dev.ribs else (lambda d: float(d))

    # Design positions of every set, then pick missing / wrong-size bars among inner positions.
    sets, lower_phase = [], {}
    for layer in ("lower", "upper"):
        lat = design.lattice(layer)
        for level in ("bottom", "top"):
            s = lat.level(level).spacing_mm
            phase = rng.uniform(-s / 2, s / 2)
            below = lower_phase.get(level)
            if dev.stacked and layer == "upper" and below is not None and below[1] == s:
                phase = below[0]  # right above the lower bars of its direction
            if layer == "lower":
                lower_phase[level] = (phase, s)
            n = int((2 * half - 2 * 25) // s) + 1
            first = -(n - 1) * s / 2 + phase
            sets.append((layer, level, [first + k * s for k in range(n)]))
    slots = [(si, k) for si, (_, _, offs) in enumerate(sets) for k in range(1, len(offs) - 1)]
    pick = rng.permutation(len(slots))
    missing_slots = {slots[i] for i in pick[:dev.missing]}
    wrong_slots = {slots[i] for i in pick[dev.missing:dev.missing + dev.wrong_size]}
    # the options below draw from ``rng`` only when set, so that earlier renders stay identical
    if dev.missing_at_end:
        ends = [(si, k) for si, (_, _, offs) in enumerate(sets) for k in (0, len(offs) - 1)]
        ends = [e for e in ends if e not in wrong_slots]
        missing_slots |= {ends[i] for i in rng.permutation(len(ends))[:dev.missing_at_end]}
    extra_slots = set()
    if dev.extra:
        gaps = [(si, k) for si, (_, _, offs) in enumerate(sets) for k in range(1, len(offs) - 2)]
        extra_slots = {gaps[i] for i in rng.permutation(len(gaps))[:dev.extra]}
    # a finite mesh: each set's bars run over the crossing set's extent, plus the overhang
    extent = {}
    if dev.end_overhang_mm is not None:
        for layer in ("lower", "upper"):
            offs = {lv: o for (la, lv, o) in sets if la == layer}
            for level, other in (("bottom", "top"), ("top", "bottom")):
                extent[(layer, level)] = (min(offs[other]) - dev.end_overhang_mm,
                                          max(offs[other]) + dev.end_overhang_mm)

    base = {"lower": design.cover_mm, "upper": design.cover_mm + design.layer_distance_mm}
    bars, missing, ghosts = [], [], []
    for si, (layer, level, offsets) in enumerate(sets):
        lat = design.lattice(layer)
        d_design = lat.level(level).diameter_mm
        bottom_env = env(lat.bottom.diameter_mm)
        along, across = (ex, ey) if level == "bottom" else (ey, ex)
        s_lo, s_hi = extent.get((layer, level), (-half, half))
        s_mid, s_half = 0.5 * (s_lo + s_hi), 0.5 * (s_hi - s_lo)
        spacing = lat.level(level).spacing_mm
        placed = [(k, off, False) for k, off in enumerate(offsets)]
        placed += [(k, off + spacing / 2, True) for k, off in enumerate(offsets) if (si, k) in extra_slots]
        for k, off, is_extra in sorted(placed, key=lambda x: x[1]):
            if not is_extra and (si, k) in missing_slots:
                missing.append((layer, level, k))
                # where it would have been (design position and height; no random draw)
                e = env(d_design)
                zc = base[layer] + (e / 2 if level == "bottom" else bottom_env + e / 2)
                s = np.array([s_lo, s_hi])
                ghosts.append(Bar(-1 - len(ghosts), layer, level, k, float(off), along.copy(),
                                  s[:, None] * along + off * across + np.array([0, 0, zc]),
                                  float(d_design), float(e), float(d_design)))
                continue
            nominal = d_design
            if not is_extra and (si, k) in wrong_slots:
                nominal = float(rng.choice(_sizes_near(d_design)))
            e = env(nominal)
            off_true = off + rng.normal(0, dev.position_sigma_mm) if dev.position_sigma_mm else off
            if dev.position_uniform_mm:
                off_true += rng.uniform(-dev.position_uniform_mm, dev.position_uniform_mm)
            z0 = base[layer] + rng.normal(0, dev.height_sigma_mm) if dev.height_sigma_mm else base[layer]
            # bottom bars rest on the spacers; top bars rest on the bottom bars of their lattice
            zc = z0 + e / 2 if level == "bottom" else z0 + bottom_env + e / 2
            n_seg = 12 if dev.bow_mm else 1
            s = np.linspace(s_lo, s_hi, n_seg + 1)
            bow = (dev.bow_mm * rng.choice([-1.0, 1.0]) * (1 - ((s - s_mid) / s_half) ** 2) if dev.bow_mm
                   else 0 * s)
            axis = (s[:, None] * along + (off_true + bow)[:, None] * across
                    + np.array([0, 0, zc]))
            bars.append(Bar(len(bars), layer, level, k, float(off_true), along.copy(), axis, float(nominal),
                            float(e), float(d_design), extra=is_extra))

    boxes, rods = [], []
    lower_b, lower_t = [b for b in bars if b.layer == "lower" and b.level == "bottom"], \
        [b for b in bars if b.layer == "lower" and b.level == "top"]
    if dev.spacers and lower_b:
        pitch = max(2, int(round(800 / design.lower.top.spacing_mm)))
        for b in lower_b[1::pitch]:
            for d_mm in np.arange(150.0, _length(b), 800.0):
                c = b.axis[0] + d_mm * b.direction
                c = np.array([c[0], c[1], (b.axis[:, 2].mean() - b.radius_mm) / 2])
                hs = np.array([25.0, 25.0, c[2]])
                boxes.append((c, hs, yaw, "spacer"))
    upper_b = [b for b in bars if b.layer == "upper" and b.level == "bottom"]
    if dev.chairs and upper_b and lower_t:
        top_of_lower = max(b.axis[:, 2].max() + b.radius_mm for b in lower_t)
        for b in upper_b[1::3]:
            for d_mm in np.arange(300.0, _length(b), 900.0):
                p = b.axis[0] + d_mm * b.direction
                z_top = b.axis[:, 2].mean() - b.radius_mm
                rods.append((np.array([p[0], p[1], top_of_lower]), np.array([p[0], p[1], z_top]), 5.0, "chair"))
    if dev.ties:
        for layer in ("lower", "upper"):
            bot = [b for b in bars if b.layer == layer and b.level == "bottom"]
            top = [b for b in bars if b.layer == layer and b.level == "top"]
            for tb in top:
                for bb in bot[::2] if len(bot) > 6 else bot:
                    # crossing of the two chord lines in plan
                    A = np.column_stack((bb.direction[:2], -tb.direction[:2]))
                    st = np.linalg.solve(A, tb.axis[0, :2] - bb.axis[0, :2])
                    xy = bb.axis[0, :2] + st[0] * bb.direction[:2]
                    z = tb.axis[:, 2].mean() + tb.radius_mm + 0.7
                    diag = (bb.direction + tb.direction) / math.sqrt(2) * (tb.radius_mm + 3)
                    c = np.array([xy[0], xy[1], z])
                    rods.append((c - diag, c + diag, 0.7, "tie"))
    if dev.edge_form and extent:
        boxes.extend(_edge_forms(design, bars, extent, ex, ey, yaw))
    return SlabScene(design, dev, tuple(bars), tuple(missing), tuple(boxes), tuple(rods),
                     key=int(rng.integers(2**31)), ghosts=tuple(ghosts))


def _length(bar: Bar) -> float:
    """Length of a bar's chord (mm)."""
    return float(np.linalg.norm(bar.axis[-1, :2] - bar.axis[0, :2]))


_EDGE_FORM_GAP_MM, _EDGE_FORM_THICKNESS_MM = 25.0, 18.0


def _edge_forms(design: Design, bars, extent: dict, ex, ey, yaw) -> list:
    """Four boards standing at the slab's edges, ``_EDGE_FORM_GAP_MM`` beyond the bar ends."""
    x_lo = min(extent[(la, "bottom")][0] for la in ("lower", "upper")) - _EDGE_FORM_GAP_MM
    x_hi = max(extent[(la, "bottom")][1] for la in ("lower", "upper")) + _EDGE_FORM_GAP_MM
    y_lo = min(extent[(la, "top")][0] for la in ("lower", "upper")) - _EDGE_FORM_GAP_MM
    y_hi = max(extent[(la, "top")][1] for la in ("lower", "upper")) + _EDGE_FORM_GAP_MM
    top = max(float(b.axis[:, 2].max()) + b.radius_mm for b in bars) + 30.0
    height = float(design.thickness_mm) if getattr(design, "thickness_mm", None) else top
    t = _EDGE_FORM_THICKNESS_MM / 2
    out = []
    for x in (x_lo - t, x_hi + t):  # boards across x, running along y
        c = x * ex + 0.5 * (y_lo + y_hi) * ey + np.array([0, 0, height / 2])
        out.append((c, np.array([t, 0.5 * (y_hi - y_lo) + 2 * t, height / 2]), yaw, "edge_form"))
    for y in (y_lo - t, y_hi + t):
        c = 0.5 * (x_lo + x_hi) * ex + y * ey + np.array([0, 0, height / 2])
        out.append((c, np.array([0.5 * (x_hi - x_lo), t, height / 2]), yaw, "edge_form"))
    return out


# --------------------------------------------------------------------------------------------
# Meshes and ray casting

_N_SIDES = 16


def _prism(p0, p1, r, n=_N_SIDES):
    """Triangles of an n-sided prism circumscribing the cylinder p0-p1 of radius r (with caps)."""
    a = p1 - p0
    a = a / np.linalg.norm(a)
    u = np.cross(a, [0, 0, 1.0] if abs(a[2]) < 0.9 else [1.0, 0, 0])
    u /= np.linalg.norm(u)
    w = np.cross(a, u)
    rc = r / math.cos(math.pi / n) * 1.001
    ang = np.arange(n) * 2 * math.pi / n
    ring = rc * (np.cos(ang)[:, None] * u + np.sin(ang)[:, None] * w)
    verts = np.vstack((p0 + ring, p1 + ring, p0, p1))
    i = np.arange(n)
    j = (i + 1) % n
    side = np.vstack((np.column_stack((i, j, n + i)), np.column_stack((j, n + j, n + i))))
    caps = np.vstack((np.column_stack((np.full(n, 2 * n), j, i)),
                      np.column_stack((np.full(n, 2 * n + 1), n + i, n + j))))
    return verts, np.vstack((side, caps))


def _box(c, hs, yaw):
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)], float) * hs
    cy, sy = math.cos(yaw), math.sin(yaw)
    R = np.array([[cy, -sy, 0], [sy, cy, 0], [0, 0, 1.0]])
    verts = corners @ R.T + c
    tris = np.array([[0, 1, 3], [0, 3, 2], [4, 6, 7], [4, 7, 5], [0, 4, 5], [0, 5, 1],
                     [2, 3, 7], [2, 7, 6], [0, 2, 6], [0, 6, 4], [1, 5, 7], [1, 7, 3]])
    return verts, tris


# object kinds, in the per-object table
K_FORMWORK, K_BAR, K_SPACER, K_CHAIR, K_TIE = 0, 1, 2, 3, 4


@dataclass
class _Geometry:
    verts: np.ndarray
    tris: np.ndarray
    tri_obj: np.ndarray  # object index of each triangle
    obj_kind: np.ndarray
    obj_bar: np.ndarray  # bar id of each object (-1 if not a bar segment)
    seg_p0: np.ndarray  # per object: cylinder segment (bars only)
    seg_p1: np.ndarray
    seg_r: np.ndarray
    # per object, for bars drawn in relief: core radius, rib height, rib spacing, shift of the
    # second side's ribs (share of a spacing), roll (rad) and the segment's start along its bar;
    # NaN core radius: a smooth cylinder of radius seg_r
    seg_rib: np.ndarray


def _relief_params(nominal_mm: float) -> tuple[float, float, float]:
    """Core radius, rib height and transverse-rib spacing (mm) of a GB 1499.2 crescent-rib bar;
    sizes not in the table scale from the nearest one."""
    key = min(_GB_RIBS, key=lambda s: abs(s - nominal_mm))
    d1, h = _GB_RIBS[key]
    k = nominal_mm / key
    return d1 * k / 2, h * k, _GB_RIB_PITCH[key] * k


def _relief_radius(s, psi, r1, h, pitch, shift):
    """Surface radius of a crescent-rib bar at ``s`` mm along it and ``psi`` rad around it from
    a longitudinal rib (arrays broadcast together).

    A core of radius ``r1``; two longitudinal ribs (psi = 0 and π) of height ``h``; transverse
    ribs every ``pitch`` on each side between them (those of the side psi in (π, 2π) shifted
    by ``shift`` x ``pitch``), highest (``h``) half-way round and tapering to the longitudinal
    ribs like a crescent. Rib tops 0.1 x the bar diameter wide, flanks at 45°."""
    top = 0.05 * 2 * (r1 + h)  # half the width of a rib's top
    ang = np.abs(np.mod(psi + np.pi / 2, np.pi) - np.pi / 2)  # angle to the nearer longitudinal rib
    longitudinal = h * np.clip((top + h - r1 * ang) / h, 0, 1)
    sin = np.sin(psi)
    x = s / pitch - np.where(sin < 0, shift, 0.0)
    x = np.abs(x - np.round(x)) * pitch  # distance along the bar to the nearest rib's middle
    transverse = h * np.abs(sin) * np.clip((top + h - x) / h, 0, 1)
    return r1 + np.maximum(longitudinal, transverse)


def _build_geometry(scene: SlabScene) -> _Geometry:
    half = scene.deviations.slab_size_mm * 2
    V = [np.array([[-half, -half, 0], [half, -half, 0], [half, half, 0], [-half, half, 0]], float)]
    T = [np.array([[0, 1, 2], [0, 2, 3]])]
    kinds, barid, p0s, p1s, rs = [K_FORMWORK], [-1], [np.zeros(3)], [np.zeros(3)], [0.0]
    no_rib = [math.nan] * 6
    ribs = [no_rib]
    relief = scene.deviations.ribs and scene.deviations.rib_relief
    # roll and rib shift of each bar belong to the slab (its key), not to the shot
    rib_rng = np.random.default_rng([scene.key, 2])
    for b in scene.bars:
        if relief:
            r1, h, pitch = _relief_params(b.nominal_mm)
            bar_rib = [r1, h, pitch, rib_rng.uniform(0, 1), rib_rng.uniform(0, 2 * math.pi)]
        s0 = 0.0
        for p0, p1 in zip(b.axis[:-1], b.axis[1:]):
            v, t = _prism(p0, p1, b.radius_mm)
            V.append(v), T.append(t)
            kinds.append(K_BAR), barid.append(b.id), p0s.append(p0), p1s.append(p1), rs.append(b.radius_mm)
            ribs.append(bar_rib + [s0] if relief else no_rib)
            s0 += float(np.linalg.norm(p1 - p0))
    for c, hs, yaw, kind in scene.boxes:
        v, t = _box(c, hs, yaw)
        V.append(v), T.append(t)
        kinds.append(K_FORMWORK if kind == "edge_form" else K_SPACER), barid.append(-1)
        p0s.append(np.zeros(3)), p1s.append(np.zeros(3)), rs.append(0.0)
        ribs.append(no_rib)
    for p0, p1, r, kind in scene.rods:
        v, t = _prism(p0, p1, r, 8)
        V.append(v), T.append(t)
        kinds.append(K_CHAIR if kind == "chair" else K_TIE), barid.append(-1)
        p0s.append(np.zeros(3)), p1s.append(np.zeros(3)), rs.append(0.0)
        ribs.append(no_rib)
    offsets = np.cumsum([0] + [len(v) for v in V[:-1]])
    tris = np.vstack([t + o for t, o in zip(T, offsets)])
    tri_obj = np.concatenate([np.full(len(t), i) for i, t in enumerate(T)])
    return _Geometry(np.vstack(V), tris, tri_obj, np.array(kinds), np.array(barid),
                     np.array(p0s), np.array(p1s), np.array(rs), np.array(ribs, float))


class _Caster:
    """Open3D ray casting over the merged scene mesh (built once per render)."""

    def __init__(self, geo: _Geometry):
        import open3d as o3d

        self.o3d = o3d
        self.geo = geo
        mesh = o3d.t.geometry.TriangleMesh()
        mesh.vertex.positions = o3d.core.Tensor(geo.verts.astype(np.float32))
        mesh.triangle.indices = o3d.core.Tensor(geo.tris.astype(np.int32))
        self.scene = o3d.t.geometry.RaycastingScene()
        self.scene.add_triangles(mesh)

    def first_hit(self, origins, dirs):
        """(t, object index, normal) of the first hit along each ray, bars exact; t = inf on a miss."""
        n = len(dirs)
        t = np.full(n, np.inf)
        obj = np.full(n, -1)
        normal = np.zeros((n, 3))
        todo = np.arange(n)
        start = np.zeros(n)
        for _ in range(8):  # re-cast the few rays that pass through a prism but miss its cylinder
            if len(todo) == 0:
                break
            o = origins[todo] + dirs[todo] * start[todo, None]
            rays = np.hstack((o, dirs[todo])).astype(np.float32)
            ans = self.scene.cast_rays(self.o3d.core.Tensor(rays))
            th = ans["t_hit"].numpy().astype(np.float64) + start[todo]
            prim = ans["primitive_ids"].numpy().astype(np.int64)
            hit = np.isfinite(th)
            ob = np.where(hit, self.geo.tri_obj[np.where(hit, prim, 0)], -1)
            nrm = ans["primitive_normals"].numpy().astype(np.float64)
            is_bar = hit & (self.geo.obj_kind[np.maximum(ob, 0)] == K_BAR)
            # exact cylinder intersection for bar hits (or the relief of a bar's ribs)
            tb, nb, ok = _ray_cylinder(origins[todo][is_bar], dirs[todo][is_bar], self.geo.seg_p0[ob[is_bar]],
                                       self.geo.seg_p1[ob[is_bar]], self.geo.seg_r[ob[is_bar]])
            rib = self.geo.seg_rib[ob[is_bar]]
            relief = np.isfinite(rib[:, 0])
            if relief.any():
                sel_b = np.flatnonzero(is_bar)[relief]
                tb[relief], nb[relief], ok[relief] = _ray_relief(
                    origins[todo][sel_b], dirs[todo][sel_b], self.geo.seg_p0[ob[sel_b]],
                    self.geo.seg_p1[ob[sel_b]], rib[relief])
            th_b = th[is_bar]
            th_b[ok] = tb[ok]
            nrm[is_bar] = np.where(ok[:, None], nb, nrm[is_bar])
            th[is_bar] = th_b
            done = ~is_bar.copy()
            bar_idx = np.flatnonzero(is_bar)
            done[bar_idx[ok]] = True
            sel = todo[done]
            t[sel], obj[sel], normal[sel] = th[done], ob[done], nrm[done]
            # planar formwork: exact by construction; flip normals to face the ray
            retry = todo[~done]
            start[retry] = th[~done] + 1e-3
            todo = retry
        flip = (normal * dirs).sum(axis=1) > 0
        normal[flip] *= -1
        return t, obj, normal

    def occluded(self, origins, dirs, t_max, own=None):
        """Whether anything lies on each segment origin -> origin + t_max * dir. ``own``: per ray,
        the object it starts on where that is a bar in relief (else -1): its surface lies inside
        its own prism, which the ray leaves first (a rib does not shade the core beside it here)."""
        origins = np.asarray(origins, np.float64)
        start = np.zeros(len(origins))
        th = np.full(len(origins), np.inf)
        todo = np.arange(len(origins))
        own = np.full(len(origins), -1) if own is None else np.array(own)  # (a copy: cleared below)
        for _ in range(2):  # at most once through its own prism
            rays = np.hstack((origins[todo] + dirs[todo] * start[todo, None], dirs[todo])).astype(np.float32)
            ans = self.scene.cast_rays(self.o3d.core.Tensor(rays))
            t_k = ans["t_hit"].numpy().astype(np.float64)
            prim = ans["primitive_ids"].numpy().astype(np.int64)
            hit = np.isfinite(t_k)
            self_hit = hit & (own[todo] >= 0) & (self.geo.tri_obj[np.where(hit, prim, 0)] == own[todo])
            th[todo] = start[todo] + t_k
            own[todo] = -1
            start[todo[self_hit]] += t_k[self_hit] + 1e-3
            th[todo[self_hit]] = np.inf
            todo = todo[self_hit]
        return th < t_max


def _ray_cylinder(o, d, p0, p1, r):
    """Nearest intersection of rays o + t d with finite cylinders (side and caps)."""
    axis = p1 - p0
    L = np.linalg.norm(axis, axis=1)
    a = axis / L[:, None]
    w = o - p0
    da = (d * a).sum(1)
    wa = (w * a).sum(1)
    dp = d - da[:, None] * a
    wp = w - wa[:, None] * a
    A = (dp * dp).sum(1)
    B = (wp * dp).sum(1)
    C = (wp * wp).sum(1) - r * r
    disc = B * B - A * C
    with np.errstate(invalid="ignore", divide="ignore"):
        t_side = (-B - np.sqrt(np.maximum(disc, 0))) / A
    s = wa + t_side * da
    side_ok = (disc >= 0) & (A > 1e-12) & (s >= 0) & (s <= L) & (t_side > 0)
    t = np.where(side_ok, t_side, np.inf)
    n = np.zeros_like(o)
    pt = o + t_side[:, None] * d
    radial = pt - p0 - ((pt - p0) * a).sum(1)[:, None] * a
    n[side_ok] = radial[side_ok] / r[side_ok, None]
    for cap, sign in ((0.0, -1.0), (1.0, 1.0)):
        with np.errstate(invalid="ignore", divide="ignore"):
            tc = (cap * L - wa) / da
        pc = o + tc[:, None] * d - (p0 + cap * L[:, None] * a)
        inside = ((pc * pc).sum(1) - ((pc * a).sum(1)) ** 2) <= r * r
        better = inside & (tc > 0) & (tc < t)
        t = np.where(better, tc, t)
        n[better] = sign * a[better]
    return t, n, np.isfinite(t)


def _relief_frame(a):
    """Unit vectors u (level) and w across bar directions ``a`` (n, 3): psi is measured from u."""
    u = np.cross(a, [0.0, 0.0, 1.0])
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    return u, np.cross(a, u)


def _relief_gap(x, p0, a, u, w, rib):
    """Distance of points ``x`` from the axis minus the relief's radius there (< 0: inside the
    bar), and their position along the segment (mm)."""
    rel = x - p0
    s = (rel * a).sum(-1)
    radial = rel - s[..., None] * a
    rho = np.linalg.norm(radial, axis=-1)
    psi = np.arctan2((radial * w).sum(-1), (radial * u).sum(-1)) - rib[..., 4]
    return rho - _relief_radius(s + rib[..., 5], psi, rib[..., 0], rib[..., 1], rib[..., 2], rib[..., 3]), s


def _ray_relief(o, d, p0, p1, rib, step_mm=0.03, block=48, bisections=12):
    """Nearest intersection of rays o + t d with bar segments drawn in relief (``rib`` rows as
    ``_Geometry.seg_rib``); (t, normal, hit). Marched in ``step_mm`` steps through the rib
    envelope's cylinder, then bisected: a ray that grazes between two ribs is a miss here."""
    n = len(o)
    t_hit, normal, hit = np.full(n, np.inf), np.zeros((n, 3)), np.zeros(n, bool)
    axis = p1 - p0
    L = np.linalg.norm(axis, axis=1)
    a = axis / L[:, None]
    u, w = _relief_frame(a)
    R = rib[:, 0] + rib[:, 1]
    dp = d - (d * a).sum(1)[:, None] * a
    wp = (o - p0) - ((o - p0) * a).sum(1)[:, None] * a
    A, B, C = (dp * dp).sum(1), (wp * dp).sum(1), (wp * wp).sum(1) - R * R
    disc = B * B - A * C
    good = (disc > 0) & (A > 1e-12)
    root = np.sqrt(np.where(good, disc, 0))
    t_in = np.where(good, np.maximum((-B - root) / np.where(good, A, 1), 0), np.inf)
    t_out = np.where(good, (-B + root) / np.where(good, A, 1), -np.inf)
    active = np.flatnonzero(good & (t_out > t_in))
    t_cur = t_in.copy()
    k = np.arange(block + 1)
    while len(active):
        i = active
        T = np.minimum(t_cur[i, None] + step_mm * k[None, :], t_out[i, None])  # (m, block+1)
        X = o[i, None, :] + T[..., None] * d[i, None, :]
        f, s = _relief_gap(X, p0[i, None, :], a[i, None, :], u[i, None, :], w[i, None, :], rib[i, None, :])
        inside = (f <= 0) & (s >= 0) & (s <= L[i, None])
        first = np.where(inside.any(axis=1), inside.argmax(axis=1), -1)
        found = first >= 0
        # bracket: the sample before the first one inside (at the entry itself: a hit there)
        j = np.flatnonzero(found)
        lo = T[j, np.maximum(first[j] - 1, 0)]
        hi = T[j, first[j]]
        ii = i[j]
        for _ in range(bisections):
            mid = (lo + hi) / 2
            fm, sm = _relief_gap(o[ii] + mid[:, None] * d[ii], p0[ii], a[ii], u[ii], w[ii], rib[ii])
            ins = (fm <= 0) & (sm >= 0) & (sm <= L[ii])
            hi = np.where(ins, mid, hi)
            lo = np.where(ins, lo, mid)
        t_hit[ii], hit[ii] = hi, True
        t_cur[i] = T[:, -1]
        active = i[~found & (T[:, -1] < t_out[i])]
    # normals: the gradient of the gap function at the hits (central differences)
    j = np.flatnonzero(hit)
    if len(j):
        x = o[j] + t_hit[j, None] * d[j]
        eps = 0.004
        g = np.zeros((len(j), 3))
        for c in range(3):
            e = np.zeros(3)
            e[c] = eps
            fp, _ = _relief_gap(x + e, p0[j], a[j], u[j], w[j], rib[j])
            fm, _ = _relief_gap(x - e, p0[j], a[j], u[j], w[j], rib[j])
            g[:, c] = fp - fm
        normal[j] = g / np.maximum(np.linalg.norm(g, axis=1, keepdims=True), 1e-12)
    return t_hit, normal, hit


# --------------------------------------------------------------------------------------------
# Rendering


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


def _formwork_albedo(kind, p, rng, extent):
    x, y = p[:, 0], p[:, 1]
    n1 = _sample(_value_noise(rng, (512, 512)), x, y, extent, 2 * extent / 512)
    n2 = _sample(_value_noise(rng, (1024, 1024), 2), x, y, extent, 2 * extent / 1024)
    if kind == "plywood":
        base = np.array([0.78, 0.60, 0.40]) * rng.uniform(0.85, 1.1)
        grain = 0.5 + 0.5 * np.sin(2 * np.pi * (x + 60 * n1) / rng.uniform(6, 12))
        shade = 0.82 + 0.12 * grain + 0.18 * (n2 - 0.5)
        seams = (np.abs(((y + extent) % 1220) - 610) > 608) | (np.abs(((x + extent) % 2440) - 1220) > 1218)
        shade = np.where(seams, 0.45, shade)
    elif kind == "film":
        base = np.array([0.20, 0.14, 0.11]) * rng.uniform(0.8, 1.2)
        shade = 0.85 + 0.3 * (n1 - 0.5) + 0.15 * (n2 - 0.5)
        dust = n2 > 0.72
        shade = np.where(dust, shade * 1.8, shade)
    else:  # plastic
        base = [np.array([0.25, 0.45, 0.75]), np.array([0.55, 0.57, 0.58]), np.array([0.3, 0.6, 0.35])][rng.integers(3)]
        shade = 0.92 + 0.1 * (n2 - 0.5)
        seams = (np.abs(((y + extent) % 500) - 250) > 247) | (np.abs(((x + extent) % 500) - 250) > 247)
        shade = np.where(seams, 0.6, shade)
    return np.clip(shade[:, None] * base, 0, 1)


def _bar_albedo(scene, bar_of_px, p, rust_of_bar, rng):
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


def render_capture(scene: SlabScene, pose: CameraPose, *, intrinsics: Intrinsics = GEMINI2,
                   sensor: SensorModel | None = None, appearance: Appearance | None = None,
                   rng=None, name: str = "synthetic") -> Capture:
    """Render one RGB-D capture of ``scene`` seen from ``pose``, with ground truth.

    Returns a :class:`~rebarlib.Capture` with ``labels``, ``bar_ids`` and
    ``metadata["truth"]`` (docs/formats.md, "truth.json", lists the keys). Deterministic for a given ``rng`` seed.
    """
    import cv2

    rng = np.random.default_rng(rng)
    sensor = sensor or SensorModel()
    app = appearance or Appearance()
    H, W = intrinsics.height, intrinsics.width
    lens = sensor.true_intrinsics(intrinsics)  # the capture is saved with ``intrinsics``
    geo = _build_geometry(scene)
    caster = _Caster(geo)

    def cast(pixels=None):
        """What the rays through ``pixels`` (default: every pixel's centre) hit: world ray
        directions, z-depth t (inf on a miss), normal, hit, point, object kind, bar index (-1:
        none) and how far off the surface a shadow ray from it starts."""
        d_world = ray_directions(lens, pixels) @ pose.rotation  # rows: R^T d; z = 1, so t is the z-depth
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
        return d_world, t, normal, hit, p, kind, bar_of, (lift, own)

    d_world, t, normal, hit, p, kind, bar_of, leave = cast()
    z_true = np.where(hit, t, 0.0).reshape(H, W)
    layer_of_bar = np.array([LABEL_LOWER if b.layer == "lower" else LABEL_UPPER for b in scene.bars] + [0])
    labels = layer_of_bar[bar_of].astype(np.uint8).reshape(H, W)
    bar_ids = (bar_of + 1).astype(np.int32).reshape(H, W)

    # ---- depth sensor
    depth = _sensor_depth(z_true, p, normal, hit, pose, intrinsics, sensor, caster, rng, leave)

    # ---- colour
    # what belongs to the slab is drawn from its key, so every capture of one slab agrees
    slab_rng = np.random.default_rng([scene.key, 1])
    formwork = app.formwork or FORMWORKS[slab_rng.integers(len(FORMWORKS))]
    elev = math.radians(app.sun_elevation_deg if app.sun_elevation_deg is not None else rng.uniform(35, 75))
    azim = math.radians(app.sun_azimuth_deg if app.sun_azimuth_deg is not None else rng.uniform(0, 360))
    light = np.array([math.cos(elev) * math.cos(azim), math.cos(elev) * math.sin(azim), math.sin(elev)])
    rust_of_bar = np.zeros(len(scene.bars) + 1)
    n_rusty = int(round(app.rust_fraction * len(scene.bars)))
    if n_rusty:
        rust_of_bar[slab_rng.permutation(len(scene.bars))[:n_rusty]] = slab_rng.uniform(0.5, 1.0, n_rusty)
    n_s = int(app.pixel_samples)
    p_centre = p  # the truth is about the pixel centres
    if n_s > 1:  # the colour pass casts n_s² rays spread over each pixel (see Appearance)
        off = (np.arange(n_s) + 0.5) / n_s - 0.5
        oy, ox = np.meshgrid(off, off, indexing="ij")
        v, u = np.mgrid[0:H, 0:W]
        px = np.stack([np.column_stack(((u + dx).ravel(), (v + dy).ravel())) for dx, dy in zip(ox.ravel(), oy.ravel())])
        d_world, t, normal, hit, p, kind, bar_of, leave = cast(px.reshape(-1, 2))
    albedo = np.zeros((len(t), 3))
    extent = scene.deviations.slab_size_mm * 2
    fw = kind == K_FORMWORK
    albedo[fw] = _formwork_albedo(formwork, p[fw], slab_rng, extent)
    bars_px = kind == K_BAR
    albedo[bars_px] = _bar_albedo(scene, bar_of[bars_px], p[bars_px], rust_of_bar, slab_rng)
    albedo[kind == K_SPACER] = [0.62, 0.61, 0.58]
    albedo[kind == K_CHAIR] = [0.35, 0.34, 0.33]
    albedo[kind == K_TIE] = [0.18, 0.18, 0.19]
    lambert = np.clip(normal @ light, 0, None)
    lit = hit & (lambert > 0)
    idx = np.flatnonzero(lit)
    shadow = np.zeros(len(t), bool)
    if app.cast_shadows:
        shadow[idx] = caster.occluded(p[idx] + normal[idx] * leave[0][idx, None],
                                      np.broadcast_to(light, (len(idx), 3)).copy(), 1e5, own=leave[1][idx])
    direct = np.where(shadow, 0.0, lambert)
    # specular sheen on steel and film-faced board
    view = -d_world / np.linalg.norm(d_world, axis=1, keepdims=True)
    half_v = (view + light) / np.linalg.norm(view + light, axis=1, keepdims=True)
    spec_k = np.where(bars_px, 0.25 * (1 - rust_of_bar[bar_of]), np.where(fw & (formwork != "plywood"), 0.15, 0.0))
    spec = spec_k * np.clip((normal * half_v).sum(1), 0, 1) ** 30 * (~shadow)
    shade = app.ambient + (1 - app.ambient) * 1.25 * direct
    rgb = albedo * shade[:, None] + spec[:, None]
    rgb = np.where(hit[:, None], rgb, 0.0)
    rgb = (rgb.reshape(n_s * n_s, H * W, 3).mean(axis=0) if n_s > 1 else rgb).reshape(H, W, 3) * app.exposure
    if app.blur_px > 0:
        rgb = cv2.GaussianBlur(rgb, (0, 0), app.blur_px)
    img = np.clip(rgb ** (1 / 1.8) * 255 + rng.normal(0, app.noise_sigma, rgb.shape), 0, 255).astype(np.uint8)
    if app.jpeg_quality:
        ok, buf = cv2.imencode(".jpg", img[..., ::-1], [cv2.IMWRITE_JPEG_QUALITY, int(app.jpeg_quality)])
        img = cv2.imdecode(buf, cv2.IMREAD_COLOR)[..., ::-1].copy()

    truth = _truth(scene, pose, intrinsics, bar_ids, p_centre, formwork, light, rust_of_bar, sensor, app)
    no_depth = _remove_bar_depth(depth, bar_ids, truth, sensor.bars_without_depth, rng)
    for tb in truth["bars"]:
        tb["no_depth"] = tb["id"] in no_depth
    meta = {"depth_scale_mm": sensor.depth_scale_mm, "device": "rebarlib synthetic (Gemini-2-like)",
            "name": name, "truth": truth}
    return Capture(img, depth, intrinsics, meta, labels, bar_ids)


def _remove_bar_depth(depth, bar_ids, truth: dict, n: int, rng) -> set:
    """Blank the depth of ``n`` lower-lattice bars in view (their pixels and 2 px around them);
    returns their ids. Draws from ``rng`` only when ``n`` > 0."""
    import cv2

    if not n:
        return set()
    seen = [tb["id"] for tb in truth["bars"]
            if tb["layer"] == "lower" and tb["visible"] and tb["visible_length_mm"] >= 400]
    ids = {seen[i] for i in rng.permutation(len(seen))[:n]}
    if ids:
        mask = np.isin(bar_ids - 1, sorted(ids)).astype(np.uint8)
        mask = cv2.dilate(mask, np.ones((5, 5), np.uint8))
        depth[mask > 0] = 0
    return ids


def _sensor_depth(z_true, p, normal, hit, pose, intr, s: SensorModel, caster, rng, leave):
    import cv2

    H, W = z_true.shape
    f = intr.fx
    z = z_true.astype(np.float64).copy()
    valid = z > 0
    if s.lateral_jitter_px > 0:
        v, u = np.mgrid[0:H, 0:W]
        uj = np.clip(np.rint(u + rng.normal(0, s.lateral_jitter_px, (H, W))), 0, W - 1).astype(int)
        vj = np.clip(np.rint(v + rng.normal(0, s.lateral_jitter_px, (H, W))), 0, H - 1).astype(int)
        z = z[vj, uj]
        valid = z > 0
    big = np.where(valid, z, 1e9).astype(np.float32)
    k3 = np.ones((3, 3), np.uint8)
    zmin = cv2.erode(big, k3)
    zmax = cv2.dilate(np.where(valid, z, 0).astype(np.float32), k3)
    edge = valid & ((zmax - zmin) > s.edge_jump_mm)
    u01 = rng.random((H, W))
    if s.edge_fatten_prob > 0:  # the nearer surface bleeds over the edge
        fat = edge & (u01 < s.edge_fatten_prob)
        z[fat] = zmin[fat]
    if s.flying_pixel_prob > 0:
        lo = s.edge_fatten_prob
        fly = edge & (u01 >= lo) & (u01 < lo + s.flying_pixel_prob)
        mix = rng.random((H, W))
        z[fly] = (zmin + mix * (zmax - zmin))[fly]
    if s.edge_hole_prob > 0:
        lo = s.edge_fatten_prob + s.flying_pixel_prob
        hole = edge & (u01 >= lo) & (u01 < lo + s.edge_hole_prob)
        z[hole] = 0
    if s.edge_fatten_px > 1 and s.edge_fatten_prob > 0:
        # the wider band: d px from a nearer surface (d >= 2), judged on the depth before the
        # edge effects above; the pixels next to the edge are as drawn there
        near = np.zeros((H, W), bool)
        u2 = rng.random((H, W))
        for d in range(2, int(s.edge_fatten_px) + 1):
            kd = np.ones((2 * d + 1, 2 * d + 1), np.uint8)
            zd = cv2.erode(big, kd)
            band = valid & ~edge & ~near & (big - zd > s.edge_jump_mm)
            take = band & (u2 < s.edge_fatten_prob * (s.edge_fatten_px - d + 1) / s.edge_fatten_px)
            z[take] = zd[take]
            near |= band
    if s.projector_shadow:
        proj = pose.centre + pose.rotation.T @ np.array([s.projector_offset_mm, 0.0, 0.0])
        idx = np.flatnonzero(hit)
        start = p[idx] + normal[idx] * leave[0][idx, None]
        vec = proj - start
        dist = np.linalg.norm(vec, axis=1)
        occ = caster.occluded(start, vec / dist[:, None], dist - 0.1, own=leave[1][idx])
        shadow = np.zeros(H * W, bool)
        shadow[idx[occ]] = True
        z[shadow.reshape(H, W)] = 0
    valid = z > 0
    if s.disparity_sigma_px > 0 or s.subpixel_px > 0:
        fb = f * s.baseline_mm
        disp = np.where(valid, fb / np.where(valid, z, 1), 0)
        if s.disparity_sigma_px > 0:
            noise = rng.normal(0, 1, (H, W)).astype(np.float32)
            if s.noise_correlation_px > 0:
                noise = cv2.GaussianBlur(noise, (0, 0), s.noise_correlation_px)
                noise /= noise.std()
            disp = disp + s.disparity_sigma_px * noise
        if s.subpixel_px > 0:
            disp = np.round(disp / s.subpixel_px) * s.subpixel_px
        z = np.where(valid & (disp > 0), fb / np.where(disp > 0, disp, 1), 0)
    if s.bias_mm_per_m2:
        z = np.where(z > 0, z + s.bias_mm_per_m2 * (z / 1000) ** 2, 0)
    if s.depth_scale_error or s.depth_offset_mm:
        z = np.where(z > 0, (1.0 + s.depth_scale_error) * z + s.depth_offset_mm, 0)
    z[(z > s.max_depth_mm)] = 0
    if s.dropout > 0:
        z[dropout_mask(z > 0, s.dropout, s.dropout_patch_px, rng)] = 0
    if s.quantize:
        z = np.round(z / s.depth_scale_mm) * s.depth_scale_mm
    return z


def dropout_mask(valid, fraction: float, patch_px: float = 0.0, rng=None) -> np.ndarray:
    """Pixels of ``valid`` (H, W bool) whose depth a sensor loses: ``fraction`` of them, each on
    its own (``patch_px=0``) or in random blobs about ``patch_px`` across (a smoothed random
    field's lowest ``fraction`` among the valid pixels).

    Examples
    --------
    >>> m = dropout_mask(np.ones((200, 200), bool), 0.9, 8, rng=0)
    >>> round(float(m.mean()), 2)
    0.9
    """
    import cv2

    rng = np.random.default_rng(rng)
    valid = np.asarray(valid, bool)
    field_ = rng.random(valid.shape).astype(np.float32)
    if patch_px > 0:
        field_ = cv2.GaussianBlur(field_, (0, 0), float(patch_px) / 2)
    if not valid.any() or fraction <= 0:
        return np.zeros(valid.shape, bool)
    cut = np.quantile(field_[valid], min(float(fraction), 1.0))
    return valid & (field_ <= cut) if fraction >= 1 else valid & (field_ < cut)


def _truth(scene, pose, intr, bar_ids, p, formwork, light, rust_of_bar, sensor, app):
    """Ground truth in the camera frame (mm); heights above the formwork."""
    R = pose.rotation
    normal_c = R @ np.array([0, 0, 1.0])
    offset_c = float(-normal_c @ pose.to_camera([[0, 0, 0]])[0])
    ids = bar_ids.ravel() - 1
    counts = np.bincount(ids[ids >= 0], minlength=len(scene.bars))
    bars = []
    vis_len = {}
    for b in scene.bars:
        sel = ids == b.id
        vis = counts[b.id]
        if vis:
            s = (p[sel] - b.axis[0]) @ b.direction
            s0, s1 = float(s.min()), float(s.max())
        else:
            s0 = s1 = 0.0
        a0, a1 = b.axis[0], b.axis[-1]
        chord = a1 - a0
        vis_len[b.id] = s1 - s0
        vs = a0 + s0 * b.direction
        ve = a0 + s1 * b.direction
        vs[2] = ve[2] = b.axis[:, 2].mean()
        bars.append({
            "id": b.id, "layer": b.layer, "level": b.level, "index": b.index,
            "axis_start_mm": pose.to_camera([a0])[0].round(4).tolist(),
            "axis_end_mm": pose.to_camera([a1])[0].round(4).tolist(),
            "visible_start_mm": pose.to_camera([vs])[0].round(4).tolist(),
            "visible_end_mm": pose.to_camera([ve])[0].round(4).tolist(),
            "plan_angle_deg": round(math.degrees(math.atan2(chord[1], chord[0])) % 180, 4),
            "offset_mm": round(b.offset_mm, 4),
            "underside_mm": round(b.underside_mm, 4),
            "top_mm": round(b.underside_mm + b.envelope_mm, 4),
            "diameter_mm": b.nominal_mm, "envelope_mm": b.envelope_mm, "design_diameter_mm": b.design_mm,
            "wrong_size": b.nominal_mm != b.design_mm, "extra": bool(b.extra),
            "rust": round(float(rust_of_bar[b.id]), 3),
            "visible_pixels": int(vis), "visible_length_mm": round(s1 - s0, 2),
            "visible": bool(vis >= 100 and s1 - s0 >= 50),
        })
    by = {(bb["layer"], bb["level"]): [] for bb in bars}
    for bb in bars:
        by[(bb["layer"], bb["level"])].append(bb)

    def mean_of(key, layer, level, visible=True):
        vals = [bb[key] for bb in by.get((layer, level), []) if bb["visible"] or not visible]
        if not vals:
            vals = [bb[key] for bb in by.get((layer, level), [])]
        return float(np.mean(vals)) if vals else None

    cover = mean_of("underside_mm", "lower", "bottom")
    upper_bottom = mean_of("underside_mm", "upper", "bottom")
    spacings = []
    for (layer, level), group in sorted(by.items()):
        group = sorted(group, key=lambda bb: bb["offset_mm"])
        for a, b in zip(group[:-1], group[1:]):
            spacings.append({"layer": layer, "level": level, "bar_a": a["id"], "bar_b": b["id"],
                             "spacing_mm": round(b["offset_mm"] - a["offset_mm"], 4),
                             "visible": a["visible"] and b["visible"]})
    d = scene.design
    return {
        "units": "mm, camera frame (OpenCV: x right, y down, z forward); heights above the formwork",
        "cover_mm": round(cover, 4) if cover is not None else None,
        "layer_distance_mm": round(upper_bottom - cover, 4) if None not in (cover, upper_bottom) else None,
        "upper_top_mm": mean_of("top_mm", "upper", "top"),
        "formwork_plane": {"normal": normal_c.round(8).tolist(), "offset_mm": round(offset_c, 4)},
        "camera": {"height_mm": round(float(pose.centre[2]), 4),
                   "rotation_world_to_camera": R.round(10).tolist(),
                   "centre_world_mm": pose.centre.round(4).tolist()},
        "bars": bars,
        "missing": [{"layer": lay, "level": v, "index": k, **_ghost_truth(scene, i, pose, intr)}
                    for i, (lay, v, k) in enumerate(scene.missing)],
        "mesh": _mesh_truth(scene, pose),
        "spacings": spacings,
        "design": {"cover_mm": d.cover_mm, "layer_distance_mm": d.layer_distance_mm,
                   "lower_diameter_mm": d.lower.bottom.diameter_mm, "upper_diameter_mm": d.upper.bottom.diameter_mm},
        "deviations": asdict(scene.deviations),
        "sensor": asdict(sensor),
        "appearance": {**asdict(app), "formwork": formwork, "light_world": light.round(6).tolist()},
    }


def _ghost_truth(scene, i: int, pose, intr) -> dict:
    """Where missing bar ``i`` would have been: its axis ends (camera frame) and how much of
    that axis (at its top) the image frames, in mm."""
    from ._camera import project

    if i >= len(scene.ghosts):
        return {}
    g = scene.ghosts[i]
    a0, a1 = g.axis[0], g.axis[-1]
    t = np.linspace(0.0, 1.0, 401)
    pts = a0 + t[:, None] * (a1 - a0) + np.array([0, 0, g.radius_mm])
    cam = pose.to_camera(pts)
    uv = project(cam, intr)
    inside = (cam[:, 2] > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < intr.width) & (uv[:, 1] >= 0) & (uv[:, 1] < intr.height)
    step = float(np.linalg.norm(a1 - a0)) / 400
    return {"offset_mm": round(g.offset_mm, 4), "axis_start_mm": pose.to_camera([a0])[0].round(4).tolist(),
            "axis_end_mm": pose.to_camera([a1])[0].round(4).tolist(),
            "in_view_mm": round(float(inside.sum()) * step, 1)}


def _mesh_truth(scene, pose) -> dict:
    """The finite mesh's corners per lattice (camera frame), or None for the full-slab layout."""
    if scene.deviations.end_overhang_mm is None:
        return {"finite": False}
    out = {"finite": True}
    for layer in ("lower", "upper"):
        bb = [b for b in scene.bars if b.layer == layer]
        if not bb:
            continue
        pts = np.vstack([np.vstack((b.axis[0], b.axis[-1])) for b in bb])
        out[layer] = {"ends_camera_mm": pose.to_camera(pts).round(3).tolist()}
    return out


def synth_capture(design: Design, *, height_mm: float = 500.0, tilt_deg: float = 10.0,
                  yaw_deg: float = 0.0, target_mm=(0.0, 0.0), deviations: Deviations | None = None,
                  sensor: SensorModel | None = None, appearance: Appearance | None = None,
                  intrinsics: Intrinsics = GEMINI2, seed: int = 0, scene_seed: int | None = None,
                  name: str = "synthetic") -> Capture:
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
    return render_capture(scene, pose, intrinsics=intrinsics, sensor=sensor, appearance=appearance,
                          rng=np.random.default_rng(render_rng), name=name)


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
    depth[max(dv, 0):h + min(dv, 0), max(du, 0):w + min(du, 0)] = \
        capture.depth_mm[max(-dv, 0):h + min(-dv, 0), max(-du, 0):w + min(-du, 0)]
    return replace(capture, depth_mm=depth)
