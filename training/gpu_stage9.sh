#!/usr/bin/env bash
# Stage 9 (training/README.md): stage 8 continued. Scenes composed on the GPU machine's CPU cores
# (a new seed, the hard negatives and, in 30 % of them, a room behind the bars: --indoor 0.3)
# while three runs of train_segmentation.py train side by side on its GPU, each started from a
# stage-8 candidate (--init-onnx, batch norms frozen) and mixed with more renders than stage 8 had.
# Run from the repository root, the renders made first (on any machine; they need Open3D):
#   python training/train_segmentation.py data --work .segdata8 --extra 700 --jobs 2 --jpeg-quality 85
#   (stopped when time ran out; split.json then written for the captures rendered, see the README)
#
#   bash training/gpu_stage9.sh DATA_DIR RUN_DIR MINUTES [OUT_DIR]
#
# Environment (for a smoke test on the CPU): PY (python3), DEVICE (cuda), JOBS (scene processes,
# 13), CAP (scenes per run's buffer, 16000), WAIT (seconds of scenes before training, 40), BATCH
# (64), CROP (256), VAL (seconds between validations and snapshots, 50).
set -uo pipefail
D=${1:-.segdata8}
RUNS=${2:-/tmp/stage9_runs}
MIN=${3:-7}
OUT=${4:-}
WAIT=${WAIT:-40}
source training/gpu_export.sh
# the scenes: seed 20261128 (stage 8's was 20261127), hard negatives, rooms in 30 %
$PY training/domain_random.py --work "$DR" --n "$CAP" --seed 20261128 --hard --indoor 0.3 --jobs "$JOBS" \
    > "$RUNS/scenes.log" 2>&1 &
GEN=$!
sleep "$WAIT"
T="$PY training/train_segmentation.py train --work $D --minutes $MIN --batch $BATCH --crop $CROP --zoom 0.2
   --val-every-s $VAL --device $DEVICE --threads 1 --out-dir $RUNS --dr-work $DR --dr-capacity $CAP --freeze-bn"
TAGS="s9_w45 s9_w60 s9_ft"
# the wider stage-8 candidate with 45 % and 60 % scenes a batch; the shipped-size one with 50 %
$T --arch deeplab_fine_w --init-onnx training/candidates/deeplab_fine_w_dr8.onnx --lr 1e-3 --dr-share 0.45 \
    --tag s9_w45 > "$RUNS/A.log" 2>&1 &
A=$!
$T --arch deeplab_fine_w --init-onnx training/candidates/deeplab_fine_w_dr8.onnx --lr 1e-3 --dr-share 0.6 \
    --tag s9_w60 > "$RUNS/B.log" 2>&1 &
B=$!
$T --arch deeplab_fine --init-onnx training/candidates/deeplab_fine_dr8.onnx --lr 5e-4 --dr-share 0.5 \
    --tag s9_ft > "$RUNS/C.log" 2>&1 &
C=$!
wait $A $B $C
kill $GEN 2>/dev/null
wait $GEN 2>/dev/null
tail -n 2 "$RUNS/scenes.log"
# each run's last state exported, its threshold chosen on the validation renders with the flips
export_and_pack s9_w $TAGS
