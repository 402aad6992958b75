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

import re
import warnings
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from ._checks import RebarInputError

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
    """The point cloud files directly in ``folder`` (by suffix), sorted by name."""
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


def _colour_fields(names, get) -> dict:
    """``colors`` (N, 3) in 0..1 from red/green/blue (or r/g/b) columns, else {}."""
    for trio in (("red", "green", "blue"), ("r", "g", "b"), ("diffuse_red", "diffuse_green", "diffuse_blue")):
        if all(t in names for t in trio):
            rgb = np.column_stack([np.asarray(get(t), np.float64) for t in trio])
            top = 65535.0 if rgb.max(initial=0) > 255 else (255.0 if rgb.max(initial=0) > 1 else 1.0)
            return {"colors": rgb / top}
    return {}


def _structured_fields(arr, skip=("x", "y", "z")) -> tuple[np.ndarray, dict]:
    """x, y, z and the other columns of a structured array (colour and normals grouped)."""
    names = [n.lower() for n in arr.dtype.names]
    col = dict(zip(names, arr.dtype.names))
    for need in skip:
        if need not in col:
            raise RebarInputError(f"no '{need}' field among {list(arr.dtype.names)}")
    xyz = np.column_stack([arr[col[c]].astype(np.float64) for c in skip])
    fields = _colour_fields(col, lambda t: arr[col[t]])
    used = set(skip)
    if fields:
        used |= {
            t
            for t in ("red", "green", "blue", "r", "g", "b", "diffuse_red", "diffuse_green", "diffuse_blue")
            if t in col
        }
    for trio in (("nx", "ny", "nz"), ("normal_x", "normal_y", "normal_z")):
        if all(t in col for t in trio):
            fields["normals"] = np.column_stack([arr[col[t]].astype(np.float64) for t in trio])
            used |= set(trio)
    for n in names:
        if n not in used and arr[col[n]].ndim == 1:
            fields["intensity" if n in ("scalar_intensity", "reflectance") else n] = np.asarray(arr[col[n]])
    return xyz, fields


# --- PLY ----------------------------------------------------------------------------------------

_PLY_TYPES = {
    "char": "i1",
    "int8": "i1",
    "uchar": "u1",
    "uint8": "u1",
    "short": "i2",
    "int16": "i2",
    "ushort": "u2",
    "uint16": "u2",
    "int": "i4",
    "int32": "i4",
    "uint": "u4",
    "uint32": "u4",
    "float": "f4",
    "float32": "f4",
    "double": "f8",
    "float64": "f8",
}


def _read_ply(p: Path):
    with open(p, "rb") as f:
        if f.readline().strip() != b"ply":
            raise RebarInputError(f"{p}: not a PLY file (no 'ply' magic line)")
        fmt, elements = None, []
        while True:
            line = f.readline()
            if not line:
                raise RebarInputError(f"{p}: PLY header has no 'end_header'")
            words = line.decode("ascii", "replace").split()
            if not words or words[0] in ("comment", "obj_info"):
                continue
            if words[0] == "format":
                fmt = words[1]
            elif words[0] == "element":
                elements.append((words[1], int(words[2]), []))
            elif words[0] == "property":
                if words[1] == "list":
                    elements[-1][2].append((words[4], None))
                else:
                    elements[-1][2].append((words[2], _PLY_TYPES[words[1]]))
            elif words[0] == "end_header":
                break
        for name, count, props in elements:
            if name == "vertex":
                break
            if count and fmt != "ascii":
                raise RebarInputError(f"{p}: PLY element '{name}' precedes the vertices (not supported)")
        else:
            raise RebarInputError(f"{p}: PLY file has no 'vertex' element")
        if any(t is None for _, t in props):
            raise RebarInputError(f"{p}: PLY vertices with list properties are not supported")
        if fmt == "ascii":
            skip = sum(c for n, c, _ in elements[: [e[0] for e in elements].index("vertex")])
            data = np.loadtxt(f, max_rows=count, skiprows=skip, ndmin=2)
            arr = np.rec.fromarrays(data.T[: len(props)], names=[n for n, _ in props])
        else:
            order = {"binary_little_endian": "<", "binary_big_endian": ">"}.get(fmt)
            if order is None:
                raise RebarInputError(f"{p}: unknown PLY format {fmt!r}")
            dtype = np.dtype([(n, order + t) for n, t in props])
            arr = np.frombuffer(f.read(count * dtype.itemsize), dtype=dtype, count=count)
    return _structured_fields(arr)


# --- PCD ----------------------------------------------------------------------------------------


def _read_pcd(p: Path):
    with open(p, "rb") as f:
        head = {}
        while True:
            line = f.readline()
            if not line:
                raise RebarInputError(f"{p}: PCD header has no DATA line")
            words = line.decode("ascii", "replace").split()
            if not words or words[0].startswith("#"):
                continue
            head[words[0].upper()] = words[1:]
            if words[0].upper() == "DATA":
                break
        names = [n.lower() for n in head["FIELDS"]]
        sizes = [int(s) for s in head["SIZE"]]
        types = head["TYPE"]
        counts = [int(c) for c in head.get("COUNT", ["1"] * len(names))]
        n = int(head["POINTS"][0])
        kind = head["DATA"][0].lower()
        dtype = np.dtype(
            [(nm, f"<{t.lower()}{s}", () if c == 1 else (c,)) for nm, s, t, c in zip(names, sizes, types, counts)]
        )
        if kind == "ascii":
            rows = np.loadtxt(f, ndmin=2, max_rows=n)
            cols, k = [], 0
            for nm, s, t, c in zip(names, sizes, types, counts):
                cols.append(rows[:, k].astype(f"<{t.lower()}{s}") if c == 1 else rows[:, k : k + c])
                k += c
            arr = np.rec.fromarrays(cols, dtype=dtype)
        elif kind == "binary":
            arr = np.frombuffer(f.read(n * dtype.itemsize), dtype=dtype, count=n)
        elif kind == "binary_compressed":
            arr = _pcd_compressed(f.read(), dtype, n)
        else:
            raise RebarInputError(f"{p}: unknown PCD DATA kind {kind!r}")
    arr = _unpack_pcd_rgb(arr)
    return _structured_fields(arr)


def _pcd_compressed(buf: bytes, dtype, n):
    """PCL's binary_compressed: LZF of the fields stored column by column."""
    comp, raw = np.frombuffer(buf[:8], "<u4")
    data = _lzf_decompress(buf[8 : 8 + int(comp)], int(raw))
    out = np.empty(n, dtype)
    k = 0
    for name in dtype.names:
        sub = dtype[name]
        size = sub.itemsize * n
        out[name] = np.frombuffer(data[k : k + size], sub.base).reshape(out[name].shape)
        k += size
    return out


def _lzf_decompress(src: bytes, size: int) -> bytes:
    """LZF decompression (the format liblzf writes): literal runs and back references."""
    out = bytearray(size)
    i = o = 0
    n = len(src)
    while i < n:
        ctrl = src[i]
        i += 1
        if ctrl < 32:
            ln = ctrl + 1
            out[o : o + ln] = src[i : i + ln]
            i += ln
            o += ln
        else:
            ln = ctrl >> 5
            ref = o - ((ctrl & 0x1F) << 8) - 1
            if ln == 7:
                ln += src[i]
                i += 1
            ref -= src[i]
            i += 1
            ln += 2
            if ref < 0:
                raise ValueError("corrupt LZF stream")
            for j in range(ln):  # overlapping copies are allowed
                out[o + j] = out[ref + j]
            o += ln
    return bytes(out[:o])


def _unpack_pcd_rgb(arr):
    """PCL packs colour into one float (``rgb``) or uint32 (``rgba``): split it into r, g, b."""
    names = [n.lower() for n in arr.dtype.names]
    key = next((arr.dtype.names[i] for i, n in enumerate(names) if n in ("rgb", "rgba")), None)
    if key is None:
        return arr
    packed = (
        np.ascontiguousarray(arr[key]).view(np.uint32) if arr[key].dtype.itemsize == 4 else arr[key].astype(np.uint32)
    )
    rest = [n for n in arr.dtype.names if n != key]
    cols = [arr[n] for n in rest] + [(packed >> 16) & 255, (packed >> 8) & 255, packed & 255]
    return np.rec.fromarrays(cols, names=rest + ["red", "green", "blue"])


# --- text: XYZ, PTS, CSV, TXT ------------------------------------------------------------------

_NUMBER = re.compile(r"^[-+]?(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")


def _read_text(p: Path):
    import pandas as pd

    with open(p, "r", encoding="utf-8", errors="replace") as f:
        first = [f.readline() for _ in range(3)]
    sep = "," if p.suffix.lower() == ".csv" or "," in first[0] else r"\s+"
    skip, names = 0, None
    toks = [t for t in re.split(sep, first[0].strip().lstrip("/#")) if t]
    if len(toks) == 1 and _NUMBER.match(toks[0]) and len(first[1].split()) >= 3:
        skip = 1  # Leica PTS: the first line is the point count
    elif toks and not all(_NUMBER.match(t) for t in toks):
        skip, names = 1, [t.strip().lower() for t in toks]
    df = pd.read_csv(
        p, sep=sep, header=None, skiprows=skip, comment="#", dtype=np.float64, on_bad_lines="skip", engine="c"
    )
    a = df.to_numpy()
    if a.ndim != 2 or a.shape[1] < 3:
        raise RebarInputError(f"{p}: expected at least three columns x, y, z")
    if names is None or len(names) != a.shape[1]:
        names = _text_names(a)
    arr = np.rec.fromarrays(a.T, names=names)
    return _structured_fields(arr)


def _text_names(a) -> list:
    """Column names of a header-less text cloud, by the common layouts of scanner exports:
    x y z [intensity] [r g b] [nx ny nz]."""
    k = a.shape[1]
    extra = k - 3
    rest = a[:, 3:]

    def is_rgb(c):
        return np.all((c >= 0) & (c <= 255)) and np.allclose(c, np.round(c)) and c.max(initial=0) > 1

    names = ["x", "y", "z"]
    if extra in (1, 4, 7) or (extra == 3 and not is_rgb(rest[:, :3]) and np.abs(rest[:, :3]).max() > 1.0):
        names.append("intensity")
        rest = rest[:, 1:]
        extra -= 1
    if extra >= 3 and is_rgb(rest[:, :3]):
        names += ["red", "green", "blue"]
        rest, extra = rest[:, 3:], extra - 3
    if extra >= 3 and np.abs(rest[:, :3]).max(initial=0) <= 1.0 + 1e-6:
        names += ["nx", "ny", "nz"]
        rest, extra = rest[:, 3:], extra - 3
    names += [f"field{i}" for i in range(extra)]
    return names


# --- NPZ (numpy / Open3D exports) -------------------------------------------------------------


def _read_npz(p: Path):
    with np.load(p, allow_pickle=False) as z:
        arrays = {k: z[k] for k in z.files}
    key = next((k for k in ("points", "xyz", "positions") if k in arrays), None)
    if key is None:
        key = next((k for k, v in arrays.items() if v.ndim == 2 and v.shape[1] == 3), None)
    if key is None:
        raise RebarInputError(f"{p}: no (N, 3) array of points in the NPZ file")
    xyz = arrays.pop(key)
    fields = {k: v for k, v in arrays.items() if v.ndim >= 1 and len(v) == len(xyz)}
    if "colors" in fields and fields["colors"].max(initial=0) > 1:
        fields["colors"] = fields["colors"] / 255.0
    return xyz, fields


# --- LAS / LAZ ----------------------------------------------------------------------------------


def _read_las(p: Path):
    try:
        import laspy
    except ImportError:  # pragma: no cover - a declared dependency
        raise RebarInputError(f"{p}: reading LAS/LAZ needs the 'laspy' package (and 'lazrs' for LAZ)") from None
    try:
        las = laspy.read(str(p))
    except laspy.errors.LaspyException as exc:
        raise RebarInputError(f"{p}: cannot read the LAS/LAZ file ({exc})") from None
    xyz = np.column_stack([np.asarray(las.x), np.asarray(las.y), np.asarray(las.z)])
    dims = list(las.point_format.dimension_names)
    fields = _colour_fields([d.lower() for d in dims], lambda t: las[t])
    for d in dims:
        if d in ("X", "Y", "Z", "red", "green", "blue"):
            continue
        fields[d.lower()] = np.asarray(las[d])
    return xyz, fields


# --- E57 ----------------------------------------------------------------------------------------


def _read_e57(p: Path):
    try:
        import pye57
    except ImportError:  # pragma: no cover - a declared dependency
        raise RebarInputError(f"{p}: reading E57 needs the 'pye57' package") from None
    e57 = pye57.E57(str(p))
    xyz_all, fields_all = [], []
    for i in range(e57.scan_count):
        scan = e57.read_scan(i, ignore_missing_fields=True, intensity=True, colors=True, transform=True)
        xyz_all.append(np.column_stack([scan["cartesianX"], scan["cartesianY"], scan["cartesianZ"]]))
        f = {}
        if "intensity" in scan:
            f["intensity"] = np.asarray(scan["intensity"])
        if "colorRed" in scan:
            f["colors"] = np.column_stack([scan["colorRed"], scan["colorGreen"], scan["colorBlue"]]) / 255.0
        f["station"] = np.full(len(xyz_all[-1]), i, np.int32)
        fields_all.append(f)
    if not xyz_all:
        raise RebarInputError(f"{p}: the E57 file holds no scan")
    keys = set.intersection(*(set(f) for f in fields_all))
    return np.vstack(xyz_all), {k: np.concatenate([f[k] for f in fields_all]) for k in keys}


_READERS = {
    ".ply": _read_ply,
    ".pcd": _read_pcd,
    ".xyz": _read_text,
    ".pts": _read_text,
    ".csv": _read_text,
    ".txt": _read_text,
    ".npz": _read_npz,
    ".las": _read_las,
    ".laz": _read_las,
    ".e57": _read_e57,
}


# ----------------------------------------------------------------------------------------------
# Writing (synthetic scans and tests)
# ----------------------------------------------------------------------------------------------


def write_cloud(path, cloud: ScanCloud, *, units: str = "mm") -> Path:
    """Write ``cloud`` (its absolute coordinates) to ``path`` in the format its suffix names,
    in ``units``; ``intensity`` and ``colors`` are written where the format has room for them,
    ``normals`` in PLY, and every field in NPZ."""
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


def _write_ply(p, xyz, inten, rgb8, normals=None):
    cols = [("x", "<f8"), ("y", "<f8"), ("z", "<f8")]
    if normals is not None:
        cols += [("nx", "<f4"), ("ny", "<f4"), ("nz", "<f4")]
    if inten is not None:
        cols.append(("intensity", "<f4"))
    if rgb8 is not None:
        cols += [("red", "u1"), ("green", "u1"), ("blue", "u1")]
    arr = np.empty(len(xyz), np.dtype(cols))
    arr["x"], arr["y"], arr["z"] = xyz.T
    if normals is not None:
        arr["nx"], arr["ny"], arr["nz"] = np.asarray(normals, float).T
    if inten is not None:
        arr["intensity"] = inten
    if rgb8 is not None:
        arr["red"], arr["green"], arr["blue"] = rgb8.T
    names = {"<f8": "double", "<f4": "float", "u1": "uchar"}
    head = ["ply", "format binary_little_endian 1.0", f"element vertex {len(xyz)}"]
    head += [f"property {names[t]} {n}" for n, t in cols] + ["end_header"]
    with open(p, "wb") as f:
        f.write(("\n".join(head) + "\n").encode("ascii"))
        f.write(arr.tobytes())


def _write_pcd(p, xyz, inten):
    fields = ["x", "y", "z"] + (["intensity"] if inten is not None else [])
    arr = np.column_stack([xyz] + ([np.asarray(inten, float)] if inten is not None else [])).astype("<f8")
    k = len(fields)
    head = [
        "# .PCD v0.7",
        "VERSION 0.7",
        "FIELDS " + " ".join(fields),
        "SIZE " + " ".join(["8"] * k),
        "TYPE " + " ".join(["F"] * k),
        "COUNT " + " ".join(["1"] * k),
        f"WIDTH {len(xyz)}",
        "HEIGHT 1",
        "VIEWPOINT 0 0 0 1 0 0 0",
        f"POINTS {len(xyz)}",
        "DATA binary",
    ]
    with open(p, "wb") as f:
        f.write(("\n".join(head) + "\n").encode("ascii"))
        f.write(arr.tobytes())


def _write_text(p, xyz, inten, rgb8, suffix):
    cols = [xyz]
    if inten is not None:
        cols.append(np.asarray(inten, float)[:, None])
    if rgb8 is not None:
        cols.append(rgb8.astype(float))
    a = np.hstack(cols)
    fmt = ["%.6f"] * 3 + ["%.4g"] * (inten is not None) + ["%d"] * (3 if rgb8 is not None else 0)
    delim = "," if suffix == ".csv" else " "
    with open(p, "w", encoding="utf-8") as f:
        if suffix == ".pts":
            f.write(f"{len(a)}\n")
        elif suffix == ".csv":
            f.write(
                ",".join(
                    ["x", "y", "z"]
                    + ["intensity"] * (inten is not None)
                    + ["red", "green", "blue"] * (rgb8 is not None)
                )
                + "\n"
            )
        np.savetxt(f, a, fmt=fmt, delimiter=delim)


def _write_las(p, xyz, inten, rgb8):
    import laspy

    header = laspy.LasHeader(point_format=3 if rgb8 is not None else 1, version="1.2")
    header.offsets = np.floor(xyz.min(axis=0))
    header.scales = np.array([1e-4, 1e-4, 1e-4])
    las = laspy.LasData(header)
    las.x, las.y, las.z = xyz[:, 0], xyz[:, 1], xyz[:, 2]
    if inten is not None:
        las.intensity = np.clip(np.asarray(inten, float), 0, 65535).astype(np.uint16)
    if rgb8 is not None:
        las.red, las.green, las.blue = (rgb8.astype(np.uint16) * 257).T
    las.write(str(p))


def _write_e57(p, xyz, inten):
    import pye57

    # pye57 stores coordinates as single floats: the scan's pose carries the offset in double,
    # so georeferenced coordinates keep their precision
    origin = np.floor(np.median(xyz, axis=0))
    rel = xyz - origin
    data = {"cartesianX": rel[:, 0], "cartesianY": rel[:, 1], "cartesianZ": rel[:, 2]}
    if inten is not None:
        data["intensity"] = np.asarray(inten, float)
    with pye57.E57(str(p), mode="w") as e57:
        e57.write_scan_raw(data, rotation=np.array([1.0, 0.0, 0.0, 0.0]), translation=origin)
