#!/usr/bin/env bash
# Converts the CC0 world HDRIs of Debian's blender-data package (DWAB-compressed
# OpenEXR) into ZIP half-float EXRs, the lossless form the bundled copies in
# assets/hdris/ take (matseg reads both; `matseg assets fetch` keeps the DWAB files).
# Usage: scripts/convert-hdris.sh OUT_DIR [NAME...]   (names without .exr;
# default: all eight). Prints one JSON line of source statistics per file.
# Needs apt-get (download only, no root needed for the unpack) and PyPI; the
# OpenEXR wheel goes into a throw-away venv under target/.
set -euo pipefail
out=$(realpath -m "$1"); shift
root=$(cd "$(dirname "$0")/.." && pwd)
work="$root/target/hdri-work"
venv="$root/target/exr-venv"
mkdir -p "$work"
if [ ! -x "$venv/bin/python" ]; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet OpenEXR==3.5.3 numpy
fi
if [ ! -d "$work/deb" ]; then
    (cd "$work" && apt-get download blender-data >/dev/null)
    dpkg -x "$work"/blender-data_*.deb "$work/deb.part"
    mv "$work/deb.part" "$work/deb"
fi
world=$(find "$work/deb" -type d -path '*studiolights/world' | head -n 1)
[ -n "$world" ] || { echo "blender-data has no studiolights/world folder" >&2; exit 1; }
names=("$@")
[ ${#names[@]} -gt 0 ] || names=(city courtyard forest interior night studio sunrise sunset)
files=()
for n in "${names[@]}"; do files+=("$world/$n.exr"); done
"$venv/bin/python" "$root/scripts/convert-hdris.py" "$out" "${files[@]}"
cp "$world/license.txt" "$out/license.txt"
