#!/usr/bin/env bash
# Stage 8 (training/README.md): domain-randomised scenes composed on the GPU machine's CPU cores
# while three runs of train_segmentation.py train side by side on its GPU, each loading the
# scenes as they are written (--dr-capacity), mixed with the renders of DATA_DIR.
# Run from the repository root, the renders made first (on any machine; they need Open3D):
#   python training/train_segmentation.py data --work .segdata --extra 200 --jobs 2 --jpeg-quality 85
#
#   bash training/gpu_stage8.sh DATA_DIR RUN_DIR MINUTES [OUT_DIR]
#
# Environment (for a smoke test on the CPU): PY (python3), DEVICE (cuda), JOBS (scene processes,
# 13), CAP (scenes per run's buffer, 16000), WAIT (seconds of scenes before training, 45), BATCH
# (64), CROP (256), VAL (seconds between validations and snapshots, 50).
# OUT_DIR: one archive a run (its log, snapshots and export) and one of the logs.
set -uo pipefail
D=${1:-.segdata}
RUNS=${2:-/tmp/stage8_runs}
MIN=${3:-6.5}
OUT=${4:-}
WAIT=${WAIT:-45}
source training/gpu_export.sh
# the scenes: seed 20261127 (stage 7's was 20261126), with the hard negatives
$PY training/domain_random.py --work "$DR" --n "$CAP" --seed 20261127 --hard --jobs "$JOBS" > "$RUNS/scenes.log" 2>&1 &
GEN=$!
sleep "$WAIT"
T="$PY training/train_segmentation.py train --work $D --minutes $MIN --batch $BATCH --crop $CROP --zoom 0.2
   --val-every-s $VAL --device $DEVICE --threads 1 --out-dir $RUNS --dr-work $DR --dr-capacity $CAP"
INIT="--init-onnx rebarlib/models/rebar_seg.onnx --freeze-bn"
if [ -z "${CONTINUE:-}" ]; then
    # from the shipped model, half of each batch scenes; the same with 70 % scenes and a higher
    # learning rate; the 1.5 x wider network from scratch, 60 % scenes
    TAGS="s8_ft50 s8_ft70 s8_w"
    $T --arch deeplab_fine $INIT --lr 5e-4 --dr-share 0.5 --tag s8_ft50 > "$RUNS/A.log" 2>&1 &
    A=$!
    $T --arch deeplab_fine $INIT --lr 1e-3 --dr-share 0.7 --tag s8_ft70 > "$RUNS/B.log" 2>&1 &
    B=$!
    $T --arch deeplab_fine_w --lr 3e-3 --dr-share 0.6 --tag s8_w > "$RUNS/C.log" 2>&1 &
    C=$!
else
    # CONTINUE=STATE_DICT: a second, short run of the wider network from that state, with more
    # renders in each batch (35 % scenes), for the synthetic captures it had lost
    TAGS="s8_w2"
    $T --arch deeplab_fine_w --init "$CONTINUE" --lr 1e-3 --dr-share 0.35 --tag s8_w2 > "$RUNS/D.log" 2>&1 &
    A=$!
    B= C=
fi
wait $A $B $C
kill $GEN 2>/dev/null
wait $GEN 2>/dev/null
tail -n 2 "$RUNS/scenes.log"
# each run's last state exported, its threshold chosen on the validation renders with the flips
export_and_pack s8_w $TAGS
