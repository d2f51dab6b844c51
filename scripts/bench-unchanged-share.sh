#!/usr/bin/env bash
# Compares the in-memory generation time of two builds of matseg when the
# machine's speed moves too much for timings to agree (this shared VM's
# does, by up to 2x within minutes, and its two cores differ: side-by-side
# timings of one build against itself ranged 0.84-1.37).
#
# Each build's `matseg bench --in-memory-only` runs under `perf record`,
# A and B alternated (A first in odd pairs, B first in even ones). Code that a change does not touch does the same work
# on the same scenes in both builds (when the change keeps the bytes
# generated), so it takes the same time in both, and its share of a run's
# samples scales inversely with the run's total: B's time over A's is A's
# share of that code over B's, whatever the machine's speed during each
# run. The untouched code defaults to the layers' blending, weighing,
# rounding and texture reads (bound by memory like the rest of
# generation); set UNCHANGED to a regular expression of other symbols when
# a change touches those. Needs `perf` (Debian: linux-perf).
#
# Usage: scripts/bench-unchanged-share.sh A_BINARY B_BINARY [PAIRS] [SCENES]
# (defaults: 5 pairs of 300 scenes). Binaries built elsewhere need
# MATSEG_ASSETS pointing at this checkout's assets/.
set -euo pipefail
a=${1:?usage: bench-unchanged-share.sh A_BINARY B_BINARY [PAIRS] [SCENES]}
b=${2:?usage: bench-unchanged-share.sh A_BINARY B_BINARY [PAIRS] [SCENES]}
pairs=${3:-5}
scenes=${4:-300}
unchanged=${UNCHANGED:-'blend_run|weigh_row|interleave_rounded|copy_reversed|Layer::add_row|material::widen|rotate_hue_planes'}
command -v perf > /dev/null || { echo "bench-unchanged-share.sh: perf is not installed" >&2; exit 1; }
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for pair in $(seq "$pairs"); do
    # A first in odd pairs, B first in even ones, so that neither always
    # runs on a machine the other has just warmed or slowed.
    order="a b"
    [ $((pair % 2)) = 0 ] && order="b a"
    for side in $order; do
        binary=$a
        [ "$side" = b ] && binary=$b
        perf record -q -F 3000 -o "$work/$side.$pair.data" \
            "$binary" bench --in-memory-only --scenes "$scenes" > "$work/$side.$pair.log" 2>&1 \
            || { cat "$work/$side.$pair.log" >&2; exit 1; }
        perf report -i "$work/$side.$pair.data" --no-children --sort symbol --stdio \
            2> /dev/null > "$work/$side.$pair.txt"
    done
done
python3 - "$work" "$pairs" "$unchanged" <<'PY'
import re, statistics, sys

work, pairs, unchanged = sys.argv[1], int(sys.argv[2]), re.compile(sys.argv[3])

def share(path):
    """Percent of samples in the untouched symbols."""
    total = 0.0
    for line in open(path):
        m = re.match(r"\s+([0-9.]+)%\s+\[.\]\s+(\S.*?)\s*$", line)
        if m and unchanged.search(m.group(2)):
            total += float(m.group(1))
    return total

def cpu(path):
    """The run's own CPU s per scene (noisy: for reference)."""
    for line in open(path):
        if "generate in memory" in line:
            return float(line.split("|")[4])
    raise SystemExit(f"{path}: no in-memory row")

ratios = []
print(f"{'pair':>4} {'A share %':>9} {'B share %':>9} {'B/A time':>8} {'A CPU s':>8} {'B CPU s':>8}")
for p in range(1, pairs + 1):
    sa, sb = share(f"{work}/a.{p}.txt"), share(f"{work}/b.{p}.txt")
    ratios.append(sa / sb)
    print(f"{p:>4} {sa:9.2f} {sb:9.2f} {sa / sb:8.3f} "
          f"{cpu(f'{work}/a.{p}.log'):8.4f} {cpu(f'{work}/b.{p}.log'):8.4f}")
print(f"in-memory generation time B/A, median of {pairs} pairs: {statistics.median(ratios):.3f}")
PY
