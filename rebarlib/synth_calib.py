"""Synthetic calibration captures: a flat printed checkerboard seen by a depth camera whose
intrinsics and depth are off by known amounts (``SensorModel.focal_error``,
``depth_scale_error``, ``depth_offset_mm``), so that ``rebar calibrate`` can be tested end to end.

The board lies in the world plane z = 0, centred on the origin; the camera looks at it from
``CameraPose.looking_down`` poses. Nothing else is in view: rays that miss the board have no
depth and a dark grey colour.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from ._camera import GEMINI2, Intrinsics, ray_directions
from ._capture import Capture
from ._checks import RebarInputError
from .synth import CameraPose, SensorModel, _sensor_depth

__all__ = ["Checkerboard", "render_board", "board_poses", "board_captures"]


@dataclass(frozen=True)
class Checkerboard:
    """A printed checkerboard: ``cols`` x ``rows`` inner corners, ``square_mm`` squares, a white
    ``margin_mm`` around the pattern. OpenCV's ``patternSize`` is ``(cols, rows)``."""

    cols: int = 9
    rows: int = 6
    square_mm: float = 40.0
    margin_mm: float = 40.0

    def __post_init__(self):
        if int(self.cols) != self.cols or int(self.rows) != self.rows or min(self.cols, self.rows) < 3:
            raise RebarInputError(f"board: expected at least 3 x 3 inner corners, got {self.cols} x {self.rows}")
        if not self.square_mm > 0:
            raise RebarInputError(f"board square: expected a positive size in mm, got {self.square_mm!r}")

    def object_points(self) -> np.ndarray:
        """(rows * cols, 3) float32 inner corners on the board (mm, z = 0), centred on the board,
        in OpenCV's order (row by row, ``cols`` per row)."""
        j, i = np.mgrid[0 : self.rows, 0 : self.cols]
        x = (i.ravel() - (self.cols - 1) / 2) * self.square_mm
        y = (j.ravel() - (self.rows - 1) / 2) * self.square_mm
        return np.column_stack((x, y, np.zeros_like(x))).astype(np.float32)

    def reflectance(self, x, y) -> np.ndarray:
        """Board reflectance at board coordinates (mm): 0.08 black, 0.85 white, NaN off the board."""
        half_w = (self.cols + 1) * self.square_mm / 2
        half_h = (self.rows + 1) * self.square_mm / 2
        on_board = (np.abs(x) <= half_w + self.margin_mm) & (np.abs(y) <= half_h + self.margin_mm)
        in_pattern = (np.abs(x) < half_w) & (np.abs(y) < half_h)
        parity = (np.floor((x + half_w) / self.square_mm) + np.floor((y + half_h) / self.square_mm)) % 2
        out = np.where(in_pattern & (parity == 0), 0.08, 0.85)
        return np.where(on_board, out, np.nan)


def _board_hits(pose: CameraPose, lens: Intrinsics, pixels=None):
    """Board coordinates (x, y) and z-depth of the rays through ``pixels`` (inf: no hit)."""
    d = ray_directions(lens, pixels) @ pose.rotation  # world directions, camera z = 1
    with np.errstate(divide="ignore", invalid="ignore"):
        t = -pose.centre[2] / d[:, 2]
    t = np.where(t > 0, t, np.inf)
    p = pose.centre + d * np.where(np.isfinite(t), t, 0.0)[:, None]
    return p[:, 0], p[:, 1], t


def render_board(
    pose: CameraPose,
    *,
    board: Checkerboard = Checkerboard(),
    intrinsics: Intrinsics = GEMINI2,
    sensor: SensorModel | None = None,
    rng=None,
    samples: int = 3,
    name: str = "board",
) -> Capture:
    """One RGB-D capture of ``board`` seen from ``pose`` through ``sensor``.

    The colour of a pixel is the mean over ``samples`` x ``samples`` rays spread over it (so
    the corners lie to a fraction of a pixel); its depth is the board's z-depth at the pixel's
    centre through ``sensor``'s noise, quantisation and systematic errors (the projector's
    shadow does not apply to a lone board). The capture is written with ``intrinsics``; the rays
    are cast through ``sensor.true_intrinsics(intrinsics)``. ``metadata["truth"]`` holds the
    pose and the errors rendered.
    """
    sensor = sensor or SensorModel()
    rng = np.random.default_rng(rng)
    lens = sensor.true_intrinsics(intrinsics)
    H, W = intrinsics.height, intrinsics.width
    v, u = np.mgrid[0:H, 0:W]
    off = (np.arange(samples) + 0.5) / samples - 0.5
    acc = np.zeros(H * W)
    for dy in off:
        for dx in off:
            x, y, _ = _board_hits(pose, lens, np.column_stack(((u + dx).ravel(), (v + dy).ravel())))
            acc += np.nan_to_num(board.reflectance(x, y), nan=0.25)
    grey = acc / samples**2
    img = np.clip(grey ** (1 / 1.8) * 255 + rng.normal(0, 1.5, grey.shape), 0, 255).astype(np.uint8)
    color = np.repeat(img.reshape(H, W, 1), 3, axis=2)
    x, y, t = _board_hits(pose, lens)
    on = np.isfinite(board.reflectance(x, y)) & np.isfinite(t)
    z_true = np.where(on, t, 0.0).reshape(H, W)
    depth = _sensor_depth(
        z_true, None, None, None, pose, lens, replace(sensor, projector_shadow=False), None, rng, None
    )
    truth = {
        "kind": "checkerboard",
        "cols": board.cols,
        "rows": board.rows,
        "square_mm": board.square_mm,
        "rotation_world_to_camera": pose.rotation.round(10).tolist(),
        "centre_world_mm": pose.centre.round(4).tolist(),
        "true_intrinsics": [lens.fx, lens.fy, lens.cx, lens.cy],
        "depth_scale_error": sensor.depth_scale_error,
        "depth_offset_mm": sensor.depth_offset_mm,
        "focal_error": sensor.focal_error,
    }
    meta = {
        "depth_scale_mm": sensor.depth_scale_mm,
        "device": "rebarlib synthetic (Gemini-2-like)",
        "name": name,
        "truth": truth,
    }
    return Capture(color, depth, intrinsics, meta)


def board_poses(n: int = 6, *, distances_mm=(450.0, 900.0), tilt_deg: float = 30.0) -> list:
    """``n`` camera poses over the board for a calibration: distances (along the optical axis)
    spread over ``distances_mm`` and the view tilted by 60-100 % of ``tilt_deg`` about axes
    turning round the image (a focal length is only seen apart from the distance in tilted
    views, and fy apart from cy only in views tilted about the image's x axis too)."""
    if n < 3:
        raise RebarInputError(f"n: a calibration needs at least 3 board captures, got {n}")
    out = []
    for i, h in enumerate(np.linspace(distances_mm[0], distances_mm[1], n)):
        tilt = tilt_deg * (0.6 + 0.4 * (i % 2))
        out.append(_tilted_pose(float(h), tilt, 360.0 * i / n + 25.0 * i))
    return out


def _tilted_pose(distance_mm: float, tilt_deg: float, axis_deg: float) -> CameraPose:
    """Camera ``distance_mm`` from the board's centre along its optical axis, which meets the
    centre; the view tilted by ``tilt_deg`` about the camera-frame axis at ``axis_deg`` in the
    image plane (tilts about one camera axis only leave fy and cy undetermined)."""
    import cv2

    down = np.array([[1.0, 0, 0], [0, -1.0, 0], [0, 0, -1.0]])  # straight down, image x = world x
    a = np.radians(axis_deg)
    tilt, _ = cv2.Rodrigues(np.array([np.cos(a), np.sin(a), 0.0]) * np.radians(tilt_deg))
    rotation = tilt @ down
    axis_world = rotation.T @ np.array([0, 0, 1.0])
    return CameraPose(rotation, -axis_world * distance_mm)


def board_captures(
    sensor: SensorModel,
    *,
    n: int = 6,
    board: Checkerboard = Checkerboard(),
    intrinsics: Intrinsics = GEMINI2,
    seed: int = 0,
    **pose_kw,
) -> list:
    """``n`` captures of ``board`` (:func:`board_poses`), each rendered through ``sensor``."""
    rngs = np.random.SeedSequence(seed).spawn(n)
    return [
        render_board(
            p, board=board, intrinsics=intrinsics, sensor=sensor, rng=np.random.default_rng(r), name=f"board_{i:02d}"
        )
        for i, (p, r) in enumerate(zip(board_poses(n, **pose_kw), rngs))
    ]
