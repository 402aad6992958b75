"""Standard bar sizes per system and snapping a width seen by a camera to the nominal size."""

from __future__ import annotations

import math
from dataclasses import dataclass

from .._checks import RebarInputError
from .._design import DEFAULT_BAR_SYSTEM

__all__ = [
    "BAR_SYSTEMS",
    "BarSystem",
    "bar_system",
    "barset_width_mm",
    "observed_width_mm",
    "snap_diameter",
    "GB_RIBS",
    "GB_RIB_PITCH",
    "rib_envelope_mm",
]


@dataclass(frozen=True)
class BarSystem:
    """Nominal sizes of one standard with the width a mask or depth camera sees of each.

    Attributes
    ----------
    name : str, e.g. ``"GB1499.2"``
    sizes_mm : tuple of float, nominal diameters, increasing
    labels : tuple of str, designations as written on drawings (``"Φ12"``, ``"#4"``, ``"15M"``)
    envelope_mm : tuple of float, outer diameter over the ribs of a deformed bar of each size
    core_mm : tuple of float, diameter of the core between the ribs (GB 1499.2 d1), what a
        silhouette shows between the rib crests where a camera resolves them
    rib_pitch_mm : tuple of float, spacing of the transverse ribs of each size where the standard
        sets one per size (GB 1499.2 l); empty where it does not (ASTM A615 only caps the
        average spacing at 0.7 d, so a pitch there says nothing of the size)
    """

    name: str
    sizes_mm: tuple
    labels: tuple
    envelope_mm: tuple
    core_mm: tuple = ()
    rib_pitch_mm: tuple = ()

    def label(self, nominal_mm: float) -> str:
        """Designation of a nominal size of this system (``""`` if it is not one)."""
        return self.of_size(self.labels, nominal_mm, "")

    def neighbours(self, nominal_mm: float) -> set:
        """The size nearest ``nominal_mm`` and the sizes next to it up and down (one at either end
        of the table).

        >>> sorted(bar_system("GB1499.2").neighbours(12))
        [10.0, 12.0, 14.0]
        """
        j = _nearest(self.sizes_mm, nominal_mm)
        return set(self.sizes_mm[max(j - 1, 0) : j + 2])

    def of_size(self, values, nominal_mm: float, default=None):
        """The entry of ``values`` (one of this system's per-size tuples) for the nominal size
        ``nominal_mm``; ``default`` where it is not one of the sizes (or ``values`` has none)."""
        for s, v in zip(self.sizes_mm, values):
            if abs(s - nominal_mm) < 1e-6:
                return v
        return default


# GB 1499.2 (docs/acceptance.md): nominal size, inner diameter d1, rib height h. The rib envelope
# d1 + 2h is what a silhouette shows (a Φ12 bar looks 13.9 mm wide).
_GB = (
    (6, 5.8, 0.6),
    (8, 7.7, 0.8),
    (10, 9.6, 1.0),
    (12, 11.5, 1.2),
    (14, 13.4, 1.4),
    (16, 15.4, 1.5),
    (18, 17.3, 1.6),
    (20, 19.3, 1.7),
    (22, 21.3, 1.9),
    (25, 24.2, 2.1),
    (28, 27.2, 2.2),
    (32, 31.0, 2.4),
    (36, 35.0, 2.6),
    (40, 38.7, 2.9),
    (50, 48.5, 3.2),
)
# GB 1499.2 crescent-rib bars: nominal spacing l of the transverse ribs per size (same order)
_GB_PITCH = (4.0, 5.5, 7.0, 8.0, 9.0, 10.0, 10.0, 10.0, 10.5, 12.5, 12.5, 14.0, 15.0, 15.0, 16.0)
#: The same table by size, as the simulator draws ribs (``rebarlib.synth``): nominal size ->
#: (d1, h), and nominal size -> transverse-rib spacing l
GB_RIBS = {s: (d1, h) for s, d1, h in _GB}
GB_RIB_PITCH = {s: p for (s, _, _), p in zip(_GB, _GB_PITCH)}
_GB_RATIO = {s: (d1 + 2 * h) / s for s, d1, h in _GB}
_GB_CORE_RATIO = {s: d1 / s for s, d1, h in _GB}


def rib_envelope_mm(nominal_mm: float) -> float:
    """Outer diameter over the ribs of a GB 1499.2 deformed bar, d1 + 2h (e.g. 12 -> 13.9 mm):
    :func:`observed_width_mm` of a deformed bar in GB 1499.2, the one place the envelope is
    computed. Sizes not in the table scale with the nearest tabulated size's envelope.

    Parameters
    ----------
    nominal_mm : nominal diameter, mm

    Returns
    -------
    float, mm

    Examples
    --------
    >>> rib_envelope_mm(12), rib_envelope_mm(13)
    (13.9, 15.058)
    """
    return observed_width_mm(nominal_mm, system="GB1499.2")


def _gb_like(nominal_mm: float, ratios=_GB_RATIO) -> float:
    # Other standards do not tabulate the rib envelope in our sources (docs/acceptance.md), so it
    # is estimated with the GB 1499.2 envelope-to-nominal ratio of the nearest GB size: deformed
    # bars of all standards have ribs of a similar relative height (a few % of the diameter).
    # The core (d1) likewise, with ``ratios=_GB_CORE_RATIO``.
    key = min(ratios, key=lambda s: abs(s - nominal_mm))
    return round(nominal_mm * ratios[key], 3)


def _system(name, sizes, labels, smooth=()):
    env = tuple(float(s) if s in smooth else _gb_like(s) for s in sizes)
    core = tuple(float(s) if s in smooth else _gb_like(s, _GB_CORE_RATIO) for s in sizes)
    return BarSystem(name, tuple(float(s) for s in sizes), tuple(labels), env, core)


BAR_SYSTEMS = {
    "GB1499.2": BarSystem(
        "GB1499.2",
        tuple(float(s) for s, _, _ in _GB),
        tuple(f"Φ{s}" for s, _, _ in _GB),
        tuple(round(d1 + 2 * h, 3) for _, d1, h in _GB),
        tuple(float(d1) for _, d1, _ in _GB),
        _GB_PITCH,
    ),
    # ASTM A615 #3 .. #11, #14, #18 (nominal diameters in mm)
    "ASTM-A615": _system(
        "ASTM-A615",
        (9.5, 12.7, 15.9, 19.1, 22.2, 25.4, 28.7, 32.3, 35.8, 43.0, 57.3),
        ("#3", "#4", "#5", "#6", "#7", "#8", "#9", "#10", "#11", "#14", "#18"),
    ),
    # CSA G30.18 10M .. 55M
    "CSA": _system(
        "CSA",
        (11.3, 16.0, 19.5, 25.2, 29.9, 35.7, 43.7, 56.4),
        ("10M", "15M", "20M", "25M", "30M", "35M", "45M", "55M"),
    ),
    # UK / EU (B500): 6 mm is mild (smooth) steel, so its envelope is its diameter
    "EU": _system(
        "EU",
        (6, 8, 10, 12, 16, 20, 25, 32, 40, 50),
        ("Ø6", "Ø8", "Ø10", "Ø12", "Ø16", "Ø20", "Ø25", "Ø32", "Ø40", "Ø50"),
        smooth=(6,),
    ),
}

# Designs from other markets (issue 58). Nominal diameters are those each standard defines; only
# JIS G 3112 / KS D 3504 list an outer diameter over the ribs per size, the others' envelopes are
# estimated with the GB 1499.2 ratio (``_gb_like``) and marked so in docs/scanned_clouds.md.
# JIS G 3112 (SD295..SD490) and KS D 3504 share the D-series: nominal diameter (mm) and the
# maximum outer diameter over the ribs given in the standard's dimension table (reference values
# as published in the JIS table; recalled, not checked against the standard's text here).
_JIS = (
    ("D6", 6.35, 7.0),
    ("D10", 9.53, 11.0),
    ("D13", 12.7, 14.0),
    ("D16", 15.9, 18.0),
    ("D19", 19.1, 21.0),
    ("D22", 22.2, 25.0),
    ("D25", 25.4, 28.0),
    ("D29", 28.6, 33.0),
    ("D32", 31.8, 36.0),
    ("D35", 34.9, 40.0),
    ("D38", 38.1, 43.0),
    ("D41", 41.3, 46.0),
    ("D51", 50.8, 58.0),
)


def _jis_like(name: str) -> BarSystem:
    return BarSystem(
        name,
        tuple(d for _, d, _ in _JIS),
        tuple(lb for lb, _, _ in _JIS),
        tuple(e for _, _, e in _JIS),
        tuple(_gb_like(d, _GB_CORE_RATIO) for _, d, _ in _JIS),
    )


BAR_SYSTEMS.update(
    {
        "JIS-G3112": _jis_like("JIS-G3112"),
        "KS-D3504": _jis_like("KS-D3504"),
        # AS/NZS 4671: D500N deformed bars N10..N40 (nominal = designation); envelopes estimated
        "AS/NZS4671": _system(
            "AS/NZS4671",
            (10, 12, 16, 20, 24, 28, 32, 36, 40),
            ("N10", "N12", "N16", "N20", "N24", "N28", "N32", "N36", "N40"),
        ),
        # IS 1786: HYSD bars, nominal sizes 8..40 mm; envelopes estimated
        "IS1786": _system(
            "IS1786",
            (8, 10, 12, 16, 20, 25, 28, 32, 36, 40),
            ("Ø8", "Ø10", "Ø12", "Ø16", "Ø20", "Ø25", "Ø28", "Ø32", "Ø36", "Ø40"),
        ),
        # BS 4449: B500 bars, preferred sizes 8..50 mm ("H" on UK drawings); envelopes estimated
        "BS4449": _system(
            "BS4449",
            (8, 10, 12, 16, 20, 25, 32, 40, 50),
            ("H8", "H10", "H12", "H16", "H20", "H25", "H32", "H40", "H50"),
        ),
    }
)

_ALIASES = {
    "JIS": "JIS-G3112",
    "JIS G 3112": "JIS-G3112",
    "JIS G3112": "JIS-G3112",
    "KS": "KS-D3504",
    "KS D 3504": "KS-D3504",
    "KS D3504": "KS-D3504",
    "AS/NZS 4671": "AS/NZS4671",
    "AS4671": "AS/NZS4671",
    "AS/NZS": "AS/NZS4671",
    "NZS4671": "AS/NZS4671",
    "IS 1786": "IS1786",
    "IS": "IS1786",
    "BS 4449": "BS4449",
    "BS": "BS4449",
    "GB": "GB1499.2",
    "GB1499": "GB1499.2",
    "GB 1499.2": "GB1499.2",
    "ASTM": "ASTM-A615",
    "A615": "ASTM-A615",
    "ASTM A615": "ASTM-A615",
    "CSA G30.18": "CSA",
    "UK": "EU",
    "EN": "EU",
}

#: Standard uncertainty (mm) of the tabulated envelope itself: rib height varies between mills.
ENVELOPE_SIGMA_MM = 0.15

#: Degrees of freedom of a width's standard uncertainty, for the sizes' likelihoods (Student's t):
#: a width's σ is itself estimated, mostly from the spread between a capture's bars of one size
#: (5 to 20 of them), so a width far from a size is less unlikely than a normal error says.
WIDTH_SIGMA_DOF = 10.0


def bar_system(name: str) -> BarSystem:
    """The bar-size table of a standard (``"GB1499.2"``, ``"ASTM-A615"``, ``"CSA"``, ``"EU"``).

    Parameters
    ----------
    name : a system's name or an alias (``"GB"``, ``"ASTM"``, ``"JIS G 3112"``, ...), any case

    Returns
    -------
    BarSystem

    Examples
    --------
    >>> bar_system("GB1499.2").envelope_mm[3]
    13.9
    """
    key = _ALIASES.get(str(name).strip().upper(), str(name).strip())
    key = {k.upper(): k for k in BAR_SYSTEMS}.get(key.upper(), key)
    if key not in BAR_SYSTEMS:
        raise RebarInputError(f"system: expected one of {sorted(BAR_SYSTEMS)}, got {name!r}")
    return BAR_SYSTEMS[key]


def observed_width_mm(nominal_mm: float, *, system: str = DEFAULT_BAR_SYSTEM, deformed: bool = True) -> float:
    """Width a silhouette shows of a bar of ``nominal_mm``: the rib envelope, or the diameter if smooth.

    Parameters
    ----------
    nominal_mm : nominal diameter (a size off the table: scaled like the nearest GB 1499.2 size)
    system : bar-size standard (:func:`bar_system`)
    deformed : False for a smooth bar

    Returns
    -------
    float, mm

    Examples
    --------
    >>> observed_width_mm(12), observed_width_mm(12, deformed=False)
    (13.9, 12.0)
    """
    if not deformed:
        return float(nominal_mm)
    sysm = bar_system(system)
    e = sysm.of_size(sysm.envelope_mm, nominal_mm)
    return e if e is not None else _gb_like(float(nominal_mm))


def barset_width_mm(bar_set, system: str = DEFAULT_BAR_SYSTEM) -> float:
    """Outer width of the bars of one design bar set: the rib envelope of a deformed bar, the
    true diameter of a plain one (``bar_set.surface == "plain"``: plain round bars have no ribs,
    so cover, heights and sizes use their diameter).

    Parameters
    ----------
    bar_set : a design's BarSet (``diameter_mm``, ``surface``)
    system : bar-size standard

    Returns
    -------
    float, mm

    Examples
    --------
    >>> from rebarlib._design import BarSet
    >>> barset_width_mm(BarSet(12, 200)), barset_width_mm(BarSet(8, 200, surface="plain"))
    (13.9, 8.0)
    """
    deformed = getattr(bar_set, "surface", "deformed") != "plain"
    return float(observed_width_mm(bar_set.diameter_mm, system=system, deformed=deformed))


def _nearest(values, x: float) -> int:
    """Index of the entry of ``values`` nearest to ``x`` (the first of a tie)."""
    return min(range(len(values)), key=lambda k: abs(values[k] - x))


def core_size(width_mm: float, *, system: str = DEFAULT_BAR_SYSTEM) -> float:
    """Nominal size of ``system`` whose core diameter (between the ribs) is nearest to ``width_mm``.

    Parameters
    ----------
    width_mm : a width read between the ribs (NaN gives NaN)
    system : bar-size standard

    Returns
    -------
    float, the nominal size (mm)

    Examples
    --------
    >>> core_size(11.7), core_size(13.5)  # GB 1499.2 cores: Φ12 11.5, Φ14 13.4
    (12.0, 14.0)
    """
    sysm = bar_system(system)
    w = float(width_mm)
    return float(sysm.sizes_mm[_nearest(sysm.core_mm, w)]) if math.isfinite(w) else math.nan


def rib_pitch_mm(nominal_mm: float, *, system: str = DEFAULT_BAR_SYSTEM) -> float:
    """Transverse-rib spacing the standard sets for size ``nominal_mm`` (NaN where it sets none,
    or for a size not in its table).

    Parameters
    ----------
    nominal_mm : nominal diameter
    system : bar-size standard

    Returns
    -------
    float, mm (NaN where the standard sets none)

    Examples
    --------
    >>> rib_pitch_mm(12), rib_pitch_mm(14), rib_pitch_mm(12, system="ASTM-A615")
    (8.0, 9.0, nan)
    """
    sysm = bar_system(system)
    return float(sysm.of_size(sysm.rib_pitch_mm, nominal_mm, math.nan))


def rib_height_mm(width_mm: float, *, system: str = DEFAULT_BAR_SYSTEM) -> float:
    """Rib height h, (envelope − core) / 2, of the size of ``system`` whose envelope is nearest
    to ``width_mm``.

    Parameters
    ----------
    width_mm : a width over the ribs (NaN gives NaN)
    system : bar-size standard

    Returns
    -------
    float, mm

    Examples
    --------
    >>> rib_height_mm(13.6)  # Φ12: 13.9 over the ribs, core 11.5
    1.2
    """
    sysm = bar_system(system)
    w = float(width_mm)
    if not math.isfinite(w):
        return math.nan
    i = _nearest(sysm.envelope_mm, w)
    return round((sysm.envelope_mm[i] - sysm.core_mm[i]) / 2, 4)


def _half_gaps(obs, i) -> tuple[float, float]:
    lo = (obs[i] - obs[i - 1]) / 2 if i > 0 else (obs[1] - obs[0]) / 2
    hi = (obs[i + 1] - obs[i]) / 2 if i + 1 < len(obs) else (obs[-1] - obs[-2]) / 2
    return lo, hi


def size_half_gaps_mm(
    nominal_mm: float, *, system: str = DEFAULT_BAR_SYSTEM, deformed: bool = True
) -> tuple[float, float]:
    """Half the distances (mm) from the observed width of size ``nominal_mm`` to those of the
    next smaller and next larger sizes of ``system`` (at the ends of the table, the nearest
    step): a width beyond them snaps to another size.

    Parameters
    ----------
    nominal_mm : nominal diameter
    system : bar-size standard
    deformed : compare rib envelopes (True) or nominal sizes

    Returns
    -------
    (to the smaller size, to the larger size), mm

    Examples
    --------
    >>> [round(g, 2) for g in size_half_gaps_mm(14)]  # envelopes 13.9, 16.2, 18.4
    [1.15, 1.1]
    """
    sysm = bar_system(system)
    obs = sysm.envelope_mm if deformed else sysm.sizes_mm
    i = _nearest(sysm.sizes_mm, nominal_mm)
    return _half_gaps(obs, i)


def bracketing_sizes(width_mm: float, *, system: str = DEFAULT_BAR_SYSTEM, deformed: bool = True):
    """The two nominal sizes of ``system`` whose observed widths lie either side of
    ``width_mm``, as ``((smaller, its width), (larger, its width))``; ``None`` for a width
    outside the table (what an ambiguous width names as the sizes to tell apart by hand).

    Parameters
    ----------
    width_mm : a measured width
    system : bar-size standard
    deformed : compare rib envelopes (True) or nominal sizes

    Returns
    -------
    ((smaller size, its width), (larger size, its width)) or None

    Examples
    --------
    >>> bracketing_sizes(15.4)  # between Φ12 (13.9 mm) and Φ14 (16.2 mm)
    ((12.0, 13.9), (14.0, 16.2))
    """
    sysm = bar_system(system)
    obs = sysm.envelope_mm if deformed else sysm.sizes_mm
    w = float(width_mm)
    if not math.isfinite(w):
        return None
    for k in range(len(obs) - 1):  # a width on a size: that size and the next larger one
        if obs[k] <= w < obs[k + 1] or (k == len(obs) - 2 and w == obs[k + 1]):
            return (sysm.sizes_mm[k], obs[k]), (sysm.sizes_mm[k + 1], obs[k + 1])
    return None


def snap_diameter(
    width_mm: float,
    *,
    system: str = DEFAULT_BAR_SYSTEM,
    deformed: bool = True,
    sigma_mm: float = 0.0,
    dof: float = WIDTH_SIGMA_DOF,
) -> tuple[float, float]:
    """Nominal size whose observed width is nearest to ``width_mm``, and a confidence in 0..1.

    The confidence is the probability of the chosen size given the width: its posterior over the
    table's sizes, equally likely beforehand, for a width whose error about the size's observed
    width is Student's t with ``dof`` degrees of freedom and scale ``sigma_mm`` (plus the envelope
    table's own :data:`ENVELOPE_SIGMA_MM`): 1 close to the size's observed width, 0.5 half-way
    between two sizes. (With ``dof=inf``, a normal error, and the sizes' observed widths ``2g``
    apart, the width ``d`` from the nearest, it is ``1 / (1 + exp(-2g (g - d) / σ²))`` between
    two sizes.) A width beyond the table by more than half a step gives ``(nan, 0.0)``.

    Parameters
    ----------
    width_mm : float, measured width across the bar (mm)
    system : bar-size standard (see :func:`bar_system`)
    deformed : True: compare with the rib envelope (deformed bars); False: with the nominal size
    sigma_mm : standard uncertainty of ``width_mm``
    dof : degrees of freedom of ``sigma_mm`` (:data:`WIDTH_SIGMA_DOF`; ``math.inf``: a normal error)

    Returns
    -------
    (nominal_mm, confidence): the chosen size's nominal diameter (mm, a float of the system's
    table) and its posterior probability in 0..1 (rounded to 4 decimals); ``(nan, 0.0)`` for a
    width that is not finite, not positive or beyond the table.

    Examples
    --------
    >>> snap_diameter(13.8)
    (12.0, 1.0)
    >>> nominal, conf = snap_diameter(15.1, sigma_mm=0.5)  # between Φ12 (13.9) and Φ14 (16.2)
    >>> nominal, round(conf, 2)
    (14.0, 0.58)
    >>> snap_diameter(13.1, sigma_mm=0.4)  # 0.8 mm from Φ12, 1.5 from Φ10 (11.6)
    (12.0, 0.9405)
    >>> snap_diameter(13.1, sigma_mm=0.4, dof=math.inf)  # as if σ were known exactly
    (12.0, 0.988)
    """
    sysm = bar_system(system)
    w = float(width_mm)
    if not math.isfinite(w) or w <= 0:
        return math.nan, 0.0
    sizes = sysm.sizes_mm
    obs = sysm.envelope_mm if deformed else sizes
    i = _nearest(obs, w)
    lo_gap, hi_gap = _half_gaps(obs, i)
    d = w - obs[i]
    gap = hi_gap if d >= 0 else lo_gap
    if abs(d) > gap:  # beyond the largest or below the smallest size
        return math.nan, 0.0
    sigma = math.hypot(float(sigma_mm), ENVELOPE_SIGMA_MM)
    # A bar has one of the table's sizes, so what decides is how much likelier this width is from
    # the nearest size than from the others. (It used to be the chance that a continuous width
    # falls on this side of the midpoint, Φ((gap − |d|) / σ), which ignores that: docs/diameters.md,
    # "The confidence as the size's posterior".)
    if math.isinf(dof):
        ll = [-0.5 * ((w - o) / sigma) ** 2 for o in obs]
    else:
        ll = [-(dof + 1) / 2 * math.log1p(((w - o) / sigma) ** 2 / dof) for o in obs]
    top = max(ll)
    conf = 1.0 / sum(math.exp(x - top) for x in ll)
    return float(sizes[i]), round(conf, 4)
