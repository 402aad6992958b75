"""Slab design files (``design.toml``): what the inspection is checked against."""

from __future__ import annotations

import difflib
import sys
from dataclasses import dataclass, field
from pathlib import Path

from ._checks import RebarInputError

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = ["BarSet", "Lattice", "Design", "load_design", "design_from_dict", "DESIGN_KEYS", "DEFAULT_BAR_SYSTEM"]

#: Bar-size standard of a design that names none (``bar_system``), and of every function that
#: takes a ``system``: GB 1499.2, the Chinese standard the method was developed under.
DEFAULT_BAR_SYSTEM = "GB1499.2"

#: Direction groups of a lattice: its bottom bars and the bars resting on them.
LEVELS = ("bottom", "top")
#: Bar surfaces: ribbed bars are seen at their rib envelope, plain round bars at their diameter.
SURFACES = ("deformed", "plain")

#: Every key a design file may hold, per table: the one list an unknown key is checked against
#: (a misspelt key would otherwise be dropped without a word, and the item it names with it).
#: ``[tolerances]`` is checked by ``Tolerances.with_overrides``, which knows the preset's items.
#: A module that reads a new key adds it here.
DESIGN_KEYS = {
    "": {"slab", "design", "tolerances"},
    "slab": {
        "id",
        "element",
        "location",
        "standard",
        "project",
        "drawing",
        "contractor",
        "record",
        "lot",
        "bar_system",
    },
    "design": {"cover_mm", "layer_distance_mm", "thickness_mm", "lower", "upper", "bar_system"},
    "lattice": {"diameter_mm", "spacing_mm", "surface", *LEVELS},
    "level": {"diameter_mm", "spacing_mm", "surface"},
}


def _check_keys(table: dict, kind: str, where: str) -> None:
    """Refuse a key of ``table`` that is not in ``DESIGN_KEYS[kind]``, suggesting the nearest."""
    known = DESIGN_KEYS[kind]
    for key in table:
        if key in known:
            continue
        near = difflib.get_close_matches(str(key), sorted(known), n=1, cutoff=0.6)
        hint = f"did you mean '{near[0]}'? " if near else ""
        raise RebarInputError(f"{where}: unknown key '{key}'; {hint}expected one of {sorted(known)}")


def _table(data: dict, key: str, where: str, *, required: bool) -> dict:
    """``data[key]`` checked to be a table (``{}`` when absent and not required)."""
    if key not in data:
        if required:
            raise RebarInputError(f"{where}: missing table [{key}]")
        return {}
    value = data[key]
    if not isinstance(value, dict):
        raise RebarInputError(
            f"{where}: [{key}] must be a table (a [{key}] header with keys under it), "
            f"got {type(value).__name__} {_short(value)}"
        )
    return value


def _short(value, n: int = 40) -> str:
    text = repr(value)
    return text if len(text) <= n else text[: n - 1] + "…"


def _text(table: dict, key: str, where: str, default: str) -> str:
    """An optional text value of ``table`` (a string; numbers are accepted as their text)."""
    v = table.get(key, default)
    if isinstance(v, bool) or not isinstance(v, (str, int, float)):
        raise RebarInputError(f"{where}.{key}: expected a text string, got {type(v).__name__} {_short(v)}")
    return str(v)


@dataclass(frozen=True)
class BarSet:
    """One direction of one lattice: parallel bars of one size at one spacing (mm).

    ``surface``: "deformed" (ribbed: seen at its rib envelope) or "plain" (a plain round bar,
    e.g. HPB300: seen at its diameter)."""

    diameter_mm: float
    spacing_mm: float
    surface: str = "deformed"


@dataclass(frozen=True)
class Lattice:
    """A lattice: ``bottom`` bars and the crossing ``top`` bars that rest on them."""

    bottom: BarSet
    top: BarSet

    @property
    def thickness_mm(self) -> float:
        """The lattice's depth: its two bar diameters (mm)."""
        return self.bottom.diameter_mm + self.top.diameter_mm

    def level(self, name: str) -> BarSet:
        """The bar set of level ``name`` ("bottom" or "top")."""
        return getattr(self, name)


@dataclass(frozen=True)
class Design:
    """Design values of one slab, in mm, plus the identification printed on the report."""

    slab_id: str
    cover_mm: float
    layer_distance_mm: float
    lower: Lattice
    upper: Lattice
    thickness_mm: float | None = None
    element: str = "slab"
    location: str = ""
    standard: str = "GB50204-2015"
    bar_system: str = DEFAULT_BAR_SYSTEM
    slab: dict = field(default_factory=dict, compare=False)
    tolerances: dict = field(default_factory=dict, compare=False)
    source: str = ""

    def lattice(self, layer: str) -> Lattice:
        """The lattice ``layer`` ("lower" or "upper"); another name raises
        :class:`RebarInputError`."""
        if layer not in ("lower", "upper"):
            raise RebarInputError(f"layer: expected 'lower' or 'upper', got {layer!r}")
        return getattr(self, layer)

    @property
    def upper_top_mm(self) -> float:
        """Design height of the top of the upper lattice above the formwork."""
        return self.cover_mm + self.layer_distance_mm + self.upper.thickness_mm

    @property
    def top_cover_mm(self) -> float | None:
        """Design cover over the upper lattice (thickness less its top), None without a thickness."""
        return None if self.thickness_mm is None else self.thickness_mm - self.upper_top_mm


def _number(table: dict, key: str, where: str, *, lo: float, hi: float):
    if key not in table:
        raise RebarInputError(f"{where}: missing required key '{key}' (a number in mm)")
    v = table[key]
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise RebarInputError(f"{where}.{key}: expected a number in mm, got {v!r}")
    if not (lo <= v <= hi):
        raise RebarInputError(f"{where}.{key}: {v!r} mm is outside the plausible range {lo:g}..{hi:g} mm")
    return float(v)


def _lattice(table: dict, where: str) -> Lattice:
    if not isinstance(table, dict):
        raise RebarInputError(
            f"{where}: expected a table with diameter_mm and spacing_mm, got {type(table).__name__} {_short(table)}"
        )
    _check_keys(table, "lattice", where)
    sets = {}
    for lvl in LEVELS:
        sub = table.get(lvl, {})
        if not isinstance(sub, dict):
            raise RebarInputError(
                f"{where}.{lvl}: expected a table with diameter_mm and/or spacing_mm, "
                f"got {type(sub).__name__} {_short(sub)}"
            )
        _check_keys(sub, "level", f"{where}.{lvl}")
        values = []
        for key, lo, hi in (("diameter_mm", 4, 60), ("spacing_mm", 30, 1000)):
            if key in sub:
                values.append(_number(sub, key, f"{where}.{lvl}", lo=lo, hi=hi))
            else:  # the lattice-wide value applies to both directions
                values.append(_number(table, key, where, lo=lo, hi=hi))
        surface = sub.get("surface", table.get("surface", "deformed"))
        if surface not in SURFACES:
            raise RebarInputError(f"{where}.{lvl}.surface: expected one of {SURFACES}, got {surface!r}")
        sets[lvl] = BarSet(*values, surface=surface)
    return Lattice(**sets)


def design_from_dict(data: dict, *, source: str = "design") -> Design:
    """Build a :class:`Design` from the parsed TOML tables (docs/formats.md, "Design files").

    Parameters
    ----------
    data : dict
        The tables ``slab``, ``design`` (with ``lower`` and ``upper``) and, optionally,
        ``tolerances``.
    source : str
        What the data came from, named in every error.

    Returns
    -------
    Design

    Raises
    ------
    RebarInputError
        Naming the key, for a missing table or key, an unknown key, or an implausible value.

    Examples
    --------
    >>> d = design_from_dict({"slab": {"id": "S-1"}, "design": {"cover_mm": 20,
    ...     "layer_distance_mm": 85, "lower": {"diameter_mm": 14, "spacing_mm": 200},
    ...     "upper": {"diameter_mm": 12, "spacing_mm": 200}}})
    >>> d.lower.bottom.diameter_mm, d.upper_top_mm
    (14.0, 129.0)
    """
    if not isinstance(data, dict):
        raise RebarInputError(f"{source}: expected the tables [slab] and [design], got {type(data).__name__}")
    _check_keys(data, "", source)
    slab = _table(data, "slab", source, required=False)
    des = data.get("design")
    if not isinstance(des, dict):
        raise RebarInputError(f"{source}: missing table [design] with cover_mm and layer_distance_mm")
    _check_keys(slab, "slab", f"{source}: slab")
    _check_keys(des, "design", f"{source}: design")
    tolerances = _table(data, "tolerances", source, required=False)
    where = f"{source}: design"
    for layer in ("lower", "upper"):
        if layer not in des:
            raise RebarInputError(f"{source}: missing table [design.{layer}] with diameter_mm and spacing_mm")
    lower = _lattice(des["lower"], f"{source}: design.lower")
    upper = _lattice(des["upper"], f"{source}: design.upper")
    cover = _number(des, "cover_mm", where, lo=5, hi=200)
    layer_distance = _number(des, "layer_distance_mm", where, lo=10, hi=2000)
    if layer_distance < lower.thickness_mm:
        raise RebarInputError(
            f"{where}.layer_distance_mm: {layer_distance:g} mm is less than the lower lattice's "
            f"thickness ({lower.thickness_mm:g} mm): the lattices would intersect"
        )
    thickness = des.get("thickness_mm")
    if thickness is not None:
        thickness = _number(des, "thickness_mm", where, lo=50, hi=3000)
        if thickness <= cover + layer_distance + upper.thickness_mm:
            raise RebarInputError(
                f"{where}.thickness_mm: {thickness:g} mm leaves no top cover over the upper lattice "
                f"(top of upper bars at {cover + layer_distance + upper.thickness_mm:g} mm)"
            )
    sid = slab.get("id", "")
    if not isinstance(sid, str) or not sid.strip():
        raise RebarInputError(f"{source}: [slab] needs an 'id' string (e.g. id = \"S-101\")")
    sw = f"{source}: slab"
    for key in ("project", "drawing", "contractor", "record", "lot"):
        _text(slab, key, sw, "")
    bar_sys = (
        _text(des, "bar_system", where, "")
        if "bar_system" in des
        else _text(slab, "bar_system", sw, DEFAULT_BAR_SYSTEM)
    )
    return Design(
        slab_id=sid,
        cover_mm=cover,
        layer_distance_mm=layer_distance,
        lower=lower,
        upper=upper,
        thickness_mm=thickness,
        element=_text(slab, "element", sw, "slab"),
        location=_text(slab, "location", sw, ""),
        standard=_text(slab, "standard", sw, "GB50204-2015"),
        bar_system=bar_sys,
        slab=dict(slab),
        tolerances=dict(tolerances),
        source=source,
    )


def load_design(path) -> Design:
    """Read a slab's ``design.toml``.

    Parameters
    ----------
    path : str or Path
        The file, or a folder holding ``design.toml``.

    Returns
    -------
    Design

    Raises
    ------
    RebarInputError
        Naming the file and the key when the file is missing, not TOML, or a value is absent or absurd.

    Examples
    --------
    >>> from rebarlib.data import examples_dir
    >>> d = load_design(examples_dir() / "paper_slab")
    >>> d.cover_mm, d.lower.bottom.spacing_mm
    (20.0, 200.0)
    """
    p = Path(path)
    if p.is_dir():
        p = p / "design.toml"
    if not p.is_file():
        raise RebarInputError(f"{p}: design file not found (expected a design.toml)")
    try:
        data = tomllib.loads(p.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RebarInputError(f"{p}: not a valid TOML design file: {exc}") from None
    return design_from_dict(data, source=str(p))
