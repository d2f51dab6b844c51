#!/usr/bin/env bash
# The figures that need an NVIDIA GPU (BENCHMARKS.md "The net on a GPU",
# docs/scale-out.md), in one run on a GPU machine from two files built on
# any x86-64 Linux machine, with nothing to compile or download there:
#   scripts/bench-gpu.sh WHEEL MATSEG [PART...]
# WHEEL   the Python package built with libtorch:
#         `MATURIN_PEP517_ARGS="--features torch" .venv/bin/pip wheel --no-deps ./python -w DIR`;
# MATSEG  `cargo build --release -p matseg-cli --features cuda` (docs/gpu.md).
# The machine's python3 (PYTHON) must hold torch 2.11 with CUDA and numpy;
# the wheel goes into a temporary folder on PYTHONPATH and both programs
# use that torch's libraries. Run it from the repository root (the bundled
# assets and the shipped model are read from there).
# PARTs, in the order given (default: train generate):
#   train     training images/s, from the shipped model, of `python -m
#             matseg.train --device cuda` (one process, and DDP over every
#             GPU under torchrun when there are several) and of `matseg
#             train --online --device cuda` on the same batches: STEPS_FIXED
#             steps of fixed 4 x 512² batches, then STEPS_PLAN steps of the
#             paper's batch plan; per run the whole run's rate (start-up
#             included) and the steady rate (steps after the first SKIP,
#             from metrics.jsonl) with the share of it spent waiting for
#             batches. DataLoader workers and loader threads: all cores but two.
#   generate  scripts/bench-scale-out.sh with one job per core.
#   net       the per-encoder table: `matseg bench-net` against
#             scripts/bench-net-pytorch.py, alternating, each row a fresh
#             process, the median of REPEATS timings after 3 untimed ones.
# DEVICE=cpu (with small STEPS_*) tries the whole script on a machine with no GPU.
set -euo pipefail
if (($# < 2)); then
    sed -n '2,/^set /p' "$0" | sed '$d; s/^# \{0,1\}//' >&2
    exit 2
fi
WHEEL=$(realpath "$1")
MATSEG=$(realpath "$2")
shift 2
PARTS=("$@")
((${#PARTS[@]})) || PARTS=(train generate)
PY=${PYTHON:-python3}
DEVICE=${DEVICE:-cuda}
STEPS_FIXED=${STEPS_FIXED:-200}
STEPS_PLAN=${STEPS_PLAN:-300}
SKIP=${SKIP:-20}
REPEATS=${REPEATS:-10}
CORES=$(nproc)
LOADERS=$((CORES > 2 ? CORES - 2 : 1))

work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
"$PY" -m pip install --quiet --no-index --no-deps --no-compile --disable-pip-version-check \
    --target "$work/site" "$WHEEL"
export PYTHONPATH=$work/site${PYTHONPATH:+:$PYTHONPATH}
torch_lib=$("$PY" -c 'import os, torch; print(os.path.join(os.path.dirname(torch.__file__), "lib"))')
export LD_LIBRARY_PATH=$torch_lib${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}
export MATSEG_ASSETS=$PWD/assets MATSEG_DEFAULT_MODEL=$PWD/models/default
"$PY" - "$DEVICE" <<'EOF'
import sys, torch
if not torch.__version__.startswith("2.11"):
    sys.exit(f"bench-gpu.sh: torch {torch.__version__} here; the matseg programs need 2.11")
if sys.argv[1] == "cuda" and not torch.cuda.is_available():
    sys.exit("bench-gpu.sh: torch sees no CUDA device here")
gpus = [torch.cuda.get_device_name(i) for i in range(torch.cuda.device_count())]
print(f"torch {torch.__version__}, {len(gpus)} GPU(s) {gpus}, driver CUDA {torch.version.cuda}")
EOF
echo "$(nproc) cores; $("$MATSEG" --version)"
gpus=$("$PY" -c 'import torch; print(torch.cuda.device_count())')

# The rates of a run folder whose run took WALL seconds: its whole run's
# (all images of metrics.jsonl over WALL) and the steady one (steps after
# the first SKIP, from their own times), with the share spent waiting for
# batches.
rates() {
    "$PY" - "$1/metrics.jsonl" "$2" "$SKIP" <<'EOF'
import json, sys
rows = [json.loads(l) for l in open(sys.argv[1])]
wall, steady = float(sys.argv[2]), rows[int(sys.argv[3]):]
seconds = sum(r["seconds"] for r in steady)
print(f"{sum(r['images'] for r in rows) / wall:.1f} images/s whole run ({wall:.1f} s); "
      f"{sum(r['images'] for r in steady) / seconds:.1f} images/s steady over {len(steady)} steps, "
      f"{100 * sum(r['data_seconds'] for r in steady) / seconds:.1f}% waiting for batches")
EOF
}

# Runs a trainer command writing RUN; prints LABEL and its rates.
train_run() {
    local label=$1 out=$2
    shift 2
    rm -rf "$out"
    local start end
    start=$(date +%s.%N)
    "$@" >"$work/log" 2>&1 || { cat "$work/log" >&2; exit 1; }
    end=$(date +%s.%N)
    echo "$label: $(rates "$out" "$(echo "$end - $start" | bc -l)")"
}

train_part() {
    local name steps sizes
    for setting in "fixed-4x512 $STEPS_FIXED --min-side 512 --max-side 512 --batch-pixels $((4 * 512 * 512))" \
        "paper-plan $STEPS_PLAN"; do
        read -r name steps sizes <<<"$setting"
        # shellcheck disable=SC2206
        local size_args=($sizes)
        local common=(--steps "$steps" --device "$DEVICE" --checkpoint-every "$steps" --validation-batches 0
            "${size_args[@]}")
        echo "== $name, $steps steps"
        train_run "python -m matseg.train, 1 process, $LOADERS workers" "$work/py" \
            "$PY" -m matseg.train --out "$work/py" --workers "$LOADERS" "${common[@]}"
        if ((gpus > 1)); then
            local per=$(((CORES - 2) / gpus > 0 ? (CORES - 2) / gpus : 1))
            # Rank 0's metrics hold its own batches: the whole-run figure is
            # the trainer's own (all ranks' images).
            rm -rf "$work/ddp"
            "$PY" -m torch.distributed.run --nproc_per_node "$gpus" -m matseg.train --out "$work/ddp" \
                --workers "$per" "${common[@]}" 2>&1 | sed -n "s/^.*: \(.* images\/s\))$/DDP over $gpus GPUs, $per workers each: \1/p"
        fi
        train_run "matseg train --online, $LOADERS loader threads" "$work/rs" \
            "$MATSEG" train --online --out "$work/rs" --init models/default/model.safetensors \
            --encoder-features --colour-features --lr-scale encoder.=0.1 --lr-scale colour.=100 \
            --loader-threads "$LOADERS" "${common[@]}"
    done
}

generate_part() {
    echo "== generation, 1 and $CORES jobs"
    JOBS=$CORES SAMPLES=$((CORES * 50)) SHARD_SIZE=25 scripts/bench-scale-out.sh "$MATSEG"
}

net_part() {
    echo "== the net per encoder, 4-image batches, matseg then PyTorch, ms"
    local enc side
    for enc in mobilenet-v2 convnext-tiny convnext-base; do
        for side in 256 512; do
            local args=(--device "$DEVICE" --encoder "$enc" --side "$side" --batch 4 --repeats "$REPEATS" --warmup 3)
            echo "$enc $side matseg: $("$MATSEG" bench-net "${args[@]}" --json)"
            echo "$enc $side pytorch: $("$PY" scripts/bench-net-pytorch.py "${args[@]}")"
        done
    done
}

for part in "${PARTS[@]}"; do
    case $part in
    train) train_part ;;
    generate) generate_part ;;
    net) net_part ;;
    *)
        echo "bench-gpu.sh: unknown part '$part' (train, generate or net)" >&2
        exit 2
        ;;
    esac
done
