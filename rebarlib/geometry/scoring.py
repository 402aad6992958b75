"""Score an :class:`~rebarlib.InspectionResult` against a synthetic capture's ground truth.

Used by the geometry tests and benchmarks; handy in a notebook to see which bar went wrong.

Rules (stated once, here):

- A detected bar *matches* a true bar of the same layer when the mid point of its axis lies
  within ``MAX_OFFSET_MM`` of the true axis line (camera frame) and both its ends within twice
  that; of several candidates the one nearest the mid point wins. Each true bar takes at most
  one detected bar; a second detected bar on the same true bar, or one matching no true bar, is a **phantom**.
- A true bar is **measurable** (must be found) when the renderer flags it ``visible``, its
  visible stretch is at least ``MEASURABLE_LENGTH_MM`` long, and its visible pixels cover at
  least ``MEASURABLE_AREA_FRACTION`` of the pixels the stretch would cover if nothing hid it
  (visible length × envelope / pixel footprint², footprint = depth / focal length): a bar end in
  the image corner, or a lower bar seen only in slivers beside the upper bar right above it,
  cannot give an axis. Bars visible but not measurable may be found or not; they count neither
  as missed nor, when found, as phantoms.
- A detected spacing is scored when both its bars match true bars that are adjacent in the truth
  (``truth["spacings"]``); its error is detected − true spacing.
"""

from __future__ import annotations

import math

import numpy as np
import pandas as pd

from .._status import MEASURED

__all__ = [
    "MAX_OFFSET_MM",
    "MEASURABLE_AREA_FRACTION",
    "MEASURABLE_LENGTH_MM",
    "match_bars",
    "measurable_bars",
    "score_result",
]

MEASURABLE_LENGTH_MM = 100.0
MAX_OFFSET_MM = 15.0
MEASURABLE_AREA_FRACTION = 0.3


def _line_dist(p, a, b) -> float:
    d = b - a
    d = d / np.linalg.norm(d)
    return float(np.linalg.norm(np.cross(p - a, d)))


def _dir_angle_deg(d1, d2) -> float:
    c = abs(float(np.dot(d1, d2)) / (np.linalg.norm(d1) * np.linalg.norm(d2)))
    return math.degrees(math.acos(min(1.0, c)))


def match_bars(bars: pd.DataFrame, truth: dict) -> pd.DataFrame:
    """Match every detected bar to a true bar.

    Parameters
    ----------
    bars : the ``bars`` table of an InspectionResult (camera-frame axis end points, mm)
    truth : ``capture.metadata["truth"]`` of a synthetic capture

    Returns
    -------
    DataFrame, one row per detected bar: ``bar_id, layer, level, truth_id, truth_level,
    offset_mm`` (mid point to true axis), ``angle_deg``, ``phantom`` (bool).
    """
    rows, taken = [], {}
    tb = truth["bars"]
    for r in bars.itertuples():
        s = np.array([r.start_x_mm, r.start_y_mm, r.start_z_mm], float)
        e = np.array([r.end_x_mm, r.end_y_mm, r.end_z_mm], float)
        mid, d = (s + e) / 2, e - s
        best = None
        for t in tb:
            if t["layer"] != r.layer:
                continue
            a, b = np.asarray(t["axis_start_mm"], float), np.asarray(t["axis_end_mm"], float)
            ends_off = max(_line_dist(s, a, b), _line_dist(e, a, b)) > 2 * MAX_OFFSET_MM
            if ends_off or _line_dist(mid, a, b) > MAX_OFFSET_MM:
                continue
            off = _line_dist(mid, a, b)
            if best is None or off < best[0]:
                best = (off, t, _dir_angle_deg(d, b - a) if np.linalg.norm(d) > 0 else np.nan)
        rec = {
            "bar_id": r.bar_id,
            "layer": r.layer,
            "level": r.level,
            "truth_id": None,
            "truth_level": None,
            "offset_mm": np.nan,
            "angle_deg": np.nan,
            "phantom": True,
        }
        if best is not None:
            off, t, ang = best
            rec.update(truth_id=int(t["id"]), truth_level=t["level"], offset_mm=off, angle_deg=ang)
            prev = taken.get(t["id"])
            if prev is None:
                rec["phantom"] = False
                taken[t["id"]] = len(rows)
            elif rows[prev]["offset_mm"] > off:  # keep the closer one, the other is the duplicate
                rows[prev]["phantom"] = True
                rec["phantom"] = False
                taken[t["id"]] = len(rows)
        rows.append(rec)
    return pd.DataFrame(
        rows, columns=["bar_id", "layer", "level", "truth_id", "truth_level", "offset_mm", "angle_deg", "phantom"]
    )


def measurable_bars(capture) -> list:
    """The true bars of a synthetic capture that must be found (rule in the module docstring).

    Examples
    --------
    >>> from rebarlib import GEMINI2
    >>> from rebarlib.data import paper_design
    >>> from rebarlib.synth import synth_capture
    >>> cap = synth_capture(paper_design(), tilt_deg=0, intrinsics=GEMINI2.scaled(0.25), seed=1)
    >>> bars = measurable_bars(cap)
    >>> len(bars) > 8, {b["layer"] for b in bars} == {"lower", "upper"}
    (True, True)
    """
    K = capture.intrinsics
    f = 0.5 * (K.fx + K.fy)
    out = []
    for t in capture.metadata["truth"]["bars"]:
        if not t["visible"] or t["visible_length_mm"] < MEASURABLE_LENGTH_MM:
            continue
        z = 0.5 * (t["visible_start_mm"][2] + t["visible_end_mm"][2])
        full_px = t["visible_length_mm"] * t["envelope_mm"] / (z / f) ** 2
        if t["visible_pixels"] >= MEASURABLE_AREA_FRACTION * full_px:
            out.append(t)
    return out


def score_result(result, capture) -> dict:
    """Errors of one result against the truth of the synthetic ``capture`` it was measured on.

    Parameters
    ----------
    result : InspectionResult (or its dict) of ``capture``
    capture : Capture rendered by :mod:`rebarlib.synth`, with its ``truth``

    Returns
    -------
    dict with ``cover_err_mm``, ``layer_distance_err_mm``, ``upper_top_err_mm`` (detected − true,
    NaN when not measured), ``measurable`` (number of true bars that must be found), ``found``,
    ``missed`` (list of true ids), ``phantoms`` (list of detected ids), ``wrong_level`` (detected
    ids whose level differs from the truth), ``spacing_errors_mm`` (array), ``spacings_unscored``
    (detected spacings between bars not adjacent in the truth), ``matches`` (the match_bars table).
    """
    truth = capture.metadata["truth"]
    m = match_bars(result.bars, truth)
    meas = measurable_bars(capture)
    ok = m[~m["phantom"]]
    found_ids = {int(x) for x in ok["truth_id"]}
    missed = sorted(t["id"] for t in meas if t["id"] not in found_ids)
    phantoms = [int(r.bar_id) for r in m.itertuples() if r.phantom]
    wrong_level = [int(r.bar_id) for r in ok.itertuples() if r.level != r.truth_level]
    to_truth = {int(r.bar_id): int(r.truth_id) for r in ok.itertuples()}
    true_sp = {frozenset((s["bar_a"], s["bar_b"])): s["spacing_mm"] for s in truth["spacings"]}
    errs, unscored = [], 0
    sp = result.spacings
    if sp is not None:
        for r in sp.itertuples():
            if r.status != MEASURED or not np.isfinite(r.spacing_mm):
                continue
            key = frozenset((to_truth.get(int(r.bar_a)), to_truth.get(int(r.bar_b))))
            if key in true_sp:
                errs.append(r.spacing_mm - true_sp[key])
            else:
                unscored += 1

    def err(meas_, true):
        return meas_.value_mm - true if meas_.ok else float("nan")

    return {
        "cover_err_mm": err(result.cover, truth["cover_mm"]),
        "layer_distance_err_mm": err(result.layer_distance, truth["layer_distance_mm"]),
        "upper_top_err_mm": err(result.upper_top, truth["upper_top_mm"]),
        "measurable": len(meas),
        "found": len(meas) - len(missed),
        "missed": missed,
        "phantoms": phantoms,
        "wrong_level": wrong_level,
        "spacing_errors_mm": np.asarray(errs, float),
        "spacings_unscored": unscored,
        "matches": m,
    }
