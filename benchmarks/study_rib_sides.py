"""Study: what each edge of a ribbed bar says on its own, on the diameter benchmark's captures.

Two ways to size bars that the widths leave between two sizes were measured with this script and
not adopted (docs/diameters.md, "Each side on its own"):

* **each side's core**: the two edges are read against one straight line fitted to the sections'
  centres along the bar (the axis drops out), and the lower quartile of each side's extent is
  taken. Where a side's transverse ribs stand out (its 90th percentile at least ``--amp`` px
  above its lower quartile), that quartile is the core between its ribs, and the two together
  are the bar's core d1, whatever the two sides' ribs' stagger (which hides the crests from the
  width). Printed: (core - true d1) / h by how far the ribs stand out, and what snapping it to
  the table's d1 would do to the bars left unmeasured;
* **one edge's pitch**: each edge's rib periodicity (``_rib_periodicity``) on its own; printed:
  how often a clear pitch is the bar's size's GB 1499.2 spacing (within 2 %), by its p-value.

Usage (the captures as ``bench_diameter.py`` renders them; ``--cache`` shares its folder)::

    python benchmarks/study_rib_sides.py --ribs relief --mask fused --axes detected --cache DIR
"""

from __future__ import annotations

import argparse
import math
import sys
from pathlib import Path

import numpy as np
import pandas as pd

sys.path.insert(0, str(Path(__file__).resolve().parent))

import bench_diameter as B  # noqa: E402  (the captures, masks and axes the benchmark uses)

import rebarlib.diameter.measure as D  # noqa: E402  (its _refined_bar is wrapped below)
from rebarlib.diameter.barsizes import bar_system, rib_pitch_mm  # noqa: E402
from rebarlib.diameter.params import DiameterParams  # noqa: E402
from rebarlib.diameter.ribs import _rib_periodicity  # noqa: E402
from rebarlib.synth import Appearance  # noqa: E402


def _sides(info, prm):
    """Quantiles of each side's extent about a line through the section centres, and each edge's
    rib periodicity ``(pitch, p)``; None with too few two-edged sections."""
    s, lo, hi = info.edges
    good = np.isfinite(lo) & np.isfinite(hi)
    if good.sum() < prm.rib_min_sections:
        return None
    s, lo, hi = s[good], lo[good], hi[good]
    line = np.polyval(np.polyfit(s, (lo + hi) / 2, 1), s)
    right, left = hi - line, line - lo
    width = float(np.median(hi - lo))
    out = {
        "core": float(np.percentile(right, 25) + np.percentile(left, 25)),
        "amp_px": min(np.percentile(x, 90) - np.percentile(x, 25) for x in (right, left)) / info.px_mm,
    }
    for k, e in (("lo", lo), ("hi", hi)):
        out[k] = _rib_periodicity(s, e - np.polyval(np.polyfit(s, e, 1), s), band=prm.rib_band, width_mm=width)
    return out


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--ribs", default="relief", choices=("envelope", "relief"))
    ap.add_argument("--mask", default="fused")
    ap.add_argument("--axes", default="detected")
    ap.add_argument("--amp", type=float, default=1.0, help="px a side's ribs must stand out by")
    ap.add_argument("--cache", default="")
    ap.add_argument("--quick", action="store_true")
    args = ap.parse_args()
    prm = DiameterParams()
    gb = bar_system("GB1499.2")
    masks, _ = B._mask_sources()
    axes_src, _ = B._axis_sources()
    app = Appearance(rust_fraction=0.3)  # as bench_diameter.py draws them (its cache has no key for it)
    rows = []
    for name, design, kw in B.scenarios(args.quick):
        cap = B._capture(name, design, kw, app, args.cache, relief=args.ribs == "relief")
        m = masks[args.mask](cap, design)
        mask, measured_on = m[:2] if isinstance(m, tuple) else (m, cap)
        bars = axes_src[args.axes](cap, design)
        ids = B._match(bars, cap.truth) if args.axes != "truth" else np.asarray(bars.bar_id, int)
        kept = {}
        orig = D._refined_bar

        def keep(i, bar, *a, **k):
            kept[i] = orig(i, bar, *a, **k)
            return kept[i]

        D._refined_bar = keep
        try:
            t = D.measure_diameters(measured_on, bars, mask, design=design)
        finally:
            D._refined_bar = orig
        truth = {b["id"]: b for b in cap.truth["bars"]}
        for j, tid in enumerate(ids):
            sd = _sides(kept[j], prm) if tid >= 0 and j in kept else None
            if sd is None:
                continue
            true = truth[int(tid)]["diameter_mm"]
            d1 = gb.of_size(gb.core_mm, true)
            rows.append(
                dict(
                    capture=name,
                    true_mm=true,
                    h=(truth[int(tid)]["envelope_mm"] - d1) / 2,
                    d1=d1,
                    status=t.iloc[j].diameter_status,
                    spacing=rib_pitch_mm(true),
                    **sd,
                )
            )
        print(f"{name}: {len(t)} bars", file=sys.stderr, flush=True)
    d = pd.DataFrame(rows)
    pd.set_option("display.width", 200)
    print(
        f"\nEach side's core - true d1 (in rib heights h), by how far the ribs stand out "
        f"({args.mask} mask, {args.axes} axes, ribs {args.ribs})"
    )
    d["err_h"] = (d.core - d.d1) / d.h
    print(d.groupby(pd.cut(d.amp_px, [0, 0.5, 0.75, 1, 1.5, 2, 3, 99])).err_h.describe().round(2).to_string())
    d1s = np.array(gb.core_mm)
    near = np.abs(d.core.to_numpy()[:, None] - d1s[None, :])
    srt = np.sort(near, axis=1)
    d["snap"] = np.array(gb.sizes_mm)[near.argmin(axis=1)]
    d["margin"] = (srt[:, 1] - srt[:, 0]) / (srt[:, 1] + srt[:, 0])  # 0 half-way, 1 on a d1
    print(
        f"\nSnapping each side's core to the table's d1, bars whose ribs stand out >= {args.amp} px "
        "and whose core lies at least this margin from half-way (1 = on a d1)"
    )
    print("margin   bars  right  wrong | not measured: decided  right  wrong")
    for mg in (0.3, 0.5, 0.7):
        x = d[(d.amp_px >= args.amp) & (d.margin >= mg)]
        nm = x[x.status == "not measured"]
        print(
            f"{mg:5.1f}  {len(x):5d}  {(x.snap == x.true_mm).sum():5d}  {(x.snap != x.true_mm).sum():5d} | "
            f"{len(nm):21d}  {(nm.snap == nm.true_mm).sum():5d}  {(nm.snap != nm.true_mm).sum():5d}"
        )
    print("\nOne edge's clear pitch against its size's spacing (2 %), by p-value (each edge a read)")
    reads = pd.DataFrame(
        [(p, abs(q / r.spacing - 1) <= 0.02) for r in d.itertuples() for q, p in (r.lo, r.hi) if math.isfinite(q)],
        columns=["p", "right"],
    )
    bins = pd.cut(reads.p, [0, 1e-12, 1e-8, 1e-6, 1e-4, 1e-2, 1.0])
    print(pd.crosstab(reads.right.map({True: "spacing", False: "other"}).rename("pitch"), bins).to_string())


if __name__ == "__main__":
    main()
