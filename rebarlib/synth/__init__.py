"""Synthetic RGB-D captures of a double-layer bar mesh on formwork, with exact ground truth.

A design is laid out as a scene with as-built deviations (:mod:`~rebarlib.synth.scene`), its
objects turned into triangles and exact cylinders that rays are cast into
(:mod:`~rebarlib.synth.raycast`), seen through a depth sensor's errors
(:mod:`~rebarlib.synth.sensor`) and a colour camera (:mod:`~rebarlib.synth.render`), and
described by its ground truth (:mod:`~rebarlib.synth.truth`). :func:`synth_capture` does it in
one call; the same seed gives the same arrays.

The simulator is for tests, benchmarks and the notebooks: nothing the inspection runs imports it.

Examples
--------
>>> from rebarlib.data import paper_design
>>> from rebarlib.synth import Deviations, SensorModel, synth_capture
>>> from rebarlib._camera import GEMINI2
>>> cap = synth_capture(paper_design(), sensor=SensorModel.ideal(), deviations=Deviations.none(),
...                     intrinsics=GEMINI2.scaled(0.25), tilt_deg=0)
>>> cap.depth_mm.shape, round(cap.truth["cover_mm"], 3)
((200, 320), 20.0)
"""

from __future__ import annotations

from ..diameter.barsizes import rib_envelope_mm

# (and the internals the other simulators use: ``synth_scan`` casts its laser's rays into the
# same geometry, ``synth_calib`` puts a checkerboard through the same sensor model)
from .raycast import K_BAR, K_CHAIR, K_FORMWORK, K_SPACER, K_TIE
from .raycast import _build_geometry as _build_geometry, _Caster as _Caster
from .render import (
    FORMWORKS,
    LABEL_BACKGROUND,
    LABEL_LOWER,
    LABEL_UPPER,
    Appearance,
    CameraPose,
    misregister,
    render_capture,
    synth_capture,
)
from .from_truth import result_from_truth
from .scene import Bar, Deviations, SlabScene, make_scene
from .sensor import SensorModel, dropout_mask
from .sensor import _sensor_depth as _sensor_depth

__all__ = [
    "Deviations",
    "SensorModel",
    "Appearance",
    "CameraPose",
    "Bar",
    "SlabScene",
    "make_scene",
    "render_capture",
    "synth_capture",
    "result_from_truth",
    "rib_envelope_mm",
    "misregister",
    "dropout_mask",
    "FORMWORKS",
    "LABEL_BACKGROUND",
    "LABEL_LOWER",
    "LABEL_UPPER",
    "K_FORMWORK",
    "K_BAR",
    "K_SPACER",
    "K_CHAIR",
    "K_TIE",
]
