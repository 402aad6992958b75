"""A capture's ground truth written as an inspection result: what a perfect inspection of it
would report. The report's tests and benchmarks build sheets from it, and the verdict benchmark
judges it to learn whether a slab's own as-built deviations are within tolerance."""

from __future__ import annotations

import json
import math
from pathlib import Path


def result_from_truth(
    capture_dir, design, *, hide_every: int = 0, cover_offset_mm: float = 0.0, uncertainty_mm: float = 0.7
) -> dict:
    """A ``result.json`` dict holding a synthetic capture's ground truth.

    Parameters
    ----------
    capture_dir : path of a capture saved with its ``truth.json`` (:func:`rebarlib.save_capture`)
    design : Design, for the design spacings and the top cover
    hide_every : int
        every this-many-th visible bar is reported hidden under crossing bars (its size not
        read), as an inspection reports some; 0: none
    cover_offset_mm : float
        added to the true cover (a sheet with a cover out of tolerance)
    uncertainty_mm : float
        the standard uncertainty written with the cover, layer distance and top values

    Returns
    -------
    dict
        the result: measurements, formwork, camera, bars (visible ones, with their true sizes),
        spacings (visible ones), counts (every visible bar found, none missing)
    """
    capture_dir = Path(capture_dir)
    t = json.loads((capture_dir / "truth.json").read_text(encoding="utf-8"))
    n = t["formwork_plane"]["normal"]
    bars = []
    for i, b in enumerate(x for x in t["bars"] if x["visible"]):
        hidden = bool(hide_every) and i % hide_every == hide_every - 1
        rec = {
            "bar_id": b["id"],
            "layer": b["layer"],
            "level": b["level"],
            "plan_angle_deg": b["plan_angle_deg"],
            "visible_length_mm": b["visible_length_mm"],
            "n_points": b["visible_pixels"],
            "status": "measured",
            "reason": "",
            "width_median_mm": None if hidden else b["envelope_mm"],
            "width_spread_mm": None if hidden else 0.5,
            "nominal_mm": None if hidden else b["diameter_mm"],
            "confidence": 0.0 if hidden else 0.97,
            "diameter_status": "hidden" if hidden else "measured",
            "diameter_reason": "under crossing bars" if hidden else "",
            "design_diameter_mm": b["design_diameter_mm"],
            "hidden": hidden,
        }
        for c, s, e in zip("xyz", b["visible_start_mm"], b["visible_end_mm"]):
            rec[f"start_{c}_mm"], rec[f"end_{c}_mm"] = s, e
        bars.append(rec)
    spacings = []
    for s in t["spacings"]:
        if s["visible"]:
            ds = design.lattice(s["layer"]).level(s["level"]).spacing_mm
            spacings.append(
                {
                    "layer": s["layer"],
                    "level": s["level"],
                    "bar_a": s["bar_a"],
                    "bar_b": s["bar_b"],
                    "spacing_mm": s["spacing_mm"],
                    "design_spacing_mm": ds,
                    "deviation_mm": s["spacing_mm"] - ds,
                    "status": "measured",
                    "reason": "",
                }
            )
    counts = []
    for la in ("lower", "upper"):
        for lv in ("bottom", "top"):
            k = sum(b["layer"] == la and b["level"] == lv for b in bars)
            counts.append({"layer": la, "level": lv, "found": k, "expected": k, "missing": 0, "extra": 0})

    def m(v):
        return {"value_mm": v, "uncertainty_mm": uncertainty_mm, "n_points": 1000, "status": "measured", "reason": ""}

    meas = {
        "cover": m(t["cover_mm"] + cover_offset_mm),
        "layer_distance": m(t["layer_distance_mm"]),
        "upper_top": m(t["upper_top_mm"]),
    }
    if design.thickness_mm is not None:
        meas["top_cover"] = m(design.thickness_mm - t["upper_top_mm"])
    return {
        "capture": capture_dir.name,
        "method": "truth",
        "measurements": meas,
        "formwork": {"normal": n, "offset_mm": t["formwork_plane"]["offset_mm"]},
        "camera": {"height_mm": t["camera"]["height_mm"], "tilt_deg": math.degrees(math.acos(abs(n[2])))},
        "bars": bars,
        "spacings": spacings,
        "counts": counts,
        "notes": [],
    }
