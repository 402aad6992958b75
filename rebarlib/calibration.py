"""Calibrating a depth camera from a few captures of a flat printed checkerboard.

The colour images give the focal lengths and principal point (OpenCV's
``findChessboardCorners`` and ``calibrateCamera``) and, for every capture, the board's pose;
the board's plane then says what depth every pixel on it should read, and the depth image says
what it did read. A straight line through those pairs, over all captures, is the depth error
model ``measured = (1 + scale) * true + offset``. The uncertainties of the intrinsics are
OpenCV's; those of the depth scale and offset are jackknife estimates over the captures (one
capture left out at a time), which see what a pooled least-squares fit over correlated pixels
would not: the error of each capture's pose.

A :class:`Calibration` is written to a JSON file (:meth:`Calibration.save`) that ``rebar
inspect --calibration FILE`` applies (:func:`apply_calibration`) and the uncertainty budget
uses in place of the device profile's datasheet limits.
"""

from __future__ import annotations

import dataclasses
import datetime as _dt
import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._camera import Intrinsics
from ._capture import Capture
from ._checks import RebarInputError

__all__ = ["Calibration", "calibrate", "apply_calibration", "load_calibration", "find_board", "calibration_id"]

FORMAT = "rebarlib calibration 1"
#: At least this many captures must show the whole board.
MIN_CAPTURES = 3
#: Depth pixels closer than this to the board's corner hull's border are left out (edge effects).
EDGE_MARGIN_PX = 6
#: Every STRIDE-th pixel of the board in each direction enters the depth fit.
STRIDE = 3


@dataclass(frozen=True)
class Calibration:
    """The result of :func:`calibrate`.

    ``intrinsics``: the calibrated pinhole intrinsics; ``u_intrinsics``: standard uncertainties
    of (fx, fy, cx, cy) in px. Depth: ``measured = (1 + depth_scale) * true + depth_offset_mm``,
    with standard uncertainties and their correlation ``r_scale_offset``.
    """

    intrinsics: Intrinsics
    u_intrinsics: tuple
    depth_scale: float
    depth_offset_mm: float
    u_depth_scale: float
    u_depth_offset_mm: float
    r_scale_offset: float
    depth_range_mm: tuple
    reprojection_rms_px: float
    depth_rms_mm: float
    n_captures: int
    board: dict
    device: str = ""
    calibrated_on: str = ""
    captures: tuple = ()
    source: str = field(default="", compare=False)

    def correct_depth(self, depth_mm) -> np.ndarray:
        """The true depth of measured depths (0 stays 0).

        Examples
        --------
        >>> from rebarlib import GEMINI2
        >>> c = Calibration(GEMINI2, (0, 0, 0, 0), 0.02, 1.0, 0, 0, 0, (400, 900), 0, 0, 3, {})
        >>> c.correct_depth(np.array([0.0, 511.0])).tolist()
        [0.0, 500.0]
        """
        d = np.asarray(depth_mm, float)
        return np.where(d > 0, (d - self.depth_offset_mm) / (1.0 + self.depth_scale), 0.0)

    def summary(self) -> str:
        """One line for the report: "calibrated on <date> from N board captures (...)"."""
        return (
            f"calibrated on {self.calibrated_on or 'an unrecorded date'} from {self.n_captures} board captures"
            f" (depth scale {self.depth_scale * 100:+.2f} ± {self.u_depth_scale * 100:.2f} %, offset "
            f"{self.depth_offset_mm:+.1f} ± {self.u_depth_offset_mm:.1f} mm, fx {self.intrinsics.fx:.1f} ± "
            f"{self.u_intrinsics[0]:.1f} px)"
        )

    def to_dict(self) -> dict:
        """The calibration as the JSON object :meth:`save` writes and :func:`load_calibration`
        reads (intrinsics, their uncertainties, the depth line and its fit)."""
        K = self.intrinsics
        return {
            "format": FORMAT,
            "device": self.device,
            "calibrated_on": self.calibrated_on,
            "captures": list(self.captures),
            "board": self.board,
            "intrinsics": {"fx": K.fx, "fy": K.fy, "cx": K.cx, "cy": K.cy, "width": K.width, "height": K.height},
            "u_intrinsics_px": dict(zip(("fx", "fy", "cx", "cy"), (float(u) for u in self.u_intrinsics))),
            "depth": {
                "model": "measured = (1 + scale) * true + offset_mm",
                "scale": self.depth_scale,
                "offset_mm": self.depth_offset_mm,
                "u_scale": self.u_depth_scale,
                "u_offset_mm": self.u_depth_offset_mm,
                "r_scale_offset": self.r_scale_offset,
                "range_mm": list(self.depth_range_mm),
                "rms_mm": self.depth_rms_mm,
            },
            "reprojection_rms_px": self.reprojection_rms_px,
            "n_captures": self.n_captures,
        }

    def save(self, path) -> Path:
        """Write the calibration as JSON (refuses to overwrite a capture's files)."""
        path = Path(path)
        if path.suffix.lower() != ".json":
            raise RebarInputError(f"--out {path}: expected a .json file name")
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(json.dumps(self.to_dict(), indent=1) + "\n", encoding="utf-8")
        return path


def load_calibration(path) -> Calibration:
    """Read a calibration file written by :meth:`Calibration.save` (``rebar calibrate``).

    Parameters
    ----------
    path : str, Path or Calibration
        The file (a Calibration is returned as it is).

    Returns
    -------
    Calibration

    Raises
    ------
    RebarInputError
        Naming the file when it is missing, not JSON, of another format or malformed.
    """
    if isinstance(path, Calibration):
        return path
    path = Path(path)
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise RebarInputError(f"--calibration {path}: not a readable calibration JSON file: {exc}") from None
    if not isinstance(d, dict) or d.get("format") != FORMAT:
        raise RebarInputError(
            f'--calibration {path}: expected a file written by `rebar calibrate` ("format": "{FORMAT}")'
        )
    try:
        K, u, dep = d["intrinsics"], d["u_intrinsics_px"], d["depth"]
        vals = [float(dep[k]) for k in ("scale", "offset_mm", "u_scale", "u_offset_mm", "r_scale_offset")]
        if not all(math.isfinite(v) for v in vals) or not -0.5 < vals[0] < 0.5 or min(vals[2:4]) < 0:
            raise ValueError("depth scale, offset or their uncertainties out of range")
        intr = Intrinsics(
            float(K["fx"]), float(K["fy"]), float(K["cx"]), float(K["cy"]), int(K["width"]), int(K["height"])
        )
        return Calibration(
            intr,
            tuple(float(u[k]) for k in ("fx", "fy", "cx", "cy")),
            *vals,
            tuple(float(x) for x in dep.get("range_mm", (0, 0))),
            float(d.get("reprojection_rms_px", math.nan)),
            float(dep.get("rms_mm", math.nan)),
            int(d.get("n_captures", 0)),
            dict(d.get("board") or {}),
            str(d.get("device", "")),
            str(d.get("calibrated_on", "")),
            tuple(d.get("captures") or ()),
            source=str(path),
        )
    except (KeyError, TypeError, ValueError, RebarInputError) as exc:
        raise RebarInputError(f"--calibration {path}: malformed calibration file ({exc})") from None


def calibration_id(path) -> dict:
    """``{"file": name, "sha256": digest}`` of a calibration file, after checking that it reads
    (for a result's manifest options: a result made with another calibration is not the same).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    dict
        The file's name and the SHA-256 of its bytes (hex).
    """
    import hashlib

    load_calibration(path)
    data = Path(path).read_bytes()
    return {"file": Path(path).name, "sha256": hashlib.sha256(data).hexdigest()}


def apply_calibration(capture: Capture, calibration: Calibration) -> Capture:
    """A copy of ``capture`` with the calibration's intrinsics and its depth corrected.

    Parameters
    ----------
    capture : Capture
    calibration : Calibration, str or Path
        The calibration or its file.

    Returns
    -------
    Capture
        The copy (the capture given is not changed).

    Raises
    ------
    RebarInputError
        Where the calibration was made for another image size.
    """
    cal = load_calibration(calibration)
    K, k = capture.intrinsics, cal.intrinsics
    if (K.width, K.height) != (k.width, k.height):
        raise RebarInputError(
            f"calibration {cal.source or ''}: made for {k.width}x{k.height} images, the capture "
            f"{capture.name!r} is {K.width}x{K.height}"
        )
    return dataclasses.replace(capture, intrinsics=k, depth_mm=cal.correct_depth(capture.depth_mm))


def find_board(capture: Capture, cols: int, rows: int):
    """The board's inner corners in the colour image, (rows * cols, 2) float32, or None.

    Parameters
    ----------
    capture : Capture
    cols, rows : int
        Inner corners of the board (OpenCV's ``patternSize``).

    Returns
    -------
    ndarray or None
        The corners to a fraction of a pixel, None where the whole board is not found.
    """
    import cv2

    gray = capture.color[..., 0] if capture.color.ndim == 3 else capture.color
    gray = np.ascontiguousarray(gray.astype(np.uint8))
    flags = cv2.CALIB_CB_ADAPTIVE_THRESH | cv2.CALIB_CB_NORMALIZE_IMAGE
    ok, corners = cv2.findChessboardCorners(gray, (cols, rows), flags=flags)
    if not ok:
        return None
    crit = (cv2.TERM_CRITERIA_EPS + cv2.TERM_CRITERIA_MAX_ITER, 50, 1e-3)
    corners = cv2.cornerSubPix(gray, corners, (5, 5), (-1, -1), crit)
    return corners.reshape(-1, 2).astype(np.float32)


def _object_points(cols: int, rows: int, square_mm: float) -> np.ndarray:
    j, i = np.mgrid[0:rows, 0:cols]
    return np.column_stack(
        ((i.ravel() - (cols - 1) / 2) * square_mm, (j.ravel() - (rows - 1) / 2) * square_mm, np.zeros(cols * rows))
    ).astype(np.float32)


def _board_depth_pairs(capture: Capture, corners, K: Intrinsics, rvec, tvec):
    """(true z, measured z) of the pixels inside the board's corner hull, every STRIDE-th."""
    import cv2

    R, _ = cv2.Rodrigues(rvec)
    n, t = R[:, 2], np.asarray(tvec, float).ravel()
    H, W = capture.depth_mm.shape
    hull = np.zeros((H, W), np.uint8)
    cv2.fillConvexPoly(hull, cv2.convexHull(np.round(corners).astype(np.int32)), 1)
    hull = cv2.erode(hull, np.ones((2 * EDGE_MARGIN_PX + 1,) * 2, np.uint8))
    v, u = np.nonzero(hull[::STRIDE, ::STRIDE])
    v, u = v * STRIDE, u * STRIDE
    z_meas = capture.depth_mm[v, u]
    ok = z_meas > 0
    u, v, z_meas = u[ok], v[ok], z_meas[ok]
    ray = np.column_stack(((u - K.cx) / K.fx, (v - K.cy) / K.fy, np.ones(len(u))))
    z_true = float(n @ t) / (ray @ n)
    return z_true, z_meas


def _line(pairs):
    zt = np.concatenate([p[0] for p in pairs])
    zm = np.concatenate([p[1] for p in pairs])
    A = np.column_stack((zt, np.ones_like(zt)))
    (a, b), *_ = np.linalg.lstsq(A, zm, rcond=None)
    return (a - 1.0, b, float(np.sqrt(np.mean((zm - (a * zt + b)) ** 2))), (float(zt.min()), float(zt.max())))


def _estimate(found, obj, K0: Intrinsics, flags) -> dict:
    """Intrinsics from the board corners, then the depth line from the boards' poses."""
    import cv2

    size = (K0.width, K0.height)
    rms, Kmat, _, rvecs, tvecs, std_in, _, _ = cv2.calibrateCameraExtended(
        [obj] * len(found), [c.reshape(-1, 1, 2) for _, c in found], size, K0.matrix.copy(), np.zeros(5), flags=flags
    )
    K = Intrinsics(float(Kmat[0, 0]), float(Kmat[1, 1]), float(Kmat[0, 2]), float(Kmat[1, 2]), *size)
    pairs = [_board_depth_pairs(cap, c, K, r, t) for (cap, c), r, t in zip(found, rvecs, tvecs)]
    s, o, rms_d, zrange = _line(pairs)
    return {
        "K": K,
        "std": np.asarray(std_in, float).ravel()[:4],
        "rms": float(rms),
        "pairs": pairs,
        "scale": float(s),
        "offset": float(o),
        "rms_depth": rms_d,
        "range": zrange,
        "vector": np.array([K.fx, K.fy, K.cx, K.cy, s, o]),
    }


def calibrate(
    captures, *, cols: int, rows: int, square_mm: float, device: str | None = None, fix_aspect: bool = False
) -> Calibration:
    """Calibrate intrinsics and depth from captures of a flat checkerboard.

    Parameters
    ----------
    captures : list of Capture (``load_capture``), each showing the whole board; at least 3,
        at several distances and tilted views (a focal length is not seen apart from the
        distance in views square to the board)
    cols, rows : inner corners of the board (OpenCV's ``patternSize``)
    square_mm : the printed squares' side, measured on the print (mm)
    device : the camera's name for the file (default: the first capture's ``device``)
    fix_aspect : keep fx / fy as the captures' intrinsics have it

    Returns
    -------
    Calibration
        The intrinsics, the depth line ``measured = (1 + scale) * true + offset_mm`` and their
        standard uncertainties.

    Raises
    ------
    RebarInputError
        For a bad board or square size, fewer than 3 captures showing the board, or captures
        of different image sizes.

    Notes
    -----
    Distortion is not estimated (the inspection uses a pinhole model): the captures should come
    undistorted, as depth cameras' SDKs give them.
    """
    import cv2

    captures = list(captures)
    if int(cols) != cols or int(rows) != rows or min(cols, rows) < 3:
        raise RebarInputError(f"--board: expected at least 3x3 inner corners, got {cols}x{rows}")
    if not (isinstance(square_mm, (int, float)) and math.isfinite(square_mm) and square_mm > 0):
        raise RebarInputError(f"--square-mm: expected a positive size in mm, got {square_mm!r}")
    found, names, missing = [], [], []
    for cap in captures:
        c = find_board(cap, int(cols), int(rows))
        (missing if c is None else names).append(cap.name)
        if c is not None:
            found.append((cap, c))
    if len(found) < MIN_CAPTURES:
        raise RebarInputError(
            f"captures: a {cols}x{rows} board was found in {len(found)} of {len(captures)} "
            f"captures (not in {missing}); at least {MIN_CAPTURES} are needed"
        )
    K0 = found[0][0].intrinsics
    size = (K0.width, K0.height)
    for cap, _ in found:
        if (cap.intrinsics.width, cap.intrinsics.height) != size:
            raise RebarInputError(
                f"capture {cap.name!r}: {cap.intrinsics.width}x{cap.intrinsics.height}, "
                f"the others are {size[0]}x{size[1]}: calibrate one image size at a time"
            )
    obj = _object_points(int(cols), int(rows), float(square_mm))
    flags = (
        cv2.CALIB_USE_INTRINSIC_GUESS
        | cv2.CALIB_FIX_K1
        | cv2.CALIB_FIX_K2
        | cv2.CALIB_FIX_K3
        | cv2.CALIB_ZERO_TANGENT_DIST
        | (cv2.CALIB_FIX_ASPECT_RATIO if fix_aspect else 0)
    )
    est = _estimate(found, obj, K0, flags)
    if sum(len(p[0]) for p in est["pairs"]) < 100:
        raise RebarInputError("captures: fewer than 100 pixels with depth on the board; is the depth image empty?")
    # jackknife over captures (one left out at a time, the whole estimate made again): each
    # capture's pose error is shared by all its corners and pixels, which neither OpenCV's
    # standard deviations nor a pooled fit see; the focal length's error reaches the depth
    # scale through the poses, and the jackknife carries that along
    n = len(found)
    loo = np.array([_estimate(found[:i] + found[i + 1 :], obj, K0, flags)["vector"] for i in range(n)])
    dev = loo - loo.mean(axis=0)
    cov = (n - 1) / n * dev.T @ dev
    u = np.sqrt(np.clip(np.diag(cov), 0, None))
    u_K = tuple(float(max(a, b)) for a, b in zip(u[:4], est["std"]))
    u_s, u_o = float(u[4]), float(u[5])
    r = float(cov[4, 5] / (u_s * u_o)) if u_s > 0 and u_o > 0 else 0.0
    K, s, o = est["K"], est["scale"], est["offset"]
    rms, rms_d, zrange = est["rms"], est["rms_depth"], est["range"]
    dev_name = device if device is not None else str(found[0][0].metadata.get("device", ""))
    return Calibration(
        K,
        u_K,
        float(s),
        float(o),
        u_s,
        u_o,
        r,
        (round(zrange[0], 1), round(zrange[1], 1)),
        float(rms),
        rms_d,
        n,
        {"cols": int(cols), "rows": int(rows), "square_mm": float(square_mm)},
        dev_name,
        _dt.date.today().isoformat(),
        tuple(names),
    )
