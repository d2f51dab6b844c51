#!/usr/bin/env bash
# Generation rate with 1 and JOBS jobs of a split dataset (docs/scale-out.md):
# SAMPLES 2D samples in WebDataset shards of SHARD_SIZE, written by
#   one job with one thread, JOBS jobs of one thread each at once (as JOBS
#   array jobs on one machine), and one job with JOBS threads;
# RUNS times each, printing samples/s of each run and the median.
#   scripts/bench-scale-out.sh [target/release/matseg]
#   JOBS=16 SAMPLES=800 SHARD_SIZE=25 scripts/bench-scale-out.sh   (16 cores)
set -euo pipefail
MATSEG=${1:-target/release/matseg}
JOBS=${JOBS:-2}
SAMPLES=${SAMPLES:-400}
SHARD_SIZE=${SHARD_SIZE:-50}
RUNS=${RUNS:-3}
if ((SAMPLES < JOBS * SHARD_SIZE)); then
    echo "bench-scale-out.sh: $SAMPLES samples in shards of $SHARD_SIZE leave some of $JOBS jobs idle" >&2
    exit 2
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# Runs JOBS jobs of THREADS threads each at once; prints samples/s.
rate() {
    local jobs=$1 threads=$2 out="$work/out"
    rm -rf "$out"
    local start end
    start=$(date +%s.%N)
    for ((i = 0; i < jobs; i++)); do
        "$MATSEG" generate --out "$out" --samples "$SAMPLES" --format wds \
            --shard-size "$SHARD_SIZE" --num-shards "$jobs" --shard-index "$i" \
            --threads "$threads" >/dev/null 2>&1 &
    done
    wait
    end=$(date +%s.%N)
    echo "$SAMPLES / ($end - $start)" | bc -l
}

median() { sort -g | awk '{ v[NR] = $1 } END { print v[int((NR + 1) / 2)] }'; }

for setting in "1 1" "$JOBS 1" "1 $JOBS"; do
    read -r jobs threads <<< "$setting"
    rates=()
    for ((r = 0; r < RUNS; r++)); do
        rates+=("$(rate "$jobs" "$threads")")
    done
    printf '%s job(s) x %s thread(s): %s samples/s (runs: %s)\n' "$jobs" "$threads" \
        "$(printf '%s\n' "${rates[@]}" | median | xargs printf '%.1f')" \
        "$(printf '%.1f ' "${rates[@]}")"
done
