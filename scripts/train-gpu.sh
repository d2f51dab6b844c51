#!/usr/bin/env bash
# Trains the shipped model further on a GPU machine that has only python3
# with torch 2.11 (as scripts/bench-gpu.sh expects: no compiler, no
# network), within a time limit, and leaves the weights as files small
# enough to carry back (at most 16 MiB each), which `matseg eval` then
# scores on any machine:
#   scripts/train-gpu.sh MATSEG OUT
# MATSEG  `cargo build --release -p matseg-cli --features cuda` (docs/gpu.md).
# OUT     a new folder: run.json, metrics.jsonl, loss.png, the 16-bit weights
#         in parts (model.half.safetensors.part-00, -01, ...) and their SHA-256.
# Run it from the repository root (the bundled assets, the shipped model and
# the fetched corpus, when there is one, are read from there and the cache).
# It trains `matseg train --online --device cuda` from models/default, with
# the shipped model's recipe (the encoder at a tenth of the head's learning
# rate, the colour part at a hundred times) on the paper's batch plan
# (sides 224..768, ~1 MP, 2-7 images), with 3D renders mixed in when MIX
# names a dataset, for STEPS steps (default 4000) or TIME_LIMIT seconds
# (default 480), whichever comes first: the run is stopped at its last
# checkpoint (every CHECKPOINT steps, default 250) and that one is kept.
# Back on the 2-core machine:
#   cat OUT/model.half.safetensors.part-* > RUN/model.safetensors
#   (cd OUT && sha256sum -c SHA256SUMS) && cp OUT/run.json RUN/
#   matseg eval points benchmarks/real-dev --model RUN
# PLAN_ARGS replaces the batch plan (e.g. "--min-side 64 --max-side 96
# --batch-pixels 20000"); DEVICE=cpu with small STEPS and PLAN_ARGS tries the
# whole script on a machine with no GPU.
set -euo pipefail
if (($# != 2)); then
    sed -n '2,/^set /p' "$0" | sed '$d; s/^# \{0,1\}//' >&2
    exit 2
fi
MATSEG=$(realpath "$1")
OUT=$2
PY=${PYTHON:-python3}
DEVICE=${DEVICE:-cuda}
STEPS=${STEPS:-4000}
TIME_LIMIT=${TIME_LIMIT:-480}
CHECKPOINT=${CHECKPOINT:-250}
PART_BYTES=$((15 * 1024 * 1024))
if [ -e "$OUT" ]; then
    echo "train-gpu.sh: $OUT exists; give a new folder" >&2
    exit 2
fi
torch_lib=$("$PY" -c 'import os, torch; print(os.path.join(os.path.dirname(torch.__file__), "lib"))')
export LD_LIBRARY_PATH=$torch_lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
export MATSEG_ASSETS=$PWD/assets MATSEG_DEFAULT_MODEL=$PWD/models/default
echo "$(nproc) cores; $("$MATSEG" --version); device $DEVICE"

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
run=$work/run
# shellcheck disable=SC2206
plan=(${PLAN_ARGS:-})
mix=()
if [ -n "${MIX:-}" ]; then
    mix=(--mix-data "$MIX" --mix-fraction "${MIX_FRACTION:-0.3}")
fi
# The run stops at the limit (SIGINT, as a user's Ctrl-C); its last
# checkpoint is a complete run folder.
set +e
timeout --signal INT "$TIME_LIMIT" "$MATSEG" train --online --device "$DEVICE" --out "$run" \
    --init default --encoder-features --colour-features \
    --lr-scale encoder.=0.1 --lr-scale colour.=100 --lr 1e-4 --warmup 100 \
    --steps "$STEPS" --checkpoint-every "$CHECKPOINT" --validation-batches 4 \
    --inference-side 700,448,256,128 --seed 21 "${plan[@]}" "${mix[@]}" 2>"$work/log"
status=$?
set -e
if ((status != 0 && status != 124)) && ! grep -q '"step"' "$run/metrics.jsonl" 2>/dev/null; then
    cat "$work/log" >&2
    exit "$status"
fi
if [ ! -f "$run/checkpoint.safetensors" ]; then
    echo "train-gpu.sh: stopped before the first checkpoint (step $CHECKPOINT); lower CHECKPOINT" >&2
    exit 1
fi
trained=$("$PY" -c 'import json, sys; print(max(json.loads(l)["step"] for l in open(sys.argv[1])) + 1)' \
    "$run/metrics.jsonl")
echo "trained $trained steps (limit $STEPS steps, $TIME_LIMIT s; exit $status)"

mkdir -p "$OUT"
"$MATSEG" weights half "$run/model.safetensors" --out "$work/half.safetensors" >/dev/null
split -b "$PART_BYTES" -d -a 2 "$work/half.safetensors" "$OUT/model.half.safetensors.part-"
# The kept checkpoint's metrics: the steps up to it.
"$PY" - "$run/metrics.jsonl" "$OUT/metrics.jsonl" <<'EOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
last = max(r["step"] for r in rows if "validation" in r)
with open(sys.argv[2], "w") as f:
    for r in rows:
        if r["step"] <= last:
            f.write(json.dumps(r) + "\n")
seen = [r for r in rows if r["step"] <= last]
seconds = sum(r["seconds"] for r in seen)
images = sum(r["images"] for r in seen)
print(f"kept step {last + 1}: {images} images in {seconds:.0f} s of steps ({images / max(seconds, 1e-9):.1f} images/s), "
      f"held-out loss {[round(r['validation'], 4) for r in seen if 'validation' in r]}")
EOF
cp "$run/run.json" "$run/loss.png" "$OUT/"
(cd "$OUT" && sha256sum model.half.safetensors.part-* >SHA256SUMS)
echo "the joined weights: $(sha256sum <"$work/half.safetensors" | cut -d' ' -f1)"
ls -l "$OUT"
