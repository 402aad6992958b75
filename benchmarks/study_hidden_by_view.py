"""Which captures leave a lower-lattice position hidden under an upper bar, by the camera's tilt
and height: read from the saved results and truths of verdict-benchmark caches
(``bench_verdicts.py --cache DIR``), no inspection run.

    python benchmarks/study_hidden_by_view.py --cache /tmp/vd_f --cache /tmp/vd_new

Prints, per band of tilt (the optical axis from straight down) and of camera height, the
captures, the share with at least one position "not measured" for being hidden under another
bar, and the mean count of such positions per capture (docs/capturing.md).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path

import numpy as np


def _rows(cache: Path):
    for slab in sorted(cache.glob("slab_*")):
        spec = json.loads((slab / "slab.json").read_text(encoding="utf-8"))
        for cap in spec["captures"]:
            res, truth = slab / f"result_{cap}.json", slab / cap / "truth.json"
            if not (res.exists() and truth.exists()):
                continue
            r = json.loads(res.read_text(encoding="utf-8"))
            cam = json.loads(truth.read_text(encoding="utf-8"))["camera"]
            # the camera's z axis in the world (slab) frame is the third row of world->camera;
            # straight down is (0, 0, -1)
            tilt = math.degrees(math.acos(max(-1.0, min(1.0, -cam["rotation_world_to_camera"][2][2]))))
            hidden = sum(
                1
                for p in r.get("positions", [])
                if p.get("status") == "not measured" and "hidden under" in (p.get("reason") or "")
            )
            yield tilt, float(cam["height_mm"]), hidden


def _table(a, col, edges, label, unit):
    print(f"| {label} | captures | with a hidden position | hidden positions per capture |")
    print("|---|---:|---:|---:|")
    for lo, hi in zip(edges[:-1], edges[1:]):
        m = (a[:, col] >= lo) & (a[:, col] < hi)
        if not m.any():
            continue
        print(f"| {lo:g}–{hi:g} {unit} | {int(m.sum())} | {100 * np.mean(a[m, 2] > 0):.0f} % | {a[m, 2].mean():.2f} |")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", action="append", required=True, help="a bench_verdicts.py cache (repeatable)")
    args = ap.parse_args(argv)
    rows = []
    for c in args.cache:
        path = Path(c)
        if not path.is_dir():
            sys.exit(f"--cache {c}: not a folder (expected a bench_verdicts.py --cache folder)")
        rows += list(_rows(path))
    if not rows:
        sys.exit("no saved results with truths in the caches given")
    a = np.asarray(rows, float)
    print(f"# {len(a)} captures from {len(args.cache)} cache(s)\n")
    _table(a, 0, [0, 2, 7, 12, 17, 25], "tilt", "°")
    print()
    _table(a, 1, [350, 450, 550, 650, 750], "height", "mm")


if __name__ == "__main__":
    main()
