#!/usr/bin/env bash
# Runs the commands that write files with two matseg binaries, on the
# bundled assets, into the same paths, and compares what they wrote file
# by file: a change that means to keep every output must print "same" on
# every row. Files only one build writes are listed (matseg's marker,
# `.matseg-output`, is not an output and is left out); the JSON reports
# that hold timings (track.json, render.json) are compared without them.
#
#   scripts/same-outputs.sh BEFORE_BINARY AFTER_BINARY [WORK_DIR]
#
# The net commands (segment, apply, track) run when both binaries have
# them. MATSEG_CACHE is a folder of the script's own, so both builds make
# the same bundled materials, and MATSEG_ASSETS names the bundled assets
# for both (a build records where it was compiled as their default).
set -euo pipefail
before=$(realpath "$1")
after=$(realpath "$2")
work=${3:-$(mktemp -d)}
root=$(cd "$(dirname "$0")/.." && pwd)
assets="$root/assets"
export MATSEG_CACHE="$work/cache"
export MATSEG_ASSETS="$assets"
mkdir -p "$work/in"

# Inputs both builds read, made by the first: a small clip, a point
# benchmark, a mask benchmark and a dataset.
mkdir -p "$work/in/frames"
for k in 0 1 2; do
    "$before" maps "$assets/photos/coffee.jpg" -n 1 --max-side 64 --seed $k --out "$work/in/m$k" >/dev/null 2>&1
    cp "$work/in/m$k/colour.png" "$work/in/frames/$(printf %04d $k).png"
done
"$before" bench-set make -n 3 --out "$work/in/bench" >/dev/null
"$before" bench-set masks -n 3 --out "$work/in/masks" >/dev/null
"$before" generate -n 3 --size-range 64..96 --out "$work/in/bench-data" >/dev/null 2>&1

has_net() { "$1" segment --help >/dev/null 2>&1; }

# NAME|ARGS (OUT stands for the output folder; a command that prints its
# results, `>ARGS`, is compared by what it prints).
commands=(
    "eval points --json|>eval points $work/in/bench --baseline rgb lab --model none --json"
    "eval masks --json|>eval masks $work/in/masks --baseline rgb lab --model none --json"
    "eval clicks --json|>eval clicks $work/in/masks --baseline rgb --model none --json"
    "generate 2d|generate -n 12 --size-range 64..200 --out OUT"
    "generate 3d|generate --kind 3d -n 2 --size 48 --spp 4 --out OUT"
    "generate wds|generate -n 7 --format wds --shard-size 3 --out OUT"
    "maps|maps $assets/photos/coffee.jpg -n 5 --out OUT"
    "textures|textures $assets/photos --out OUT"
    "pbr|pbr $assets/textures -n 1 --out OUT"
    "bench-set make|bench-set make -n 4 --out OUT"
    "bench-set masks|bench-set masks -n 3 --out OUT"
    "bench-set masks --from|bench-set masks --from $work/in/bench-data --out OUT"
    "bench-set draw|bench-set draw $work/in/bench --out OUT"
)
if has_net "$before" && has_net "$after"; then
    commands+=(
        "segment|segment $assets/photos/coffee.jpg --point 290,130 --point 100,300 --not 500,50 --out OUT"
        "segment --auto|segment $assets/photos/coffee.jpg --auto 4 --out OUT"
        "apply|apply OUT_SEGMENT/selection_0.json $assets/photos --out OUT"
        "track|track $work/in/frames --point 30,20 --preview --out OUT"
    )
fi

# The files of folder $1, relative, the marker left out.
files() { (cd "$1" && find . -type f ! -name .matseg-output | sort); }

# Whether two files are the same output: the same bytes, or for the
# reports with timings the same JSON once those are left out.
same_file() {
    cmp -s "$1" "$2" && return 0
    case "$1" in
    *track.json | *render.json)
        python3 - "$1" "$2" <<'EOF'
import json, sys
def plain(path):
    value = json.load(open(path))
    for key in list(value):
        if "seconds" in key:
            del value[key]
    return value
sys.exit(0 if plain(sys.argv[1]) == plain(sys.argv[2]) else 1)
EOF
        ;;
    *) return 1 ;;
    esac
}

echo "| command | files | result |"
echo "|---|---|---|"
for entry in "${commands[@]}"; do
    name=${entry%%|*}
    args=${entry#*|}
    for build in before after; do
        binary=${!build}
        out="$work/out"
        rm -rf "$out" "$work/$build-$name"
        line=${args//OUT_SEGMENT/$work/before-segment}
        if [ "${line:0:1}" = ">" ]; then
            mkdir -p "$out"
            # shellcheck disable=SC2086
            "$binary" ${line:1} >"$out/stdout" 2>/dev/null || { echo "| $name | - | $build build failed |"; continue 2; }
        else
            # shellcheck disable=SC2086
            "$binary" ${line//OUT/$out} >/dev/null 2>&1 || { echo "| $name | - | $build build failed |"; continue 2; }
        fi
        mv "$out" "$work/$build-$name"
    done
    a="$work/before-$name"
    b="$work/after-$name"
    if ! diff <(files "$a") <(files "$b") >/dev/null; then
        echo "| $name | - | different files: $(diff <(files "$a") <(files "$b") | grep '^[<>]' | head -3 | tr '\n' ' ') |"
        continue
    fi
    count=0
    differ=()
    while read -r f; do
        count=$((count + 1))
        same_file "$a/$f" "$b/$f" || differ+=("$f")
    done < <(files "$a")
    if [ ${#differ[@]} -eq 0 ]; then
        echo "| $name | $count | same |"
    else
        echo "| $name | $count | ${#differ[@]} differ: ${differ[*]:0:3} |"
    fi
done
