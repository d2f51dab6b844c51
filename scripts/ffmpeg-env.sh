#!/usr/bin/env bash
# Installs Debian's FFmpeg (the ffmpeg and ffprobe programs) into the
# project's git-ignored .venv, for `matseg track` on video files and the
# tests that encode and decode videos. No root: the .deb files of ffmpeg
# and of every library it needs that this machine lacks are fetched with
# `apt-get download` and unpacked (scripts/debs.sh). A no-op once there.
#
# The programs are .venv/ffmpeg/ffmpeg and .venv/ffmpeg/ffprobe (wrappers
# that set the library path of the unpacked libraries); matseg finds them
# there, or through $MATSEG_FFMPEG, or on the PATH. Frame folders (PNG,
# JPEG) need none of this.
set -euo pipefail
cd "$(dirname "$0")/.."

ROOT=.venv/ffmpeg
STAMP="$ROOT/installed"
if [ -f "$STAMP" ]; then
    exit 0
fi
echo "ffmpeg-env: installing Debian's ffmpeg into $ROOT (once; about 160 MB unpacked)" >&2
rm -rf "$ROOT.partial"
. scripts/debs.sh
# What installing ffmpeg would add to this machine: ffmpeg and the
# libraries it lacks (the simulation needs no root).
missing() {
    apt-get "$@" -s install --no-install-recommends ffmpeg 2>/dev/null |
        awk '/^Inst /{print $2}'
}
packages=$(missing)
if [ -z "$packages" ]; then
    apt_refresh
    packages=$(missing "${APT_PRIVATE[@]}")
fi
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
export LD_LIBRARY_PATH="\$lib:\$lib/blas:\$lib/lapack:\$lib/pulseaudio\${LD_LIBRARY_PATH:+:\$LD_LIBRARY_PATH}"
exec "\$here/root/usr/bin/$program" "\$@"
WRAPPER
    chmod +x "$ROOT.partial/$program"
done
"$ROOT.partial/ffmpeg" -hide_banner -version | head -1 >&2
finish_install "$ROOT"
