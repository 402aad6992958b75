"""The words a result uses for what became of a measurement, a bar position, a checkpoint, an
item and a slab: one definition of each, so that the tables, the JSON and CSV exports and the
report agree. They are plain strings (written as they are into every export), not an enum.

Examples
--------
>>> from rebarlib._status import NOT_MEASURED
>>> NOT_MEASURED
'not measured'
"""

from __future__ import annotations

__all__ = [
    "MEASURED",
    "NOT_MEASURED",
    "HIDDEN",
    "AXIS_OUTSIDE",
    "MISSING",
    "PRESENT",
    "PRESENT_NO_DEPTH",
    "OUTSIDE",
    "NOT_IN_VIEW",
    "EXTRA",
    "NOT_EXTRA",
    "WITHIN",
    "BEYOND",
    "BEYOND_MAX",
    "EXCLUDED",
    "WITHIN_NOT_PROVEN",
    "BEYOND_NOT_PROVEN",
    "PASS",
    "FAIL",
    "INCOMPLETE",
    "NOT_CHECKED",
    "ACCEPTED",
    "REJECTED",
    "SLAB_INCOMPLETE",
]

# A measurement, a bar, a spacing (``status``) and a bar's diameter (``diameter_status``);
# HIDDEN: a bar's diameter, where another bar covers too much of it to be read.
MEASURED, NOT_MEASURED, HIDDEN = "measured", "not measured", "hidden"

# A design position examined for a bar (the ``positions`` table's ``status``).
MISSING, PRESENT, PRESENT_NO_DEPTH = "missing", "present", "present (no depth)"
OUTSIDE, NOT_IN_VIEW = "outside the mesh", "not in view"
#: a bar's diameter reason where no cross-section's axis point lies in the image: less than half
#: of the bar's width is in view (a bar at the image's border)
AXIS_OUTSIDE = "bar axis is outside the image"
#: a bar-size checkpoint left to another capture of the slab that sized the same bar
SIZED_ELSEWHERE = "sized in capture"
#: a spacing checkpoint left to an earlier capture of the slab that measured the same spacing
SAME_SPACING = "the same spacing as in capture"
#: a spacing checkpoint whose gap holds a bar position evidenced missing (judged by the count)
SPANS_MISSING = "the gap of the missing bar"
EXTRA, NOT_EXTRA = "extra", "not counted"

# A checkpoint: one measured value against its tolerance (acceptance; NOT_MEASURED as above).
WITHIN, BEYOND, BEYOND_MAX, EXCLUDED = "within", "beyond", "beyond max", "excluded"
# A checkpoint's decision where its expanded uncertainty reaches over a limit (decision rules).
WITHIN_NOT_PROVEN, BEYOND_NOT_PROVEN = "within, not proven", "beyond, not proven"

# An item (cover, one lattice's spacing, ...) and a bar drawn in the report.
PASS, FAIL, INCOMPLETE, NOT_CHECKED = "pass", "fail", "incomplete", "not checked"

# The slab.
ACCEPTED, REJECTED, SLAB_INCOMPLETE = "accepted", "rejected", "incomplete"
