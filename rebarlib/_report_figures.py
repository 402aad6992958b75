"""The report's drawings, computed from the results (presentation only): the bars on the
colour image in pixel coordinates, coloured by verdict, and the plan view of a capture in the
formwork's plane (mm) with its spacings, missing and unjudged positions and the mesh's outline.
The templates ``overlay.svg.j2`` and ``plan.svg.j2`` draw them."""

from __future__ import annotations

import base64
from pathlib import Path

import numpy as np

from ._camera import project
from ._checks import RebarInputError
from ._design import Design
from ._status import BEYOND, BEYOND_MAX, FAIL, HIDDEN, INCOMPLETE, MISSING, NOT_CHECKED, NOT_MEASURED, PASS
from .acceptance import is_true

#: Colour of a bar drawn on the image by its verdict (colour-blind-safe pair for pass / fail).
BAR_COLOURS = {PASS: "#1b9e77", FAIL: "#d62728", INCOMPLETE: "#e7c21f", NOT_CHECKED: "#f0a30a", HIDDEN: "#7f3fbf"}
LAYER_COLOURS = {"lower": "#1f5fa8", "upper": "#e07b00"}
PLAN_BACKGROUND = "#fbfaf7"
IMAGE_WIDTH_PX = 720  # embedded colour images are re-encoded at this width: sharp enough on A4, small PDF


def _image_data_uri(path: Path) -> tuple[str, float]:
    """The colour image, shrunk to ``IMAGE_WIDTH_PX``, as a JPEG data URI, and the scale used."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_COLOR)
    if img is None:
        raise RebarInputError(f"{path}: cannot read the colour image")
    scale = min(1.0, IMAGE_WIDTH_PX / img.shape[1])
    if scale < 1.0:
        img = cv2.resize(img, None, fx=scale, fy=scale, interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".jpg", img, [cv2.IMWRITE_JPEG_QUALITY, 82])
    return "data:image/jpeg;base64," + base64.b64encode(buf.tobytes()).decode("ascii"), scale


def _clip_segment(p0, p1, w, h):
    """Liang-Barsky clip of the segment p0-p1 to the image rectangle; None when outside.
    (A handful of segments: simpler by hand than pulling in a geometry library.)"""
    x0, y0 = p0
    dx, dy = p1[0] - x0, p1[1] - y0
    t0, t1 = 0.0, 1.0
    for p, q in ((-dx, x0), (dx, w - 1 - x0), (-dy, y0), (dy, h - 1 - y0)):
        if p == 0:
            if q < 0:
                return None
            continue
        t = q / p
        if p < 0:
            t0 = max(t0, t)
        else:
            t1 = min(t1, t)
    if t0 > t1:
        return None
    return (x0 + t0 * dx, y0 + t0 * dy), (x0 + t1 * dx, y0 + t1 * dy)


def _axis(rec: dict):
    try:
        a = np.array([rec[f"start_{c}_mm"] for c in "xyz"], dtype=float)
        b = np.array([rec[f"end_{c}_mm"] for c in "xyz"], dtype=float)
    except (KeyError, TypeError, ValueError):
        return None
    return (a, b) if np.all(np.isfinite(a)) and np.all(np.isfinite(b)) else None


def _image_overlay(bars: list, verdicts: dict, intrinsics) -> list:
    """Bar segments in pixel coordinates (of the original image) with label positions."""
    out = []
    for rec in bars:
        ax = _axis(rec)
        if ax is None or ax[0][2] <= 0 or ax[1][2] <= 0:
            continue
        uv = project(np.vstack(ax), intrinsics)
        seg = _clip_segment(uv[0], uv[1], intrinsics.width, intrinsics.height)
        if seg is None:
            continue
        (x0, y0), (x1, y1) = seg
        v = verdicts.get(str(rec.get("bar_id")), NOT_CHECKED)
        hidden = v == HIDDEN or is_true(rec.get("hidden")) or rec.get("diameter_status") == HIDDEN
        # Labels of the bottom level at 12 % along the bar, of the top level at 88 %, so that the
        # ids of crossing bars do not sit on each other.
        t = 0.12 if rec.get("level") == "bottom" else 0.88
        if rec.get("layer") == "upper":
            t = 1 - t - 0.06 if t > 0.5 else t + 0.06
        # Keep the label box (about 1.8 x 1.2 label heights, see overlay.svg.j2) inside the image.
        m = intrinsics.width / 60
        lx = float(np.clip(x0 + t * (x1 - x0), 0.9 * m, intrinsics.width - 0.9 * m))
        ly = float(np.clip(y0 + t * (y1 - y0), 0.62 * m, intrinsics.height - 0.62 * m))
        out.append(
            {
                "x0": x0,
                "y0": y0,
                "x1": x1,
                "y1": y1,
                "lx": lx,
                "ly": ly,
                "id": str(rec.get("bar_id")),
                "colour": BAR_COLOURS[HIDDEN if hidden else v],
                "hidden": hidden,
                "verdict": HIDDEN if hidden else v,
            }
        )
    return out


def _plan_basis(normal):
    """Two in-plane unit vectors of the formwork: e1 along the camera x axis, e2 along camera y.

    Plan coordinates (p·e1, p·e2) look like the image seen square-on, with no tilt distortion.
    """
    n = np.asarray(normal, dtype=float) if normal is not None else np.array([0.0, 0.0, -1.0])
    if n.shape != (3,) or not np.all(np.isfinite(n)) or np.linalg.norm(n) == 0:
        n = np.array([0.0, 0.0, -1.0])
    n = n / np.linalg.norm(n)
    e1 = np.array([1.0, 0.0, 0.0]) - n[0] * n
    e1 /= np.linalg.norm(e1)
    e2 = np.cross(n, e1)
    if e2[1] < 0:
        e2 = -e2
    return e1, e2


def _plan_view(
    bars: list,
    spacings: list,
    acc_rows: dict,
    formwork: dict,
    design: Design,
    positions: list | None = None,
    boundary: dict | None = None,
) -> dict | None:
    """Bars and spacing labels in plan (mm, formwork frame) for the SVG drawing; with
    ``positions`` (the result's examined positions) the missing and unjudged positions, with
    ``boundary`` (``extras["mesh_boundary"]``) each lattice's outline in the view.

    Parameters
    ----------
    bars, spacings : list of dict
        The result's bars and spacings table rows.
    acc_rows : dict
        Each spacing's checkpoint status, keyed ``(capture, bar_a, bar_b, layer, level)``.
    formwork : dict
        The result's formwork (its ``normal`` sets the plan's axes).
    design : Design
        For the bars' drawn widths.
    positions : list of dict or None
    boundary : dict or None

    Returns
    -------
    dict or None
        What the template draws: ``segments``, ``labels``, ``marks``, ``outlines``, the view box
        (``x``, ``y``, ``w``, ``h``), ``font``, the scale bar (``scale_mm``, ``sx``, ``sy``); None
        where no bar has an axis.
    """
    e1, e2 = _plan_basis((formwork or {}).get("normal"))
    segs, by_id = _plan_segments(bars, design, e1, e2)
    if not segs:
        return None
    marks = _plan_marks(positions, e1, e2)
    outlines = _plan_outlines(boundary, e1, e2)
    pts = np.array(
        [[s["x0"], s["y0"]] for s in segs] + [[s["x1"], s["y1"]] for s in segs] + [[s["lx"], s["ly"]] for s in segs]
    )
    lo, hi = pts.min(axis=0), pts.max(axis=0)
    span = max(float((hi - lo).max()), 1.0)
    pad = 0.06 * span
    labels = _spacing_labels(spacings, by_id, acc_rows)
    return {
        "segments": segs,
        "labels": labels,
        "marks": marks,
        "outlines": outlines,
        "x": lo[0] - pad,
        "y": lo[1] - pad,
        # An extra strip at the bottom holds the scale bar, clear of the bar ids.
        "w": (hi - lo)[0] + 2 * pad,
        "h": (hi - lo)[1] + 3 * pad,
        "font": span / 45,
        "background": PLAN_BACKGROUND,
        "scale_mm": _scale_bar(span),
        "sx": lo[0],
        "sy": hi[1] + pad * 2.0,
    }


def over(colour: str, alpha: float, background: str = "#ffffff") -> str:
    """The colour seen where ``colour`` is drawn at opacity ``alpha`` over ``background`` (both
    ``#rrggbb``): the drawings are opaque, their translucency mixed beforehand.

    Examples
    --------
    >>> over("#000000", 0.5), over("#1f5fa8", 1.0, "#fbfaf7")
    ('#808080', '#1f5fa8')
    """
    c = [int(colour[i : i + 2], 16) for i in (1, 3, 5)]
    b = [int(background[i : i + 2], 16) for i in (1, 3, 5)]
    return "#" + "".join(f"{round(alpha * x + (1 - alpha) * y):02x}" for x, y in zip(c, b))


def _plan_segments(bars: list, design: Design, e1, e2) -> tuple:
    """Each bar with an axis as a segment in plan, with its id's label place, width and colour.

    Parameters
    ----------
    bars : list of dict
        The bars table rows.
    design : Design
    e1, e2 : ndarray
        The plan's axes (camera frame).

    Returns
    -------
    segs : list of dict
        One per drawn bar.
    by_id : dict
        The plan ends ``(a, b)`` of each drawn bar, by its id as text.
    """
    segs, by_id = [], {}
    for rec in bars:
        ax = _axis(rec)
        if ax is None:
            continue
        a, b = (np.array([p @ e1, p @ e2]) for p in ax)
        layer, level = rec.get("layer"), rec.get("level")
        try:
            width = design.lattice(layer).level(level).diameter_mm
        except (RebarInputError, AttributeError):
            width = 10.0
        by_id[str(rec.get("bar_id"))] = (a, b)
        # Bar ids at the far end of the bottom level and the near end of the top level, so the
        # ids of crossing directions sit on different sides of the drawing.
        lab = b + 0.07 * (b - a) if level == "bottom" else a - 0.07 * (b - a)
        segs.append(
            {
                "x0": a[0],
                "y0": a[1],
                "x1": b[0],
                "y1": b[1],
                "id": str(rec.get("bar_id")),
                "lx": lab[0],
                "ly": lab[1],
                "layer": layer,
                "level": level,
                "width": width,
                "colour": LAYER_COLOURS.get(layer, "#555"),
                "hidden": is_true(rec.get("hidden")) or rec.get("diameter_status") == HIDDEN,
            }
        )
    return segs, by_id


def _plan_marks(positions, e1, e2) -> list:
    """The missing and the unjudged design positions as marks in plan.

    Parameters
    ----------
    positions : list of dict or None
        The result's examined positions.
    e1, e2 : ndarray
        The plan's axes.

    Returns
    -------
    list of dict
    """
    marks = []
    for rec in positions or []:
        ax = _axis(rec)
        status = rec.get("status")
        if ax is None or status not in (MISSING, NOT_MEASURED):
            continue
        a, b = (np.array([p @ e1, p @ e2]) for p in ax)
        marks.append(
            {
                "x0": a[0],
                "y0": a[1],
                "x1": b[0],
                "y1": b[1],
                "missing": status == MISSING,
                "text": "missing" if status == MISSING else "?",
                "lx": (a[0] + b[0]) / 2,
                "ly": (a[1] + b[1]) / 2,
            }
        )
    return marks


def _plan_outlines(boundary, e1, e2) -> list:
    """Each lattice's outline in the view, as an SVG polygon's points.

    Parameters
    ----------
    boundary : dict or None
        ``extras["mesh_boundary"]``.
    e1, e2 : ndarray
        The plan's axes.

    Returns
    -------
    list of dict
    """
    outlines = []
    for layer, info in (boundary or {}).items():
        corners = (info or {}).get("corners_camera_mm") if isinstance(info, dict) else None
        if corners:
            pts2 = [(float(np.asarray(c) @ e1), float(np.asarray(c) @ e2)) for c in corners]
            outlines.append(
                {"points": " ".join(f"{x:.1f},{y:.1f}" for x, y in pts2), "colour": LAYER_COLOURS.get(layer, "#555")}
            )
    return outlines


def _spacing_labels(spacings: list, by_id: dict, acc_rows: dict) -> list:
    """A label for each spacing between two drawn bars, placed across the gap it describes and
    marked where its checkpoint is beyond tolerance.

    Parameters
    ----------
    spacings : list of dict
        The spacings table rows.
    by_id : dict
        The drawn bars' plan ends (:func:`_plan_segments`).
    acc_rows : dict
        Each spacing's checkpoint status.

    Returns
    -------
    list of dict
    """
    labels = []
    for rec in spacings:
        a, b = by_id.get(str(rec.get("bar_a"))), by_id.get(str(rec.get("bar_b")))
        if a is None or b is None:
            continue
        # Lower-mesh spacings are written a third of the way along the bars, upper-mesh ones at
        # two thirds, so the two meshes' numbers do not overlap where their bars run parallel.
        t = 1 / 3 if rec.get("layer") == "lower" else 2 / 3
        pa = a[0] + t * (a[1] - a[0])
        # The foot of pa on bar b: the label sits half way across the gap it describes.
        d = b[1] - b[0]
        pb = b[0] + np.clip((pa - b[0]) @ d / max(d @ d, 1e-9), 0, 1) * d
        mid = (pa + pb) / 2
        key = (rec.get("capture"), str(rec.get("bar_a")), str(rec.get("bar_b")), rec.get("layer"), rec.get("level"))
        status = acc_rows.get(key, "")
        v = rec.get("spacing_mm")
        labels.append(
            {
                "x": mid[0],
                "y": mid[1],
                "x0": pa[0],
                "y0": pa[1],
                "x1": pb[0],
                "y1": pb[1],
                "text": "n/m" if v is None else f"{v:.0f}",
                "bad": status in (BEYOND, BEYOND_MAX),
                "layer": rec.get("layer"),
            }
        )
    return labels


def _scale_bar(span: float) -> float:
    for s in (50, 100, 200, 250, 500, 1000, 2000):
        if s >= span / 6:
            return float(s)
    return 5000.0
