"""Cameras the benchmarks can render their captures with (``--camera``).

All use the same active-stereo noise model (``SensorModel()``, 50 mm baseline, as both units
have); only the intrinsics differ. "d435-848": a RealSense D435 at 848 × 480, the depth
resolution its maker recommends: the 1280 × 720 focal length of docs/sensors.md (f ≈ 638 px)
scaled to 848 px wide. Bars are then about 2/3 as many pixels wide as on the reference Gemini 2,
its depth noise 1.5 × larger and its disparity steps 2-3 mm at 600 mm: a check that nothing
depends on the reference camera.

``SENSORS``: depth-sensor variants to render with instead of the default ``SensorModel()``
(``--sensor``): three times the default flying pixels at depth edges, 2.5 times the stereo
noise, no edge effects at all (no holes, fattening, flying pixels or jitter), and "fattened":
the nearer surface bleeding 3 px over every depth edge, as a stereo matcher's window does
(probability 0.6, 0.4, 0.2 at 1, 2, 3 px from it: 1.2 px per edge on average, against 0.35 px
by default; fewer holes there, since the matcher found the nearer surface instead).
"""

from rebarlib import GEMINI2, Intrinsics
from rebarlib.synth import SensorModel

CAMERAS = {
    "gemini2": GEMINI2,
    "d435-848": Intrinsics(fx=638.0 * 848 / 1280, fy=638.0 * 848 / 1280, cx=423.5, cy=239.5, width=848, height=480),
}

SENSORS = {
    "default": SensorModel(),
    "flying": SensorModel(edge_hole_prob=0.15, edge_fatten_prob=0.2, flying_pixel_prob=0.5),
    "noisy": SensorModel(disparity_sigma_px=0.2),
    "clean": SensorModel(edge_hole_prob=0.0, edge_fatten_prob=0.0, flying_pixel_prob=0.0, lateral_jitter_px=0.0),
    "fattened": SensorModel(edge_fatten_px=3, edge_fatten_prob=0.6, edge_hole_prob=0.2),
}
