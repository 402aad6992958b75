"""Pinhole camera model (OpenCV frame, mm): projection, back-projection, depth image to points."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ._checks import RebarInputError

__all__ = ["Intrinsics", "Cloud", "project", "backproject", "depth_to_points", "GEMINI2"]


@dataclass(frozen=True)
class Intrinsics:
    """Pinhole intrinsics of an image of ``width`` x ``height`` pixels.

    Pixel (u, v) = (column, row); the centre of pixel (u, v) is at integer coordinates, so
    ``u = fx * x / z + cx`` lands on integer u for a point seen through the middle of a pixel.
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int
    height: int

    def __post_init__(self):
        for k in ("fx", "fy"):
            v = getattr(self, k)
            if not np.isfinite(v) or v <= 0:
                raise RebarInputError(f"intrinsics {k}: expected a positive focal length in px, got {v!r}")
        for k in ("width", "height"):
            v = getattr(self, k)
            if int(v) != v or v <= 0:
                raise RebarInputError(f"intrinsics {k}: expected a positive integer in px, got {v!r}")
        if not (-self.width < self.cx < 2 * self.width and -self.height < self.cy < 2 * self.height):
            raise RebarInputError(
                f"intrinsics principal point ({self.cx}, {self.cy}) is far outside the {self.width}x{self.height} image"
            )

    @property
    def matrix(self) -> np.ndarray:
        """The 3x3 camera matrix K."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def scaled(self, factor: float) -> "Intrinsics":
        """Intrinsics of the same camera with the image resized by ``factor``."""
        w, h = round(self.width * factor), round(self.height * factor)
        # Pixel centres at integer coordinates: centre u maps to (u + 0.5) * f - 0.5.
        return Intrinsics(
            self.fx * factor, self.fy * factor, (self.cx + 0.5) * factor - 0.5, (self.cy + 0.5) * factor - 0.5, w, h
        )


#: Orbbec Gemini 2 depth intrinsics at 1280x800 (device log quoted in docs/sensors.md).
GEMINI2 = Intrinsics(fx=616.395, fy=616.395, cx=636.922, cy=395.71, width=1280, height=800)


@dataclass(frozen=True)
class Cloud:
    """Points in the camera frame with the pixel each came from.

    Attributes
    ----------
    points : (N, 3) float64, mm
    pixels : (N, 2) int32, (u, v) of the source pixel
    """

    points: np.ndarray
    pixels: np.ndarray

    def __len__(self) -> int:
        return len(self.points)

    def subset(self, index) -> "Cloud":
        """The points selected by a boolean mask or an index array, links kept."""
        return Cloud(self.points[index], self.pixels[index])


def project(points, intrinsics: Intrinsics) -> np.ndarray:
    """Project camera-frame points to pixel coordinates.

    Parameters
    ----------
    points : (N, 3) float, mm, z > 0
    intrinsics : Intrinsics

    Returns
    -------
    (N, 2) float, (u, v) in px

    Examples
    --------
    >>> K = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)
    >>> project([[100.0, -50.0, 500.0]], K)
    array([[420., 190.]])
    """
    p = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    z = p[:, 2]
    return np.column_stack((intrinsics.fx * p[:, 0] / z + intrinsics.cx, intrinsics.fy * p[:, 1] / z + intrinsics.cy))


def backproject(pixels, depth_mm, intrinsics: Intrinsics) -> np.ndarray:
    """Back-project pixels with their depth (z, mm) to camera-frame points.

    Examples
    --------
    >>> K = Intrinsics(500.0, 500.0, 320.0, 240.0, 640, 480)
    >>> backproject([[420.0, 190.0]], [500.0], K)
    array([[100., -50., 500.]])
    """
    uv = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    z = np.asarray(depth_mm, dtype=np.float64).reshape(-1)
    return np.column_stack(
        ((uv[:, 0] - intrinsics.cx) * z / intrinsics.fx, (uv[:, 1] - intrinsics.cy) * z / intrinsics.fy, z)
    )


def ray_directions(intrinsics: Intrinsics, pixels=None) -> np.ndarray:
    """Ray directions with z = 1 through pixel centres (all pixels, row-major, if none given)."""
    if pixels is None:
        v, u = np.mgrid[0 : intrinsics.height, 0 : intrinsics.width]
        pixels = np.column_stack((u.ravel(), v.ravel()))
    return backproject(pixels, np.ones(len(pixels)), intrinsics)


def _valid_depth(d, max_depth_mm: float = 10_000.0) -> np.ndarray:
    """The pixels of a float depth image that :func:`depth_to_points` makes points of."""
    return (d > 0) & (d <= max_depth_mm) & np.isfinite(d)


def depth_to_points(depth_mm, intrinsics: Intrinsics, *, max_depth_mm: float = 10_000.0) -> Cloud:
    """Every pixel with valid depth (0 < z <= max_depth_mm) as a camera-frame point with its pixel.

    Parameters
    ----------
    depth_mm : (H, W) float, mm, 0 = missing
    intrinsics : Intrinsics
    max_depth_mm : depths beyond this are treated as missing (there is no silent 3 m cut-off).

    Examples
    --------
    >>> K = Intrinsics(500.0, 500.0, 1.0, 1.0, 3, 2)
    >>> cloud = depth_to_points([[0, 500, 500], [500, 0, 0]], K)
    >>> cloud.pixels.tolist()
    [[1, 0], [2, 0], [0, 1]]
    >>> cloud.points[0].tolist()
    [0.0, -1.0, 500.0]
    """
    d = np.asarray(depth_mm, dtype=np.float64)
    if d.shape != (intrinsics.height, intrinsics.width):
        raise RebarInputError(
            f"depth: expected shape ({intrinsics.height}, {intrinsics.width}) from the intrinsics, got {d.shape}"
        )
    valid = _valid_depth(d, max_depth_mm)
    v, u = np.nonzero(valid)
    pixels = np.column_stack((u, v)).astype(np.int32)
    return Cloud(backproject(pixels, d[v, u], intrinsics), pixels)
