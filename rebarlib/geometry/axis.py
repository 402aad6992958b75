"""One fitted bar, :class:`BarAxis`, and small helpers on runs of points along an axis."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from .._design import DEFAULT_BAR_SYSTEM
from .._status import MEASURED


@dataclass(frozen=True)
class BarAxis:
    """One fitted bar in the slab frame.

    The axis is ``p(t) = t·direction + (offset_mm + slope·t)·normal2d`` in plan, at height
    ``centre_h_mm + h_slope·t``, for ``t`` in ``[t0_mm, t1_mm]`` (the visible extent).

    Its fields: ``layer`` ("lower" or "upper"); ``direction`` ((2,) unit plan direction);
    ``offset_mm`` and ``slope`` (plan offset across the direction at t = 0, and its drift per mm
    along); ``centre_h_mm`` and ``h_slope`` (axis height at t = 0, and its drift per mm);
    ``t0_mm``, ``t1_mm`` (the visible extent along the direction); ``radius_mm`` (the cylinder's
    radius; 0: none fitted, the paper's lines); ``n_points``, ``rms_mm`` (points fitted, the
    fit's residual); ``point_index`` (the fitted points' indices into the lattice's points);
    ``group``, ``level`` (direction group 0 or 1, "bottom" or "top"); ``status``, ``reason``
    ("measured", or "not measured" and why); ``arc_deg`` (span of the cross-section the fitted
    points cover); ``axis_se_mm`` (standard error of the axis position); ``lap_shift_mm``
    (across, from the axis to the middle of a lap: a bar touching this one alongside; 0 where
    none is seen, :func:`~rebarlib.geometry.bar_checks._laps`).

    Examples
    --------
    >>> b = BarAxis("lower", np.array([1.0, 0.0]), 50.0, 0.0, 30.0, 0.0, -100.0, 300.0, 7.0, 400,
    ...             0.3)
    >>> b.axis_height_mm, b.underside_mm, b.t_mid, b.plan_angle_deg
    (30.0, 23.0, 100.0, 0.0)
    """

    layer: str
    direction: np.ndarray  # (2,) unit plan direction
    offset_mm: float  # plan offset across the direction at t = 0
    slope: float  # plan drift across per mm along
    centre_h_mm: float  # axis height at t = 0
    h_slope: float
    t0_mm: float
    t1_mm: float
    radius_mm: float
    n_points: int
    rms_mm: float
    point_index: np.ndarray = field(repr=False, default=None)  # indices into the layer's points
    group: int = -1
    level: str = ""
    status: str = MEASURED
    reason: str = ""
    arc_deg: float = float("nan")  # span of the cross-section covered by the fitted points
    axis_se_mm: float = float("nan")  # standard error of the axis position (offset / height)
    lap_shift_mm: float = 0.0  # across, from the axis to the middle of a lap (0: no lap seen)

    @property
    def normal2d(self) -> np.ndarray:
        return np.array([-self.direction[1], self.direction[0]])

    @property
    def t_mid(self) -> float:
        return 0.5 * (self.t0_mm + self.t1_mm)

    def plan_point(self, t) -> np.ndarray:
        t = np.asarray(t, float)
        return t[..., None] * self.direction + (self.offset_mm + self.slope * t)[..., None] * self.normal2d

    def axis_points(self, t) -> np.ndarray:
        """(…, 3) slab-frame points of the axis at ``t``."""
        t = np.asarray(t, float)
        return np.concatenate([self.plan_point(t), (self.centre_h_mm + self.h_slope * t)[..., None]], axis=-1)

    @property
    def axis_height_mm(self) -> float:
        """Height of the axis above the formwork at the middle of the visible extent."""
        return float(self.centre_h_mm + self.h_slope * self.t_mid)

    @property
    def underside_mm(self) -> float:
        return self.axis_height_mm - self.radius_mm

    @property
    def top_mm(self) -> float:
        return self.axis_height_mm + self.radius_mm

    @property
    def plan_angle_deg(self) -> float:
        return math.degrees(math.atan2(self.direction[1], self.direction[0])) % 180.0


def envelope_mm(nominal_mm: float, system: str = DEFAULT_BAR_SYSTEM) -> float:
    """Outer diameter over the ribs (what a depth camera sees) of a nominal size: the bar
    sizes' :func:`~rebarlib.diameter.barsizes.observed_width_mm` of a deformed bar.

    Parameters
    ----------
    nominal_mm : nominal diameter
    system : bar-size standard

    Returns
    -------
    float, mm

    Examples
    --------
    >>> envelope_mm(12)
    13.9
    """
    from ..diameter.barsizes import observed_width_mm

    return float(observed_width_mm(nominal_mm, system=system, deformed=True))


def _level_axis(b: BarAxis, offset_mm: float, height_mm: float, **changes) -> BarAxis:
    """``b`` with an approximate axis: its direction, at ``offset_mm`` across and ``height_mm``,
    level and parallel to its direction."""
    return replace(b, offset_mm=offset_mm, slope=0.0, h_slope=0.0, centre_h_mm=height_mm, **changes)


def _run_length(t, *, cell_mm: float, max_gap_mm: float) -> float:
    """Length (mm) of the longest stretch of ``t`` with no gap longer than ``max_gap_mm``."""
    if len(t) < 2:
        return 0.0
    a, b = _longest_run(t, cell_mm=cell_mm, max_gap_mm=max_gap_mm, by="length")
    return b - a


def _runs(flags: np.ndarray) -> list:
    """(start, stop) of each run of True in a 1-D boolean array."""
    f = np.r_[False, flags, False].astype(np.int8)
    d = np.diff(f)
    return list(zip(np.flatnonzero(d == 1), np.flatnonzero(d == -1)))


def _longest_run(t, *, cell_mm: float, max_gap_mm: float, by: str = "count") -> tuple[float, float]:
    ts = np.sort(t)
    if len(ts) == 1:
        return float(ts[0]), float(ts[0])
    breaks = np.where(np.diff(ts) > max_gap_mm)[0]
    starts = np.r_[0, breaks + 1]
    ends = np.r_[breaks, len(ts) - 1]
    score = ends - starts + 1 if by == "count" else ts[ends] - ts[starts]
    i = int(np.argmax(score))
    return float(ts[starts[i]]), float(ts[ends[i]])
