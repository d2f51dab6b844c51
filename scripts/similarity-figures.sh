#!/usr/bin/env bash
# Remakes the similarity figures of the README (docs/images/similarity/) and
# of models/default/MODEL.md (models/default/failures/) with a model:
# `matseg segment` on real-dev photos at the points listed below, each result
# drawn as two panels by similarity-figures.py.
# Usage: scripts/similarity-figures.sh [MODEL]   (default: default)
# Needs a release build (cargo build --release -p matseg-cli) and PyPI; the
# Pillow wheel goes into a throw-away venv under target/.
set -euo pipefail
model=${1:-default}
root=$(cd "$(dirname "$0")/.." && pwd)
venv="$root/target/figures-venv"
matseg="$root/target/release/matseg"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet Pillow==11.3.0
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
# photo  x  y  figure
while read -r name x y figure; do
    photo="$root/benchmarks/real-dev/images/$name.jpg"
    "$matseg" segment "$photo" --model "$model" --point "$x,$y" --out "$work/$name" >/dev/null
    "$venv/bin/python" "$root/scripts/similarity-figures.py" "$work/$name" "$x" "$y" "$root/$figure"
    echo "$figure"
done <<'LIST'
burnt-bark 330 460 docs/images/similarity/burnt-bark.jpg
wool-mill 228 268 docs/images/similarity/wool-mill.jpg
snow-trees 352 252 docs/images/similarity/snow-trees.jpg
ivy-wall 262 215 docs/images/similarity/ivy-wall.jpg
pizza 150 482 docs/images/similarity/pizza.jpg
citrus 460 235 docs/images/similarity/citrus.jpg
mudstone 230 352 models/default/failures/mudstone.jpg
pebbles 60 415 models/default/failures/pebbles.jpg
red-maple 382 322 models/default/failures/red-maple.jpg
LIST
