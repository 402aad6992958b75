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
import os
import statistics
import tempfile
import time
from pathlib import Path

import pypdf

from rebarlib import load_design
from rebarlib.acceptance import evaluate
from rebarlib.report import build_report, find_captures
from rebarlib.synth import result_from_truth as synth_result_from_truth

ROOT = Path(__file__).resolve().parent.parent
TARGET_S = 3.0


def result_from_truth(capture_dir: Path, design) -> dict:
    """A result.json dict with the synthetic capture's ground truth (every 5th bar hidden)."""
    return synth_result_from_truth(capture_dir, design, hide_every=5)


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
