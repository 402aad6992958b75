"""The rib envelope for the judge (``acceptance``): GB 1499.2's table and the envelope live in
:mod:`rebarlib.diameter.barsizes`, once; this name stays for the importers that still use it."""

from __future__ import annotations

from .diameter.barsizes import rib_envelope_mm

__all__ = ["rib_envelope_mm"]
