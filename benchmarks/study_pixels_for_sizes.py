"""How often a bar is sized, by the gap its camera's pixels put between its size's rib envelope and
its neighbour's: read from the saved results of verdict-benchmark caches (``bench_verdicts.py
--cache DIR``), no inspection run.

    python benchmarks/study_pixels_for_sizes.py --cache /tmp/verdicts --cache /tmp/verdicts_held_out

For every bar of every capture saved in the caches (bars hidden under nearer bars left out: no
camera distance uncovers them), the gap ``f · Δ / z``: ``f`` the capture's focal length in pixels
(the geometric mean of fx and fy, its camera.json), ``Δ`` the smaller gap between the bar's design
size's envelope and its neighbours' (``rebarlib.diameter.closer.envelope_gap_mm``), ``z`` the
depth of the bar's seen middle. Prints, per band of that gap (a quarter pixel wide), the bars, the
share sized, the share left unsized by their widths (``closer.WIDTH_REASONS``: between two sizes,
the mask and cloud widths disagreeing, the mask widths scattered) and the share unsized for
another reason. ``CloserParams.min_gap_px`` is read from this table (docs/capturing.md,
docs/decisions/063).
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from collections import Counter, defaultdict
from pathlib import Path


def _rows(cache: Path):
    import rebarlib as R
    from rebarlib.diameter.closer import WIDTH_REASONS, envelope_gap_mm

    for slab in sorted(cache.glob("slab_*")):
        system = R.load_design(slab / "design.toml").bar_system
        for res in sorted(slab.glob("result_*.json")):
            cap = slab / res.stem[len("result_") :]
            cam_file = cap / "camera.json"
            if not cam_file.exists():
                continue
            k = json.loads(cam_file.read_text(encoding="utf-8"))["intrinsic_matrix"]
            focal = math.sqrt(float(k[0]) * float(k[4]))
            for b in json.loads(res.read_text(encoding="utf-8")).get("bars", []):
                reason = str(b.get("diameter_reason") or "")
                if b.get("diameter_status") == "hidden" or reason.startswith("hidden"):
                    continue
                z = 0.5 * (float(b["start_z_mm"]) + float(b["end_z_mm"]))
                d = b.get("design_diameter_mm")
                if d is None or not (z > 0):
                    continue
                gap = envelope_gap_mm(float(d), system=system)
                if not math.isfinite(gap):
                    continue
                if b.get("diameter_status") == "measured":
                    kind = "sized"
                elif reason.startswith(WIDTH_REASONS):
                    kind = "width"
                else:
                    kind = "other"
                yield focal * gap / z, kind


def main(argv=None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cache", action="append", required=True, help="a bench_verdicts.py cache (repeatable)")
    ap.add_argument("--band", type=float, default=0.25, help="width of a band of the gap, px (default 0.25)")
    args = ap.parse_args(argv)
    bands: dict = defaultdict(Counter)
    for c in args.cache:
        cache = Path(c)
        if not cache.is_dir():
            raise SystemExit(f"--cache {c}: not a folder")
        for gap, kind in _rows(cache):
            bands[math.floor(gap / args.band) * args.band][kind] += 1
    if not bands:
        raise SystemExit("no saved results with camera.json in the caches given")
    print("| envelopes apart, px | bars | sized | unsized by their widths | unsized otherwise |")
    print("|---|---:|---:|---:|---:|")
    for lo in sorted(bands):
        c = bands[lo]
        n = sum(c.values())
        print(
            f"| {lo:.2f}–{lo + args.band:.2f} | {n} | {c['sized'] / n:.1%} | {c['width'] / n:.1%} | "
            f"{c['other'] / n:.1%} |"
        )
    return 0


if __name__ == "__main__":
    sys.exit(main())
