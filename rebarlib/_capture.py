"""RGB-D captures on disk: the capture folder format, and bare point clouds."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from ._camera import Intrinsics
from ._checks import RebarInputError

__all__ = [
    "Capture",
    "load_capture",
    "save_capture",
    "load_cloud",
    "read_intrinsics",
    "write_intrinsics",
    "CAPTURE_FILES",
]

CAPTURE_FILES = ("color.png | color.jpg", "depth.png", "camera.json")

#: Largest image a capture may hold, in pixels (50 megapixels: 6 times a 4K frame, 50 times the
#: 1280 x 800 depth of the cameras this toolkit is for). Image headers are read and checked
#: against this and ``camera.json`` before anything is decoded: a few-kilobyte PNG can declare
#: 30000 x 30000 pixels and take gigabytes to decode.
MAX_IMAGE_PIXELS = 50_000_000
#: the optional record of a capture taken because another capture's sheet asked for it, aimed at
#: one of that capture's bars (docs/formats.md, docs/decisions/043)
AIM_FILE = "aim.json"
#: ``depth_scale_mm`` when ``camera.json`` gives none (said in the result's notes).
DEFAULT_DEPTH_SCALE_MM = 1.0


@dataclass(frozen=True, eq=False)
class Capture:
    """One aligned RGB-D capture.

    Attributes
    ----------
    color : (H, W, 3) uint8, RGB
    depth_mm : (H, W) float64, mm, 0 = no depth
    intrinsics : Intrinsics (of both images: depth is aligned to colour)
    metadata : dict: ``depth_scale_mm``, and optionally ``device``, ``captured_at``, ``name``,
        ``source`` (the folder it was read from), ``truth`` (synthetic ground truth),
        ``aimed_at`` (``{"capture": name, "bar_id": k}``: the bar of another capture this one was
        aimed at, from ``aim.json``, ``read_aim``).
    labels : (H, W) uint8 or None: 0 formwork/background, 1 lower-lattice bar, 2 upper-lattice bar
        (synthetic captures only).
    bar_ids : (H, W) int32 or None: 0 no bar, k + 1 for the bar with id k (synthetic only).
    """

    color: np.ndarray
    depth_mm: np.ndarray
    intrinsics: Intrinsics
    metadata: dict = field(default_factory=dict)
    labels: np.ndarray | None = None
    bar_ids: np.ndarray | None = None

    def __post_init__(self):
        h, w = self.intrinsics.height, self.intrinsics.width
        if self.color.shape != (h, w, 3) or self.color.dtype != np.uint8:
            raise RebarInputError(
                f"color: expected ({h}, {w}, 3) uint8 RGB from the intrinsics, "
                f"got {self.color.shape} {self.color.dtype}"
            )
        if self.depth_mm.shape != (h, w):
            raise RebarInputError(f"depth: expected ({h}, {w}) from the intrinsics, got {self.depth_mm.shape}")

    @property
    def name(self) -> str:
        """The capture's name (its folder's name when loaded; "capture" where unnamed)."""
        return str(self.metadata.get("name", "capture"))

    @property
    def truth(self) -> dict | None:
        """A synthetic capture's ground truth (``truth.json``), None for a real one."""
        return self.metadata.get("truth")

    @property
    def depth_scale_mm(self) -> float:
        """mm per unit of the 16-bit depth image (``camera.json``'s ``depth_scale_mm``)."""
        return float(self.metadata.get("depth_scale_mm", DEFAULT_DEPTH_SCALE_MM))


def _read_json(path: Path) -> dict:
    try:
        data = json.loads(path.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise RebarInputError(f"{path}: file not found") from None
    except (json.JSONDecodeError, UnicodeDecodeError) as exc:
        raise RebarInputError(f"{path}: not valid JSON ({exc})") from None
    if not isinstance(data, dict):
        raise RebarInputError(f"{path}: expected a JSON object, got {type(data).__name__}")
    return data


def read_aim(path) -> dict:
    """Read a capture folder's ``aim.json``: the record of a capture taken because another
    capture's sheet asked for it ("a capture ... aimed at its middle", a bar the other capture
    could not size), saying which bar it was aimed at::

        {"aimed_at": {"capture": "C1_665", "bar_id": 12}}

    ``capture`` is the asking capture's name (its folder's name, as its sheet and ``result.json``
    name it) and ``bar_id`` the bar's id there. The camera's optical axis (the image's middle) was
    put on that bar's middle. Returns ``{"capture": str, "bar_id": int}``; anything else raises
    :class:`RebarInputError` naming the file and what was expected."""
    path = Path(path)
    data = _read_json(path)
    want = 'expected {"aimed_at": {"capture": "<capture folder name>", "bar_id": <bar id, a whole number >= 0>}}'
    if set(data) != {"aimed_at"} or not isinstance(data["aimed_at"], dict):
        raise RebarInputError(f"{path}: {want}; got the keys {sorted(data)}")
    aim = data["aimed_at"]
    if set(aim) != {"capture", "bar_id"}:
        raise RebarInputError(f"{path}: {want}; got aimed_at's keys {sorted(aim)}")
    cap, bid = aim["capture"], aim["bar_id"]
    if not isinstance(cap, str) or not cap.strip():
        raise RebarInputError(f"{path}: {want}; got capture {cap!r}")
    if isinstance(bid, bool) or not isinstance(bid, int) or bid < 0:
        raise RebarInputError(f"{path}: {want}; got bar_id {bid!r}")
    return {"capture": cap.strip(), "bar_id": int(bid)}


def read_intrinsics(path) -> tuple[Intrinsics, dict]:
    """Read ``camera.json`` (Open3D's pinhole intrinsic keys plus ``depth_scale_mm``).

    Parameters
    ----------
    path : str or Path
        The ``camera.json`` file.

    Returns
    -------
    intrinsics : Intrinsics
    meta : dict
        The remaining keys (depth scale, device, capture time).

    Raises
    ------
    RebarInputError
        Naming the file and the key, for a missing file, invalid JSON or a bad value.
    """
    path = Path(path)
    data = _read_json(path)
    for key in ("width", "height", "intrinsic_matrix"):
        if key not in data:
            raise RebarInputError(
                f"{path}: missing key '{key}' (Open3D intrinsic JSON: width, height, "
                "intrinsic_matrix column-major [fx,0,0, 0,fy,0, cx,cy,1])"
            )
    for key in ("width", "height"):
        _image_side(data[key], f"{path}: {key}")
    if data["width"] * data["height"] > MAX_IMAGE_PIXELS:
        raise RebarInputError(
            f"{path}: width x height = {data['width']} x {data['height']} is over the "
            f"limit of {MAX_IMAGE_PIXELS / 1e6:g} megapixels per image"
        )
    for key in ("device", "captured_at"):
        if key in data and not isinstance(data[key], str):
            raise RebarInputError(f"{path}: {key} must be a text string, got {_short(data[key])}")
    m = data["intrinsic_matrix"]
    if not (
        isinstance(m, list)
        and len(m) == 9
        and all(isinstance(x, (int, float)) and not isinstance(x, bool) and math.isfinite(x) for x in m)
    ):
        raise RebarInputError(f"{path}: intrinsic_matrix must be a list of 9 finite numbers, got {_short(m)}")
    K = np.array(m, dtype=np.float64).reshape(3, 3).T  # stored column-major
    if abs(K[0, 1]) > 1e-9 or abs(K[1, 0]) > 1e-9 or np.abs(K[2] - [0, 0, 1]).max() > 1e-9:
        raise RebarInputError(f"{path}: intrinsic_matrix is not a pinhole matrix [fx,0,0, 0,fy,0, cx,cy,1]: {m}")
    try:
        intr = Intrinsics(
            float(K[0, 0]), float(K[1, 1]), float(K[0, 2]), float(K[1, 2]), int(data["width"]), int(data["height"])
        )
    except RebarInputError as exc:
        raise RebarInputError(f"{path}: {exc}") from None
    extra = {k: v for k, v in data.items() if k not in ("width", "height", "intrinsic_matrix")}
    if "depth_scale_mm" not in extra:
        extra["depth_scale_assumed"] = True
    scale = extra.get("depth_scale_mm", DEFAULT_DEPTH_SCALE_MM)
    if isinstance(scale, bool) or not isinstance(scale, (int, float)) or not (0 < scale <= 100):
        raise RebarInputError(f"{path}: depth_scale_mm must be mm per depth unit in (0, 100], got {_short(scale)}")
    extra["depth_scale_mm"] = float(scale)
    return intr, extra


def _short(value, n: int = 60) -> str:
    text = repr(value)
    return text if len(text) <= n else text[: n - 1] + "…"


def _image_side(value, where: str) -> int:
    """A width or height from ``camera.json``: a whole number of pixels, 1 or more."""
    if isinstance(value, bool) or not isinstance(value, int):
        raise RebarInputError(f"{where}: expected a whole number of pixels, got {type(value).__name__} {_short(value)}")
    if value < 1:
        raise RebarInputError(f"{where}: expected at least 1 pixel, got {value}")
    return value


def image_size(path) -> tuple[int, int]:
    """``(width, height)`` of a PNG or JPEG file from its header alone (nothing is decoded).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    tuple of int
        ``(width, height)`` in pixels.

    Raises
    ------
    RebarInputError
        Naming the file when it is neither a PNG nor a JPEG, or its header is cut short.
    """
    path = Path(path)
    with open(path, "rb") as f:
        head = f.read(24)
        if head[:8] == b"\x89PNG\r\n\x1a\n" and len(head) == 24 and head[12:16] == b"IHDR":
            return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")
        if head[:2] == b"\xff\xd8":
            f.seek(2)
            return _jpeg_size(f, path)
    raise RebarInputError(f"{path}: not a PNG or JPEG file (its header is neither)")


def _jpeg_size(f, path: Path) -> tuple[int, int]:
    """Walk a JPEG's segments to its first start-of-frame marker and read the frame's size."""
    while True:
        b = f.read(1)
        if b != b"\xff":
            break
        while b == b"\xff":  # fill bytes before a marker
            b = f.read(1)
        if not b:
            break
        marker = b[0]
        if 0xD0 <= marker <= 0xD8 or marker == 0x01:  # markers without a length
            continue
        size = f.read(2)
        if len(size) < 2 or int.from_bytes(size, "big") < 2:
            break
        if 0xC0 <= marker <= 0xCF and marker not in (0xC4, 0xC8, 0xCC):
            body = f.read(5)
            if len(body) < 5:
                break
            return int.from_bytes(body[3:5], "big"), int.from_bytes(body[1:3], "big")
        f.seek(int.from_bytes(size, "big") - 2, 1)
    raise RebarInputError(f"{path}: JPEG header cut short or damaged (no frame size found)")


def _check_image_headers(color: Path, depth: Path, intr: Intrinsics, camera_json: Path) -> None:
    """Refuse images whose headers declare a size over the limit, sizes that differ, or a size
    other than camera.json's: all before anything is decoded."""
    sizes = {}
    for path in (color, depth):
        w, h = sizes[path] = image_size(path)
        if w * h > MAX_IMAGE_PIXELS:
            raise RebarInputError(
                f"{path}: declares {w} x {h} pixels, over the limit of "
                f"{MAX_IMAGE_PIXELS / 1e6:g} megapixels per image (not decoded)"
            )
    (cw, ch), (dw, dh) = sizes[color], sizes[depth]
    if (cw, ch) != (dw, dh):
        raise RebarInputError(
            f"{color.parent}: colour {cw}x{ch} and depth {dw}x{dh} differ in size: depth must be aligned to colour"
        )
    if (dw, dh) != (intr.width, intr.height):
        raise RebarInputError(f"{camera_json}: says {intr.width}x{intr.height} but the images are {dw}x{dh}")


def write_intrinsics(path, intrinsics: Intrinsics, **extra) -> None:
    """Write ``camera.json`` as :func:`read_intrinsics` reads it.

    Parameters
    ----------
    path : str or Path
        The file to write.
    intrinsics : Intrinsics
    **extra
        Further keys written as given (``depth_scale_mm``, ``device``, ``captured_at``).
    """
    K = intrinsics.matrix
    data = {
        "width": intrinsics.width,
        "height": intrinsics.height,
        "intrinsic_matrix": [float(x) for x in K.T.ravel()],
        **extra,
    }
    Path(path).write_text(json.dumps(data, indent=2) + "\n", encoding="utf-8")


def _imread(path: Path, flags):
    import cv2

    img = cv2.imread(str(path), flags)
    if img is None:
        raise RebarInputError(f"{path}: could not be read as an image")
    return img


def _read_truth_image(path: Path, intr: Intrinsics) -> np.ndarray:
    """A synthetic capture's one-channel ground-truth image, its header checked like the images'."""
    import cv2

    w, h = image_size(path)
    if (w, h) != (intr.width, intr.height):
        raise RebarInputError(
            f"{path}: is {w}x{h}, not the capture's {intr.width}x{intr.height} (checked before decoding)"
        )
    img = _imread(path, cv2.IMREAD_UNCHANGED)
    if img.ndim != 2:
        raise RebarInputError(f"{path}: expected a single-channel image, got shape {img.shape}")
    return img


def load_capture(path) -> Capture:
    """Read a capture folder: ``color.png`` (or ``.jpg``), ``depth.png`` (16-bit), ``camera.json``.

    Synthetic captures also carry ``truth.json``, ``labels.png`` and ``bar_ids.png``, which are
    read when present. Every problem raises :class:`RebarInputError` naming the file.

    Parameters
    ----------
    path : str or Path
        The capture folder.

    Returns
    -------
    Capture
        Colour (H, W, 3) uint8 RGB, depth (H, W) in mm (0 where none), the intrinsics, and the
        metadata (``name``: the folder's name, ``source``, ``depth_scale_mm``, ...).

    Raises
    ------
    RebarInputError
        Naming the file: a missing folder or file, an unreadable image, sizes that disagree,
        a depth image with no depth at all.

    Examples
    --------
    >>> from rebarlib.data import example_capture
    >>> cap = load_capture(example_capture("paper_slab", "A_400"))
    >>> cap.name, cap.color.shape, cap.intrinsics.width
    ('A_400', (800, 1280, 3), 1280)
    """
    import cv2

    folder = Path(path)
    if not folder.is_dir():
        raise RebarInputError(f"{folder}: capture folder not found (expected a folder with {', '.join(CAPTURE_FILES)})")
    colors = [folder / n for n in ("color.png", "color.jpg", "color.jpeg") if (folder / n).is_file()]
    if not colors:
        raise RebarInputError(f"{folder}: no color.png or color.jpg in the capture folder")
    if len(colors) > 1:
        raise RebarInputError(
            f"{folder}: holds {' and '.join(c.name for c in colors)}: which one is the "
            "capture's colour image is ambiguous; keep one"
        )
    depth_path = folder / "depth.png"
    if not depth_path.is_file():
        raise RebarInputError(f"{depth_path}: file not found (16-bit depth image expected)")
    intr, meta = read_intrinsics(folder / "camera.json")
    _check_image_headers(colors[0], depth_path, intr, folder / "camera.json")

    color = _imread(colors[0], cv2.IMREAD_UNCHANGED)
    if color.ndim == 2:
        color = cv2.cvtColor(color, cv2.COLOR_GRAY2RGB)
    elif color.shape[2] == 4:
        color = cv2.cvtColor(color, cv2.COLOR_BGRA2RGB)
    else:
        color = cv2.cvtColor(color, cv2.COLOR_BGR2RGB)
    if color.dtype != np.uint8:
        raise RebarInputError(f"{colors[0]}: expected an 8-bit colour image, got {color.dtype}")
    raw = _imread(depth_path, cv2.IMREAD_UNCHANGED)
    if raw.dtype != np.uint16 or raw.ndim != 2:
        raise RebarInputError(
            f"{depth_path}: expected a single-channel 16-bit PNG, got {raw.dtype} with shape {raw.shape}"
        )
    if color.shape[:2] != raw.shape:
        raise RebarInputError(
            f"{folder}: colour {color.shape[1]}x{color.shape[0]} and depth "
            f"{raw.shape[1]}x{raw.shape[0]} differ in size: depth must be aligned to colour"
        )
    if raw.shape != (intr.height, intr.width):
        raise RebarInputError(
            f"{folder / 'camera.json'}: says {intr.width}x{intr.height} but the images "
            f"are {raw.shape[1]}x{raw.shape[0]}"
        )
    if not raw.any():
        raise RebarInputError(f"{depth_path}: every pixel is 0 (no depth at all)")
    depth = raw.astype(np.float64) * meta["depth_scale_mm"]

    meta["name"] = folder.name
    meta["source"] = str(folder)
    labels = bar_ids = None
    if (folder / AIM_FILE).is_file():
        meta["aimed_at"] = read_aim(folder / AIM_FILE)
    if (folder / "truth.json").is_file():
        meta["truth"] = _read_json(folder / "truth.json")
    if (folder / "labels.png").is_file():
        labels = _read_truth_image(folder / "labels.png", intr).astype(np.uint8)
    if (folder / "bar_ids.png").is_file():
        bar_ids = _read_truth_image(folder / "bar_ids.png", intr).astype(np.int32)
    return Capture(color, depth, intr, meta, labels, bar_ids)


def save_capture(capture: Capture, path, *, color_format: str = "png", overwrite: bool = False) -> Path:
    """Write a capture folder that :func:`load_capture` reads back.

    Depth is stored as ``round(depth_mm / depth_scale_mm)`` in a 16-bit PNG; a depth already on
    that grid (every loaded or synthetic capture) round-trips exactly. An existing non-empty
    folder is never written into unless ``overwrite=True``.

    Parameters
    ----------
    capture : Capture
    path : str or Path
        The folder to write (created where missing).
    color_format : str
        "png" (lossless) or "jpg" (quality 92).
    overwrite : bool
        Write into a folder that is not empty.

    Returns
    -------
    Path
        The folder.

    Raises
    ------
    RebarInputError
        For a non-empty folder without ``overwrite``, an unknown ``color_format``, or a depth
        that does not fit 16 bits at the capture's depth scale.
    """
    import cv2

    folder = Path(path)
    if folder.exists() and any(folder.iterdir()) and not overwrite:
        raise RebarInputError(
            f"{folder}: folder exists and is not empty; refusing to overwrite "
            "(pass overwrite=True or choose a new folder)"
        )
    if color_format not in ("png", "jpg"):
        raise RebarInputError(f"color_format: expected 'png' or 'jpg', got {color_format!r}")
    scale = capture.depth_scale_mm
    units = np.round(capture.depth_mm / scale)
    if units.max() > 65535:
        raise RebarInputError(
            f"depth: {capture.depth_mm.max():.0f} mm does not fit 16 bits at "
            f"{scale} mm per unit; use a larger depth_scale_mm"
        )
    folder.mkdir(parents=True, exist_ok=True)
    bgr = cv2.cvtColor(capture.color, cv2.COLOR_RGB2BGR)
    if color_format == "png":
        cv2.imwrite(str(folder / "color.png"), bgr, [cv2.IMWRITE_PNG_COMPRESSION, 6])
    else:
        cv2.imwrite(str(folder / "color.jpg"), bgr, [cv2.IMWRITE_JPEG_QUALITY, 92])
    cv2.imwrite(str(folder / "depth.png"), units.astype(np.uint16))
    extra = {k: capture.metadata[k] for k in ("device", "captured_at") if k in capture.metadata}
    write_intrinsics(folder / "camera.json", capture.intrinsics, depth_scale_mm=scale, **extra)
    if capture.metadata.get("aimed_at") is not None:
        aim = {"aimed_at": dict(capture.metadata["aimed_at"])}
        (folder / AIM_FILE).write_text(json.dumps(aim) + "\n", encoding="utf-8")
    if capture.truth is not None:
        (folder / "truth.json").write_text(json.dumps(capture.truth, indent=1) + "\n", encoding="utf-8")
    if capture.labels is not None:
        cv2.imwrite(str(folder / "labels.png"), capture.labels.astype(np.uint8))
    if capture.bar_ids is not None:
        cv2.imwrite(str(folder / "bar_ids.png"), capture.bar_ids.astype(np.uint16))
    return folder


def load_cloud(path, *, units: str) -> np.ndarray:
    """Read a bare point cloud (PLY, PCD, XYZ/PTS/CSV/TXT, NPZ, LAS/LAZ, E57) as (N, 3) mm points
    in the file's own frame.

    ``units`` must be given ("mm" or "m"): clouds arrive in either. A cloud whose extent looks
    like the other unit (under 10 units across when said to be mm, over 100 when said to be m)
    gets a warning rather than a silent thousand-fold error. The readers (and the per-point
    fields this drops) are in :mod:`rebarlib.cloud_io`; ``read_cloud`` keeps them.

    Parameters
    ----------
    path : str or Path
        The cloud file.
    units : str
        "mm" or "m", the unit of the file's coordinates (required: never guessed).

    Returns
    -------
    ndarray
        (N, 3) float64 points in mm, the file's frame (non-finite points left out).

    Raises
    ------
    RebarInputError
        Naming the file when it is missing, of an unknown format, unreadable or empty.
    """
    from .cloud_io import read_cloud

    return read_cloud(path, units=units, recentre=False).points
