#!/usr/bin/env bash
# Which pure-Rust library runs the net's learned part (MobileNetV2 encoder,
# PSP, decoder, head; the shipped weights, BatchNorm folded) fastest on the
# CPU, against libtorch on the same machine, and whether their outputs agree.
# Run from the repository's root after `make test` (the .venv with torch):
#
#     scripts/engines/run.sh
#
# For each of burn (flex), candle and rten: a clean release build into its
# own target folder (wall and CPU seconds, crates compiled), then the
# forward pass at 704x512 and 704x384 (median of 5 after 2 warm-ups, 2
# threads, peak RSS); then libtorch through python/matseg/net.py, and the
# per-cell cosine between every pair of outputs. Results in
# scripts/engines/data/ (git-ignored): results.txt, compare.txt, the logs.
set -euo pipefail
cd "$(dirname "$0")"
root=$(cd ../.. && pwd)
python="$root/.venv/bin/python"
mkdir -p data
export RAYON_NUM_THREADS=2 RTEN_NUM_THREADS=2
(cd "$root" && "$python" scripts/engines/py/torch_ref.py prep)
cargo fetch --quiet
: > data/results.txt
for lib in burn candle rten; do
    export CARGO_TARGET_DIR="$PWD/data/target-$lib"
    rm -rf "$CARGO_TARGET_DIR"
    /usr/bin/time -v -o "data/build-$lib.time" cargo build --release --offline -p "bench-$lib" 2> "data/build-$lib.log"
    {
        echo "$lib: clean build, $(grep -c '^ *Compiling' "data/build-$lib.log") crates"
        grep -E "Elapsed|User time|System time" "data/build-$lib.time"
    } | tee -a data/results.txt
    variants=("$lib")
    [ "$lib" = candle ] && variants+=(candle-dwshift)
    for variant in "${variants[@]}"; do
        for size in 704x512 704x384; do
            w=${size%x*}; h=${size#*x}
            depthwise=conv
            [ "$variant" = candle-dwshift ] && depthwise=shift
            CANDLE_DW=$depthwise /usr/bin/time -v -o "data/run-$variant-$size.time" \
                "$CARGO_TARGET_DIR/release/bench-$lib" "$root/models/default/model.safetensors" \
                "data/input_$size.f32" "$h" "$w" "data/out_${variant}_$size.f32" 5 2 \
                2> "data/run-$variant-$size.log" | tee -a data/results.txt
            echo "  peak RSS: $(grep 'Maximum resident' "data/run-$variant-$size.time" | awk '{print $NF}') kB" | tee -a data/results.txt
        done
    done
done
(cd "$root" && THREADS=2 "$python" scripts/engines/py/torch_ref.py ref) | tee -a data/results.txt
(cd "$root" && "$python" scripts/engines/py/torch_ref.py compare) | tee data/compare.txt
