"""The depth sensor: what an active-stereo camera does to the true depth of a scene (noise,
quantisation, holes and fattening at edges, the projector's shadow, bias, dropout) and the
bars it loses altogether. docs/sensors.md describes the model."""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from .._camera import Intrinsics
from .._checks import RebarInputError

__all__ = ["SensorModel", "dropout_mask"]


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
            raise RebarInputError(
                f"SensorModel: dropout must be in 0..1 and dropout_patch_px >= 0, got "
                f"{self.dropout!r} and {self.dropout_patch_px!r}"
            )

    @classmethod
    def ideal(cls) -> "SensorModel":
        """Exact depth: no noise, holes, jitter or quantisation (depth_scale_mm for saving only)."""
        return cls(
            disparity_sigma_px=0.0,
            noise_correlation_px=0.0,
            subpixel_px=0.0,
            lateral_jitter_px=0.0,
            edge_hole_prob=0.0,
            edge_fatten_prob=0.0,
            flying_pixel_prob=0.0,
            projector_shadow=False,
            depth_scale_mm=0.02,
            quantize=False,
        )

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


def _sensor_depth(z_true, p, normal, hit, pose, intr, s: SensorModel, caster, rng, leave):
    """The depth image (H, W mm, 0 = none) the sensor ``s`` reports of the true z-depth
    ``z_true``: lateral jitter, what happens at edges, the projector's shadow (rays from the hit
    points ``p`` towards the projector cast with ``caster``), disparity noise and quantisation,
    bias and scale errors, range limit, dropout and the stored depth grid, drawn from ``rng`` in
    that order."""
    H, W = z_true.shape
    z = z_true.astype(np.float64).copy()
    valid = z > 0
    if s.lateral_jitter_px > 0:
        v, u = np.mgrid[0:H, 0:W]
        uj = np.clip(np.rint(u + rng.normal(0, s.lateral_jitter_px, (H, W))), 0, W - 1).astype(int)
        vj = np.clip(np.rint(v + rng.normal(0, s.lateral_jitter_px, (H, W))), 0, H - 1).astype(int)
        z = z[vj, uj]
        valid = z > 0
    _edge_effects(z, valid, s, rng)
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
        z = _disparity_noise(z, valid, intr.fx, s, rng)
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


def _edge_effects(z, valid, s: SensorModel, rng) -> None:
    """At depth discontinuities (a step over ``s.edge_jump_mm`` to a neighbour), give pixels the
    nearer surface's depth (edge fattening), a mixed depth (flying pixels) or none (holes), in
    place; with ``s.edge_fatten_px`` > 1 the nearer surface also bleeds further out."""
    import cv2

    H, W = z.shape
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


def _disparity_noise(z, valid, f: float, s: SensorModel, rng) -> np.ndarray:
    """Depth ``z`` through the disparity fB / z: Gaussian noise of ``s.disparity_sigma_px``
    (correlated over ``s.noise_correlation_px``) and rounding to ``s.subpixel_px``."""
    import cv2

    H, W = z.shape
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
    return np.where(valid & (disp > 0), fb / np.where(disp > 0, disp, 1), 0)


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


def _remove_bar_depth(depth, bar_ids, truth: dict, n: int, rng) -> set:
    """Blank the depth of ``n`` lower-lattice bars in view (their pixels and 2 px around them);
    returns their ids. Draws from ``rng`` only when ``n`` > 0."""
    import cv2

    if not n:
        return set()
    seen = [
        tb["id"] for tb in truth["bars"] if tb["layer"] == "lower" and tb["visible"] and tb["visible_length_mm"] >= 400
    ]
    ids = {seen[i] for i in rng.permutation(len(seen))[:n]}
    if ids:
        mask = np.isin(bar_ids - 1, sorted(ids)).astype(np.uint8)
        mask = cv2.dilate(mask, np.ones((5, 5), np.uint8))
        depth[mask > 0] = 0
    return ids
