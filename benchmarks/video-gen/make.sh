#!/usr/bin/env bash
# Makes the generated video benchmark into benchmarks/video-gen/data (git-
# ignored) from the bundled assets alone, whatever corpus is fetched: 8
# scenes of 12 frames at 256 px, each frame with its exact masks. The
# frames' images and masks are byte-identical on every run and machine
# (checked against SHA256SUMS); meta.json files name this checkout's paths.
# Usage: benchmarks/video-gen/make.sh [MATSEG]   (default: target/release/matseg)
set -euo pipefail
cd "$(dirname "$0")/../.."
MATSEG=${1:-target/release/matseg}
HERE=benchmarks/video-gen
"$MATSEG" pbr assets/textures --out "$HERE/materials" >/dev/null
"$MATSEG" generate --kind 3d -n 8 --seed 0 --config "$HERE/recipe.toml" \
    --camera-path "$HERE/camera-path.toml" --sources assets/photos \
    --materials "$HERE/materials" --meshes assets/meshes --hdris assets/hdris \
    --out "$HERE/data"
(cd "$HERE/data" && sha256sum --quiet -c ../SHA256SUMS)
echo "$HERE/data: the benchmark, as SHA256SUMS lists it" >&2
