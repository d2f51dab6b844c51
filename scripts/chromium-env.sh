#!/usr/bin/env bash
# Installs Debian's headless Chromium into the project's git-ignored .venv
# (no root: the .deb files are fetched with `apt-get download` and
# unpacked by scripts/debs.sh), for the browser tests of `matseg serve`
# (crates/matseg-serve/tests/browser.rs). A no-op once there.
#
# The browser is .venv/chromium/chromium (a wrapper that sets the library
# path of the unpacked libraries and runs chromium-headless-shell).
# On a fresh machine whose apt lists are empty, the lists are refreshed
# into .venv/apt (again without root).
set -euo pipefail
cd "$(dirname "$0")/.."

ROOT=.venv/chromium
STAMP="$ROOT/installed"
# chromium-headless-shell and the libraries it needs beyond a minimal
# Debian system with the project's build tools.
PACKAGES=(
    chromium-headless-shell chromium-common libopenh264-7 libdouble-conversion3
    libopus0 libharfbuzz-subset0 libxnvctrl0 libpulse0 libflac12 libminizip1
    libogg0 libsndfile1 libasyncns0 libvorbis0a libvorbisenc2 libmpg123-0
    libmp3lame0
)

if [ -f "$STAMP" ]; then
    exit 0
fi
echo "chromium-env: installing headless Chromium into $ROOT (once; ~70 MB download)" >&2
rm -rf "$ROOT.partial"
. scripts/debs.sh
unpack_debs "$ROOT.partial/root" "${PACKAGES[@]}"
shell="$ROOT.partial/root/usr/lib/chromium/chromium-headless-shell"
test -x "$shell" || { echo "chromium-env: $shell missing after unpacking" >&2; exit 1; }
cat > "$ROOT.partial/chromium" <<'WRAPPER'
#!/bin/sh
# Runs the unpacked headless Chromium with its libraries.
here=$(dirname "$(realpath "$0")")
lib="$here/root/usr/lib/x86_64-linux-gnu"
export LD_LIBRARY_PATH="$lib:$lib/pulseaudio${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
exec "$here/root/usr/lib/chromium/chromium-headless-shell" "$@"
WRAPPER
chmod +x "$ROOT.partial/chromium"
"$ROOT.partial/chromium" --version >&2
finish_install "$ROOT"
