"""How edge-heavy are the segmentation benchmark's subsets? The truth mask grown / shrunk by one
pixel at every edge, scored overall and on the shadow, rust and unlit subsets of 20 test captures.

    python benchmarks/edge_sensitivity.py

A mask that is wrong by the same pixel at every edge, wherever the light is, loses more IoU on a
subset whose bar pixels are more often edge pixels: this separates "bars in shadow are harder"
from "the subset is made of bar flanks" (the unlit subset: every bar's self-shaded side).
"""

from __future__ import annotations

import cv2
import numpy as np

from bench_segmentation import _add, _zero
from rebarlib import GEMINI2
from rebarlib.segmentation import confusion_counts, iou
from rebarlib.synth_segmentation import (
    DATASET_SEED,
    DATASET_SIZE,
    split_indices,
    synth_eval_regions,
    synth_segmentation_capture,
)

SUBSETS = ("all", "shadow", "rust", "unlit")
N_CAPTURES = 20


def main() -> None:
    kernel = np.ones((3, 3), np.uint8)
    counts = {(m, s): _zero() for m in ("dilated", "eroded") for s in SUBSETS}
    edge = {s: [0, 0] for s in SUBSETS}  # edge pixels, bar pixels
    for i in split_indices(DATASET_SIZE, seed=DATASET_SEED)["test"][:N_CAPTURES]:
        cap = synth_segmentation_capture(int(i), seed=DATASET_SEED, intrinsics=GEMINI2)
        truth = cap.labels > 0
        regions = {**synth_eval_regions(int(i), cap, seed=DATASET_SEED), "all": None}
        grown = cv2.dilate(truth.astype(np.uint8), kernel) > 0
        shrunk = cv2.erode(truth.astype(np.uint8), kernel) > 0
        for s in SUBSETS:
            inside = np.ones_like(truth) if regions[s] is None else regions[s]
            edge[s][0] += int((truth & ~shrunk & inside).sum())
            edge[s][1] += int((truth & inside).sum())
            for m, mask in (("dilated", grown), ("eroded", shrunk)):
                counts[(m, s)] = _add(counts[(m, s)], confusion_counts(mask, truth, region=regions[s]))
    for s in SUBSETS:
        print(
            f"{s}: edge-pixel share of bar pixels {100 * edge[s][0] / edge[s][1]:.1f} %, IoU of the truth "
            f"dilated 1 px {100 * iou(counts[('dilated', s)]):.2f}, "
            f"eroded 1 px {100 * iou(counts[('eroded', s)]):.2f}"
        )


if __name__ == "__main__":
    main()
