#!/usr/bin/env bash
# Stage 13 (training/README.md): the stage-11 candidate (candidates/deeplab_fine_w_dr11.onnx)
# continued on scenes where some bars come packed side by side (--bundles: a cage's side seen at
# a slant, bundled bars, laps), as the `lab` photos' bars the network missed are; two runs side
# by side on one lent GPU, the scenes composed beside them on the GPU machine's CPUs:
#   s13_b     half of each batch from those scenes (as stages 11 and 12)
#   s13_bd    70 % of each batch from them
# Run from the repository root, the renders made first (training/README.md, stage 11):
#   bash training/gpu_stage13.sh DATA_DIR RUN_DIR MINUTES [OUT_DIR]
# Environment: as gpu_stage9.sh, and SEED (20261202), BUNDLES (0.5), DOF (0.6), NEAR (0.3),
# INDOOR (0.4), CURVES (0.5), LR (5e-4).
set -uo pipefail
D=${1:-.segdata8}
RUNS=${2:-/tmp/stage13_runs}
MIN=${3:-6}
OUT=${4:-}
WAIT=${WAIT:-25}
SEED=${SEED:-20261202}
BUNDLES=${BUNDLES:-0.5}
DOF=${DOF:-0.6}
NEAR=${NEAR:-0.3}
INDOOR=${INDOOR:-0.4}
CURVES=${CURVES:-0.5}
LR=${LR:-5e-4}
JOBS=${JOBS:-12}
source training/gpu_export.sh
compose_scenes
T="$PY training/train_segmentation.py train --work $D --minutes $MIN --val-every-s $VAL --device $DEVICE
   --threads 1 --out-dir $RUNS --dr-work $DR --dr-capacity $CAP --arch deeplab_fine_w
   --init-onnx training/candidates/deeplab_fine_w_dr11.onnx --lr $LR --freeze-bn --batch $BATCH --crop $CROP
   --zoom 0.2"
$T --dr-share 0.5 --tag s13_b > "$RUNS/A.log" 2>&1 &
A=$!
$T --dr-share 0.7 --tag s13_bd > "$RUNS/B.log" 2>&1 &
B=$!
wait $A $B
stop_scenes
export_and_pack s13_b s13_b s13_bd
