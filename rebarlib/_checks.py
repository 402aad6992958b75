"""Input checks shared by every public entry point: clear errors that name what was wrong."""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # for the annotations only: importing this module must not load NumPy
    import numpy as np

__all__ = ["RebarInputError", "check_points", "check_positive"]


class RebarInputError(ValueError):
    """Bad user input: a file, a parameter or a value that cannot be used as given."""


def check_points(points, name: str = "points", *, min_count: int = 1) -> np.ndarray:
    """Return ``points`` as a finite ``(N, 3)`` float64 array or raise naming ``name``."""
    import numpy as np  # here, not at the top: the command line imports this module to start

    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim != 2 or arr.shape[1] != 3:
        raise RebarInputError(f"{name}: expected an (N, 3) array of x, y, z in mm, got shape {arr.shape}")
    if len(arr) < min_count:
        raise RebarInputError(f"{name}: expected at least {min_count} points, got {len(arr)}")
    if not np.all(np.isfinite(arr)):
        bad = int((~np.isfinite(arr)).any(axis=1).sum())
        raise RebarInputError(f"{name}: {bad} of {len(arr)} points are NaN or infinite")
    return arr


def check_positive(value, name: str, *, lo: float = 0.0, hi: float = math.inf, unit: str = "mm") -> float:
    """Return ``value`` as a float in ``(lo, hi]`` or raise naming ``name`` and the range."""
    try:
        v = float(value)
    except (TypeError, ValueError):
        raise RebarInputError(f"{name}: expected a number in {unit}, got {value!r}") from None
    if not math.isfinite(v) or not (lo < v <= hi):
        raise RebarInputError(f"{name}: expected a value in ({lo:g}, {hi:g}] {unit}, got {value!r}")
    return v
