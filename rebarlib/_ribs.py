"""Ribs of GB 1499.2 deformed bars: inner diameter d1, rib height h and transverse-rib spacing per
nominal size, and the outer diameter over the ribs (d1 + 2h, what a depth camera sees).

Shared by the simulator (``rebarlib.synth`` draws bars with these ribs) and the judge
(``acceptance`` places the upper lattice's top over its ribs), so that neither imports the other.
"""

from __future__ import annotations

__all__ = ["rib_envelope_mm"]

# GB 1499.2 nominal size -> (inner diameter d1, rib height h), docs/acceptance.md.
_GB_RIBS = {6: (5.8, 0.6), 8: (7.7, 0.8), 10: (9.6, 1.0), 12: (11.5, 1.2), 14: (13.4, 1.4),
            16: (15.4, 1.5), 18: (17.3, 1.6), 20: (19.3, 1.7), 22: (21.3, 1.9), 25: (24.2, 2.1),
            28: (27.2, 2.2), 32: (31.0, 2.4), 36: (35.0, 2.6), 40: (38.7, 2.9), 50: (48.5, 3.2)}
# GB 1499.2 transverse-rib spacing l (mm) per nominal size, for bars drawn in relief
_GB_RIB_PITCH = {6: 4.0, 8: 5.5, 10: 7.0, 12: 8.0, 14: 9.0, 16: 10.0, 18: 10.0, 20: 10.0, 22: 10.5,
                 25: 12.5, 28: 12.5, 32: 14.0, 36: 15.0, 40: 15.0, 50: 16.0}


def rib_envelope_mm(nominal_mm: float) -> float:
    """Outer diameter over the ribs of a GB 1499.2 deformed bar, d1 + 2h (e.g. 12 -> 13.9 mm).

    Sizes not in the table scale with the nearest tabulated ratio.

    Examples
    --------
    >>> rib_envelope_mm(12)
    13.9
    """
    key = min(_GB_RIBS, key=lambda s: abs(s - nominal_mm))
    d1, h = _GB_RIBS[key]
    if key == nominal_mm:
        return round(d1 + 2 * h, 3)
    return round(nominal_mm * (d1 + 2 * h) / key, 3)
