#!/usr/bin/env bash
# Provides FFmpeg (the ffmpeg and ffprobe programs) in the project's
# git-ignored .venv, for `matseg track` on video files and the tests that
# encode and decode videos: .venv/ffmpeg/ffmpeg and .venv/ffmpeg/ffprobe,
# where matseg finds them (else through $MATSEG_FFMPEG, or on the PATH).
# Frame folders (PNG, JPEG) need none of this.
#
# When this machine's own ffmpeg and ffprobe (on the PATH) do all that
# matseg asks of them (NEEDS below, and a tiny clip made, probed and
# decoded as matseg does), the two are wrappers that run them. Otherwise
# Debian's FFmpeg is installed there, without root: the .deb files of
# ffmpeg and of every library it needs that this machine lacks are fetched
# with `apt-get download` and unpacked (scripts/debs.sh), and the wrappers
# set the library path of the unpacked libraries.
#
# .venv/ffmpeg/installed says which was chosen. A no-op while the chosen
# programs still run; when they no longer do (this machine's ffmpeg was
# removed), the choice is made again.
set -euo pipefail
cd "$(dirname "$0")/.."

ROOT=.venv/ffmpeg
STAMP="$ROOT/installed"
if [ -f "$STAMP" ]; then
    if "$ROOT/ffmpeg" -hide_banner -version >/dev/null 2>&1 &&
        "$ROOT/ffprobe" -hide_banner -version >/dev/null 2>&1; then
        exit 0
    fi
    chosen=$(head -1 "$STAMP")
    chosen=${chosen:-"Debian's, unpacked"}
    echo "ffmpeg-env: the ffmpeg in $ROOT ($chosen) no longer runs; choosing again" >&2
fi
rm -rf "$ROOT.partial"
mkdir -p "$ROOT.partial"
. scripts/debs.sh

# What matseg and its tests ask of FFmpeg, as `ffmpeg -KIND` lists them:
# H.264 (libx264) in MP4 for the overlay videos and the tests' clips, FFV1
# in Matroska for the tests' lossless ones, PNG frame patterns and FFmpeg's
# test pattern (lavfi) as inputs, and raw RGB frames out through a pipe,
# scaled and padded.
NEEDS=(
    "encoders: libx264 ffv1 rawvideo"
    "decoders: h264 ffv1 png rawvideo"
    "muxers: mp4 matroska rawvideo"
    "demuxers: mov matroska image2 lavfi rawvideo"
    "filters: scale pad testsrc"
)

# usable FFMPEG FFPROBE: whether the two programs run and do all of NEEDS,
# and make, probe and decode a two-frame H.264 clip with matseg's own
# arguments (which an FFmpeg too old for them refuses); if not, why, on
# stdout.
usable() {
    local ffmpeg=$1 ffprobe=$2 program out need kind name names probe bytes
    local work="$ROOT.partial/check"
    for program in "$ffmpeg" "$ffprobe"; do
        if ! out=$("$program" -hide_banner -version 2>&1); then
            echo "$program does not run ($(sed -n '$p' <<<"$out"))"
            return 1
        fi
    done
    for need in "${NEEDS[@]}"; do
        kind=${need%%:*}
        # The listings' second column: names (demuxers: several, with commas).
        names=$("$ffmpeg" -hide_banner "-$kind" 2>/dev/null | awk '{print $2}' | tr , '\n')
        for name in ${need#*:}; do
            grep -qxF "$name" <<<"$names" || { echo "$ffmpeg has no $name among its $kind"; return 1; }
        done
    done
    rm -rf "$work"
    mkdir -p "$work"
    "$ffmpeg" -v error -nostdin -f lavfi -i testsrc=size=32x24:rate=10 -frames:v 2 \
        -c:v libx264 -pix_fmt yuv420p -movflags +faststart "$work/clip.mp4" >/dev/null 2>&1 ||
        { echo "$ffmpeg cannot encode an H.264 clip"; return 1; }
    probe=$("$ffprobe" -v error -select_streams v:0 -show_entries \
        stream=width,height,avg_frame_rate,nb_read_packets:stream_side_data=rotation \
        -count_packets -of json "$work/clip.mp4" 2>/dev/null || true)
    if ! grep -q '"width": 32' <<<"$probe" || ! grep -q '"nb_read_packets": "2"' <<<"$probe"; then
        echo "$ffprobe cannot read a clip as matseg asks"
        return 1
    fi
    bytes=$("$ffmpeg" -v error -nostdin -i "$work/clip.mp4" -map 0:v:0 -f rawvideo \
        -pix_fmt rgb24 -vf scale=32:24 - 2>/dev/null | wc -c)
    rm -rf "$work"
    [ "$bytes" = $((32 * 24 * 3 * 2)) ] || { echo "$ffmpeg cannot decode a clip to RGB frames"; return 1; }
}

# version FFMPEG: its version line, without the copyright.
version() {
    "$1" -hide_banner -version 2>/dev/null | sed -n '1{s/ Copyright.*//;p;}'
}

# This machine's own, when usable (and not the wrappers themselves).
system=$(command -v ffmpeg || true)
case "$(realpath -m "${system:-/}")" in
    "$(realpath .venv)"/*) system= ;;
esac
if [ -z "$system" ]; then
    reason="no ffmpeg on the PATH"
elif ! command -v ffprobe >/dev/null; then
    reason="no ffprobe beside $system on the PATH"
elif reason=$(usable "$system" "$(command -v ffprobe)"); then
    for program in ffmpeg ffprobe; do
        cat > "$ROOT.partial/$program" <<WRAPPER
#!/bin/sh
# Runs this machine's $program (scripts/ffmpeg-env.sh found it usable).
exec $(printf %q "$(command -v "$program")") "\$@"
WRAPPER
        chmod +x "$ROOT.partial/$program"
    done
    echo "ffmpeg-env: using this machine's $system ($(version "$system"))" >&2
    finish_install "$ROOT" "system $system ($(version "$system"))"
    exit 0
fi

if ! command -v apt-get >/dev/null || ! command -v dpkg-deb >/dev/null; then
    echo "ffmpeg-env: $reason, and no apt-get to fetch Debian's: install an ffmpeg with libx264 and FFV1 (and ffprobe) on the PATH" >&2
    exit 1
fi
echo "ffmpeg-env: $reason; installing Debian's ffmpeg into $ROOT (once; 3 to 460 MB unpacked, by the libraries this machine lacks)" >&2
# ffmpeg and the libraries this machine lacks.
packages=$(apt_missing ffmpeg)
test -n "$packages" || { echo "ffmpeg-env: apt knows no ffmpeg package" >&2; exit 1; }
# shellcheck disable=SC2086
unpack_debs "$ROOT.partial/root" $packages
test -x "$ROOT.partial/root/usr/bin/ffmpeg" ||
    { echo "ffmpeg-env: usr/bin/ffmpeg missing after unpacking" >&2; exit 1; }
for program in ffmpeg ffprobe; do
    cat > "$ROOT.partial/$program" <<WRAPPER
#!/bin/sh
# Runs the unpacked $program with its libraries.
here=\$(dirname "\$(realpath "\$0")")
lib="\$here/root/usr/lib/x86_64-linux-gnu"
export LD_LIBRARY_PATH="\$lib:\$lib/blas:\$lib/lapack:\$lib/pulseaudio:\$here/root/lib/x86_64-linux-gnu\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
exec "\$here/root/usr/bin/$program" "\$@"
WRAPPER
    chmod +x "$ROOT.partial/$program"
done
reason=$(usable "$ROOT.partial/ffmpeg" "$ROOT.partial/ffprobe") ||
    { echo "ffmpeg-env: Debian's ffmpeg, unpacked, is not usable either: $reason" >&2; exit 1; }
echo "ffmpeg-env: installed $(version "$ROOT.partial/ffmpeg") into $ROOT" >&2
finish_install "$ROOT" "Debian's, unpacked ($(version "$ROOT.partial/ffmpeg"))"
