#!/usr/bin/env bash
# Stage 6 (training/README.md): three runs of train_segmentation.py side by side on one CUDA GPU,
# then their exports. Run from the repository root, with the data folder rendered first (on any
# machine; 20 min on 2 cores):
#   python training/train_segmentation.py data --work .segdata --extra 200 --relief 100 --relief-val 30 \
#       --relief-label silhouette --relief-full 60 --jobs 2 --jpeg-quality 85 --full-quality 85
# (57.5 MB: with the code, under the 64 MiB that travels to a lent GPU machine).
#
#   bash training/gpu_stage6.sh train  DATA_DIR RUN_DIR MINUTES   # 6.5 min: ~8 min in all
#   bash training/gpu_stage6.sh export DATA_DIR RUN_DIR OUT_DIR    # ~4.5 min on 16 CPU cores
#
# Two steps because the two did not fit in one 10-minute call: the exports choose the threshold
# on the validation split with the test-time flips, on the CPU.
set -uo pipefail
STEP=$1
D=${2:-.segdata}
RUNS=${3:-/tmp/stage6_runs}
export PYTHONUNBUFFERED=1
T="python3 training/train_segmentation.py"
TAGS="stage6_scratch stage6_ft stage6_ft_nocolour"
mkdir -p "$RUNS"
if [ "$STEP" = train ]; then
    MIN=${4:-6.5}
    COMMON="--work $D --arch deeplab_fine --minutes $MIN --batch 48 --crop 256 --zoom 0.5 --full-zoom
            --val-every-s 60 --device cuda --out-dir $RUNS"
    nvidia-smi -L
    python3 -c "import torch, onnx, cv2; print('torch', torch.__version__, 'onnx', onnx.__version__)"
    # from scratch with the colour jitter; from the shipped model (batch norms frozen) with it;
    # the same without it (what the jitter itself changes)
    $T train $COMMON --colour --lr 3e-3 --tag stage6_scratch > "$RUNS/A.log" 2>&1 &
    $T train $COMMON --colour --lr 5e-4 --init-onnx rebarlib/models/rebar_seg.onnx --freeze-bn \
        --tag stage6_ft > "$RUNS/B.log" 2>&1 &
    $T train $COMMON --lr 5e-4 --init-onnx rebarlib/models/rebar_seg.onnx --freeze-bn \
        --tag stage6_ft_nocolour > "$RUNS/C.log" 2>&1 &
    wait
    grep -h "VAL\|parameters\|Error" "$RUNS"/[ABC].log
elif [ "$STEP" = export ]; then
    OUT=${4:?OUT_DIR}
    mkdir -p "$OUT"
    for tag in $TAGS; do
        $T export --work "$D" --arch deeplab_fine --tag $tag --run-dir "$RUNS" --flips h v hv \
            --max-bar-px 40 --out "$OUT" --name $tag > "$RUNS/export_$tag.log" 2>&1 &
    done
    wait
    tail -n 2 "$RUNS"/export_*.log
    tar czf "$OUT/runs.tgz" -C "$RUNS" .
else
    echo "usage: $0 train|export DATA_DIR RUN_DIR MINUTES|OUT_DIR" >&2
    exit 2
fi
