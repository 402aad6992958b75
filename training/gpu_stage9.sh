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
# The next stage with the same script (training/README.md, "Stage 10"): SEED (scenes' seed,
# 20261128), CURVES (share of scenes with thick cables and long hair, 0), INIT_W and INIT_FT (the
# wider and the shipped-size networks to start from, the stage-8 candidates).
set -uo pipefail
D=${1:-.segdata8}
RUNS=${2:-/tmp/stage9_runs}
MIN=${3:-7}
OUT=${4:-}
WAIT=${WAIT:-40}
SEED=${SEED:-20261128}
CURVES=${CURVES:-0}
INIT_W=${INIT_W:-training/candidates/deeplab_fine_w_dr8.onnx}
INIT_FT=${INIT_FT:-training/candidates/deeplab_fine_dr8.onnx}
source training/gpu_export.sh
# the scenes: seed 20261128 (stage 8's was 20261127), hard negatives, rooms in 30 %
$PY training/domain_random.py --work "$DR" --n "$CAP" --seed "$SEED" --hard --indoor 0.3 --curves "$CURVES" --jobs "$JOBS" \
    > "$RUNS/scenes.log" 2>&1 &
GEN=$!
sleep "$WAIT"
T="$PY training/train_segmentation.py train --work $D --minutes $MIN --batch $BATCH --crop $CROP --zoom 0.2
   --val-every-s $VAL --device $DEVICE --threads 1 --out-dir $RUNS --dr-work $DR --dr-capacity $CAP --freeze-bn"
TAGS="s9_w45 s9_w60 s9_ft"
# the wider stage-8 candidate with 45 % and 60 % scenes a batch; the shipped-size one with 50 %
$T --arch deeplab_fine_w --init-onnx "$INIT_W" --lr 1e-3 --dr-share 0.45 \
    --tag s9_w45 > "$RUNS/A.log" 2>&1 &
A=$!
$T --arch deeplab_fine_w --init-onnx "$INIT_W" --lr 1e-3 --dr-share 0.6 \
    --tag s9_w60 > "$RUNS/B.log" 2>&1 &
B=$!
$T --arch deeplab_fine --init-onnx "$INIT_FT" --lr 5e-4 --dr-share 0.5 \
    --tag s9_ft > "$RUNS/C.log" 2>&1 &
C=$!
wait $A $B $C
kill $GEN 2>/dev/null
wait $GEN 2>/dev/null
tail -n 2 "$RUNS/scenes.log"
# each run's last state exported, its threshold chosen on the validation renders with the flips
export_and_pack s9_w $TAGS
