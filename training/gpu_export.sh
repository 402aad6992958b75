# Sourced by the gpu_stage*.sh scripts (set D, RUNS, MIN, OUT and WAIT first): the settings every
# GPU training call shares, from the environment, and the end of the call.
#   DEVICE (cuda), JOBS (scene processes, 13), CAP (scenes per run's buffer, 16000), BATCH (64),
#   CROP (256), VAL (seconds between validations and snapshots, 50), PY (python3), FLIPS (the
#   test-time flips the export's threshold is chosen with, "h v hv")
DEVICE=${DEVICE:-cuda}
JOBS=${JOBS:-13}
CAP=${CAP:-16000}
BATCH=${BATCH:-64}
CROP=${CROP:-256}
VAL=${VAL:-50}
PY=${PY:-python3}
FLIPS=${FLIPS-h v hv}  # empty: no flips
export PYTHONUNBUFFERED=1 OMP_NUM_THREADS=1
DR=$RUNS/scenes
mkdir -p "$RUNS" "$DR"
[ "$DEVICE" = cuda ] && nvidia-smi -L
$PY -c "import torch, onnx, cv2; print('torch', torch.__version__, 'onnx', onnx.__version__, 'cv2', cv2.__version__)"

#   compose_scenes / stop_scenes   (uses PY, DR, CAP, JOBS, RUNS, WAIT and SEED, INDOOR, CURVES,
#   DOF, NEAR, BUNDLES): every kind of scene the compositor draws, composed on the machine's
#   CPUs beside the training runs (which load them as they are written); compose_scenes gives
#   the composer WAIT seconds' start, stop_scenes ends it once the runs are done.
compose_scenes() {
    $PY training/domain_random.py --work "$DR" --n "$CAP" --seed "$SEED" --hard --indoor "$INDOOR" \
        --curves "$CURVES" --dof "$DOF" --near-blur "$NEAR" --bundles "$BUNDLES" --jobs "$JOBS" \
        > "$RUNS/scenes.log" 2>&1 &
    GEN=$!
    sleep "$WAIT"
}
stop_scenes() {
    kill $GEN 2>/dev/null
    wait $GEN 2>/dev/null
    tail -n 2 "$RUNS/scenes.log"
}

#   export_and_pack WIDE_PREFIX TAG...   (uses PY, D, RUNS, DEVICE, OUT and the A/B/C/D logs)
# Prints the runs' validations, exports each run's last state (its threshold chosen on the
# validation renders with the flips, logits on $DEVICE; a tag starting with WIDE_PREFIX is the
# wider deeplab_fine_w) and, with OUT set, packs one archive a run (each under the 16 MiB a file
# that comes back from the GPU machine may be) and one of the logs and the first scenes.
export_and_pack() {
    local wide=$1 tag arch
    shift
    grep -h "VAL\|parameters\|scenes at\|Error\|error\|Traceback" "$RUNS"/[ABCD].log
    for tag in "$@"; do
        arch=deeplab_fine
        [ "${tag:0:${#wide}}" = "$wide" ] && arch=deeplab_fine_w
        # the run's own log names its architecture (stage 14 on)
        [ -f "$RUNS/$tag.json" ] && arch=$($PY -c "import json,sys; print(json.load(open(sys.argv[1]))['arch'])" "$RUNS/$tag.json")
        $PY training/train_segmentation.py export --work "$D" --arch $arch --run-dir "$RUNS" \
            --tag "$(cat "$RUNS/${tag}_last.txt")" --dynamic --flips $FLIPS --device "$DEVICE" \
            --out "$RUNS/onnx" --name "$tag" > "$RUNS/export_$tag.log" 2>&1 &
    done
    wait
    tail -q -n 1 "$RUNS"/export_*.log
    if [ -n "$OUT" ]; then
        mkdir -p "$OUT"
        for tag in "$@"; do
            # the run's best state and its latest snapshots, as many as keep the archive under
            # 14 MB (a wider network's snapshots are larger)
            (cd "$RUNS" && tar czf "$OUT/$tag.tgz" "$tag.json" "onnx/$tag.onnx" "onnx/$tag.json" "$tag.pt" \
                $(ls -t "${tag}"_it*.pt | head -n $((14000000 / $(stat -c %s "$tag.pt") - 2))))
        done
        (cd "$RUNS" && tar czf "$OUT/logs.tgz" ./*.log scenes/dr/000[0-4]?.jpg scenes/dr/000[0-4]?.png)
        ls -la "$OUT"
    fi
}
