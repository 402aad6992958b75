#!/usr/bin/env bash
# Stage 14 (training/README.md): wider networks from scratch, for one run a photo without the
# test-time flips in the time the shipped network takes with them; every kind of scene the
# compositor draws (hard negatives, rooms, cables and hair, the background out of focus, bars
# nearer than the focus, bars packed side by side); two runs side by side on one lent GPU, the
# scenes composed beside them on the GPU machine's CPUs:
#   s14_w25   deeplab_fine_w25 (2.5 x the channels of deeplab_fine), from scratch
#   s14_w30   deeplab_fine_w3 (3 x), from scratch
# Run from the repository root, the renders made first (training/README.md, stage 11):
#   bash training/gpu_stage14.sh DATA_DIR RUN_DIR MINUTES [OUT_DIR]
# Environment: as gpu_stage9.sh, and SEED (20261203), DOF (0.6), NEAR (0.3), BUNDLES (0.3),
# INDOOR (0.4), CURVES (0.5), LR (3e-3), SHARE (0.6), FLIPS ("": the threshold chosen without flips).
set -uo pipefail
D=${1:-.segdata8}
RUNS=${2:-/tmp/stage14_runs}
MIN=${3:-7}
OUT=${4:-}
WAIT=${WAIT:-25}
SEED=${SEED:-20261203}
DOF=${DOF:-0.6}
NEAR=${NEAR:-0.3}
BUNDLES=${BUNDLES:-0.3}
INDOOR=${INDOOR:-0.4}
CURVES=${CURVES:-0.5}
LR=${LR:-3e-3}
SHARE=${SHARE:-0.6}
JOBS=${JOBS:-12}
FLIPS=${FLIPS-}
source training/gpu_export.sh
compose_scenes
T="$PY training/train_segmentation.py train --work $D --minutes $MIN --val-every-s $VAL --device $DEVICE
   --threads 1 --out-dir $RUNS --dr-work $DR --dr-capacity $CAP --lr $LR --batch $BATCH --crop $CROP
   --zoom 0.2 --dr-share $SHARE"
$T --arch deeplab_fine_w25 --tag s14_w25 > "$RUNS/A.log" 2>&1 &
A=$!
$T --arch deeplab_fine_w3 --tag s14_w30 > "$RUNS/B.log" 2>&1 &
B=$!
wait $A $B
stop_scenes
export_and_pack s14_ s14_w25 s14_w30
