"""Heavy depth dropout: are the heights of a capture still right, or honestly "not measured"?

    python benchmarks/bench_dropout.py                  # 50-99 %, random and in patches, 4 captures
    python benchmarks/bench_dropout.py --quick          # 90 % only, random, 2 captures
    python benchmarks/bench_dropout.py --method paper

Each example capture of ``examples/paper_slab`` loses a fraction of its depth pixels
(``rebarlib.synth.dropout_mask``: each pixel on its own, or in blobs of ``patch`` px) and is
inspected (diameters off). A measured height (cover, layer distance, top of the upper lattice)
counts as *off* when it is further from the truth than K_SIGMA times its stated uncertainty plus
SLACK_MM. The table gives, per fraction and patch size: runs, how many of each height were
measured, how many measured heights were off (the target is 0), and the range of the layer
split's height over the runs that found one (it must lie between the lattices: above the lower
lattice's top, about 50 mm, and below the upper lattice's underside, about 105 mm).
"""

from __future__ import annotations

import argparse
import dataclasses
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
K_SIGMA, SLACK_MM = 3.0, 0.5
HEIGHTS = ("cover", "layer_distance", "upper_top")


def run_one(cap, design, fraction: float, patch_px: float, seed: int, method: str) -> dict:
    """Inspect ``cap`` with ``fraction`` of its depth dropped; per height: "off", "ok" or "nm",
    and ``"split"``: the layer split's height (None when none was found)."""
    from rebarlib import RebarInputError, inspect
    from rebarlib.synth import dropout_mask

    depth = cap.depth_mm.copy()
    depth[dropout_mask(depth > 0, fraction, patch_px, rng=seed)] = 0
    try:
        res = inspect(dataclasses.replace(cap, depth_mm=depth), design, method=method, diameters=False, rng=seed)
    except RebarInputError:
        return {**{h: "nm" for h in HEIGHTS}, "split": None}
    out = {"split": res.extras.get("layer_split_mm")}
    for h in HEIGHTS:
        m, truth = getattr(res, h), cap.truth[f"{h}_mm"]
        if not m.ok:
            out[h] = "nm"
        else:
            u = m.uncertainty_mm if m.uncertainty_mm is not None else 0.0
            out[h] = "off" if abs(m.value_mm - truth) > K_SIGMA * u + SLACK_MM else "ok"
    return out


def main(argv=None) -> int:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--fractions", default="0.5,0.7,0.8,0.88,0.9,0.92,0.95,0.99")
    p.add_argument("--patches", default="0,8,40", help="patch sizes in px (0 = each pixel on its own)")
    p.add_argument("--seeds", type=int, default=2)
    p.add_argument("--captures", default="A_400,B_500,C_600,D_500")
    p.add_argument("--method", choices=("refined", "paper"), default="refined")
    p.add_argument("--quick", action="store_true", help="90 %% random dropout on A_400 and B_500, one seed")
    args = p.parse_args(argv)
    if args.quick:
        args.fractions, args.patches, args.seeds, args.captures = "0.9", "0", 1, "A_400,B_500"
    from rebarlib import load_capture, load_design

    slab = ROOT / "examples" / "paper_slab"
    design = load_design(slab / "design.toml")
    caps = [load_capture(slab / n) for n in args.captures.split(",")]
    print(f"method {args.method}; off = further than {K_SIGMA:g} sigma + {SLACK_MM} mm from the truth")
    print(f"{'dropout':>8} {'patch':>5} {'runs':>4} | {'cover':>5} {'layer':>5} {'top':>5} measured | off | split mm")
    total_off = 0
    for fraction in (float(x) for x in args.fractions.split(",")):
        for patch in (float(x) for x in args.patches.split(",")):
            rows = [run_one(c, design, fraction, patch, seed, args.method) for seed in range(args.seeds) for c in caps]
            measured = [sum(r[h] != "nm" for r in rows) for h in HEIGHTS]
            off = sum(r[h] == "off" for r in rows for h in HEIGHTS)
            total_off += off
            splits = [r["split"] for r in rows if r["split"] is not None]
            span = f"{min(splits):.0f}-{max(splits):.0f} ({len(splits)} found)" if splits else "none found"
            print(
                f"{fraction:>8.0%} {patch:>5.0f} {len(rows):>4} | {measured[0]:>5} {measured[1]:>5} "
                f"{measured[2]:>5}          | {off:>3} | {span}",
                flush=True,
            )
    print(f"measured heights off: {total_off}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
