#!/usr/bin/env bash
# Stage 5 of the shipped model (training/README.md): train on a CUDA machine, two candidate
# networks side by side on one GPU, then export both with test-time flips. Needs python3 with
# torch, onnx and opencv (the train and export steps do not import rebarlib); the data set is
# rendered beforehand, where Open3D is, by `train_segmentation.py data`.
#
#   bash training/train_gpu.sh WORK OUT MINUTES
#
# WORK: the rendered data set (split.json, data/); OUT: where the state dicts, logs and the
# exported ONNX models go; MINUTES: wall-clock training budget of each run.
set -euo pipefail
work=${1:?data set folder}
out=${2:?output folder}
minutes=${3:-7}
mkdir -p "$out"
here=$(dirname "$0")
for arch in deeplab_fine deeplab_fine_w; do
    python3 "$here/train_segmentation.py" train --work "$work" --arch "$arch" --minutes "$minutes" \
        --batch 32 --crop 256 --zoom 0.5 --lr 3e-3 --val-every-s 45 --device cuda --out-dir "$out" \
        --tag "${arch}_stage5" > "$out/${arch}_stage5.log" 2>&1 &
done
wait
for arch in deeplab_fine deeplab_fine_w; do
    python3 "$here/train_segmentation.py" export --work "$work" --arch "$arch" --tag "${arch}_stage5" \
        --run-dir "$out" --flips h v hv --max-bar-px 40 --out "$out" --name "${arch}_stage5" >> "$out/${arch}_stage5.log" 2>&1 &
done
wait
tail -n 4 "$out"/*.log
