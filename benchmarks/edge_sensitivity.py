"""How edge-heavy are the segmentation benchmark's subsets? The truth mask grown / shrunk by one
pixel at every edge, scored overall and on the shadow and rust subsets of 20 test captures.

    python benchmarks/edge_sensitivity.py

A mask that is wrong by the same pixel at every edge, wherever the light is, loses more IoU on a
subset whose bar pixels are more often edge pixels: this separates "bars in shadow are harder"
from "the shadow subset is made of bar flanks".
"""
import numpy as np, cv2
from rebarlib import GEMINI2
from rebarlib.segmentation import (DATASET_SEED, DATASET_SIZE, confusion_counts, iou, split_indices,
                                   synth_eval_regions, synth_segmentation_capture)
test = split_indices(DATASET_SIZE, seed=DATASET_SEED)["test"][:20]
k = np.ones((3, 3), np.uint8)
acc = {(m, s): {"TP": 0, "FP": 0, "FN": 0, "TN": 0} for m in ("dilated", "eroded") for s in ("all", "shadow", "rust")}
edge = {"all": [0, 0], "shadow": [0, 0], "rust": [0, 0]}
for i in test:
    cap = synth_segmentation_capture(int(i), seed=DATASET_SEED, intrinsics=GEMINI2)
    t = cap.labels > 0
    reg = synth_eval_regions(int(i), cap, seed=DATASET_SEED); reg["all"] = None
    tu = t.astype(np.uint8)
    d, e = cv2.dilate(tu, k) > 0, cv2.erode(tu, k) > 0
    boundary = t & ~e
    for s in ("all", "shadow", "rust"):
        r = np.ones_like(t) if reg[s] is None else reg[s]
        edge[s][0] += int((boundary & r).sum()); edge[s][1] += int((t & r).sum())
        for m, mk in (("dilated", d), ("eroded", e)):
            c = confusion_counts(mk, t, region=reg[s])
            acc[(m, s)] = {q: acc[(m, s)][q] + c[q] for q in c}
for s in ("all", "shadow", "rust"):
    print(s, "edge-pixel share of bar pixels %.1f %%" % (100 * edge[s][0] / edge[s][1]),
          "IoU dilated 1px %.2f eroded 1px %.2f" % (100 * iou(acc[("dilated", s)]), 100 * iou(acc[("eroded", s)])))
