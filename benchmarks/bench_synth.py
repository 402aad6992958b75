"""How long one synthetic 1280x800 capture takes to render (median of repeats), by stage.

    python benchmarks/bench_synth.py [--repeats 5]

Target (issue: foundation): under 2 s on a 2-core machine with the realistic sensor.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from rebarlib.data import paper_design, site_design
from rebarlib.synth import Appearance, Deviations, SensorModel, synth_capture


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--repeats", type=int, default=5)
    args = ap.parse_args()
    cases = [
        ("paper, 400 mm, realistic", paper_design(), dict(height_mm=400), SensorModel()),
        ("paper, 500 mm, realistic", paper_design(), dict(height_mm=500), SensorModel()),
        ("paper, 600 mm, realistic", paper_design(), dict(height_mm=600), SensorModel()),
        ("paper, 500 mm, ideal", paper_design(), dict(height_mm=500), SensorModel.ideal()),
        ("site, 500 mm, bow 5 mm", site_design(), dict(height_mm=500, deviations=Deviations(bow_mm=5)), SensorModel()),
    ]
    synth_capture(paper_design(), seed=0)  # warm-up: Open3D import and first scene
    print(f"cpu cores: {os.cpu_count()}, repeats: {args.repeats}")
    print(f"{'case':<28} {'median s':>9} {'min s':>7}")
    for name, design, kw, sensor in cases:
        times = []
        for seed in range(args.repeats):
            t0 = time.perf_counter()
            synth_capture(design, tilt_deg=10, sensor=sensor, appearance=Appearance(rust_fraction=0.3), seed=seed, **kw)
            times.append(time.perf_counter() - t0)
        print(f"{name:<28} {np.median(times):>9.2f} {np.min(times):>7.2f}")


if __name__ == "__main__":
    main()
