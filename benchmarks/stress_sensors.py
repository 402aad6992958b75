"""Bar detection of the refined method under other depth sensors than the benchmark's default.

    python benchmarks/stress_sensors.py      # ~6 min: 3 sensor variants x 8 captures

The paper's slab (cover 20) at 400 / 500 / 600 mm, tilt 5 / 15°, half of the captures with the
upper bars stacked right above the lower ones, 6 bars left out of each mesh, rendered with:
three times the default flying pixels at depth edges, 2.5 times the stereo noise, and no edge
effects at all (no holes, fattening, flying pixels or jitter). Bars are scored as in
``bench_geometry.py`` (measurable: a 50 mm stretch of pixels showing their own depth). Prints per
variant the measurable bars, the missed ones, the phantoms and how many bars the second look
(``find_missed_bars``) added, and lists every missed and phantom bar.
"""

from __future__ import annotations

import pandas as pd

from _cameras import SENSORS
from bench_geometry import bar_stretches, match_bars, own_depth_pixels, paper_design
from rebarlib._inspect import inspect
from rebarlib.synth import Deviations, SensorModel, synth_capture

VARIANTS = {
    "flying pixels x3.3": SENSORS["flying"],
    "stereo noise x2.5": SENSORS["noisy"],
    "no edge effects": SENSORS["clean"],
}
POSES = ((400, 5), (500, 15), (600, 5), (600, 15))


def main() -> None:
    design = paper_design(20)
    rows = []
    for name, sensor in VARIANTS.items():
        for k, (h, tilt) in enumerate(POSES):
            for stacked in (True, False):
                kw = dict(
                    height_mm=h,
                    tilt_deg=tilt,
                    yaw_deg=47.0 * k,
                    seed=500 + k,
                    scene_seed=600 + k,
                    deviations=Deviations(mesh_yaw_deg=31.0 * k, stacked=stacked, missing=6),
                )
                cap = synth_capture(design, sensor=sensor, **kw)
                ideal = synth_capture(design, sensor=SensorModel.ideal(), **kw)
                measurable = {i for i, r in bar_stretches(cap, own_depth_pixels(cap, ideal)).items() if r >= 50.0}
                res = inspect(cap, design, diameters=False, rng=0)
                mapping, missed, _ = match_bars(res, cap.truth, measurable)
                phantom = [i for i, v in mapping.items() if v is None]
                second = int(res.bars["reason"].str.startswith("seen only at full resolution").sum())
                rows.append(
                    {
                        "sensor": name,
                        "measurable": len(measurable),
                        "missed": len(missed),
                        "phantom": len(phantom),
                        "second look": second,
                    }
                )
                for what, ids in (("missed truth bar", missed), ("phantom bar", phantom)):
                    for i in ids:
                        print(f"  {name}: {h} mm tilt {tilt}°{' stacked' if stacked else ''}: {what} {i}", flush=True)
    print(pd.DataFrame(rows).groupby("sensor", sort=False).sum().to_string())


if __name__ == "__main__":
    main()
