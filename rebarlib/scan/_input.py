"""Input of a scanned cloud: a file, a ScanCloud or an array; the up axis as given; the result
manifest of a cloud file."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from .._checks import RebarInputError
from ..cloud_io import ScanCloud, read_cloud


METHOD = "cloud"


def as_scan_cloud(cloud, *, units: str | None = None) -> ScanCloud:
    """A :class:`ScanCloud` from a file path (``units`` required), a ScanCloud, or an (N, 3)
    array in mm (``units`` "mm" or None) or m (``units="m"``).

    Parameters
    ----------
    cloud : str or pathlib.Path of a cloud file (any format of :mod:`rebarlib.cloud_io`), a
        :class:`ScanCloud` (returned as it is, ``units`` not looked at), or an (N, 3)
        array_like of points
    units : "mm" or "m", the unit of the file or the array; required with a file; None (an
        array only) is mm

    Returns
    -------
    ScanCloud in mm. From an array: its rows with finite coordinates, less their median point
    (``offset_mm``; ``absolute_mm`` gives the array's frame back, in mm), no ``fields`` and
    ``source`` "".

    Raises
    ------
    RebarInputError
        a file without ``units``, ``units`` other than "mm" or "m", or an array that is not a
        non-empty (N, 3) one (and what :func:`rebarlib.cloud_io.read_cloud` refuses in a file).

    Examples
    --------
    >>> sc = as_scan_cloud([[1000.0, 0.0, 0.0], [1010.0, 0.0, 2.0], [1020.0, 0.0, 4.0]])
    >>> sc.points.tolist(), sc.offset_mm.tolist()
    ([[-10.0, 0.0, -2.0], [0.0, 0.0, 0.0], [10.0, 0.0, 2.0]], [1010.0, 0.0, 2.0])
    >>> as_scan_cloud([[1.0, 2.0, 3.0]], units="m").absolute_mm.tolist()
    [[1000.0, 2000.0, 3000.0]]
    """
    if isinstance(cloud, ScanCloud):
        return cloud
    if isinstance(cloud, (str, Path)):
        if units is None:
            raise RebarInputError(f"units: the unit of {Path(cloud).name} must be given ('mm' or 'm')")
        return read_cloud(cloud, units=units)
    pts = np.asarray(cloud, float)
    if pts.ndim != 2 or pts.shape[1] != 3 or len(pts) == 0:
        raise RebarInputError(f"cloud: expected a file, a ScanCloud or a non-empty (N, 3) array, got shape {pts.shape}")
    scale = {"mm": 1.0, None: 1.0, "m": 1000.0}.get(units)
    if scale is None:
        raise RebarInputError(f"units: expected 'mm' or 'm', got {units!r}")
    pts = pts[np.all(np.isfinite(pts), axis=1)] * scale
    off = np.median(pts, axis=0)
    return ScanCloud(pts - off, off, {}, units or "mm", "")


def parse_up(up) -> np.ndarray | None:
    """``"+z"``, ``"-y"``, ... or a 3-vector -> unit vector; None stays None.

    Parameters
    ----------
    up : an axis name ("+x", "-x", "+y", "-y", "+z", "-z"; a bare "x", "y" or "z" is "+";
        case and surrounding spaces ignored), a non-zero finite 3-vector, or None

    Returns
    -------
    (3,) float unit vector, or None for None.

    Raises
    ------
    RebarInputError
        any other name, or a vector that is not three finite numbers, not all zero.

    Examples
    --------
    >>> parse_up("-y").tolist(), parse_up([0, 3, 4]).tolist(), parse_up(None)
    ([0.0, -1.0, 0.0], [0.0, 0.6, 0.8], None)
    """
    if up is None:
        return None
    if isinstance(up, str):
        s = up.strip().lower()
        if len(s) == 1:
            s = "+" + s
        if len(s) != 2 or s[0] not in "+-" or s[1] not in "xyz":
            raise RebarInputError(f"up: expected one of +x, -x, +y, -y, +z, -z, got {up!r}")
        v = np.zeros(3)
        v["xyz".index(s[1])] = 1.0 if s[0] == "+" else -1.0
        return v
    v = np.asarray(up, float)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) == 0:
        raise RebarInputError(f"up: expected an axis name or a non-zero 3-vector, got {up!r}")
    return v / np.linalg.norm(v)


def cloud_manifest(cloud_path, design_path, *, method: str = METHOD, options: dict | None = None) -> dict:
    """The result manifest of a cloud file (as :func:`rebarlib._manifest.make_manifest` writes for
    a capture folder): the cloud's path and SHA-256 digest stand for the capture's.

    Parameters
    ----------
    cloud_path : str or pathlib.Path, the cloud file inspected
    design_path : str or pathlib.Path of the design file, or None where the design was given
        as an object
    method : the method recorded (:data:`METHOD`, "cloud")
    options : the options of the run (units, up, ...), recorded as they are

    Returns
    -------
    dict: ``capture_folder`` and ``capture_digest`` None, ``cloud_file`` (the absolute path),
    ``cloud_digest`` (``"sha256:<hex>"`` of its bytes), ``design_file``, ``design_digest``,
    ``method``, ``options``, ``rebarlib_version`` and ``created_at`` (UTC, ISO 8601), as
    :func:`rebarlib._manifest.manifest_problems` compares them with a cloud file.
    """
    from .. import __version__
    from .._manifest import file_digest, make_manifest

    p = Path(cloud_path).resolve()
    # no capture folder: the cloud's own digest stands for it (the files beside it, other
    # scans of a batch among them, are not read)
    man = make_manifest(None, design_path, method=method, options=options)
    man.update({"cloud_file": str(p), "cloud_digest": file_digest(p), "rebarlib_version": __version__})
    return man
