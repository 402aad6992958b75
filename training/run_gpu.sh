#!/usr/bin/env bash
# The GPU training run behind the shipped model: the candidate networks trained side by side on
# one GPU for MINUTES each, from the data set rendered by `train_segmentation.py data`.
#   bash training/run_gpu.sh WORK OUT [MINUTES]
# WORK holds data/ and split.json; OUT receives runs.tar.gz (state dicts, logs, run JSONs).
set -u
WORK=${1:?data folder}; OUT=${2:?output folder}; MIN=${3:-8}
PY=${PYTHON:-python3}
mkdir -p "$OUT/runs"
nvidia-smi -L || true
$PY -c "import torch, cv2; print('torch', torch.__version__, 'cuda', torch.cuda.is_available(), 'cv2', cv2.__version__)"
run() {  # tag arch [extra args]
  local tag=$1 arch=$2; shift 2
  $PY -u training/train_segmentation.py train --work "$WORK" --arch "$arch" --minutes "$MIN" \
      --batch 32 --crop 256 --lr 3e-3 --val-every-s 60 --device cuda --tag "$tag" \
      --out-dir "$OUT/runs" "$@" > "$OUT/runs/$tag.log" 2>&1
}
run gpu_deeplab deeplab &
run gpu_deeplab_fine deeplab_fine &
run gpu_deeplab_fine_w deeplab_fine_w &
run gpu_unet unet &
wait
grep -h "VAL final\|parameters\|Error\|error" "$OUT"/runs/*.log
tar -C "$OUT" -czf "$OUT/runs.tar.gz" runs && rm -r "$OUT/runs"
