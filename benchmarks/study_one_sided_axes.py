"""Study: where the axes of bars seen from one edge lie, against the renders' truth.

A lower bar partly under a nearer bar is sized from its one clear edge and its axis
(decision 024). On the verdict benchmark's captures such bars read their mask widths about half a
millimetre under the rib envelope at the median, bars seen whole do not (docs/verdicts.md, "A bar's
depth ending in a nearer bar's shadow"). This script measures, for every bar ``inspect`` reports,
how far its fitted axis lies from the true axis across the bar (in the plane through the axis
square to the line of sight) and along the line of sight, and its width error, grouped by how
the bar was seen, with the depth as it comes and with ``inspect(..., edge_trim_px=1)`` (the
last pixel of every occluding edge left out before the bars are fitted, decision 007), so that
a change of the fit can be judged on both kinds of bar.

Usage (a cache of ``bench_verdicts.py``; its captures with their ``truth.json``)::

    python benchmarks/study_one_sided_axes.py --cache DIR [--slabs 0-59] [--trims 0,1,auto] [--jobs 2]
"""

from __future__ import annotations

import argparse
import json
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np
import pandas as pd


def _truth_match(cap, bars: pd.DataFrame) -> list:
    """Per bar of ``bars``: its offsets (across, along the line of sight; mm) from the visible
    true bar nearest to its axis among those parallel to it (within 8°), and that bar's
    envelope; None where none is parallel or nearer than 20 mm."""
    truth = [b for b in cap.truth["bars"] if b.get("visible")]
    out = []
    for b in bars.itertuples():
        s = np.array([b.start_x_mm, b.start_y_mm, b.start_z_mm])
        e = np.array([b.end_x_mm, b.end_y_mm, b.end_z_mm])
        m, d = (s + e) / 2, (e - s) / np.linalg.norm(e - s)
        ray = m / np.linalg.norm(m)
        across = np.cross(d, ray)
        across /= np.linalg.norm(across)
        best = None
        for t in truth:
            a0, a1 = np.array(t["axis_start_mm"]), np.array(t["axis_end_mm"])
            td = (a1 - a0) / np.linalg.norm(a1 - a0)
            if abs(float(np.dot(td, d))) < np.cos(np.radians(8)):
                continue
            v = m - a0
            perp = v - np.dot(v, td) * td
            if best is None or np.linalg.norm(perp) < np.linalg.norm(best[1]):
                best = (t, perp)
        if best is None or np.linalg.norm(best[1]) > 20:
            out.append(None)
            continue
        t, perp = best
        out.append((float(np.dot(perp, across)), float(np.dot(perp, ray)), float(t["envelope_mm"])))
    return out


def _one(args):
    folder, cap_dir, trims = args
    import rebarlib as R
    from rebarlib._inspect import inspect

    design = R.load_design(Path(folder) / "design.toml")
    cap = R.load_capture(cap_dir)
    rows = []
    for trim in trims:
        res = inspect(cap, design, rng=0, edge_trim_px=None if trim == "auto" else trim)
        bars = res.bars
        for b, m in zip(bars.itertuples(), _truth_match(cap, bars)):
            if m is None or b.status != "measured":
                continue
            off_across, off_ray, env = m
            one = float(b.one_sided_share or 0) >= 0.5
            covered = float(b.occluded_fraction or 0) >= 0.5
            kind = "one edge, under a nearer bar" if one and covered else "one edge" if one else "two edges"
            w = b.width_median_mm
            rows.append(
                {
                    "trim": str(trim),
                    "capture": f"{Path(folder).name}/{Path(cap_dir).name}",
                    "bar": int(b.bar_id),
                    "kind": kind,
                    "across_abs_mm": abs(off_across),
                    "ray_mm": off_ray,
                    "width_err_mm": (w - env) if w == w else np.nan,
                    "status": b.diameter_status,
                    "reason": b.diameter_reason or "",
                }
            )
    return rows


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", required=True, help="a bench_verdicts.py cache")
    ap.add_argument("--slabs", default="0-59", help="first-last slab numbers, clean ones only")
    ap.add_argument("--trims", default="0,1", help="edge_trim_px values to compare ('auto': inspect's default)")
    ap.add_argument("--jobs", type=int, default=2)
    args = ap.parse_args(argv)
    lo, hi = (int(x) for x in args.slabs.split("-"))
    trims = [x if x == "auto" else int(x) for x in args.trims.split(",")]
    jobs = []
    for k in range(lo, hi + 1):
        folder = Path(args.cache) / f"slab_{k:03d}"
        meta = folder / "slab.json"
        if not meta.exists() or json.loads(meta.read_text())["defect"] is not None:
            continue
        for cap_dir in sorted(p for p in folder.iterdir() if p.is_dir() and (p / "truth.json").exists()):
            jobs.append((str(folder), str(cap_dir), trims))
    rows = []
    with ProcessPoolExecutor(args.jobs) as ex:
        for r in ex.map(_one, jobs):
            rows += r
    df = pd.DataFrame(rows)
    print(f"{len(jobs)} captures of clean slabs {args.slabs}; bars matched to the truth and measured\n")
    g = df.groupby(["kind", "trim"])
    table = pd.DataFrame(
        {
            "bars": g.size(),
            "|across| p50 mm": g.across_abs_mm.median(),
            "|across| p90 mm": g.across_abs_mm.quantile(0.9),
            "ray p50 mm": g.ray_mm.median(),
            "width err p50 mm": g.width_err_mm.median(),
            "width err p10 mm": g.width_err_mm.quantile(0.1),
            "sized": g.status.apply(lambda s: int((s == "measured").sum())),
            "mask≠cloud": g.reason.apply(lambda s: int(s.str.contains("disagree").sum())),
        }
    )
    print(table.round(2).to_string())  # tabulate (for to_markdown) is not a dependency
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
