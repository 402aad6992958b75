"""A synthetic terrestrial laser scanner: scanned point clouds of a synthetic mesh with ground truth.

The bar layout comes from :func:`rebarlib.synth.make_scene` (the same meshes the RGB-D renders
use); this module replaces the camera by scanner stations standing around or above the mesh:

- every station sweeps rays on a regular azimuth × elevation grid (its own angular steps, so one
  direction can be sampled far more sparsely than the other), which makes the density fall off
  with range by itself;
- the first surface each ray meets returns a point (occlusion shadows behind bars come for free),
  kept with a probability ``|cos(incidence)| ** incidence_power`` (grazing returns are weak);
- the range gets Gaussian noise ``range_sigma_mm`` along the ray;
- returns that graze a bar's silhouette are *mixed pixels* with probability ``mixed_fraction``:
  their range lies anywhere between the bar and the surface behind it;
- a share ``outlier_fraction`` of rays return at a random range;
- the formwork can be left out (a mesh scanned with nothing beneath it), and the scan can be
  limited to part of the mesh (``region``).

:func:`export_scan` writes a scan in any of the formats of :mod:`rebarlib.cloud_io`, in mm or m,
z-up or y-up, with an arbitrary (e.g. georeferenced) origin, and :class:`ScanTruth` holds what
the scan was made of (spacings, layer distance, cover, each bar's scanned length).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from ._checks import RebarInputError
from ._design import Design
from .cloud_io import ScanCloud, write_cloud
from .synth import Deviations, SlabScene, make_scene

__all__ = [
    "ScannerModel",
    "Station",
    "ScanTruth",
    "ring_stations",
    "scan_scene",
    "synth_scan",
    "export_scan",
    "frame_rotation",
    "score_scan",
]

LABEL_FORMWORK, LABEL_OTHER, LABEL_NOISE = -1, -2, -3


@dataclass(frozen=True)
class ScannerModel:
    """How a scanner samples and how its ranges err.

    range_sigma_mm : std dev of the range noise, along the ray
    step_az_deg, step_el_deg : angular sampling in azimuth and in elevation
    incidence_power : a return is kept with probability ``|cos(incidence)| ** incidence_power``
    mixed_fraction : share of the returns grazing a bar (|cos(incidence)| < 0.3) that are mixed
        with the surface behind the bar (a range anywhere in between)
    outlier_fraction : share of rays returning at a uniformly random range
    max_range_mm : returns beyond are lost
    """

    range_sigma_mm: float = 5.0
    step_az_deg: float = 0.06
    step_el_deg: float = 0.06
    incidence_power: float = 1.0
    mixed_fraction: float = 0.5
    outlier_fraction: float = 0.002
    max_range_mm: float = 30_000.0


@dataclass(frozen=True)
class Station:
    """A scanner position (world mm: the formwork is z = 0, the mesh centred on the origin)."""

    position_mm: tuple


def ring_stations(
    n: int = 3, *, distance_mm: float = 2500.0, height_mm: float = 1500.0, start_deg: float = 20.0
) -> list:
    """``n`` stations evenly round the mesh, ``distance_mm`` from its centre in plan, at ``height_mm``."""
    out = []
    for k in range(n):
        a = math.radians(start_deg + 360.0 * k / n)
        out.append(Station((distance_mm * math.cos(a), distance_mm * math.sin(a), height_mm)))
    return out


@dataclass
class ScanTruth:
    """What a synthetic scan was made of (world frame, mm).

    scene : the mesh (:class:`rebarlib.synth.SlabScene`)
    labels : (N,) per point: bar id, or -1 formwork, -2 accessory (spacer, chair, tie), -3 noise
        (outlier or mixed pixel)
    scanned_mm : bar id -> length (mm) of the bar covered by returns (10 mm cells with a return,
        inside the scanned region)
    region : (x0, x1, y0, y1) of the scanned part of the mesh, world mm
    formwork : whether the formwork is in the scan
    rotation, origin_mm : set by :func:`export_scan`: file = rotation @ world + origin_mm
    """

    scene: SlabScene
    labels: np.ndarray
    scanned_mm: dict
    region: tuple
    formwork: bool
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    origin_mm: np.ndarray = field(default_factory=lambda: np.zeros(3))

    def bars(self, layer: str, level: str) -> list:
        """The bars of one set, in order across their direction."""
        return sorted((b for b in self.scene.bars if b.layer == layer and b.level == level), key=lambda b: b.offset_mm)

    def spacings(self, layer: str, level: str) -> np.ndarray:
        """True centre-to-centre spacings of adjacent bars of one set."""
        off = np.array([b.offset_mm for b in self.bars(layer, level)])
        return np.diff(off)

    def underside_mm(self, layer: str, level: str = "bottom") -> float:
        return float(np.mean([b.underside_mm for b in self.bars(layer, level)]))

    @property
    def layer_distance_mm(self) -> float:
        """From the underside of the lower lattice's bottom bars to that of the upper lattice's."""
        return self.underside_mm("upper") - self.underside_mm("lower")

    @property
    def cover_mm(self) -> float:
        return self.underside_mm("lower")

    def to_dict(self) -> dict:
        """The truth in the file's frame (mm, after :func:`export_scan`): every bar's axis ends,
        set, sizes and scanned length; the spacings, layer distance and cover."""
        bars = []
        for b in self.scene.bars:
            ends = np.asarray(b.axis)[[0, -1]] @ self.rotation.T + self.origin_mm
            bars.append(
                {
                    "id": int(b.id),
                    "layer": b.layer,
                    "level": b.level,
                    "index": int(b.index),
                    "start_mm": [round(float(v), 3) for v in ends[0]],
                    "end_mm": [round(float(v), 3) for v in ends[1]],
                    "nominal_mm": float(b.nominal_mm),
                    "envelope_mm": float(b.envelope_mm),
                    "scanned_mm": float(self.scanned_mm.get(b.id, 0.0)),
                }
            )
        sets = [(la, lv) for la in ("lower", "upper") for lv in ("bottom", "top")]
        return {
            "bars": bars,
            "spacings_mm": {f"{la}/{lv}": [round(float(v), 3) for v in self.spacings(la, lv)] for la, lv in sets},
            "layer_distance_mm": round(self.layer_distance_mm, 3),
            "cover_mm": round(self.cover_mm, 3) if self.formwork else None,
            "formwork_in_scan": bool(self.formwork),
            "region_mm": list(self.region),
            "rotation": self.rotation.round(12).tolist(),
            "origin_mm": self.origin_mm.tolist(),
        }

    def to_world(self, p) -> np.ndarray:
        """File-frame points (mm, before re-centring) back to the world frame."""
        return (np.asarray(p, float) - self.origin_mm) @ self.rotation


def _station_rays(pos, region, top_mm, scanner: ScannerModel):
    """Unit ray directions of one station's sweep over the region's box (z from 0 to ``top_mm``)."""
    x0, x1, y0, y1 = region
    corners = np.array([[x, y, z] for x in (x0, x1) for y in (y0, y1) for z in (0.0, top_mm)]) - pos
    az = np.degrees(np.arctan2(corners[:, 1], corners[:, 0]))
    ref = az[0]
    az = ref + (az - ref + 180.0) % 360.0 - 180.0  # unwrapped around the first corner
    el = np.degrees(np.arctan2(corners[:, 2], np.hypot(corners[:, 0], corners[:, 1])))
    inside = x0 <= pos[0] <= x1 and y0 <= pos[1] <= y1
    if inside:  # a station above the mesh sweeps all round, down to the nadir
        az_grid = np.arange(-180.0, 180.0, scanner.step_az_deg)
        el_grid = np.arange(-90.0 + scanner.step_el_deg / 2, el.max(), scanner.step_el_deg)
    else:
        az_grid = np.arange(az.min(), az.max(), scanner.step_az_deg)
        el_grid = np.arange(el.min(), el.max(), scanner.step_el_deg)
    A, E = np.meshgrid(np.radians(az_grid), np.radians(el_grid), indexing="ij")
    d = np.column_stack([(np.cos(E) * np.cos(A)).ravel(), (np.cos(E) * np.sin(A)).ravel(), np.sin(E).ravel()])
    return d


def _geometry(scene: SlabScene, formwork: bool):
    from . import synth as S

    geo = S._build_geometry(scene)
    if not formwork:  # drop the formwork: its quad (object 0, the first 4 vertices) far below
        geo.verts = geo.verts.copy()
        geo.verts[:4, 2] = -1e9
    return geo, S._Caster(geo), S


def scan_scene(
    scene: SlabScene, stations, scanner: ScannerModel | None = None, *, formwork: bool = True, region=None, rng=None
) -> tuple[np.ndarray, ScanTruth, dict]:
    """Scan ``scene`` from ``stations``: world-frame points (mm), the truth and per-point fields.

    Parameters
    ----------
    scene : the mesh, from :func:`rebarlib.synth.make_scene`
    stations : list of :class:`Station` (or (3,) positions)
    scanner : :class:`ScannerModel` (default: σ 5 mm, 0.06° steps)
    formwork : False leaves the formwork out of the scan (nothing under the mesh)
    region : (x0, x1, y0, y1) world mm, the part of the mesh that is scanned (default: all of it)

    Returns
    -------
    points : (N, 3) world mm; truth : :class:`ScanTruth`; fields : ``intensity`` (N,), ``station`` (N,),
        ``normals`` (N, 3): the true surface normal at each return, turned toward its station
    """
    scanner = scanner or ScannerModel()
    if not stations:
        raise RebarInputError("stations: expected at least one scanner station")
    rng = np.random.default_rng(rng)
    half = scene.deviations.slab_size_mm / 2
    region = tuple(float(v) for v in (region or (-half, half, -half, half)))
    top = max(float(b.axis[:, 2].max() + b.radius_mm) for b in scene.bars) + 10.0
    geo, caster, S = _geometry(scene, formwork)
    pts, labels, inten, station_of, normals = [], [], [], [], []
    for k, st in enumerate(stations):
        pos = np.asarray(getattr(st, "position_mm", st), float)
        d = _station_rays(pos, region, top, scanner)
        p, lab, it, nr = _shoot(pos, d, geo, caster, S, scanner, region, rng)
        pts.append(p), labels.append(lab), inten.append(it), normals.append(nr)
        station_of.append(np.full(len(p), k, np.int16))
    points = np.vstack(pts)
    labels = np.concatenate(labels)
    truth = ScanTruth(scene, labels, _scanned_lengths(scene, points, labels, region), region, formwork)
    return (
        points,
        truth,
        {"intensity": np.concatenate(inten), "station": np.concatenate(station_of), "normals": np.vstack(normals)},
    )


def _shoot(pos, d, geo, caster, S, sc: ScannerModel, region, rng):
    """Returns of one station's rays: points, labels and intensities."""
    origins = np.broadcast_to(pos, d.shape)
    with np.errstate(invalid="ignore"):  # rays that miss everything come back as inf / NaN
        t, obj, normal = caster.first_hit(origins, d)
    hit = np.isfinite(t) & (t < sc.max_range_mm)
    cos_inc = np.abs((normal * d).sum(axis=1))
    keep = hit & (rng.random(len(t)) < np.where(hit, cos_inc, 0.0) ** sc.incidence_power)
    idx = np.flatnonzero(keep)
    t, o, cos_i, nrm = t[idx], obj[idx], cos_inc[idx], normal[idx]
    kind, bar = geo.obj_kind[o], geo.obj_bar[o]
    label = np.where(kind == S.K_BAR, bar, np.where(kind == S.K_FORMWORK, LABEL_FORMWORK, LABEL_OTHER))
    true_p = pos + d[idx] * t[:, None]
    x0, x1, y0, y1 = region
    inside = (true_p[:, 0] >= x0) & (true_p[:, 0] <= x1) & (true_p[:, 1] >= y0) & (true_p[:, 1] <= y1)
    idx, t, label, cos_i, true_p, nrm = (
        idx[inside],
        t[inside],
        label[inside],
        cos_i[inside],
        true_p[inside],
        nrm[inside],
    )
    rng_t = t.copy()
    # mixed pixels: a grazing return on a bar averages the bar with what lies behind it
    graze = np.flatnonzero((label >= 0) & (cos_i < 0.3) & (rng.random(len(t)) < sc.mixed_fraction))
    if len(graze):
        behind_o = true_p[graze] + d[idx[graze]] * 60.0
        with np.errstate(invalid="ignore"):
            t2, _, _ = caster.first_hit(behind_o, d[idx[graze]])
        ok = np.isfinite(t2) & (t2 < 1500.0)
        mix = rng.random(len(graze))
        rng_t[graze[ok]] = t[graze[ok]] + mix[ok] * (t2[ok] + 60.0)
        label[graze[ok]] = LABEL_NOISE
    # outliers: a random range along the ray
    out = np.flatnonzero(rng.random(len(t)) < sc.outlier_fraction)
    rng_t[out] = rng.uniform(0.3, 1.2, len(out)) * t[out]
    label[out] = LABEL_NOISE
    rng_t = rng_t + rng.normal(0.0, sc.range_sigma_mm, len(t))
    points = pos + d[idx] * rng_t[:, None]
    inten = np.clip(cos_i * 4.0e6 / np.maximum(t, 100.0) ** 2 * np.where(label >= 0, 0.6, 1.0), 0, 1) * 1000
    return points, label.astype(np.int32), inten, nrm


def _scanned_lengths(scene: SlabScene, points, labels, region) -> dict:
    """Per bar: the length (mm) of its 10 mm cells holding at least one of its returns."""
    out = {}
    for b in scene.bars:
        own = points[labels == b.id]
        if len(own) == 0:
            out[b.id] = 0.0
            continue
        s = (own - b.axis[0]) @ b.direction
        out[b.id] = 10.0 * len(np.unique(np.floor(s / 10.0)))
    return out


def synth_scan(
    design: Design,
    *,
    stations=None,
    scanner: ScannerModel | None = None,
    deviations: Deviations | None = None,
    formwork: bool = True,
    region=None,
    rng=None,
) -> tuple[np.ndarray, ScanTruth, dict]:
    """A scanned cloud of a synthetic mesh of ``design``: ``(points, truth, fields)`` in the world
    frame (z up, formwork at z = 0). Default stations: three round the mesh, 2.5 m off, 1.5 m up."""
    rng = np.random.default_rng(rng)
    scene = make_scene(design, deviations or Deviations(), rng=rng)
    return scan_scene(scene, stations or ring_stations(), scanner, formwork=formwork, region=region, rng=rng)


def frame_rotation(up: str) -> np.ndarray:
    """Rotation taking the world frame (z up) to a file frame whose up axis is ``up``
    ("+z", "+y", "-y", "+x", ...), right-handed."""
    axes = {"x": 0, "y": 1, "z": 2}
    if len(up) != 2 or up[0] not in "+-" or up[1] not in axes:
        raise RebarInputError(f"up: expected one of +x, -x, +y, -y, +z, -z, got {up!r}")
    target = np.zeros(3)
    target[axes[up[1]]] = 1.0 if up[0] == "+" else -1.0
    z = np.array([0.0, 0.0, 1.0])
    if np.allclose(target, z):
        return np.eye(3)
    if np.allclose(target, -z):
        return np.diag([1.0, -1.0, -1.0])
    # a rotation about the axis z x target by 90 degrees
    k = np.cross(z, target)
    k /= np.linalg.norm(k)
    K = np.array([[0, -k[2], k[1]], [k[2], 0, -k[0]], [-k[1], k[0], 0]])
    return np.eye(3) + K + K @ K  # Rodrigues with sin = 1, cos = 0


def export_scan(
    path,
    points,
    truth: ScanTruth,
    fields: dict | None = None,
    *,
    units: str = "m",
    up: str = "+z",
    origin_mm=(0.0, 0.0, 0.0),
    truth_json: bool = False,
) -> ScanTruth:
    """Write a synthetic scan to ``path`` (format by suffix) in ``units``, with the file's up axis
    ``up`` and its origin moved so that the world origin lands at ``origin_mm`` (e.g. 20 m to one
    side, or georeferenced offsets). Returns the truth with the frame change recorded; with
    ``truth_json`` it is also written beside the cloud as ``<path>.truth.json`` (mm, the file's
    frame: :meth:`ScanTruth.to_dict`)."""
    R = frame_rotation(up)
    origin = np.asarray(origin_mm, float)
    file_pts = np.asarray(points, float) @ R.T + origin
    fields = dict(fields or {})
    if "normals" in fields:
        fields["normals"] = np.asarray(fields["normals"], float) @ R.T
    write_cloud(path, ScanCloud(file_pts, np.zeros(3), fields), units=units)
    truth.rotation, truth.origin_mm = R, origin
    if truth_json:
        import json
        from pathlib import Path

        Path(f"{path}.truth.json").write_text(json.dumps(truth.to_dict(), indent=1) + "\n", encoding="utf-8")
    return truth


def score_scan(result, truth: ScanTruth, *, min_scanned_mm: float = 100.0) -> dict:
    """How an inspection of a synthetic scan compares with its truth.

    Each bar found is matched to the true bar of its layer and level nearest across (within 40 %
    of the design spacing); a found bar with no true bar there is a phantom. Returns counts
    (``scanned``: true bars with at least ``min_scanned_mm`` covered by returns; ``missed``: of
    those, not found; ``phantoms``), the spacing errors of adjacent matched pairs
    (``spacing_errors``, mm) and the cover and layer distance errors (mm, None if not measured).
    """
    res = result.to_dict() if hasattr(result, "to_dict") else result
    offset = np.asarray((res.get("extras") or {}).get("cloud", {}).get("offset_mm", [0, 0, 0]), float)
    design = truth.scene.design
    matched, phantoms, missed, scanned = {}, 0, 0, 0
    found_ids = set()
    for rec in res["bars"]:
        la, lv = rec["layer"], rec["level"]
        true = truth.bars(la, lv)
        mid = 0.5 * (
            np.array([rec["start_x_mm"], rec["start_y_mm"], rec["start_z_mm"]])
            + np.array([rec["end_x_mm"], rec["end_y_mm"], rec["end_z_mm"]])
        )
        w = truth.to_world(mid + offset)
        best = min(true, key=lambda b: abs(_across(b, w)), default=None)
        tol = 0.4 * design.lattice(la).level(lv).spacing_mm
        if best is None or abs(_across(best, w)) > tol or best.id in found_ids:
            phantoms += 1
            continue
        found_ids.add(best.id)
        matched[rec["bar_id"]] = best
    for b in truth.scene.bars:
        if truth.scanned_mm.get(b.id, 0.0) >= min_scanned_mm:
            scanned += 1
            missed += b.id not in found_ids
    errors = []
    for sp in res["spacings"]:
        a, b = matched.get(sp["bar_a"]), matched.get(sp["bar_b"])
        if a is None or b is None or sp.get("spacing_mm") is None or abs(a.index - b.index) != 1:
            continue
        errors.append(float(sp["spacing_mm"]) - abs(b.offset_mm - a.offset_mm))
    m = res["measurements"]
    ld, cv = m["layer_distance"]["value_mm"], m["cover"]["value_mm"]
    return {
        "scanned": scanned,
        "found": len(found_ids),
        "missed": missed,
        "phantoms": phantoms,
        "spacing_errors": errors,
        "spacing_max_abs_err_mm": max((abs(e) for e in errors), default=None),
        "layer_distance_err_mm": None if ld is None else ld - truth.layer_distance_mm,
        "cover_err_mm": None if cv is None or not truth.formwork else cv - truth.cover_mm,
    }


def _across(bar, p) -> float:
    """Signed plan distance of world point ``p`` from a true bar's axis."""
    d = bar.direction[:2] / np.linalg.norm(bar.direction[:2])
    n = np.array([-d[1], d[0]])
    return float((np.asarray(p)[:2] - bar.axis[0, :2]) @ n)
