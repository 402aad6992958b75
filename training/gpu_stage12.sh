#!/usr/bin/env bash
# Stage 12 (training/README.md): the stage-11 candidate (candidates/deeplab_fine_w_dr11.onnx)
# continued three ways side by side on one lent GPU, on scenes with the background out of focus
# (--dof) and some near bars soft (--near-blur), composed beside them on the GPU machine's CPUs:
#   s12_w     as stage 11, lower learning rate, longer (NEAR 0.3 instead of 11b's 0.5)
#   s12_wz    the same with more crops enlarged 1-2 x (--zoom 0.5): bars wider than the renders
#             give, as close-up photos show them
#   s12_wx    larger crops (384 px, batch 32) for more of the scene around each bar
# Run from the repository root, the renders made first (training/README.md, stage 11):
#   bash training/gpu_stage12.sh DATA_DIR RUN_DIR MINUTES [OUT_DIR]
# Environment: as gpu_stage9.sh, and SEED (20261201), DOF (0.6), NEAR (0.3), INDOOR (0.4),
# CURVES (0.5), LR (5e-4), WX (1; 0 leaves s12_wx out).
set -uo pipefail
D=${1:-.segdata8}
RUNS=${2:-/tmp/stage12_runs}
MIN=${3:-7}
OUT=${4:-}
WAIT=${WAIT:-30}
SEED=${SEED:-20261201}
DOF=${DOF:-0.6}
NEAR=${NEAR:-0.3}
INDOOR=${INDOOR:-0.4}
CURVES=${CURVES:-0.5}
LR=${LR:-5e-4}
WX=${WX:-1}
source training/gpu_export.sh
$PY training/domain_random.py --work "$DR" --n "$CAP" --seed "$SEED" --hard --indoor "$INDOOR" --curves "$CURVES" \
    --dof "$DOF" --near-blur "$NEAR" --jobs "$JOBS" > "$RUNS/scenes.log" 2>&1 &
GEN=$!
sleep "$WAIT"
T="$PY training/train_segmentation.py train --work $D --minutes $MIN --val-every-s $VAL --device $DEVICE
   --threads 1 --out-dir $RUNS --dr-work $DR --dr-capacity $CAP --dr-share 0.5 --arch deeplab_fine_w
   --init-onnx training/candidates/deeplab_fine_w_dr11.onnx --lr $LR --freeze-bn"
$T --batch "$BATCH" --crop "$CROP" --zoom 0.2 --tag s12_w > "$RUNS/A.log" 2>&1 &
A=$!
$T --batch "$BATCH" --crop "$CROP" --zoom 0.5 --tag s12_wz > "$RUNS/B.log" 2>&1 &
B=$!
TAGS="s12_w s12_wz"
PIDS="$A $B"
if [ "$WX" = 1 ]; then
    $T --batch 32 --crop 384 --zoom 0.3 --tag s12_wx > "$RUNS/C.log" 2>&1 &
    PIDS="$PIDS $!"
    TAGS="$TAGS s12_wx"
fi
# shellcheck disable=SC2086
wait $PIDS
kill $GEN 2>/dev/null
wait $GEN 2>/dev/null
tail -n 2 "$RUNS/scenes.log"
export_and_pack s12_w $TAGS
