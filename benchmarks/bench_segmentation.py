"""Segmentation benchmark: the paper's Table 3 for our models on the held-out synthetic test split.

Regenerates the test split from its seeds with rebarlib.synth (no torch, no files needed beyond
the ONNX models), at the sensor's full 1280 x 800 resolution, and prints

1. Table 3: Pixel Accuracy, IoU and Dice of the rebar class (method.md formulas; confusion
   counts summed over the split) for every model;
2. the hard cases: the same on the shadow subset (bar pixels in a cast shadow, grown by 3 px)
   and the rust subset (pixels of rusty bars, grown by 3 px), and the gap to the overall figure
   (the issue's target: at most 3 points); also on every unlit pixel (cast shadows plus the
   self-shaded side of every bar: an edge-dominated subset, see ``synth_eval_regions``);
3. colour-only vs depth-only vs fused masks (every model, on the whole image and on
   full-resolution tiles; ``fuse_masks`` with the colour probability and the depth validity),
   overall and on the subsets;
4. inference speed: median ms for one 1280 x 800 image (resize, network, full-resolution mask).

    python benchmarks/bench_segmentation.py            # the 60 test captures
    python benchmarks/bench_segmentation.py --quick    # 8 of them
    python benchmarks/bench_segmentation.py --ribs relief --count 20   # 20, ribs in relief

``--ribs relief`` renders the same scenes with the bars' ribs in relief (real bars are ribbed;
the default draws them as their smooth envelope), about 10 x slower to render, and scores the
masks against each bar's outline over its ribs (the same scene's labels with smooth envelopes),
the region the models are trained to mark and the diameter stage measures (training/README.md).

Models: the shipped ``rebarlib/models/rebar_seg.onnx`` and every ``training/candidates/*.onnx``
(the architectures it was compared with), or those given with ``--models``.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path

import numpy as np

from rebarlib import GEMINI2
from rebarlib.segmentation import (
    SegmentationModel,
    confusion_counts,
    dice,
    fuse_masks,
    iou,
    mask_from_depth,
    pixel_accuracy,
)
from rebarlib.synth_segmentation import (
    DATASET_SEED,
    DATASET_SIZE,
    split_indices,
    synth_eval_regions,
    synth_segmentation_capture,
)

ROOT = Path(__file__).resolve().parents[1]
KEYS = ("TP", "FP", "FN", "TN")


def _add(a, b):
    return {k: a[k] + b[k] for k in KEYS}


def _zero():
    return dict.fromkeys(KEYS, 0)


def _pct(x):
    return f"{100 * x:6.2f}" if np.isfinite(x) else "   n/a"


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--quick", action="store_true", help="8 test captures instead of 60")
    ap.add_argument("--count", type=int, default=None, help="the first N test captures")
    ap.add_argument(
        "--ribs",
        choices=["envelope", "relief"],
        default="envelope",
        help="bars drawn with their smooth rib envelope (default) or their ribs in relief",
    )
    ap.add_argument("--models", nargs="*", help="ONNX files (sidecar next to each)")
    ap.add_argument("--threads", type=int, default=2, help="onnxruntime threads (default 2)")
    ap.add_argument("--scale", type=float, default=1.0, help="render scale of the test captures")
    ap.add_argument("--speed-runs", type=int, default=20)
    args = ap.parse_args(argv)

    paths = (
        [Path(p) for p in args.models]
        if args.models
        else [ROOT / "rebarlib" / "models" / "rebar_seg.onnx"]
        + sorted((ROOT / "training" / "candidates").glob("*.onnx"))
    )
    models = {}
    for p in paths:
        m = SegmentationModel(p, threads=args.threads)
        arch = m.spec.get("model", {}).get("architecture", "?")
        models[f"{p.stem} ({arch})"] = m
    shipped = next(iter(models))
    test = split_indices(DATASET_SIZE, seed=DATASET_SEED)["test"]
    if args.quick or args.count:
        test = test[: args.count or 8]
    relief = args.ribs == "relief"
    intr = GEMINI2.scaled(args.scale) if args.scale != 1.0 else GEMINI2
    print(
        f"# Segmentation benchmark: {len(test)} held-out test captures (data set seed {DATASET_SEED}, "
        f"{DATASET_SIZE} captures split 6:2:2), {intr.width} x {intr.height}, ribs {args.ribs}, "
        f"onnxruntime threads {args.threads}, cpu count {os.cpu_count()}"
    )
    subsets = ("all", "shadow", "rust", "unlit")
    hard = ("shadow", "rust")  # the subsets (gap target)
    counts = {name: {s: _zero() for s in subsets} for name in models}
    # "tiles": a model on full-resolution tiles of the image (predict_proba(tiled=True)), as the
    # refined diameter stage runs it; every model's masks, the depth mask's once
    kinds = ("colour", "fused", "colour, tiles", "fused, tiles")
    sources = ["depth"] + [f"{k} ({name})" if len(models) > 1 else k for name in models for k in kinds]
    fused_counts = {src: {s: _zero() for s in subsets} for src in sources}
    share = {s: [0, 0] for s in subsets[1:]}
    t0 = time.time()
    for n, i in enumerate(test):
        cap = synth_segmentation_capture(int(i), seed=DATASET_SEED, intrinsics=intr, rib_relief=relief)
        truth = (synth_segmentation_capture(int(i), seed=DATASET_SEED, intrinsics=intr) if relief else cap).labels > 0
        regions = synth_eval_regions(int(i), cap, seed=DATASET_SEED, rib_relief=relief)
        regions["all"] = None
        for s in subsets[1:]:
            share[s][0] += int((regions[s] & truth).sum())
            share[s][1] += int(truth.sum())
        masks = {}
        for name, m in models.items():
            masks[name] = m.predict_mask(cap.color)
            for s in subsets:
                counts[name][s] = _add(counts[name][s], confusion_counts(masks[name], truth, region=regions[s]))
        dmask = mask_from_depth(cap, rng=0)
        got = [dmask]
        for name, m in models.items():
            fmask = fuse_masks(masks[name], dmask, color_proba=m.predict_proba(cap.color), depth_valid=cap.depth_mm > 0)
            p_tiles = m.predict_proba(cap.color, tiled=True)
            c_tiles = p_tiles > m.threshold
            f_tiles = fuse_masks(c_tiles, dmask, color_proba=p_tiles, depth_valid=cap.depth_mm > 0)
            got += [masks[name], fmask, c_tiles, f_tiles]
        for src, mk in zip(sources, got):
            for s in subsets:
                fused_counts[src][s] = _add(fused_counts[src][s], confusion_counts(mk, truth, region=regions[s]))
        print(f"  capture {n + 1}/{len(test)} (index {i}) done, {time.time() - t0:.0f} s", file=sys.stderr, flush=True)

    print("\n## Table 3 (held-out synthetic test split; rebar class; %)\n")
    print("| model | PA % | IoU % | Dice % |")
    print("|---|---:|---:|---:|")
    for name in models:
        c = counts[name]["all"]
        print(f"| {name} | {_pct(pixel_accuracy(c))} | {_pct(iou(c))} | {_pct(dice(c))} |")
    print("| paper K-Net (site images, for reference) | 97.90 | 93.40 | 96.50 |")

    print(
        "\n## Hard cases: shadow (bars in a cast shadow + 3 px), rust (rusty bars + 3 px); "
        "unlit (no direct sun, incl. every bar's self-shaded side)\n"
    )
    print(
        "Share of bar pixels in the subsets: "
        + ", ".join(f"{s} {100 * share[s][0] / max(share[s][1], 1):.1f} %" for s in subsets[1:])
        + "\n"
    )
    print(
        "| model | "
        + " | ".join(f"IoU {s}" for s in subsets)
        + " | "
        + " | ".join(f"Dice {s}" for s in subsets)
        + " | worst IoU gap shadow/rust (pts) | unlit gap (pts) |"
    )
    print("|---|" + "---:|" * (2 * len(subsets) + 2))
    for name in models:
        c = counts[name]
        ious = [iou(c[s]) for s in subsets]
        dices = [dice(c[s]) for s in subsets]
        gap = 100 * (ious[0] - min(iou(c[s]) for s in hard))
        print(
            f"| {name} | "
            + " | ".join(_pct(v) for v in ious + dices)
            + f" | {gap:5.2f} | {100 * (ious[0] - iou(c['unlit'])):5.2f} |"
        )

    print("\n## Colour vs depth vs fused masks (IoU %" + (f", model {shipped}" if len(models) == 1 else "") + ")\n")
    print("| mask | " + " | ".join(f"IoU {s}" for s in subsets) + " | Dice all |")
    print("|---|" + "---:|" * (len(subsets) + 1))
    for src in sources:
        c = fused_counts[src]
        print(f"| {src} | " + " | ".join(_pct(iou(c[s])) for s in subsets) + f" | {_pct(dice(c['all']))} |")

    print(f"\n## Speed: one 1280 x 800 colour image -> full-resolution mask ({args.threads} threads)\n")
    print("| model | median ms | p90 ms | ONNX size KB |")
    print("|---|---:|---:|---:|")
    img = synth_segmentation_capture(int(test[0]), seed=DATASET_SEED, intrinsics=GEMINI2).color
    for name, m in models.items():
        m.predict_mask(img)  # warm-up
        ts = []
        for _ in range(args.speed_runs):
            t = time.perf_counter()
            m.predict_mask(img)
            ts.append(1000 * (time.perf_counter() - t))
        size_kib = m.onnx_path.stat().st_size / 1024
        print(f"| {name} | {np.median(ts):7.1f} | {np.percentile(ts, 90):7.1f} | {size_kib:7.0f} |")
    m = models[shipped]
    ts = []
    for _ in range(args.speed_runs):
        t = time.perf_counter()
        _ = m.predict_proba(img, tiled=True) > m.threshold
        ts.append(1000 * (time.perf_counter() - t))
    print(f"| {shipped}, full-resolution tiles | {np.median(ts):7.1f} | {np.percentile(ts, 90):7.1f} | |")
    print(f"\n(total {time.time() - t0:.0f} s)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
