#!/usr/bin/env bash
# Rates of the Python front ends (docs/scale-out.md), with the matseg
# package installed in .venv (`MATURIN_PEP517_ARGS="--features torch" .venv/bin/pip install ./python`, a release
# build), RUNS times each, printing each run and the median:
#   - `python -m matseg.ray generate`: SAMPLES 2D samples in WebDataset
#     shards of SHARD_SIZE, as 2 Ray tasks of one CPU on a local cluster of
#     1 and of 2 CPUs; samples/s as it prints (from the tasks' submission
#     to the last one's end: the cluster's start, ~5 s, left out);
#   - `python -m matseg.train` on the CPU: STEPS steps of 2 x 224² online
#     batches from the shipped model, in one process (2 threads) and in two
#     DDP processes under torchrun (1 thread each); images/s as it prints.
#   scripts/bench-python.sh
set -euo pipefail
cd "$(dirname "$0")/.."
PY=.venv/bin/python
SAMPLES=${SAMPLES:-400}
SHARD_SIZE=${SHARD_SIZE:-25}
STEPS=${STEPS:-10}
RUNS=${RUNS:-3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

# Ray tasks on a local cluster of CPUS CPUs; prints samples/s.
ray_rate() {
    local cpus=$1 out="$work/ray"
    rm -rf "$out"
    "$PY" -m matseg.ray generate --out "$out" -n "$SAMPLES" --format wds --shard-size "$SHARD_SIZE" \
        --num-shards 2 --address local --num-cpus "$cpus" 2>/dev/null |
        sed -n 's/.*(\([0-9.]*\) samples\/s).*/\1/p'
}

# Training in PROCS processes; prints images/s (the trainer's own figure).
train_rate() {
    local procs=$1 out="$work/run"
    rm -rf "$out"
    local args=(--out "$out" --steps "$STEPS" --min-side 224 --max-side 224 --batch-pixels $((2 * 224 * 224)) --workers 1
        --validation-batches 0)
    if [ "$procs" = 1 ]; then
        OMP_NUM_THREADS=2 "$PY" -m matseg.train "${args[@]}" 2>/dev/null
    else
        OMP_NUM_THREADS=1 .venv/bin/torchrun --nproc_per_node "$procs" -m matseg.train "${args[@]}" 2>/dev/null
    fi | sed -n 's/.*(\([0-9.]*\) images\/s).*/\1/p'
}

report() {
    local label=$1
    shift
    local rates=()
    for ((r = 0; r < RUNS; r++)); do
        rates+=("$("$@")")
    done
    printf '%s: %s (runs: %s)\n' "$label" "$(printf '%s\n' "${rates[@]}" | median)" "${rates[*]}"
}

report "ray, 2 tasks on 1 CPU, samples/s" ray_rate 1
report "ray, 2 tasks on 2 CPUs, samples/s" ray_rate 2
report "train, 1 process, images/s" train_rate 1
report "train, DDP 2 processes, images/s" train_rate 2
