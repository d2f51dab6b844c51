#!/usr/bin/env bash
# Renders matseg's reference 3D scene with matseg and with Blender Cycles
# (PyPI bpy, in a throw-away venv under target/), interleaved, and prints one
# JSON line per render. Usage: scripts/bench-render-cycles.sh [REPEATS] [THREADS]
# Run from the repository root after `cargo build --release -p matseg-cli`.
set -euo pipefail
repeats=${1:-3}
threads=${2:-$(nproc)}
root=$(cd "$(dirname "$0")/.." && pwd)
venv="$root/target/bpy-venv"
scene="$root/target/bench-render-scene"
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c "import bpy" 2>/dev/null; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet bpy==5.0.1
fi
"$root/target/release/matseg" bench-render --repeats 1 --threads "$threads" --write-scene "$scene" >/dev/null
for _ in $(seq "$repeats"); do
    "$root/target/release/matseg" bench-render --repeats 1 --threads "$threads" --json
    (cd "$scene" && "$venv/bin/python" "$root/scripts/bench-render-cycles.py" "$scene" "$threads" 2>/dev/null | tail -n 1)
done
