"""Scanned clouds on the synthetic scanner: bars found, phantoms, spacing, layer distance, cover, speed.

Each case scans a synthetic mesh (the paper_slab design: 2 m x 2 m, two lattices of 14/12 mm bars at
200 mm, cover 20, layer distance 85) from three stations 2.5 m round it and 1.5 m up, with range
noise sigma, and inspects the cloud with ``rebarlib.inspect_cloud`` (up found). "dense" samples
0.06 deg in azimuth and elevation; "sparse" 0.24 deg in azimuth (4x fewer returns along one
direction, as on a scanner turning fast) with a station 4 m off (so density varies about 10x
across the cloud). Targets (issue 58): spacing max |err| <= 5 mm at sigma 15 mm, layer distance
<= 5 mm, every bar with >= 100 mm scanned found, no phantom, <= 5 s for 1 M points on 2 cores.

``--up-sign``: scans with neither formwork nor normals (3 stations, 0.1 deg steps), each as it is
and turned upside down; whether ``inspect_cloud`` guesses the mesh's up side from the crossings.

Usage: ``python benchmarks/bench_scan.py [--seeds 2] [--first-seed 0] [--sigmas 5 10 15 20] [--no-speed]
[--no-formwork] [--diameters] [--up-sign]``
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

import numpy as np
import pandas as pd

from rebarlib import RebarInputError, load_design
from rebarlib.scan import inspect_cloud
from rebarlib.synth_scan import ScannerModel, Station, ring_stations, score_scan, synth_scan

DESIGN = Path(__file__).resolve().parent.parent / "examples" / "paper_slab" / "design.toml"


def _stations(kind: str):
    if kind == "dense":
        return ring_stations(3)
    return ring_stations(2) + [Station((4000.0, -1500.0, 1500.0))]


def run_case(design, sigma, kind, seed, formwork=True) -> dict:
    """One scan inspected and scored. A case whose inspection raises
    :class:`~rebarlib.RebarInputError` (a cloud it cannot read as a two-lattice mesh) is a row with
    ``failed`` set to the reason and every scanned bar counted as missed: one such case does not
    abort the run, and the summary counts it."""
    step_az = 0.06 if kind == "dense" else 0.24
    scanner = ScannerModel(range_sigma_mm=sigma, step_az_deg=step_az, step_el_deg=0.06)
    pts, truth, _ = synth_scan(design, stations=_stations(kind), scanner=scanner, formwork=formwork, rng=seed)
    t = time.perf_counter()
    try:
        res = inspect_cloud(pts, design)
    except RebarInputError as e:
        return _failed_row(sigma, kind, formwork, seed, len(pts), truth, str(e), time.perf_counter() - t)
    dt = time.perf_counter() - t
    s = score_scan(res, truth)
    return {
        "sigma_mm": sigma,
        "sampling": kind,
        "formwork": formwork,
        "seed": seed,
        "failed": "",
        "points": len(pts),
        "scanned": s["scanned"],
        "found": s["found"],
        "missed": s["missed"],
        "phantoms": s["phantoms"],
        "spacing_max_abs_err_mm": s["spacing_max_abs_err_mm"],
        # spacings "not measured" (a bar at the scan's edge whose section may be cut): not in the
        # error, so counted here
        "spacings_not_measured": int((res.spacings["status"] != "measured").sum()),
        "layer_distance_err_mm": s["layer_distance_err_mm"],
        "cover_err_mm": s["cover_err_mm"],
        "time_s": dt,
    }


def _failed_row(sigma, kind, formwork, seed, n_points, truth, reason, dt) -> dict:
    """The row of a case whose inspection raised: nothing found, every scanned bar missed (as
    :func:`score_scan` counts them: at least 100 mm covered by returns)."""
    scanned = sum(truth.scanned_mm.get(b.id, 0.0) >= 100.0 for b in truth.scene.bars)
    return {
        "sigma_mm": sigma,
        "sampling": kind,
        "formwork": formwork,
        "seed": seed,
        "failed": f"failed: {reason}",
        "points": n_points,
        "scanned": scanned,
        "found": 0,
        "missed": scanned,
        "phantoms": 0,
        "spacing_max_abs_err_mm": np.nan,
        "spacings_not_measured": 0,
        "layer_distance_err_mm": np.nan,
        "cover_err_mm": np.nan,
        "time_s": dt,
    }


def _nanmax_abs(x) -> float:
    x = np.abs(np.asarray(x, float))
    return float(np.nanmax(x)) if np.isfinite(x).any() else np.nan


def speed(design, n_target: int = 1_000_000) -> dict:
    scanner = ScannerModel(range_sigma_mm=10.0, step_az_deg=0.042, step_el_deg=0.042)
    pts, truth, _ = synth_scan(design, scanner=scanner, rng=7)
    times, cpu = [], []
    load = os.getloadavg()[0]  # the machine's queue sets the wall time: printed with it
    for _ in range(3):
        t, c = time.perf_counter(), time.process_time()
        res = inspect_cloud(pts, design)
        times.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    s = score_scan(res, truth)
    return {
        "points": len(pts),
        "median_time_s": float(np.median(times)),
        "median_cpu_s": float(np.median(cpu)),
        "missed": s["missed"],
        "phantoms": s["phantoms"],
        "load": (load, os.getloadavg()[0]),
    }


def up_sign(design, sigmas, seeds) -> pd.DataFrame:
    """Up guessed without formwork or normals (from the crossings), each scan as it is and upside
    down (y and z negated): right or not, and the layer distance's error."""
    rows = []
    for sg in sigmas:
        for seed in seeds:
            scanner = ScannerModel(range_sigma_mm=sg, step_az_deg=0.1, step_el_deg=0.1)
            pts, truth, _ = synth_scan(design, scanner=scanner, formwork=False, rng=seed)
            for flip in (False, True):
                res = inspect_cloud(pts * np.array([1.0, -1.0, -1.0]) if flip else pts, design)
                ld = res.layer_distance
                rows.append(
                    {
                        "sigma_mm": sg,
                        "seed": seed,
                        "upside_down": flip,
                        "right": bool((res.extras["cloud"]["up"][2] < 0) == flip),
                        "layer_distance_err_mm": ld.value_mm - truth.layer_distance_mm if ld.ok else None,
                    }
                )
    return pd.DataFrame(rows)


def diameters(design, sigmas=(0.3, 1.0)) -> pd.DataFrame:
    """Bars sized from fine scans (0.05 deg steps), and how many got the design size."""
    want = {"lower": design.lower.bottom.diameter_mm, "upper": design.upper.bottom.diameter_mm}
    rows = []
    for sg in sigmas:
        scanner = ScannerModel(range_sigma_mm=sg, step_az_deg=0.05, step_el_deg=0.05, mixed_fraction=0.2)
        pts, _, _ = synth_scan(design, scanner=scanner, rng=0)
        bars = inspect_cloud(pts, design).bars
        sized = bars[bars["diameter_status"] == "measured"]
        right = sized["nominal_mm"] == sized["layer"].map(want)
        wrong_conf = sized.loc[~right, "confidence"]
        rows.append(
            {
                "sigma_mm": sg,
                "bars": len(bars),
                "sized": len(sized),
                "right": int(right.sum()),
                "wrong": int((~right).sum()),
                "wrong_max_confidence": float(wrong_conf.max()) if len(wrong_conf) else None,
            }
        )
    return pd.DataFrame(rows)


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--seeds", type=int, default=2)
    ap.add_argument("--first-seed", type=int, default=0, help="seeds first-seed ... first-seed + seeds - 1")
    ap.add_argument("--up-sign", action="store_true", help="only the up side guessed without formwork or normals")
    ap.add_argument("--sigmas", type=float, nargs="+", default=[5.0, 10.0, 15.0, 20.0])
    ap.add_argument("--no-speed", action="store_true")
    ap.add_argument("--no-formwork", action="store_true", help="scan the mesh with nothing under it")
    ap.add_argument("--diameters", action="store_true", help="also size bars on fine scans (sigma 0.3, 1 mm)")
    args = ap.parse_args(argv)
    design = load_design(DESIGN)
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    pd.set_option("display.width", 200)
    if args.up_sign:
        df = up_sign(design, args.sigmas, seeds)
        print(df.round(2).to_string(index=False))
        print("\nright:", df.groupby("sigma_mm")["right"].agg(lambda x: f"{int(x.sum())} of {len(x)}").to_string())
        return 0
    rows = [
        run_case(design, sg, kind, seed, formwork=not args.no_formwork)
        for sg in args.sigmas
        for kind in ("dense", "sparse")
        for seed in seeds
    ]
    df = pd.DataFrame(rows)
    print(df.drop(columns="failed").round(2).to_string(index=False))
    for r in df[df["failed"] != ""].itertuples():
        print(f"sigma {r.sigma_mm:g} {r.sampling} seed {r.seed}: {r.failed}")
    agg = df.groupby(["sigma_mm", "sampling"]).agg(
        failed=("failed", lambda x: int((x != "").sum())),
        missed=("missed", "sum"),
        phantoms=("phantoms", "sum"),
        spacing_max=("spacing_max_abs_err_mm", "max"),
        not_measured=("spacings_not_measured", "sum"),
        ld_max=("layer_distance_err_mm", _nanmax_abs),
        cover_max=("cover_err_mm", _nanmax_abs),
        time_s=("time_s", "median"),
    )
    print(
        "\nworst per case (max |err| in mm; sums of failed cases, of missed/phantom bars (a failed case's "
        "scanned bars all missed) and of spacings not measured):"
    )
    print(agg.round(2).to_string())
    if args.diameters:
        print("\nbar sizes on fine scans (design: lower 14, upper 12 mm):")
        print(diameters(design).to_string(index=False))
    if not args.no_speed:
        sp = speed(design)
        print(
            f"\nspeed: {sp['points']:,} points, inspect_cloud median of 3: {sp['median_time_s']:.2f} s wall, "
            f"{sp['median_cpu_s']:.2f} s CPU (missed {sp['missed']}, phantoms {sp['phantoms']}; "
            f"load average {sp['load'][0]:.1f} before, {sp['load'][1]:.1f} after)"
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
