"""Reading and writing scanned point clouds: PLY, PCD, XYZ/PTS/CSV/TXT, NPZ, LAS/LAZ and E57.

Scanners and their software export clouds in many formats, units and frames. Every reader here
returns a :class:`ScanCloud`: points in mm, *re-centred* (the median point is subtracted, so
georeferenced coordinates with offsets of 10^5–10^6 m keep their sub-millimetre precision in
float64 arithmetic) with the subtracted ``offset_mm`` kept, and every per-point field the file
holds (intensity, colour, normals, classification, ...) as arrays keyed by name.

The units of a file are never guessed: ``units`` ("mm" or "m") must be given, and a cloud whose
extent looks like the other unit gets a warning.
"""

from __future__ import annotations

import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ._checks import RebarInputError
from ._cloud_readers import _READERS
from ._cloud_writers import _write_e57, _write_las, _write_pcd, _write_ply, _write_text

__all__ = ["CLOUD_SUFFIXES", "UNIT_SCALE", "ScanCloud", "cloud_files", "read_cloud", "write_cloud"]

#: mm per unit of a file
UNIT_SCALE = {"mm": 1.0, "m": 1000.0}
CLOUD_SUFFIXES = (".ply", ".pcd", ".xyz", ".pts", ".csv", ".txt", ".npz", ".las", ".laz", ".e57")


@dataclass(frozen=True)
class ScanCloud:
    """A scanned cloud in mm: ``points + offset_mm`` are the file's coordinates (in mm).

    Attributes
    ----------
    points : (N, 3) float64, mm, re-centred
    offset_mm : (3,) float64, what was subtracted (the file's frame = points + offset_mm)
    fields : dict name -> (N,) or (N, k) array: ``intensity``, ``colors`` (N, 3 in 0..1),
        ``normals`` (N, 3), and any other per-point column of the file
    units : the unit of the file ("mm" or "m")
    source : the file it came from ("" for arrays)
    """

    points: np.ndarray
    offset_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))
    fields: dict = field(default_factory=dict)
    units: str = "mm"
    source: str = ""

    def __len__(self) -> int:
        return len(self.points)

    @property
    def absolute_mm(self) -> np.ndarray:
        """The points in the file's own frame (mm)."""
        return self.points + self.offset_mm

    def subset(self, index) -> ScanCloud:
        """The cloud restricted to ``index`` (indices or a boolean mask), fields included."""
        return replace(self, points=self.points[index], fields={k: v[index] for k, v in self.fields.items()})


# ----------------------------------------------------------------------------------------------
# Reading
# ----------------------------------------------------------------------------------------------


def cloud_files(folder) -> list:
    """The point cloud files directly in ``folder`` (by suffix), sorted by name.

    Parameters
    ----------
    folder : str or Path

    Returns
    -------
    list of Path
        The files whose suffix is one of :data:`CLOUD_SUFFIXES` (any case); empty where
        ``folder`` is not a folder.
    """
    f = Path(folder)
    if not f.is_dir():
        return []
    return sorted(p for p in f.iterdir() if p.is_file() and p.suffix.lower() in CLOUD_SUFFIXES)


def read_cloud(path, *, units: str, recentre: bool = True) -> ScanCloud:
    """Read a point cloud file into a :class:`ScanCloud` (mm, re-centred, fields kept).

    Parameters
    ----------
    path : a ``.ply``, ``.pcd``, ``.xyz``, ``.pts``, ``.csv``, ``.txt``, ``.npz``, ``.las``,
        ``.laz`` or ``.e57`` file
    units : "mm" or "m", the unit of the file's coordinates (required: never guessed)
    recentre : subtract the median point (kept as ``offset_mm``); False keeps the file's frame

    Returns
    -------
    ScanCloud
        The finite points in mm, with every per-point field the file holds.

    Raises
    ------
    RebarInputError
        Naming the file when it is missing, of an unknown format, unreadable or empty.
    """
    if units not in UNIT_SCALE:
        raise RebarInputError(f"units: expected 'mm' or 'm', got {units!r}")
    p = Path(path)
    if not p.is_file():
        raise RebarInputError(f"{p}: point cloud file not found")
    suffix = p.suffix.lower()
    reader = _READERS.get(suffix)
    if reader is None:
        raise RebarInputError(
            f"{p}: unknown point cloud format {suffix!r} (expected one of {', '.join(CLOUD_SUFFIXES)})"
        )
    try:
        xyz, fields = reader(p)
    except RebarInputError:
        raise
    except (ValueError, OSError, KeyError, IndexError, TypeError) as exc:
        raise RebarInputError(f"{p}: cannot read the {suffix[1:].upper()} file ({exc})") from None
    return _finish(xyz, fields, units=units, source=str(p), recentre=recentre)


def _finish(xyz, fields, *, units, source, recentre) -> ScanCloud:
    xyz = np.asarray(xyz, np.float64)
    if xyz.ndim != 2 or xyz.shape[1] != 3 or len(xyz) == 0:
        raise RebarInputError(f"{source}: expected a non-empty cloud of x, y, z points, got shape {xyz.shape}")
    ok = np.all(np.isfinite(xyz), axis=1)
    xyz = xyz[ok]
    fields = {k: np.asarray(v)[ok] for k, v in fields.items() if len(v) == len(ok)}
    if len(xyz) == 0:
        raise RebarInputError(f"{source}: no finite x, y, z point in the file")
    _check_units(xyz, units, source)
    mm = xyz * UNIT_SCALE[units]
    offset = np.median(mm, axis=0) if recentre else np.zeros(3)
    return ScanCloud(mm - offset, offset, fields, units, source)


def _check_units(xyz, units, source) -> None:
    extent = float(np.ptp(xyz, axis=0).max())
    if units == "mm" and 0 < extent < 10:
        warnings.warn(
            f"{source}: the cloud spans only {extent:.3g} units; are these metres? (units='mm' given)", stacklevel=4
        )
    if units == "m" and extent > 100:
        warnings.warn(
            f"{source}: the cloud spans {extent:.3g} units; are these millimetres? (units='m' given)", stacklevel=4
        )


# ----------------------------------------------------------------------------------------------
# Writing (synthetic scans and tests)
# ----------------------------------------------------------------------------------------------


def write_cloud(path, cloud: ScanCloud, *, units: str = "mm") -> Path:
    """Write ``cloud`` (its absolute coordinates) to ``path`` in the format its suffix names,
    in ``units``; ``intensity`` and ``colors`` are written where the format has room for them,
    ``normals`` in PLY, and every field in NPZ.

    Parameters
    ----------
    path : str or Path
        The file; its suffix (one of :data:`CLOUD_SUFFIXES`) names the format.
    cloud : ScanCloud
    units : str
        "mm" or "m", the unit of the written coordinates.

    Returns
    -------
    Path
        The file written.

    Raises
    ------
    RebarInputError
        For units other than "mm" or "m", or a suffix of no known format.

    Examples
    --------
    >>> import tempfile, numpy as np
    >>> pts = np.array([[0.0, 0.0, 0.0], [1000.0, 0.0, 0.0], [0.0, 1000.0, 20.0]])
    >>> with tempfile.TemporaryDirectory() as d:
    ...     path = write_cloud(f"{d}/three.xyz", ScanCloud(pts), units="m")
    ...     back = read_cloud(path, units="m", recentre=False)
    >>> np.allclose(back.points, pts)
    True
    """
    if units not in UNIT_SCALE:
        raise RebarInputError(f"units: expected 'mm' or 'm', got {units!r}")
    p = Path(path)
    suffix = p.suffix.lower()
    xyz = cloud.absolute_mm / UNIT_SCALE[units]
    inten = cloud.fields.get("intensity")
    rgb = cloud.fields.get("colors")
    rgb8 = None if rgb is None else np.clip(np.round(np.asarray(rgb) * 255), 0, 255).astype(np.uint8)
    if suffix == ".ply":
        _write_ply(p, xyz, inten, rgb8, cloud.fields.get("normals"))
    elif suffix == ".pcd":
        _write_pcd(p, xyz, inten)
    elif suffix in (".xyz", ".pts", ".txt", ".csv"):
        _write_text(p, xyz, inten, rgb8, suffix)
    elif suffix == ".npz":
        extra = {k: v for k, v in cloud.fields.items()}
        np.savez_compressed(p, points=xyz, **extra)
    elif suffix in (".las", ".laz"):
        _write_las(p, xyz, inten, rgb8)
    elif suffix == ".e57":
        _write_e57(p, xyz, inten)
    else:
        raise RebarInputError(
            f"{p}: unknown point cloud format {suffix!r} (expected one of {', '.join(CLOUD_SUFFIXES)})"
        )
    return p
