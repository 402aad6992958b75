"""Run every benchmark script's quick mode and print a table of what ran (``make bench``).

    python benchmarks/run_all.py                 # every bench_*.py, quick modes
    python benchmarks/run_all.py --only geometry,report
    python benchmarks/run_all.py --full          # the full runs (tens of minutes each)
    python benchmarks/run_all.py --list

A script runs as ``python benchmarks/bench_<name>.py --quick`` when it has a ``--quick`` option,
else with the arguments in ``QUICK_ARGS`` (or none). Each script's own output is printed as it
comes; the table at the end gives each one's exit status and wall time. The studies
(``stress_sensors.py``, ``edge_sensitivity.py``, ``study_rib_sides.py``) are not benchmarks with a
quick mode and are run by hand. Exits 1 if any script failed.
"""

from __future__ import annotations

import argparse
import subprocess
import sys
import time
from pathlib import Path

HERE = Path(__file__).resolve().parent

#: Arguments that make a script without ``--quick`` short.
QUICK_ARGS = {
    "synth": ["--repeats", "1"],
    "batch": ["--n", "4", "--repeats", "1", "--jobs", "1"],
    "scan": ["--seeds", "1", "--sigmas", "10", "--no-speed"],
    "verdicts": ["--slabs", "2", "--jobs", "1"],
}


def discover() -> dict[str, Path]:
    """The benchmark scripts, by short name (``bench_geometry.py`` -> ``geometry``).

    Returns
    -------
    dict
        Short name -> path, sorted by name.
    """
    return {p.stem.removeprefix("bench_"): p for p in sorted(HERE.glob("bench_*.py"))}


def quick_args(name: str, path: Path) -> list[str]:
    """The arguments of a script's quick run.

    Parameters
    ----------
    name : the script's short name
    path : the script

    Returns
    -------
    list of str
        ``["--quick"]`` where the script has that option, else ``QUICK_ARGS.get(name, [])``.
    """
    if name in QUICK_ARGS:
        return list(QUICK_ARGS[name])
    return ["--quick"] if '"--quick"' in path.read_text(encoding="utf-8") else []


def run(path: Path, args: list[str]) -> tuple[int, float]:
    """Run one script from the repository root, its output going straight to ours.

    Returns
    -------
    tuple
        (exit status, wall time in seconds)
    """
    start = time.perf_counter()
    rc = subprocess.call([sys.executable, str(path), *args], cwd=HERE.parent)
    return rc, time.perf_counter() - start


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--only", default="", help="comma-separated short names (geometry,report,...)")
    ap.add_argument("--full", action="store_true", help="full runs instead of quick modes")
    ap.add_argument("--list", action="store_true", help="list the scripts and their quick arguments")
    args = ap.parse_args(argv)
    scripts = discover()
    if args.only:
        wanted = [s.strip() for s in args.only.split(",") if s.strip()]
        unknown = [w for w in wanted if w not in scripts]
        if unknown:
            ap.error(f"--only: no benchmark named {', '.join(unknown)} (have: {', '.join(scripts)})")
        scripts = {w: scripts[w] for w in wanted}
    if args.list:
        for name, path in scripts.items():
            print(f"{name:14s} {path.name} {' '.join(quick_args(name, path))}")
        return 0
    rows = []
    for name, path in scripts.items():
        extra = [] if args.full else quick_args(name, path)
        print(f"\n=== {path.name} {' '.join(extra)}", flush=True)
        rc, wall = run(path, extra)
        rows.append((path.name, " ".join(extra), rc, wall))
    print("\n| script | arguments | exit | wall s |\n|---|---|---:|---:|")
    for script, extra, rc, wall in rows:
        print(f"| {script} | {extra} | {rc} | {wall:.1f} |")
    return 1 if any(rc != 0 for _, _, rc, _ in rows) else 0


if __name__ == "__main__":
    sys.exit(main())
