#!/usr/bin/env bash
# Scene pixels per CPU hour of the two training paths, side by side in one
# sitting (BENCHMARKS.md, "Training on cached features"):
#   scripts/bench-fast-path.sh [MATSEG]
# online  `matseg train --online` from the shipped model with its recipe,
#         fixed 4 x 256² batches (--batch-pixels 262144), ONLINE_STEPS steps;
# cache   `matseg features` of CACHE_SAMPLES online scenes at 256 px
#         (--zoom native, 2 loader threads);
# cached  `matseg train --features` on that cache, the same batches' size,
#         CACHED_STEPS steps.
# Each is run RUNS times (median printed, with the range); the rates count
# the whole command (start-up, checkpoints included): images/s and
# Mpixel/s of training, and for the fast path as a whole the rate when the
# cache's cost is shared by EPOCHS epochs over it. Sources: the fetched
# corpus, else the bundled assets. Run it with nothing else on the machine.
set -euo pipefail
MATSEG=${1:-target/release/matseg}
RUNS=${RUNS:-3}
ONLINE_STEPS=${ONLINE_STEPS:-30}
CACHE_SAMPLES=${CACHE_SAMPLES:-400}
CACHED_STEPS=${CACHED_STEPS:-300}
EPOCHS=${EPOCHS:-3}
PY=${PYTHON:-python3}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
recipe=(--encoder-features --colour-features --lr-scale colour.=100 --lr 1e-4 --warmup 20
    --batch-pixels 262144 --validation-batches 0)

# Wall seconds of a command (its output kept in $work/log).
timed() {
    local start end
    start=$(date +%s.%N)
    "$@" >"$work/log" 2>&1 || { cat "$work/log" >&2; exit 1; }
    end=$(date +%s.%N)
    echo "$end - $start" | bc -l
}

online=() cache=() cached=()
for ((r = 0; r < RUNS; r++)); do
    rm -rf "$work/online" "$work/cache" "$work/cached"
    online+=("$(timed "$MATSEG" train --online --out "$work/online" --init default "${recipe[@]}" \
        --lr-scale encoder.=0.1 --min-side 256 --max-side 256 --steps "$ONLINE_STEPS" \
        --checkpoint-every "$ONLINE_STEPS" --loader-threads 1)")
    cache+=("$(timed "$MATSEG" features --online -n "$CACHE_SAMPLES" --side 256 --zoom native \
        --out "$work/cache" --loader-threads 2)")
    cached+=("$(timed "$MATSEG" train --features "$work/cache" --out "$work/cached" "${recipe[@]}" \
        --steps "$CACHED_STEPS" --checkpoint-every "$CACHED_STEPS")")
    echo "run $((r + 1)): online ${online[r]} s, cache ${cache[r]} s, cached ${cached[r]} s" >&2
done
"$PY" - "$work/online/metrics.jsonl" "$work/cached/metrics.jsonl" "$CACHE_SAMPLES" "$EPOCHS" \
    "${online[*]}" "${cache[*]}" "${cached[*]}" <<'EOF'
import json, statistics, sys
def images(metrics):
    return sum(json.loads(line)["images"] for line in open(metrics))
n_online, n_cached = images(sys.argv[1]), images(sys.argv[2])
n_cache, epochs = int(sys.argv[3]), int(sys.argv[4])
online, cache, cached = ([float(v) for v in a.split()] for a in sys.argv[5:8])
px = 256 * 256 / 1e6
def row(name, images, times):
    m = statistics.median(times)
    print(f"| {name} | {images} | {m:.1f} s ({min(times):.1f}-{max(times):.1f}) | "
          f"{images / m:.2f} | {images * px / m:.3f} |")
print("| command | images | wall (median, range) | images/s | Mpixel/s |")
print("|---|---|---|---|---|")
row("matseg train --online", n_online, online)
row("matseg features (making the cache)", n_cache, cache)
row("matseg train --features", n_cached, cached)
rate_online = n_online / statistics.median(online)
per_image = statistics.median(cached) / n_cached
share = statistics.median(cache) / n_cache / epochs
fast = 1 / (per_image + share)
print(f"\nfast path with the cache shared by {epochs} epochs: {fast:.2f} images/s, "
      f"{fast * px:.3f} Mpixel/s = {fast / rate_online:.1f}x online")
EOF
