"""Speed of the geometry stage: per-stage times of ``inspect()`` on a 1280×800 capture.

Target (issue "Geometry"): the whole geometry of one capture (cloud, filtering, plane, layers,
bars, spacing) <= 0.5 s median: ``inspect(..., diameters=False)``. The diameter stage (mask and
widths) is timed once more on top, for information. Stage times are ``InspectionResult.timings_s`` (each stage timed
inside ``inspect``), medians over repeated runs after one warm-up run (the first call pays for
importing Open3D). The machine may be shared: CPU time and the load average are printed next to
wall time.

Also printed: how the time grows with the number of points (same scene at 0.5×, 0.75× and 1×
resolution) and with the number of bars (spacing 300 / 200 / 150 / 100 mm at full resolution).

    python benchmarks/bench_speed.py            # full: 7 repeats, both methods, growth tables
    python benchmarks/bench_speed.py --quick    # 3 repeats, refined only, smaller growth tables
"""

from __future__ import annotations

import argparse
import os
import statistics
import time

import numpy as np

from rebarlib import GEMINI2
from rebarlib._design import design_from_dict
from rebarlib._inspect import inspect
from rebarlib.synth import Deviations, synth_capture

TARGET_S = 0.5


def design(spacing_mm: float = 200.0):
    return design_from_dict(
        {
            "slab": {"id": f"speed-s{spacing_mm:g}"},
            "design": {
                "cover_mm": 20,
                "layer_distance_mm": 85,
                "lower": {"diameter_mm": 14, "spacing_mm": spacing_mm},
                "upper": {"diameter_mm": 12, "spacing_mm": spacing_mm},
            },
        }
    )


def capture(d, *, scale: float = 1.0, height_mm: float = 500.0):
    K = GEMINI2 if scale == 1.0 else GEMINI2.scaled(scale)
    return synth_capture(
        d,
        height_mm=height_mm,
        tilt_deg=10,
        deviations=Deviations(mesh_yaw_deg=23),
        intrinsics=K,
        seed=1,
        scene_seed=2,
        name=f"speed-{scale:g}",
    )


def time_inspect(cap, d, *, method: str, repeats: int, diameters: bool = False) -> dict:
    inspect(cap, d, method=method, diameters=diameters, rng=0)  # warm-up: imports, caches
    walls, cpus, stages, res = [], [], {}, None
    for i in range(repeats):
        t0, c0 = time.perf_counter(), time.process_time()
        res = inspect(cap, d, method=method, diameters=diameters, rng=i)
        walls.append(time.perf_counter() - t0)
        cpus.append(time.process_time() - c0)
        for k, v in res.timings_s.items():
            stages.setdefault(k, []).append(v)
    return {
        "wall": statistics.median(walls),
        "cpu": statistics.median(cpus),
        "max": max(walls),
        "stages": {k: statistics.median(v) for k, v in stages.items()},
        "n_points": res.extras.get("n_points"),
        "n_bars": int((res.bars["status"] == "measured").sum()),
    }


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="3 repeats, refined only, small growth tables")
    args = ap.parse_args(argv)
    repeats = 3 if args.quick else 7
    methods = ("refined",) if args.quick else ("refined", "paper")

    print(
        f"load average (1 min) before timing: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs "
        "(wall times include waiting for a shared CPU; CPU time does not)"
    )
    d = design()
    cap = capture(d)
    K = cap.intrinsics
    print(f"\nStage times, {K.width}x{K.height} capture at 500 mm, tilt 10°, median of {repeats} runs (s)")
    for method in methods:
        r = time_inspect(cap, d, method=method, repeats=1 if method == "paper" else repeats)
        print(f"\n[{method}]  {r['n_points']} points in the cloud, {r['n_bars']} bars measured")
        print(f"{'stage':<12}{'median s':>10}")
        for k, v in r["stages"].items():
            print(f"{k:<12}{v:>10.3f}")
        verdict = "meets" if r["wall"] <= TARGET_S else "MISSES"
        print(
            f"{'total wall':<12}{r['wall']:>10.3f}   (max {r['max']:.3f}; CPU {r['cpu']:.3f} s)  "
            f"{verdict} the {TARGET_S} s target" + ("" if method == "refined" else " (paper: 1 run)")
        )
        if method == "refined":
            rd = time_inspect(cap, d, method=method, repeats=repeats, diameters=True)
            extra = ", ".join(f"{k} {v:.3f}" for k, v in rd["stages"].items() if k not in r["stages"])
            print(f"{'+diameters':<12}{rd['wall']:>10.3f}   (CPU {rd['cpu']:.3f} s; {extra})")

    print("\nGrowth with the number of points (refined; same scene, lower resolution)")
    print(f"{'image':<11}{'points':>9}{'bars':>6}{'wall s':>9}{'CPU s':>8}{'bars s':>8}{'plane s':>9}")
    for scale in (0.5, 1.0) if args.quick else (0.5, 0.75, 1.0):
        c = cap if scale == 1.0 else capture(d, scale=scale)
        r = time_inspect(c, d, method="refined", repeats=repeats)
        print(
            f"{c.intrinsics.width}x{c.intrinsics.height:<6}{r['n_points']:>9}{r['n_bars']:>6}{r['wall']:>9.3f}"
            f"{r['cpu']:>8.3f}{r['stages'].get('bars', np.nan):>8.3f}{r['stages'].get('plane', np.nan):>9.3f}"
        )

    print("\nGrowth with the number of bars (refined; 1280x800, spacing varied)")
    print(f"{'spacing':<9}{'points':>9}{'bars':>6}{'wall s':>9}{'CPU s':>8}{'bars s':>8}{'measure s':>10}")
    for sp in (200, 100) if args.quick else (300, 200, 150, 100):
        dd = design(sp)
        c = cap if sp == 200 else capture(dd)
        r = time_inspect(c, dd, method="refined", repeats=repeats)
        print(
            f"{sp:<9}{r['n_points']:>9}{r['n_bars']:>6}{r['wall']:>9.3f}{r['cpu']:>8.3f}"
            f"{r['stages'].get('bars', np.nan):>8.3f}{r['stages'].get('measure', np.nan):>10.3f}"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
