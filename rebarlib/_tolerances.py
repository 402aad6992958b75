"""Tolerances as data: the presets (``rebarlib/presets/*.toml``), one item's limits, the lot
rules, and a design's overrides on top of them (:func:`load_tolerances`, :func:`list_presets`).

:mod:`rebarlib.acceptance` judges with them; nothing here looks at a measurement.
"""

from __future__ import annotations

import re
import sys
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from ._checks import RebarInputError
from ._decision import check_rule

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover
    import tomli as tomllib

__all__ = [
    "ItemTolerance",
    "LotRule",
    "Tolerances",
    "load_tolerances",
    "list_presets",
    "preset_path",
    "PRESETS_DIR",
    "DEFAULT_PRESET",
]

PRESETS_DIR = Path(__file__).resolve().parent / "presets"
DEFAULT_PRESET = "GB50204-2015"

LAYERS, LEVELS = ("lower", "upper"), ("bottom", "top")
_ITEM_KEYS = {
    "minus_mm",
    "plus_mm",
    "minus_bars",
    "plus_bars",
    "minus_fraction_of_design",
    "plus_by_thickness_mm",
    "lot_rule",
    "clause",
    "interpretation",
    "confirmed",
    "note",
}
#: a lot rule's fields, in the order its table is written (a tuple: the written JSON is the same on
#: every run)
_RULE_FIELDS = ("min_pass_ratio", "max_factor", "text", "clause", "interpretation", "confirmed")
_RULE_KEYS = set(_RULE_FIELDS)
_BASE_ITEMS = ("cover", "layer_distance", "spacing", "bar_size", "bar_count", "top_cover")


# --------------------------------------------------------------------------------------------
# Tolerances as data
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class ItemTolerance:
    """Allowed deviation (measured minus design) of one item, and where the value comes from.

    ``minus`` / ``plus`` are magnitudes in ``unit`` ("mm" or "bars"); ``None`` = no limit.
    """

    item: str
    minus: float | None
    plus: float | None
    lot_rule: str
    unit: str = "mm"
    clause: str = ""
    interpretation: bool = False
    confirmed: bool = True
    note: str = ""
    minus_fraction_of_design: float | None = None
    plus_by_thickness_mm: tuple | None = None

    def limits(self, design_value: float | None = None, *, thickness_mm: float | None = None):
        """The (minus, plus) limits that apply to one design value (and slab thickness).

        Examples
        --------
        >>> t = ItemTolerance("cover", 10.0, None, "all", minus_fraction_of_design=1 / 3)
        >>> t.limits(15.0)
        (5.0, None)
        """
        minus, plus = self.minus, self.plus
        if self.minus_fraction_of_design is not None and design_value is not None:
            cap = self.minus_fraction_of_design * design_value
            minus = cap if minus is None else min(minus, cap)
        if self.plus_by_thickness_mm:
            h, p = np.asarray(self.plus_by_thickness_mm, dtype=float).T
            plus = float(np.interp(thickness_mm if thickness_mm is not None else h[0], h, p))
        return (None if minus is None else round(float(minus), 3), None if plus is None else round(float(plus), 3))

    def text(self, design_value: float | None = None, *, thickness_mm: float | None = None) -> str:
        """The limits as printed: ``±3 mm``, ``-10 / +12 mm``, ``-10 mm (no upper limit)``.

        Examples
        --------
        >>> ItemTolerance("spacing", 10.0, 10.0, "general").text()
        '±10 mm'
        """
        return _tol_text(*self.limits(design_value, thickness_mm=thickness_mm), self.unit)

    @property
    def labels(self) -> str:
        out = []
        if self.interpretation:
            out.append("interpretation")
        if not self.confirmed:
            out.append("not confirmed")
        return ", ".join(out)


@dataclass(frozen=True)
class LotRule:
    """When an item passes: at least ``min_pass_ratio`` of its measured checkpoints within
    tolerance and, when ``max_factor`` is set, none beyond ``max_factor`` x the tolerance."""

    name: str
    min_pass_ratio: float
    max_factor: float | None = None
    text: str = ""
    clause: str = ""
    interpretation: bool = False
    confirmed: bool = True


@dataclass(frozen=True)
class Tolerances:
    """A tolerance preset: the standard, its lot rules and the allowed deviation of every item."""

    name: str
    standard: str
    edition: str
    items: dict
    lot_rules: dict
    title: str = ""
    source: str = ""
    overrides: tuple = ()
    #: how a value with an uncertainty is judged against a limit (rebarlib._decision)
    decision_rule: str = "simple"

    def item(self, key: str) -> ItemTolerance:
        """The tolerance of ``key``; ``spacing_<layer>_<level>`` falls back to ``spacing``.

        Examples
        --------
        >>> load_tolerances("GB50204-2015").item("spacing_upper_top").text()
        '±10 mm'
        """
        if key in self.items:
            return self.items[key]
        base = "spacing" if key.startswith("spacing_") else key
        if base in self.items:
            return replace(self.items[base], item=key)
        raise RebarInputError(f"tolerances {self.name!r} ({self.source}): no item {key!r}; it has {sorted(self.items)}")

    def rule(self, name: str) -> LotRule:
        if name not in self.lot_rules:
            raise RebarInputError(
                f"tolerances {self.name!r} ({self.source}): lot rule {name!r} is not "
                f"defined; it has {sorted(self.lot_rules)}"
            )
        return self.lot_rules[name]

    def with_overrides(self, table: dict, *, source: str = "design.toml") -> "Tolerances":
        """Apply a design file's ``[tolerances]`` table (docs/formats.md lists its keys).

        Flat keys: ``<item>_mm`` (symmetric), ``<item>_minus_mm``, ``<item>_plus_mm``,
        ``<item>_lot_rule``, ``bar_count_bars`` / ``bar_count_minus_bars`` / ``bar_count_plus_bars``,
        ``<rule>_min_pass_ratio``, ``<rule>_max_factor``; ``<item>`` is one of cover,
        layer_distance, top_cover, bar_size, spacing or spacing_<lower|upper>_<bottom|top>.
        A sub-table ``[tolerances.<item>]`` takes the preset's own item keys.

        Examples
        --------
        >>> t = load_tolerances("GB50204-2015").with_overrides({"cover_minus_mm": 5, "general_min_pass_ratio": 0.9})
        >>> t.item("cover").limits(), t.rule("general").min_pass_ratio
        ((5.0, 3.0), 0.9)
        """
        if not table:
            return self
        if not isinstance(table, dict):
            raise RebarInputError(f"{source}: [tolerances] must be a table")
        items = dict(self.items)
        rules = dict(self.lot_rules)
        item_names = set(items) | {f"spacing_{a}_{b}" for a in LAYERS for b in LEVELS}
        rule_name = self.decision_rule
        for key, value in table.items():
            where = f"{source}: tolerances.{key}"
            if key == "decision_rule":
                rule_name = check_rule(value, where)
                continue
            if isinstance(value, dict):
                if key not in item_names:
                    raise RebarInputError(f"{where}: unknown item; expected one of {sorted(item_names)}")
                base = self.item(key)
                items[key] = _item_from_table(key, {**_item_as_table(base), **value}, where)
                continue
            item, field_ = _split_override(key, item_names, set(rules))
            if item is None:
                raise RebarInputError(
                    f"{where}: unknown key; expected <item>_mm, <item>_minus_mm, <item>_plus_mm, "
                    f"<item>_lot_rule or <rule>_min_pass_ratio / <rule>_max_factor with item in "
                    f"{sorted(item_names)} and rule in {sorted(rules)}"
                )
            if field_ in ("min_pass_ratio", "max_factor"):
                v = _override_number(value, where, lo=0.0, hi=1.0 if field_ == "min_pass_ratio" else 100.0)
                r = replace(rules[item], **{field_: v})
                # The preset's wording no longer describes the rule: print what applies now.
                text = f"{r.name}: at least {r.min_pass_ratio:.0%} of checkpoints within tolerance" + (
                    f" and none beyond {r.max_factor:g} x the tolerance" if r.max_factor else ""
                )
                rules[item] = replace(r, text=text + f" (overridden in {Path(source).name})")
                continue
            base = items.get(item) or self.item(item)
            if field_ == "lot_rule":
                if value not in rules:
                    raise RebarInputError(
                        f"{where}: lot rule {value!r} is not defined; expected one of {sorted(rules)}"
                    )
                items[item] = replace(
                    base, lot_rule=value, clause=f"{base.clause} — lot rule {value!r} set in {Path(source).name}"
                )
                continue
            v = _override_number(value, where, lo=0.0, hi=1000.0)
            changes = {"minus": v, "plus": v} if field_ == "both" else {field_: v}
            if "minus" in changes:
                changes["minus_fraction_of_design"] = None
            if "plus" in changes:
                changes["plus_by_thickness_mm"] = None
            items[item] = replace(
                base,
                clause=f"{base.clause} — overridden in {Path(source).name}"
                if "overridden" not in base.clause
                else base.clause,
                **changes,
            )
        return replace(
            self,
            items=items,
            lot_rules=rules,
            decision_rule=rule_name,
            overrides=self.overrides + tuple(f"{k} = {v!r}" for k, v in table.items()),
        )

    def to_dict(self) -> dict:
        return {
            "name": self.name,
            "standard": self.standard,
            "edition": self.edition,
            "source": self.source,
            "overrides": list(self.overrides),
            "decision_rule": self.decision_rule,
            "items": {k: _item_as_table(v) for k, v in self.items.items()},
            "lot_rules": {k: {f: getattr(v, f) for f in _RULE_FIELDS} for k, v in self.lot_rules.items()},
        }


def _split_override(key: str, item_names: set, rule_names: set):
    for rule in rule_names:
        for f in ("min_pass_ratio", "max_factor"):
            if key == f"{rule}_{f}":
                return rule, f
    for suffix, f in (
        ("_minus_mm", "minus"),
        ("_plus_mm", "plus"),
        ("_minus_bars", "minus"),
        ("_plus_bars", "plus"),
        ("_lot_rule", "lot_rule"),
        ("_mm", "both"),
        ("_bars", "both"),
    ):
        if key.endswith(suffix) and key[: -len(suffix)] in item_names:
            return key[: -len(suffix)], f
    return None, None


def _override_number(value, where: str, *, lo: float, hi: float) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not (lo <= value <= hi):
        raise RebarInputError(f"{where}: expected a number in {lo:g}..{hi:g}, got {value!r}")
    return float(value)


def _tol_text(minus, plus, unit="mm") -> str:
    def f(x):
        return f"{x:g}"

    if minus is None and plus is None:
        return "no limit"
    if minus is None:
        return f"+{f(plus)} {unit} (no lower limit)"
    if plus is None:
        return f"−{f(minus)} {unit} (no upper limit)"
    if minus == plus:
        return f"±{f(minus)} {unit}" if minus else "as designed"
    return f"−{f(minus)} / +{f(plus)} {unit}"


def _item_as_table(t: ItemTolerance) -> dict:
    unit = "bars" if t.unit == "bars" else "mm"
    out = {
        f"minus_{unit}": t.minus,
        f"plus_{unit}": t.plus,
        "lot_rule": t.lot_rule,
        "clause": t.clause,
        "interpretation": t.interpretation,
        "confirmed": t.confirmed,
        "note": t.note,
        "minus_fraction_of_design": t.minus_fraction_of_design,
        "plus_by_thickness_mm": [list(p) for p in t.plus_by_thickness_mm] if t.plus_by_thickness_mm else None,
    }
    return {k: v for k, v in out.items() if v is not None}


def _item_from_table(key: str, table: dict, where: str) -> ItemTolerance:
    unknown = set(table) - _ITEM_KEYS
    if unknown:
        raise RebarInputError(f"{where}: unknown keys {sorted(unknown)}; expected some of {sorted(_ITEM_KEYS)}")
    unit = "bars" if key == "bar_count" else "mm"
    nums = {}
    for side in ("minus", "plus"):
        v = table.get(f"{side}_{unit}")
        nums[side] = None if v is None else _override_number(v, f"{where}.{side}_{unit}", lo=0, hi=1000)
    frac = table.get("minus_fraction_of_design")
    if frac is not None:
        frac = _override_number(frac, f"{where}.minus_fraction_of_design", lo=0, hi=1)
    pbt = table.get("plus_by_thickness_mm")
    if pbt is not None:
        try:
            arr = np.asarray(pbt, dtype=float)
            ok = arr.ndim == 2 and arr.shape[1] == 2 and len(arr) >= 1 and np.all(np.diff(arr[:, 0]) > 0)
        except (TypeError, ValueError):
            ok = False
        if not ok:
            raise RebarInputError(f"{where}.plus_by_thickness_mm: expected [[h_mm, plus_mm], ...] with increasing h")
        pbt = tuple(tuple(float(x) for x in p) for p in arr)
    if "lot_rule" not in table:
        raise RebarInputError(f"{where}: missing 'lot_rule' (the name of a [lot_rules.*] table)")
    return ItemTolerance(
        item=key,
        minus=nums["minus"],
        plus=nums["plus"],
        lot_rule=str(table["lot_rule"]),
        unit=unit,
        clause=str(table.get("clause", "")),
        interpretation=bool(table.get("interpretation", False)),
        confirmed=bool(table.get("confirmed", True)),
        note=str(table.get("note", "")),
        minus_fraction_of_design=frac,
        plus_by_thickness_mm=pbt,
    )


def _norm(name: str) -> str:
    return re.sub(r"[^a-z0-9]", "", name.lower())


def list_presets() -> dict:
    """The shipped presets: ``{name: path}``.

    Parameters
    ----------
    None; the presets are the ``*.toml`` files in :data:`PRESETS_DIR`.

    Returns
    -------
    dict of ``{name: pathlib.Path}``, in the order of the files' names: each preset's ``name``
    (its file's stem where it has none) and its file. Any of its spellings selects it in
    :func:`load_tolerances` (:func:`preset_path`).

    Examples
    --------
    >>> sorted(list_presets())
    ['ACI117-318', 'EN13670-class1', 'GB50204-2015', 'custom']
    """
    return {name: path for name, (path, _) in _preset_table().items()}


def _preset_table() -> dict:
    """``{name: (path, names that select it)}``: its name, file stem, ``standard`` and ``aliases``."""
    out = {}
    for p in sorted(PRESETS_DIR.glob("*.toml")):
        try:
            data = tomllib.loads(p.read_text(encoding="utf-8"))
        except tomllib.TOMLDecodeError:  # a broken preset is reported when it is loaded by path
            data = {}
        name = str(data.get("name", p.stem))
        aliases = data.get("aliases", [])
        spellings = [name, p.stem, str(data.get("standard", ""))]
        spellings += [str(a) for a in aliases] if isinstance(aliases, list) else []
        out[name] = (p, {_norm(a) for a in spellings if _norm(a)})
    return out


def preset_path(name: str) -> Path:
    """The shipped preset a standard's name selects: its ``name``, file stem, ``standard`` or
    one of its ``aliases`` (case, spaces and punctuation ignored). Anything else is refused
    with the list of presets: a standard that merely looks alike ("GB50010-2010", "ACI 350")
    is another code, and judging it by a neighbour's tolerances would be wrong.

    Examples
    --------
    >>> preset_path("ACI 318").stem
    'aci117_318'
    """
    table = _preset_table()
    match = [path for path, spellings in table.values() if _norm(str(name)) in spellings]
    if len(match) != 1:
        listed = "; ".join(
            f"{n} (also: {', '.join(_aliases(p))})" if _aliases(p) else n for n, (p, _) in sorted(table.items())
        )
        raise RebarInputError(
            f"tolerances: unknown preset {str(name)!r}; expected one of: {listed}; or a path to a .toml tolerance file"
        )
    return match[0]


def _aliases(path: Path) -> list:
    try:
        aliases = tomllib.loads(path.read_text(encoding="utf-8")).get("aliases", [])
    except tomllib.TOMLDecodeError:
        return []
    return [str(a) for a in aliases] if isinstance(aliases, list) else []


def load_tolerances(name_or_path=DEFAULT_PRESET) -> Tolerances:
    """Read a tolerance preset by name (``"GB50204-2015"``, ``"ACI117-318"``, ``"EN13670-class1"``,
    ``"custom"``, or an alias listed in the preset file; case and punctuation ignored, see
    :func:`preset_path`) or from a TOML file path.

    Parameters
    ----------
    name_or_path : str, pathlib.Path or Tolerances
        a preset's name or alias, or the path of a ``.toml`` tolerance file (the ``custom``
        preset is a commented template of one); default :data:`DEFAULT_PRESET`. A
        :class:`Tolerances` is returned as it is.

    Returns
    -------
    Tolerances: the preset's standard and edition, its items (:class:`ItemTolerance`) and its
    lot rules (:class:`LotRule`), ``source`` the file read. A design's own limits go on top
    with :meth:`Tolerances.with_overrides`.

    Raises
    ------
    RebarInputError
        an unknown name, a missing or invalid file, or one that lacks an item of the base set
        (cover, layer_distance, spacing, bar_size, bar_count, top_cover) or names a lot rule
        it does not define.

    Examples
    --------
    >>> load_tolerances("ACI 318").name
    'ACI117-318'
    >>> t = load_tolerances("gb50204_2015")
    >>> t.standard, t.item("cover").text(), t.rule("cover").max_factor
    ('GB 50204-2015', '±3 mm', 1.5)
    """
    if isinstance(name_or_path, Tolerances):
        return name_or_path
    text = str(name_or_path)
    path = Path(text)
    if path.suffix == ".toml" and not path.is_file():
        raise RebarInputError(f"{path}: tolerance file not found")
    if path.suffix != ".toml":
        path = preset_path(text)
    try:
        data = tomllib.loads(path.read_text(encoding="utf-8"))
    except (tomllib.TOMLDecodeError, UnicodeDecodeError) as exc:
        raise RebarInputError(f"{path}: not a valid TOML tolerance file: {exc}") from None
    where = str(path)
    rules = {}
    for name, table in (data.get("lot_rules") or {}).items():
        unknown = set(table) - _RULE_KEYS
        if unknown or "min_pass_ratio" not in table:
            raise RebarInputError(f"{where}: lot_rules.{name}: needs min_pass_ratio; unknown keys {sorted(unknown)}")
        mf = table.get("max_factor")
        rules[name] = LotRule(
            name,
            _override_number(table["min_pass_ratio"], f"{where}: lot_rules.{name}.min_pass_ratio", lo=0, hi=1),
            None if mf is None else _override_number(mf, f"{where}: lot_rules.{name}.max_factor", lo=1, hi=100),
            str(table.get("text", "")),
            str(table.get("clause", "")),
            bool(table.get("interpretation", False)),
            bool(table.get("confirmed", True)),
        )
    items = {k: _item_from_table(k, v, f"{where}: items.{k}") for k, v in (data.get("items") or {}).items()}
    missing = [k for k in _BASE_ITEMS if k not in items]
    if missing:
        raise RebarInputError(f"{where}: missing [items.*] tables for {missing}")
    for k, v in items.items():
        if v.lot_rule not in rules:
            raise RebarInputError(f"{where}: items.{k}.lot_rule = {v.lot_rule!r} is not a [lot_rules.*] table")
    return Tolerances(
        name=str(data.get("name", path.stem)),
        standard=str(data.get("standard", path.stem)),
        edition=str(data.get("edition", "")),
        items=items,
        lot_rules=rules,
        title=str(data.get("title", "")),
        source=where,
        decision_rule=check_rule(data.get("decision_rule", "simple"), where),
    )
