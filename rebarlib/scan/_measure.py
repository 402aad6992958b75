"""Stage 6 of a scanned cloud: spacings, layer distance, cover and the result; bar sizes where
the scan's noise allows."""

from __future__ import annotations

import math
import time
from pathlib import Path

import numpy as np
import pandas as pd

from .. import geometry as G
from .._design import Design
from .._refined import _top_cover
from .._results import InspectionResult, Measurement
from .._status import MEASURED, NOT_MEASURED
from ..cloud_io import ScanCloud
from ._axes import _cross_axes
from ._bars import _crossing_free
from ._datum import Datum
from ._input import METHOD
from ._util import _dot, _mad


def diameter_resolvable(noise_mm: float, radius_mm: float, half_gap_mm: float, n_points: int) -> tuple[bool, str]:
    """Whether a bar's size can be read from its points, and why not.

    A circle fitted to noisy points of a bar's upper half is biased by the noise unless the noise
    is well below the radius, and its radius' standard error is about σ·√(8/N) for N points over
    a half circle. The size is read only where σ ≤ radius / 4 and that error is under a quarter
    of the half gap to the nearest other standard size (so the size is told apart at 4 σ).

    Parameters
    ----------
    noise_mm : σ of the bar's cross-section points about the circle fitted to them, mm
    radius_mm : the bar's radius (half its design size's observed width), mm
    half_gap_mm : half the distance from its design size's observed width to the nearest other
        size's, mm (the smaller of :func:`rebarlib.diameter.barsizes.size_half_gaps_mm`)
    n_points : the cross-section points the circle was fitted to

    Returns
    -------
    (ok, why): True and "" where the size can be read; False and a sentence naming the
    criterion that failed (for the bar table's ``diameter_reason``).

    Examples
    --------
    >>> diameter_resolvable(1.0, 6.0, 1.0, 400)
    (True, '')
    >>> diameter_resolvable(1.0, 6.0, 1.0, 50)[1]
    '50 points at σ 1.0 mm give its radius to ±0.40 mm, more than a quarter of the half gap to the next size (1.00 mm)'
    """
    if noise_mm > radius_mm / 4:
        return False, (
            f"range noise σ {noise_mm:.1f} mm exceeds a quarter of the bar's radius "
            f"({radius_mm:.1f} mm): the scan cannot size it"
        )
    se = noise_mm * math.sqrt(8.0 / max(n_points, 1))
    if se > half_gap_mm / 4:
        return False, (
            f"{n_points} points at σ {noise_mm:.1f} mm give its radius to ±{se:.2f} mm, more than "
            f"a quarter of the half gap to the next size ({half_gap_mm:.2f} mm)"
        )
    return True, ""


def _mean_measure(values, ses, n_points: int) -> Measurement:
    """Mean of the bars' values with the standard error of that mean (one bar: its own)."""
    v = np.asarray(values, float)
    if len(v) == 0:
        return Measurement.not_measured("no bar of this level was measured")
    sd = float(np.std(v, ddof=1)) / math.sqrt(len(v)) if len(v) > 1 else float(ses[0])
    return Measurement(float(np.mean(v)), sd, n_points)


def _assemble(
    sc: ScanCloud, design: Design, plane, datum: Datum, bars: list, noise, notes, diameters, q, *, name, t_start, up_how
) -> InspectionResult:
    """The result of a cloud: spacings, layer distance, cover (with a datum), top of the upper
    lattice, the bar table (with sizes where ``diameters``), counts found, and how it was made.

    Parameters
    ----------
    sc : ScanCloud
        The cloud, re-centred.
    design : Design
    plane : Plane
        The formwork plane (or the datum's stand-in where none was found).
    datum : Datum
        Whether the formwork was found, and why not.
    bars : list of BarAxis
        The bars, in the plane's frame.
    noise : float
        The scan's range noise (mm).
    notes : list of str
    diameters : bool
        Whether to read the bar sizes (:func:`_add_diameters`).
    q : ndarray
        The cloud's points in the plane's frame (for the sizes).
    name : str or None
        The capture's name (default: the file's stem).
    t_start : float
        ``time.perf_counter()`` at the start, for the timing.
    up_how : str
        How the up direction was chosen.

    Returns
    -------
    InspectionResult
    """
    order = sorted(
        range(len(bars)),
        key=lambda i: (G.LAYERS.index(bars[i].layer), G.LEVELS.index(bars[i].level), bars[i].offset_mm),
    )
    bars = [bars[i] for i in order]
    spacing = {(la, lv): design.lattice(la).level(lv).spacing_mm for la in G.LAYERS for lv in G.LEVELS}
    spacings = G.measure_spacings(bars, design_spacing=spacing)
    table = G.bars_table(bars, plane)
    if diameters:
        table = _add_diameters(table, bars, q, design, noise)
    cover, layer_distance, upper_top = _height_measures(bars, datum)
    fw = plane.to_dict() | {"found": bool(datum.found)}
    if not datum.found:
        fw["reason"] = datum.reason
    return InspectionResult(
        capture=name or (Path(sc.source).stem if sc.source else "cloud"),
        method=METHOD,
        cover=cover,
        layer_distance=layer_distance,
        upper_top=upper_top,
        top_cover=_top_cover(design, upper_top),
        bars=table,
        spacings=spacings,
        counts=_found_counts(bars),
        formwork=fw,
        camera={},
        timings_s={"total": time.perf_counter() - t_start},
        notes=notes,
        extras={"cloud": _cloud_extras(sc, plane, datum, noise, up_how)},
    )


def _height_measures(bars: list, datum: Datum) -> tuple:
    """The cover, the layer distance and the upper lattice's top, from the bars' heights.

    Parameters
    ----------
    bars : list of BarAxis
        The bars, in the plane's frame.
    datum : Datum
        Whether the formwork (the heights' datum) was found.

    Returns
    -------
    cover, layer_distance, upper_top : Measurement
        The cover and the upper top need the datum; the layer distance (between the two
        lattices' bottom bars) does not.
    """
    # a bar whose position is not measured (its section cut by the scan's edge) has its height
    # from the part left too: not counted
    bars = [b for b in bars if b.status == MEASURED]
    und = {
        (la, lv): [b.underside_mm for b in bars if b.layer == la and b.level == lv]
        for la in G.LAYERS
        for lv in G.LEVELS
    }
    npts = {
        (la, lv): sum(b.n_points for b in bars if b.layer == la and b.level == lv) for la in G.LAYERS for lv in G.LEVELS
    }
    ses = {k: [b.axis_se_mm for b in bars if (b.layer, b.level) == k] for k in und}
    lo, hi = und[("lower", "bottom")], und[("upper", "bottom")]
    if lo and hi:
        m_lo, m_hi = (_mean_measure(lo, ses[("lower", "bottom")], 0), _mean_measure(hi, ses[("upper", "bottom")], 0))
        layer_distance = Measurement(
            m_hi.value_mm - m_lo.value_mm,
            math.hypot(m_lo.uncertainty_mm, m_hi.uncertainty_mm),
            npts[("lower", "bottom")] + npts[("upper", "bottom")],
        )
    else:
        layer_distance = Measurement.not_measured(
            f"the bottom bars of both lattices are needed; found {len(lo)} lower and {len(hi)} upper"
        )
    if not datum.found:
        cover = Measurement.not_measured(f"{datum.reason}: heights have no datum")
        upper_top = Measurement.not_measured(cover.reason)
    else:
        cover = (
            _mean_measure(lo, ses[("lower", "bottom")], npts[("lower", "bottom")])
            if lo
            else Measurement.not_measured("no bottom bar of the lower lattice found")
        )
        tops = [b.top_mm for b in bars if b.layer == "upper" and b.level == "top"]
        upper_top = (
            Measurement(float(np.mean(tops)), None, npts[("upper", "top")])
            if tops
            else Measurement.not_measured("no top bar of the upper lattice found")
        )
    return cover, layer_distance, upper_top


def _found_counts(bars: list) -> pd.DataFrame:
    """The counts table of a cloud: the bars found per lattice and level (no design positions
    are examined, so ``expected``, ``missing`` and ``extra`` are None).

    Parameters
    ----------
    bars : list of BarAxis

    Returns
    -------
    DataFrame
        Columns ``layer, level, found, expected, missing, extra``.
    """
    return pd.DataFrame(
        [
            {
                "layer": la,
                "level": lv,
                "found": sum(1 for b in bars if (b.layer, b.level) == (la, lv)),
                "expected": None,
                "missing": None,
                "extra": None,
            }
            for la in G.LAYERS
            for lv in G.LEVELS
        ]
    )


def _cloud_extras(sc: ScanCloud, plane, datum: Datum, noise, up_how: str) -> dict:
    """The result's ``extras["cloud"]``: the file, its units and size, the re-centring offset,
    the up direction and how it was chosen, the noise and whether the formwork was found.

    Parameters
    ----------
    sc, plane, datum, noise, up_how
        As for :func:`_assemble`.

    Returns
    -------
    dict
    """
    return {
        "source": sc.source,
        "units": sc.units,
        "n_points": int(len(sc)),
        "offset_mm": [round(float(v), 3) for v in sc.offset_mm],
        "up": [round(float(v), 6) for v in plane.normal],
        "up_how": up_how,
        "noise_mm": round(float(noise), 3),
        "formwork": bool(datum.found),
        "frame": "the cloud's frame re-centred: add offset_mm for the file's frame (mm)",
    }


def _add_diameters(table: pd.DataFrame, bars: list, q, design: Design, noise) -> pd.DataFrame:
    """Bar sizes where :func:`diameter_resolvable` allows: a free-radius circle through the bar's
    cross-section points (offset across its axis, height), its width snapped to the design's
    bar system; else "not measured" with the criterion that failed. Columns as the camera's
    diameter stage names them: ``nominal_mm, width_mm, width_sigma_mm, confidence,
    budget_confidence, design_diameter_mm, diameter_status, diameter_reason``."""
    from ..diameter.barsizes import bar_system, size_half_gaps_mm, snap_diameter

    system = design.bar_system
    sysm = bar_system(system)
    rows = []
    for b in bars:
        bs = design.lattice(b.layer).level(b.level)
        deformed = getattr(bs, "surface", "deformed") == "deformed"
        i = min(range(len(sysm.sizes_mm)), key=lambda k: abs(sysm.sizes_mm[k] - bs.diameter_mm))
        gap = min(size_half_gaps_mm(sysm.sizes_mm[i], system=system, deformed=deformed))
        cross = [
            c for c in (_cross_axes(b, x) for x in bars if x.layer == b.layer and x.level != b.level) if np.isfinite(c)
        ]
        fit = _cross_section_width(b, q, noise, cross)
        if fit is not None and not 0.7 < fit[0] / (2 * b.radius_mm) < 1.4:
            rows.append(
                (
                    None,
                    None,
                    None,
                    None,
                    NOT_MEASURED,
                    f"the circle through its cross-section is {fit[0]:.1f} mm wide against the set's "
                    f"{2 * b.radius_mm:.1f} mm: something else lies in its cross-section",
                )
            )
            continue
        if fit is None:
            rows.append((None, None, None, None, NOT_MEASURED, "its cross-section points do not fix a circle"))
            continue
        w, sd, sigma, n = fit
        ok, why = diameter_resolvable(sigma, b.radius_mm, gap, n)
        if not ok:
            rows.append((None, None, None, None, NOT_MEASURED, why))
            continue
        nominal, conf = snap_diameter(w, system=system, deformed=deformed, sigma_mm=sd)
        rows.append((nominal, w, sd, conf, MEASURED, ""))
    table = table.copy()
    for k, col in enumerate(("nominal_mm", "width_mm", "width_sigma_mm", "confidence")):
        table[col] = pd.to_numeric(pd.Series([r[k] for r in rows], dtype=object), errors="coerce")
    # the acceptance's decision rule reads the size's confidence here; for a cloud the width's
    # whole uncertainty is the circle fit's standard error
    table["budget_confidence"] = table["confidence"]
    table["design_diameter_mm"] = [design.lattice(b.layer).level(b.level).diameter_mm for b in bars]
    table["diameter_status"] = [r[4] for r in rows]
    table["diameter_reason"] = [r[5] for r in rows]
    return table


def _cross_section_width(b: G.BarAxis, q, noise, crossings=()) -> tuple[float, float, float, int] | None:
    """Width (2 × radius) of the circle through a bar's points in its cross-section, its standard
    error (from three independent thirds of the bar), the noise about the circle (robust σ of the
    residuals) and the points used; None if no circle fits."""
    p = q[b.point_index]
    t = _dot(p[:, :2], b.direction)
    s_ = _dot(p[:, :2], b.normal2d) - (b.offset_mm + b.slope * t)
    h = p[:, 2]
    keep = (np.abs(s_) < b.radius_mm + 3 * noise) & (np.abs(h - b.axis_height_mm) < 2 * b.radius_mm + 3 * noise)
    keep &= _crossing_free(t, list(crossings), 3 * b.radius_mm)  # away from the bars crossing it
    cut = noise
    for _ in range(4):
        if keep.sum() < 30:
            return None
        xc, yc, rad = _circle(s_[keep], h[keep])
        res = np.hypot(s_ - xc, h - yc) - rad
        cut = max(min(cut, 3 * _mad(res[keep])), 0.2)
        keep &= np.abs(res) < 3 * cut
        sigma = _mad(res[keep])
    thirds = [_circle(s_[keep][k::3], h[keep][k::3])[2] for k in range(3)]
    if not np.all(np.isfinite(thirds)):
        return None
    return 2 * rad, 2 * float(np.std(thirds, ddof=1)) / math.sqrt(3), sigma, int(keep.sum())


def _circle(s, h) -> tuple[float, float, float]:
    """Least-squares (Kåsa) circle through cross-section points: centre (s, h) and radius
    (normal equations of the 3-parameter linear problem, centred for conditioning)."""
    ms, mh = float(s.mean()), float(h.mean())
    x, y = s - ms, h - mh
    A = np.column_stack([2 * x, 2 * y, np.ones(len(x))])
    try:
        xc, yc, k = np.linalg.solve(A.T @ A, A.T @ (x**2 + y**2))
    except np.linalg.LinAlgError:
        return math.nan, math.nan, math.nan
    return float(xc + ms), float(yc + mh), float(math.sqrt(max(k + xc**2 + yc**2, 0.0)))
