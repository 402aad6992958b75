"""The readers of :mod:`rebarlib.cloud_io`, one per point cloud format: PLY (ASCII and binary),
PCD (ASCII, binary and LZF-compressed), text (XYZ, PTS, CSV, TXT), NPZ, LAS/LAZ and E57. Each
takes a path and returns the file's ``(x, y, z)`` coordinates as read (its own units and frame)
and its per-point fields by name; :data:`_READERS` maps a suffix to its reader.
"""

from __future__ import annotations

import re
from pathlib import Path

import numpy as np

from ._checks import RebarInputError


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
