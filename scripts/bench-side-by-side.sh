#!/usr/bin/env bash
# Compares two builds of matseg on the generator benchmark by running them
# side by side: each round starts `matseg bench --scenes 40 --threads 1`
# of both binaries at once (one per core), so that both see the same
# machine; then prints, per row, each binary's median CPU s per scene and
# the median of the per-round ratios B/A. A shared or virtual machine can
# change speed by more than a change being measured between two runs made
# one after the other; run at the same time, both see the same change.
# The encoding row is a control when only generation changed (its ratio
# should stay within a few percent of 1).
#
# Usage: scripts/bench-side-by-side.sh A_BINARY B_BINARY [ROUNDS]
# (BENCHMARKS.md, "2D generator throughput", uses 8 rounds.)
set -euo pipefail
a=${1:?usage: bench-side-by-side.sh A_BINARY B_BINARY [ROUNDS]}
b=${2:?usage: bench-side-by-side.sh A_BINARY B_BINARY [ROUNDS]}
rounds=${3:-8}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
for round in $(seq "$rounds"); do
    "$a" bench --scenes 40 --threads 1 > "$work/a.$round" &
    "$b" bench --scenes 40 --threads 1 > "$work/b.$round"
    wait
done
python3 - "$work" "$rounds" <<'PY'
import statistics, sys

work, rounds = sys.argv[1], int(sys.argv[2])

def rows(path):
    """(name, CPU s per scene) of each table row of one `matseg bench`
    output, in order (with one thread, two rows share a name)."""
    out = []
    for line in open(path):
        cells = [c.strip() for c in line.strip().strip("|").split("|")]
        if len(cells) == 6 and cells[0][:1].isalpha() and cells[0] != "measure":
            out.append((cells[0], float(cells[3])))
    return out

runs = [(rows(f"{work}/a.{r}"), rows(f"{work}/b.{r}")) for r in range(1, rounds + 1)]
print(f"{'row':42} {'A':>8} {'B':>8} {'B/A':>6}  per round")
for i, (name, _) in enumerate(runs[0][0]):
    a = [ra[i][1] for ra, _ in runs]
    b = [rb[i][1] for _, rb in runs]
    ratios = [y / x for x, y in zip(a, b)]
    print(
        f"{name:42} {statistics.median(a):8.4f} {statistics.median(b):8.4f} "
        f"{statistics.median(ratios):6.3f}  {' '.join(f'{r:.2f}' for r in ratios)}"
    )
PY
