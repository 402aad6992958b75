"""Cameras the benchmarks can render their captures with (``--camera``).

All use the same active-stereo noise model (``SensorModel()``, 50 mm baseline, as both units
have); only the intrinsics differ. "d435-848": a RealSense D435 at 848 × 480, the depth
resolution its maker recommends: the 1280 × 720 focal length of docs/sensors.md (f ≈ 638 px)
scaled to 848 px wide. Bars are then about 2/3 as many pixels wide as on the reference Gemini 2,
its depth noise 1.5 × larger and its disparity steps 2-3 mm at 600 mm: a check that nothing
depends on the reference camera.
"""

from rebarlib import GEMINI2, Intrinsics

CAMERAS = {"gemini2": GEMINI2,
           "d435-848": Intrinsics(fx=638.0 * 848 / 1280, fy=638.0 * 848 / 1280, cx=423.5, cy=239.5,
                                  width=848, height=480)}
