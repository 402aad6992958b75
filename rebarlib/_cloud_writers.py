"""The writers of :func:`rebarlib.cloud_io.write_cloud`, one per point cloud format (PLY, PCD,
text, LAS/LAZ, E57; NPZ is written by ``write_cloud`` itself). Each takes the path, the
coordinates in the file's units, and the fields the format has room for.
"""

from __future__ import annotations

import numpy as np


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
