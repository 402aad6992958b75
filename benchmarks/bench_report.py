"""Speed of the acceptance report: the PDF for the four-capture example slab, given the results.

Target (issue 6): the PDF of a four-capture slab in <= 3 s. Only the report is timed (evaluation,
HTML, PDF), never the inspection: the results are read once before timing.

Results come from ``rebarlib._inspect.inspect`` when that stage is installed (``--source
inspect``), else from the captures' ground truth written in the result.json layout
(``--source truth``, the default: the report's speed does not depend on where the numbers came from).

    python benchmarks/bench_report.py            # full: 5 repetitions
    python benchmarks/bench_report.py --quick    # 1 repetition
"""

from __future__ import annotations

import argparse
import json
import math
import os
import statistics
import tempfile
import time
from pathlib import Path

import pypdf

from rebarlib import load_design
from rebarlib.acceptance import evaluate
from rebarlib.report import build_report, find_captures

ROOT = Path(__file__).resolve().parent.parent
TARGET_S = 3.0


def result_from_truth(capture_dir: Path, design) -> dict:
    """A result.json dict with the synthetic capture's ground truth (every 5th bar hidden)."""
    t = json.loads((capture_dir / "truth.json").read_text(encoding="utf-8"))
    n = t["formwork_plane"]["normal"]
    bars = []
    for i, b in enumerate(x for x in t["bars"] if x["visible"]):
        hidden = i % 5 == 4
        rec = {
            "bar_id": b["id"],
            "layer": b["layer"],
            "level": b["level"],
            "plan_angle_deg": b["plan_angle_deg"],
            "visible_length_mm": b["visible_length_mm"],
            "n_points": b["visible_pixels"],
            "status": "measured",
            "reason": "",
            "width_median_mm": None if hidden else b["envelope_mm"],
            "width_spread_mm": None if hidden else 0.5,
            "nominal_mm": None if hidden else b["diameter_mm"],
            "diameter_status": "hidden" if hidden else "measured",
            "diameter_reason": "",
            "design_diameter_mm": b["design_diameter_mm"],
            "hidden": hidden,
        }
        for c, s, e in zip("xyz", b["visible_start_mm"], b["visible_end_mm"]):
            rec[f"start_{c}_mm"], rec[f"end_{c}_mm"] = s, e
        bars.append(rec)
    spacings = []
    for s in t["spacings"]:
        if s["visible"]:
            ds = design.lattice(s["layer"]).level(s["level"]).spacing_mm
            spacings.append(
                {
                    "layer": s["layer"],
                    "level": s["level"],
                    "bar_a": s["bar_a"],
                    "bar_b": s["bar_b"],
                    "spacing_mm": s["spacing_mm"],
                    "design_spacing_mm": ds,
                    "deviation_mm": s["spacing_mm"] - ds,
                    "status": "measured",
                    "reason": "",
                }
            )
    counts = [
        {"layer": la, "level": lv, "found": k, "expected": k, "missing": 0, "extra": 0}
        for la in ("lower", "upper")
        for lv in ("bottom", "top")
        for k in [sum(b["layer"] == la and b["level"] == lv for b in bars)]
    ]

    def m(v):
        return {"value_mm": v, "uncertainty_mm": 0.7, "n_points": 1000, "status": "measured", "reason": ""}

    return {
        "capture": capture_dir.name,
        "method": "truth",
        "measurements": {
            "cover": m(t["cover_mm"]),
            "layer_distance": m(t["layer_distance_mm"]),
            "upper_top": m(t["upper_top_mm"]),
            "top_cover": m(design.thickness_mm - t["upper_top_mm"]),
        },
        "formwork": {"normal": n, "offset_mm": t["formwork_plane"]["offset_mm"]},
        "camera": {"height_mm": t["camera"]["height_mm"], "tilt_deg": math.degrees(math.acos(abs(n[2])))},
        "bars": bars,
        "spacings": spacings,
        "counts": counts,
        "notes": [],
    }


def load_results(slab: Path, design, source: str) -> list:
    caps = find_captures(slab)
    if source == "inspect":
        from rebarlib import load_capture
        from rebarlib._inspect import inspect

        return [inspect(load_capture(c), design, method="refined").to_dict() for c in caps]
    return [result_from_truth(c, design) for c in caps]


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="one repetition")
    ap.add_argument("--slab", default=str(ROOT / "examples" / "paper_slab"))
    ap.add_argument("--source", choices=("truth", "inspect"), default="truth")
    args = ap.parse_args(argv)
    slab = Path(args.slab)
    design = load_design(slab)
    results = load_results(slab, design, args.source)
    reps = 1 if args.quick else 5
    rows = []
    with tempfile.TemporaryDirectory() as tmp:
        build_report(slab, design, evaluate(results, design), out_path=Path(tmp) / "warm.html", format="html")
        for fmt in ("pdf", "html"):
            times, cpu = [], []
            for i in range(reps):
                out = Path(tmp) / f"r{i}.{fmt}"
                t0, c0 = time.perf_counter(), time.process_time()
                acc = evaluate(results, design)
                build_report(slab, design, acc, out_path=out, format=fmt)
                times.append(time.perf_counter() - t0)
                cpu.append(time.process_time() - c0)
            pages = len(pypdf.PdfReader(str(out)).pages) if fmt == "pdf" else "-"
            rows.append(
                (
                    fmt,
                    len(results),
                    pages,
                    out.stat().st_size / 1024,
                    statistics.median(times),
                    max(times),
                    statistics.median(cpu),
                )
            )
    print(
        f"slab {design.slab_id} ({slab.name}), results from {args.source}, {reps} repetition(s); "
        f"timed: evaluate + build_report (+ CSV/JSON exports)"
    )
    print(
        f"load average (1 min) before timing: {os.getloadavg()[0]:.1f} on {os.cpu_count()} CPUs "
        "(wall time grows with other processes' load; CPU time much less)"
    )
    print(
        f"{'format':<7}{'captures':>9}{'pages':>7}{'size KiB':>10}{'wall median s':>15}{'wall max s':>12}"
        f"{'CPU median s':>14}  target (wall)"
    )
    for fmt, n, pages, kib, med, mx, cpu_med in rows:
        verdict = ""
        if fmt == "pdf":
            verdict = f"<= {TARGET_S:g} s: {'yes' if med <= TARGET_S else 'NO'}"
        print(f"{fmt:<7}{n:>9}{pages!s:>7}{kib:>10.0f}{med:>15.2f}{mx:>12.2f}{cpu_med:>14.2f}  {verdict}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
