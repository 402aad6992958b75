#!/usr/bin/env bash
# Stage 11b (training/README.md): stage 11's wider network (candidates/deeplab_fine_w_dr11.onnx)
# continued for a short while on scenes where, besides the background out of focus, some bars of
# a cage or of starter bars are nearer than the focus (domain_random.py --near-blur): soft, no
# ribs, labelled by their footprint. One run on a lent GPU, the scenes composed beside it.
#   bash training/gpu_stage11b.sh DATA_DIR RUN_DIR MINUTES [OUT_DIR]
# Environment: as gpu_stage9.sh, and SEED (20261131), DOF (0.6), NEAR (0.5), INDOOR (0.4),
# CURVES (0.5), LR (5e-4).
set -uo pipefail
D=${1:-.segdata8}
RUNS=${2:-/tmp/stage11b_runs}
MIN=${3:-2}
OUT=${4:-}
WAIT=${WAIT:-20}
SEED=${SEED:-20261131}
DOF=${DOF:-0.6}
NEAR=${NEAR:-0.5}
INDOOR=${INDOOR:-0.4}
CURVES=${CURVES:-0.5}
LR=${LR:-5e-4}
source training/gpu_export.sh
$PY training/domain_random.py --work "$DR" --n "$CAP" --seed "$SEED" --hard --indoor "$INDOOR" --curves "$CURVES" \
    --dof "$DOF" --near-blur "$NEAR" --jobs "$JOBS" > "$RUNS/scenes.log" 2>&1 &
GEN=$!
sleep "$WAIT"
$PY training/train_segmentation.py train --work "$D" --minutes "$MIN" --batch "$BATCH" --crop "$CROP" --zoom 0.2 \
    --val-every-s "$VAL" --device "$DEVICE" --threads 1 --out-dir "$RUNS" --dr-work "$DR" --dr-capacity "$CAP" \
    --dr-share 0.5 --arch deeplab_fine_w --init-onnx training/candidates/deeplab_fine_w_dr11.onnx --lr "$LR" \
    --freeze-bn --tag s11b_w > "$RUNS/A.log" 2>&1
kill $GEN 2>/dev/null
wait $GEN 2>/dev/null
tail -n 2 "$RUNS/scenes.log"
export_and_pack s11b_w s11b_w
