"""Depth-camera profiles as data (``rebarlib/devices/*.toml``): what the uncertainty budget
assumes about a camera's systematic errors when no calibration file is given.

``camera.json``'s ``"device"`` string picks a profile (:func:`device_for`): a profile matches when
the string, with case, spaces and punctuation ignored, contains one of its ``match`` words; the
longest match wins. A string that matches none, or a capture that names no device, gets the
conservative ``unknown`` profile, and the result says so.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass
from pathlib import Path

from .._checks import RebarInputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["DeviceProfile", "DEVICES_DIR", "list_devices", "load_device", "device_for"]

DEVICES_DIR = Path(__file__).resolve().parent
UNKNOWN = "unknown"
_GROWS = ("with distance", "constant")


@dataclass(frozen=True)
class DeviceProfile:
    """One camera's datasheet figures, as the budget uses them.

    ``depth_percent`` at ``depth_at_mm``: the limit of the systematic depth error. ``grows``:
    "with distance" (active or passive stereo: a disparity offset, an error ``k z²``, so the
    relative error grows linearly with z, plus a constant scale ``scale_percent``) or "constant"
    (a scale ``s``, plus ``offset_mm``).
    ``focal_percent``, ``principal_point_px``, ``registration_px``: limits of the factory
    calibration's residuals. All limits are half-widths of rectangular distributions.
    """

    key: str
    name: str
    match: tuple
    principle: str
    range_mm: tuple
    depth_percent: float
    depth_at_mm: float
    grows: str
    offset_mm: float
    scale_percent: float
    focal_percent: float
    principal_point_px: float
    registration_px: float
    depth_confirmed: bool
    depth_source: str
    intrinsics_source: str
    path: str = ""

    @property
    def is_default(self) -> bool:
        return self.key == UNKNOWN

    def depth_limits(self) -> dict:
        """Limits of the depth error model ``dz = s z + o + k (z / 1000 m)²``:
        ``{"scale": s, "offset_mm": o, "quad_mm_per_m2": k}`` (half-widths).

        Examples
        --------
        >>> load_device("gemini2").depth_limits()
        {'scale': 0.005, 'offset_mm': 0.0, 'quad_mm_per_m2': 10.0}
        """
        a = self.depth_percent / 100.0
        if self.grows == "with distance":
            # A z_ref of error at z_ref, growing as z²: k (z_ref / 1 m)² = A z_ref
            k = a * self.depth_at_mm / (self.depth_at_mm / 1000.0) ** 2
            return {
                "scale": self.scale_percent / 100.0,
                "offset_mm": float(self.offset_mm),
                "quad_mm_per_m2": round(k, 6),
            }
        return {"scale": a, "offset_mm": float(self.offset_mm), "quad_mm_per_m2": 0.0}

    def to_dict(self) -> dict:
        return {
            "key": self.key,
            "name": self.name,
            "principle": self.principle,
            "range_mm": list(self.range_mm),
            "depth_error": {
                "percent": self.depth_percent,
                "at_mm": self.depth_at_mm,
                "grows": self.grows,
                "offset_mm": self.offset_mm,
                "scale_percent": self.scale_percent,
                "confirmed": self.depth_confirmed,
                "source": self.depth_source,
            },
            "intrinsics": {
                "focal_percent": self.focal_percent,
                "principal_point_px": self.principal_point_px,
                "registration_px": self.registration_px,
                "source": self.intrinsics_source,
            },
            "default": self.is_default,
        }


def _norm(text: str) -> str:
    return re.sub(r"[^a-z0-9]", "", str(text).lower())


def _num(table: dict, key: str, where: str, *, lo: float = 0.0, hi: float = 1e6) -> float:
    v = table.get(key)
    if isinstance(v, bool) or not isinstance(v, (int, float)) or not lo <= v <= hi:
        raise RebarInputError(f"{where}: {key}: expected a number in {lo:g}..{hi:g}, got {v!r}")
    return float(v)


def _from_file(path: Path) -> DeviceProfile:
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, tomllib.TOMLDecodeError) as exc:
        raise RebarInputError(f"{path}: not a readable TOML device profile: {exc}") from None
    where = str(path)
    dep, intr = data.get("depth_error"), data.get("intrinsics")
    if not isinstance(dep, dict) or not isinstance(intr, dict) or "name" not in data:
        raise RebarInputError(f"{where}: expected 'name', a [depth_error] and an [intrinsics] table")
    grows = dep.get("grows", "constant")
    if grows not in _GROWS:
        raise RebarInputError(f"{where}: depth_error.grows: expected one of {_GROWS}, got {grows!r}")
    rng = data.get("range_mm", [0, 0])
    return DeviceProfile(
        key=path.stem,
        name=str(data["name"]),
        match=tuple(_norm(m) for m in data.get("match", []) if _norm(m)),
        principle=str(data.get("principle", "")),
        range_mm=tuple(float(x) for x in rng),
        depth_percent=_num(dep, "percent", f"{where}: depth_error", hi=50),
        depth_at_mm=_num(dep, "at_mm", f"{where}: depth_error", lo=1),
        grows=grows,
        offset_mm=_num({"o": dep.get("offset_mm", 0.0)}, "o", f"{where}: depth_error.offset_mm", hi=500),
        scale_percent=_num({"s": dep.get("scale_percent", 0.0)}, "s", f"{where}: depth_error.scale_percent", hi=50),
        focal_percent=_num(intr, "focal_percent", f"{where}: intrinsics", hi=20),
        principal_point_px=_num(intr, "principal_point_px", f"{where}: intrinsics", hi=500),
        registration_px=_num(intr, "registration_px", f"{where}: intrinsics", hi=100),
        depth_confirmed=bool(dep.get("confirmed", False)),
        depth_source=str(dep.get("source", "")),
        intrinsics_source=str(intr.get("source", "")),
        path=where,
    )


def list_devices() -> dict:
    """The shipped profiles: ``{key: DeviceProfile}`` (key = file name without ``.toml``).

    Examples
    --------
    >>> sorted(list_devices())[:3]
    ['azure_kinect', 'femto', 'gemini2']
    """
    return {p.stem: _from_file(p) for p in sorted(DEVICES_DIR.glob("*.toml"))}


def load_device(name_or_path) -> DeviceProfile:
    """A profile by key (``"gemini2"``, ``"realsense_d435"``, ``"unknown"``), by a device string
    (as :func:`device_for`, but an unmatched string is an error), or from a TOML file path."""
    if isinstance(name_or_path, DeviceProfile):
        return name_or_path
    path = Path(str(name_or_path))
    if path.suffix == ".toml":
        if not path.is_file():
            raise RebarInputError(f"{path}: device profile not found")
        return _from_file(path)
    devices = list_devices()
    if str(name_or_path) in devices:
        return devices[str(name_or_path)]
    prof, matched = device_for(str(name_or_path))
    if not matched:
        raise RebarInputError(
            f"device {name_or_path!r}: no profile matches; expected one of {sorted(devices)}, "
            "a device name containing one of their match words, or a .toml path"
        )
    return prof


def device_for(device) -> tuple:
    """``(profile, matched)`` for a ``camera.json`` device string; ``matched`` is False where the
    conservative ``unknown`` profile was given instead.

    Examples
    --------
    >>> device_for("rebarlib synthetic (Gemini-2-like)")[0].key
    'gemini2'
    >>> device_for("Intel RealSense D435I")[0].key
    'realsense_d435'
    >>> device_for("my camera")[0].key, device_for("my camera")[1]
    ('unknown', False)
    """
    devices = list_devices()
    text = _norm(device or "")
    best, best_len = None, 0
    for prof in devices.values():
        for m in prof.match:
            if m in text and len(m) > best_len:
                best, best_len = prof, len(m)
    if best is None:
        return devices[UNKNOWN], False
    return best, True
