"""Ground truth of a rendered capture (``Capture.metadata["truth"]``), after the definitions of
docs/method.md: cover = formwork top to the underside of the lower lattice's lowest bars; layer
distance = underside of the lower lattice's lowest bars to underside of the upper lattice's
lowest bars; spacing = centre-to-centre distance between adjacent parallel bars. Camera frame,
mm; heights above the formwork. docs/formats.md ("truth.json") lists the keys."""

from __future__ import annotations

import math
from dataclasses import asdict

import numpy as np

__all__ = []


def _truth(scene, pose, intr, bar_ids, p, formwork, light, rust_of_bar, sensor, app):
    """Ground truth in the camera frame (mm); heights above the formwork.

    ``p`` is the world point hit through each pixel's centre, ``bar_ids`` the (H, W) bar id + 1
    of each pixel; the others are what the capture was rendered with."""
    R = pose.rotation
    normal_c = R @ np.array([0, 0, 1.0])
    offset_c = float(-normal_c @ pose.to_camera([[0, 0, 0]])[0])
    ids = bar_ids.ravel() - 1
    counts = np.bincount(ids[ids >= 0], minlength=len(scene.bars))
    bars = [
        _bar_truth(b, pose, p[ids == b.id] if counts[b.id] else None, int(counts[b.id]), rust_of_bar)
        for b in scene.bars
    ]
    by = {(bb["layer"], bb["level"]): [] for bb in bars}
    for bb in bars:
        by[(bb["layer"], bb["level"])].append(bb)

    def mean_of(key, layer, level, visible=True):
        vals = [bb[key] for bb in by.get((layer, level), []) if bb["visible"] or not visible]
        if not vals:
            vals = [bb[key] for bb in by.get((layer, level), [])]
        return float(np.mean(vals)) if vals else None

    cover = mean_of("underside_mm", "lower", "bottom")
    upper_bottom = mean_of("underside_mm", "upper", "bottom")
    d = scene.design
    return {
        "units": "mm, camera frame (OpenCV: x right, y down, z forward); heights above the formwork",
        "cover_mm": round(cover, 4) if cover is not None else None,
        "layer_distance_mm": (round(upper_bottom - cover, 4) if None not in (cover, upper_bottom) else None),
        "upper_top_mm": mean_of("top_mm", "upper", "top"),
        "formwork_plane": {"normal": normal_c.round(8).tolist(), "offset_mm": round(offset_c, 4)},
        "camera": {
            "height_mm": round(float(pose.centre[2]), 4),
            "rotation_world_to_camera": R.round(10).tolist(),
            "centre_world_mm": pose.centre.round(4).tolist(),
        },
        "bars": bars,
        "missing": [
            {"layer": lay, "level": v, "index": k, **_ghost_truth(scene, i, pose, intr)}
            for i, (lay, v, k) in enumerate(scene.missing)
        ],
        "mesh": _mesh_truth(scene, pose),
        "spacings": _spacings_truth(by),
        "design": {
            "cover_mm": d.cover_mm,
            "layer_distance_mm": d.layer_distance_mm,
            "lower_diameter_mm": d.lower.bottom.diameter_mm,
            "upper_diameter_mm": d.upper.bottom.diameter_mm,
        },
        "deviations": asdict(scene.deviations),
        "sensor": asdict(sensor),
        "appearance": {**asdict(app), "formwork": formwork, "light_world": light.round(6).tolist()},
    }


def _bar_truth(b, pose, seen, n_seen: int, rust_of_bar) -> dict:
    """One bar's truth: its axis and the part of it in view (camera frame), sizes, heights and
    how much of it the image shows. ``seen``: the world points of its pixels (None: none)."""
    if n_seen:
        s = (seen - b.axis[0]) @ b.direction
        s0, s1 = float(s.min()), float(s.max())
    else:
        s0 = s1 = 0.0
    a0, a1 = b.axis[0], b.axis[-1]
    chord = a1 - a0
    vs = a0 + s0 * b.direction
    ve = a0 + s1 * b.direction
    vs[2] = ve[2] = b.axis[:, 2].mean()
    return {
        "id": b.id,
        "layer": b.layer,
        "level": b.level,
        "index": b.index,
        "axis_start_mm": pose.to_camera([a0])[0].round(4).tolist(),
        "axis_end_mm": pose.to_camera([a1])[0].round(4).tolist(),
        "visible_start_mm": pose.to_camera([vs])[0].round(4).tolist(),
        "visible_end_mm": pose.to_camera([ve])[0].round(4).tolist(),
        "plan_angle_deg": round(math.degrees(math.atan2(chord[1], chord[0])) % 180, 4),
        "offset_mm": round(b.offset_mm, 4),
        "underside_mm": round(b.underside_mm, 4),
        "top_mm": round(b.underside_mm + b.envelope_mm, 4),
        "diameter_mm": b.nominal_mm,
        "envelope_mm": b.envelope_mm,
        "design_diameter_mm": b.design_mm,
        "wrong_size": b.nominal_mm != b.design_mm,
        "extra": bool(b.extra),
        "lap_partner": b.lap_partner if b.lap_partner >= 0 else None,
        "rust": round(float(rust_of_bar[b.id]), 3),
        "visible_pixels": int(n_seen),
        "visible_length_mm": round(s1 - s0, 2),
        "visible": bool(n_seen >= 100 and s1 - s0 >= 50),
    }


def _spacings_truth(by: dict) -> list:
    """Centre-to-centre spacing of each pair of neighbouring bars of a set (``by``: the bars'
    truth per (layer, level)). A lap's two pieces stand for one design position together, at
    their middle: the spacings beside a lap are taken from there (as ``rebarlib`` measures them,
    docs/decisions/071), named by the piece nearer the neighbour, and seen where either piece
    is. Where this capture sees one piece of a lap and not the other (beyond the lap, or the
    other hidden), the bar there is the piece it sees, and it is spaced as it lies: from that
    piece, named by it (decision 071; decision 076 for the truth)."""
    spacings = []
    for (layer, level), group in sorted(by.items()):
        group = sorted(group, key=lambda bb: bb["offset_mm"])
        slots = []  # one or two bars a design position
        for bar in group:
            if slots and slots[-1][-1].get("lap_partner") == bar["id"]:
                slots[-1].append(bar)
            else:
                slots.append([bar])
        # what stands at each position in this capture: the pieces it sees, else all of them
        slots = [[x for x in slot if x["visible"]] or slot for slot in slots]
        for a, b in zip(slots[:-1], slots[1:]):
            middle_a = float(np.mean([x["offset_mm"] for x in a]))
            middle_b = float(np.mean([x["offset_mm"] for x in b]))
            spacings.append(
                {
                    "layer": layer,
                    "level": level,
                    "bar_a": a[-1]["id"],
                    "bar_b": b[0]["id"],
                    "spacing_mm": round(middle_b - middle_a, 4),
                    "visible": any(x["visible"] for x in a) and any(x["visible"] for x in b),
                }
            )
    return spacings


def _ghost_truth(scene, i: int, pose, intr) -> dict:
    """Where missing bar ``i`` would have been: its axis ends (camera frame) and how much of
    that axis (at its top) the image frames, in mm."""
    from .._camera import project

    if i >= len(scene.ghosts):
        return {}
    g = scene.ghosts[i]
    a0, a1 = g.axis[0], g.axis[-1]
    t = np.linspace(0.0, 1.0, 401)
    pts = a0 + t[:, None] * (a1 - a0) + np.array([0, 0, g.radius_mm])
    cam = pose.to_camera(pts)
    uv = project(cam, intr)
    inside = (cam[:, 2] > 0) & (uv[:, 0] >= 0) & (uv[:, 0] < intr.width) & (uv[:, 1] >= 0) & (uv[:, 1] < intr.height)
    step = float(np.linalg.norm(a1 - a0)) / 400
    return {
        "offset_mm": round(g.offset_mm, 4),
        "axis_start_mm": pose.to_camera([a0])[0].round(4).tolist(),
        "axis_end_mm": pose.to_camera([a1])[0].round(4).tolist(),
        "in_view_mm": round(float(inside.sum()) * step, 1),
    }


def _mesh_truth(scene, pose) -> dict:
    """The finite mesh's corners per lattice (camera frame), or None for the full-slab layout."""
    if scene.deviations.end_overhang_mm is None:
        return {"finite": False}
    out = {"finite": True}
    for layer in ("lower", "upper"):
        bb = [b for b in scene.bars if b.layer == layer]
        if not bb:
            continue
        pts = np.vstack([np.vstack((b.axis[0], b.axis[-1])) for b in bb])
        out[layer] = {"ends_camera_mm": pose.to_camera(pts).round(3).tolist()}
    return out
