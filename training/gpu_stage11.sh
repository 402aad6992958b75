#!/usr/bin/env bash
# Stage 11 (training/README.md): the stage-10 candidates continued on scenes whose background is
# out of focus behind cages, starter bars and rooms (domain_random.py --dof), as a photo taken
# from close and focused on the bars shows it. Scenes composed on the GPU machine's CPU cores
# while three runs train side by side on its GPU:
#   s11_w     the wider network from deeplab_fine_w_dr10, batch norms frozen (as stages 8-10)
#   s11_wc    the same with colour jitter beyond the renderer's palette (--colour)
#   s11_ft    the shipped-size network from deeplab_fine_dr9, batch norms frozen
# Run from the repository root, the renders made first (on any machine; they need Open3D):
#   python training/train_segmentation.py data --work .segdata8 --extra 700 --jobs 2 --jpeg-quality 85
#   (stopped when time ran out; split.json then lists the captures rendered, see the README)
#
#   bash training/gpu_stage11.sh DATA_DIR RUN_DIR MINUTES [OUT_DIR]
#
# Environment: as gpu_stage9.sh (PY, DEVICE, JOBS, CAP, WAIT, BATCH, CROP, VAL), and SEED (scenes'
# seed, 20261130), DOF (share of cage, starter and room scenes out of focus, 0.6), INDOOR (share
# of scenes with a room, 0.4), CURVES (share with thick cables and long hair, 0.5).
set -uo pipefail
D=${1:-.segdata8}
RUNS=${2:-/tmp/stage11_runs}
MIN=${3:-7}
OUT=${4:-}
WAIT=${WAIT:-40}
SEED=${SEED:-20261130}
DOF=${DOF:-0.6}
INDOOR=${INDOOR:-0.4}
CURVES=${CURVES:-0.5}
source training/gpu_export.sh
$PY training/domain_random.py --work "$DR" --n "$CAP" --seed "$SEED" --hard --indoor "$INDOOR" --curves "$CURVES" \
    --dof "$DOF" --jobs "$JOBS" > "$RUNS/scenes.log" 2>&1 &
GEN=$!
sleep "$WAIT"
T="$PY training/train_segmentation.py train --work $D --minutes $MIN --batch $BATCH --crop $CROP --zoom 0.2
   --val-every-s $VAL --device $DEVICE --threads 1 --out-dir $RUNS --dr-work $DR --dr-capacity $CAP --dr-share 0.5"
$T --arch deeplab_fine_w --init-onnx training/candidates/deeplab_fine_w_dr10.onnx --lr 1e-3 --freeze-bn \
    --tag s11_w > "$RUNS/A.log" 2>&1 &
A=$!
$T --arch deeplab_fine_w --init-onnx training/candidates/deeplab_fine_w_dr10.onnx --lr 1e-3 --freeze-bn \
    --colour --tag s11_wc > "$RUNS/B.log" 2>&1 &
B=$!
$T --arch deeplab_fine --init-onnx training/candidates/deeplab_fine_dr9.onnx --lr 5e-4 --freeze-bn \
    --tag s11_ft > "$RUNS/C.log" 2>&1 &
C=$!
wait $A $B $C
kill $GEN 2>/dev/null
wait $GEN 2>/dev/null
tail -n 2 "$RUNS/scenes.log"
export_and_pack s11_w s11_w s11_wc s11_ft
