"""Result types shared by every stage: a measurement that can say "not measured", and the
whole inspection of one capture. Stages fill them; the report only reads them."""

from __future__ import annotations

import json
import math
from dataclasses import dataclass, field

import numpy as np

from ._status import MEASURED, NOT_MEASURED

__all__ = ["Measurement", "InspectionResult", "MEASURED", "NOT_MEASURED", "table_records"]


@dataclass(frozen=True)
class Measurement:
    """One measured length (mm) with its standard uncertainty and the evidence behind it.

    A measurement that could not be made has ``value_mm=None``, ``status="not measured"`` and a
    ``reason`` a person can act on. Never a made-up number.
    """

    value_mm: float | None
    uncertainty_mm: float | None = None
    n_points: int = 0
    status: str = MEASURED
    reason: str = ""

    @classmethod
    def not_measured(cls, reason: str, n_points: int = 0) -> "Measurement":
        """A measurement that could not be made, with the reason and the points it had."""
        return cls(None, None, n_points, NOT_MEASURED, reason)

    @property
    def ok(self) -> bool:
        """Whether there is a value."""
        return self.status == MEASURED and self.value_mm is not None

    def to_dict(self) -> dict:
        """The measurement as JSON-ready Python (values rounded to 0.001 mm, NaN as None)."""
        return {
            "value_mm": _num(self.value_mm),
            "uncertainty_mm": _num(self.uncertainty_mm),
            "n_points": int(self.n_points),
            "status": self.status,
            "reason": self.reason,
        }


def _num(x, digits: int | None = 3):
    """``x`` as a Python float rounded to ``digits`` (``None``: not rounded); ``None`` if it is
    ``None`` or not finite."""
    if x is None:
        return None
    x = float(x)
    if not math.isfinite(x):
        return None
    return x if digits is None else round(x, digits)


def table_records(df, *, digits: int | None = 3) -> list:
    """The rows of ``df`` as dicts ready for JSON: NumPy scalars as Python ones, floats rounded to
    ``digits`` (``None``: kept whole) with NaN and infinities as ``None``, arrays as lists.

    The one conversion every export of a table uses (a result's tables, the acceptance's items and
    checkpoints, the report's rows). ``None`` or an empty table gives ``[]``.

    Examples
    --------
    >>> import pandas as pd
    >>> df = pd.DataFrame({"bar_id": [1, 2], "width_mm": [13.91234, float("nan")]})
    >>> table_records(df)
    [{'bar_id': 1, 'width_mm': 13.912}, {'bar_id': 2, 'width_mm': None}]
    >>> table_records(df, digits=None)[0]["width_mm"]
    13.91234
    """
    if df is None:
        return []
    return [{k: _plain(v, digits) for k, v in rec.items()} for rec in df.to_dict(orient="records")]


def _plain(v, digits: int | None):
    """One table cell as JSON-ready Python (see :func:`table_records`)."""
    if isinstance(v, (np.floating, float)):
        return _num(v, digits)
    if isinstance(v, np.integer):
        return int(v)
    if isinstance(v, np.bool_):
        return bool(v)
    if isinstance(v, np.ndarray):
        return [_num(t, digits) for t in v.ravel()]
    if isinstance(v, np.generic):
        return v.item()
    return v


@dataclass
class InspectionResult:
    """Everything measured on one capture.

    Tables are pandas DataFrames with one row per measured thing and unit-suffixed columns:

    - ``bars``: ``bar_id, layer ("lower"|"upper"), level ("bottom"|"top": the direction group
      resting lowest / on top within its lattice), plan_angle_deg, start_{x,y,z}_mm,
      end_{x,y,z}_mm`` (axis end points, camera frame), ``visible_length_mm, n_points, status,
      reason``; the diameter stage adds its columns (``nominal_mm``, ``diameter_status``, ...).
    - ``spacings``: ``layer, level, bar_a, bar_b, spacing_mm, design_spacing_mm, deviation_mm,
      status, reason`` in order across the bars.
    - ``counts``: ``layer, level, found, expected, missing, extra, not_measured, outside,
      evidence`` (missing and extra bars are counted only on evidence: docs/verdicts.md).
    - ``positions``: one row per examined position (``_counts.POSITION_COLUMNS``).
    """

    capture: str
    method: str
    cover: Measurement
    layer_distance: Measurement
    upper_top: Measurement
    top_cover: Measurement
    bars: object  # pandas.DataFrame
    spacings: object  # pandas.DataFrame
    counts: object = None  # pandas.DataFrame
    #: every examined bar position: empty design positions and close pairs (``_counts``)
    positions: object = None  # pandas.DataFrame
    formwork: dict = field(default_factory=dict)  # normal, offset_mm, n_inliers (camera frame)
    camera: dict = field(default_factory=dict)  # height_mm, tilt_deg of the camera over the formwork
    timings_s: dict = field(default_factory=dict)
    notes: list = field(default_factory=list)
    extras: dict = field(default_factory=dict)  # later stages (diameter, mask) put summaries here
    #: bar_id -> Cloud of the points fitted to that bar (camera frame, with pixels); not serialised
    bar_points: dict = field(default_factory=dict, repr=False)

    def to_dict(self) -> dict:
        """The result as written to ``result.json`` (docs/formats.md); ``bar_points`` is left out."""
        return {
            "capture": self.capture,
            "method": self.method,
            "cover_mm": _num(self.cover.value_mm),
            "layer_distance_mm": _num(self.layer_distance.value_mm),
            "upper_top_mm": _num(self.upper_top.value_mm),
            "top_cover_mm": _num(self.top_cover.value_mm),
            "measurements": {
                "cover": self.cover.to_dict(),
                "layer_distance": self.layer_distance.to_dict(),
                "upper_top": self.upper_top.to_dict(),
                "top_cover": self.top_cover.to_dict(),
            },
            "formwork": self.formwork,
            "camera": self.camera,
            "bars": table_records(self.bars),
            "spacings": table_records(self.spacings),
            "counts": table_records(self.counts),
            "positions": table_records(self.positions),
            "timings_s": {k: round(v, 4) for k, v in self.timings_s.items()},
            "notes": list(self.notes),
            "extras": self.extras,
        }

    def to_json(self, **kw) -> str:
        """:meth:`to_dict` as JSON text (``indent=1`` unless given; other keywords to ``json.dumps``)."""
        return json.dumps(self.to_dict(), indent=kw.pop("indent", 1), **kw)
