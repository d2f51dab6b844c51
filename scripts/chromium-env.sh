#!/usr/bin/env bash
# Provides a headless Chromium in the project's git-ignored .venv, for the
# browser tests of `matseg serve` (crates/matseg-serve/tests/browser.rs):
# .venv/chromium/chromium, which those tests start (unless
# $MATSEG_CHROMIUM names another).
#
# When this machine has a Chromium of its own (chromium-headless-shell,
# chromium, chromium-browser or google-chrome on the PATH) that renders a
# page headless, it is a wrapper that runs that one, headless. Otherwise
# Debian's chromium-headless-shell is installed there, without root: the
# .deb files are fetched with `apt-get download` and unpacked
# (scripts/debs.sh; on a fresh machine whose apt lists are empty, the
# lists are refreshed into .venv/apt), and the wrapper sets the library
# path of the unpacked libraries.
#
# .venv/chromium/installed says which was chosen. A no-op while the chosen
# browser still runs; when it no longer does (this machine's Chromium was
# removed), the choice is made again.
set -euo pipefail
cd "$(dirname "$0")/.."

ROOT=.venv/chromium
STAMP="$ROOT/installed"
# This machine's browsers worth trying, best first.
CANDIDATES=(chromium-headless-shell chromium chromium-browser google-chrome)

if [ -f "$STAMP" ]; then
    if "$ROOT/chromium" --version >/dev/null 2>&1; then
        exit 0
    fi
    chosen=$(head -1 "$STAMP")
    chosen=${chosen:-"Debian's chromium-headless-shell, unpacked"}
    echo "chromium-env: the Chromium in $ROOT ($chosen) no longer runs; choosing again" >&2
fi
rm -rf "$ROOT.partial"
mkdir -p "$ROOT.partial"
. scripts/debs.sh

# usable BROWSER...: whether the command BROWSER... (a program and the
# options that make it headless) names its Chromium version and renders a
# page headless, started as the browser tests start it (no sandbox, no GPU,
# a fresh profile); if not, why, on stdout.
usable() {
    local profile out dom
    profile="$(realpath "$ROOT.partial")/check"
    out=$("$1" --version 2>&1 || true)
    if ! grep -qE '(Chromium|Chrome) [0-9]+\.' <<<"$out"; then
        echo "$1 --version names no Chromium version ($(sed -n '$p' <<<"$out"))"
        return 1
    fi
    rm -rf "$profile"
    mkdir -p "$profile"
    dom=$(timeout 60 "$@" --no-sandbox --disable-gpu --user-data-dir="$profile" \
        --dump-dom 'data:text/html,<p>matseg</p>' 2>/dev/null || true)
    rm -rf "$profile"
    if ! grep -qF '<p>matseg</p>' <<<"$dom"; then
        echo "$* does not render a page headless"
        return 1
    fi
}

# version BROWSER: its version line.
version() {
    "$1" --version 2>/dev/null | sed -n '1p'
}

# This machine's own, when usable (and not the wrapper itself).
reasons=()
for candidate in "${CANDIDATES[@]}"; do
    browser=$(command -v "$candidate") || continue
    case "$(realpath -m "$browser")" in
        "$(realpath .venv)"/*) continue ;;
    esac
    # Only chromium-headless-shell is headless without being asked.
    headless=(--headless)
    [ "$candidate" = chromium-headless-shell ] && headless=()
    if ! reason=$(usable "$browser" "${headless[@]}"); then
        reasons+=("$reason")
        continue
    fi
    cat > "$ROOT.partial/chromium" <<WRAPPER
#!/bin/sh
# Runs this machine's $candidate headless (scripts/chromium-env.sh found it usable).
exec $(printf '%q ' "$browser" "${headless[@]}")"\$@"
WRAPPER
    chmod +x "$ROOT.partial/chromium"
    echo "chromium-env: using this machine's $browser ($(version "$browser"))" >&2
    finish_install "$ROOT" "system $browser ($(version "$browser"))"
    exit 0
done
if [ "${#reasons[@]}" = 0 ]; then
    reason="no chromium-headless-shell, chromium, chromium-browser or google-chrome on the PATH"
else
    reason=$(printf '%s; ' "${reasons[@]}")
    reason=${reason%; }
fi

if ! command -v apt-get >/dev/null || ! command -v dpkg-deb >/dev/null; then
    echo "chromium-env: $reason, and no apt-get to fetch Debian's: install Chromium (or chromium-headless-shell) on the PATH" >&2
    exit 1
fi
echo "chromium-env: $reason; installing Debian's headless Chromium into $ROOT (once; 290 to 540 MB unpacked, by the libraries this machine lacks)" >&2
# chromium-headless-shell and the libraries this machine lacks, and
# always chromium-common: the browser reads its data (ICU tables, V8
# snapshots, resources) from beside its own program.
packages=$(apt_missing chromium-headless-shell)
test -n "$packages" || { echo "chromium-env: apt knows no chromium-headless-shell package" >&2; exit 1; }
# shellcheck disable=SC2086
packages=$(printf '%s\n' chromium-common $packages | sort -u)
# shellcheck disable=SC2086
unpack_debs "$ROOT.partial/root" $packages
shell="$ROOT.partial/root/usr/lib/chromium/chromium-headless-shell"
test -x "$shell" || { echo "chromium-env: $shell missing after unpacking" >&2; exit 1; }
cat > "$ROOT.partial/chromium" <<'WRAPPER'
#!/bin/sh
# Runs the unpacked headless Chromium with its libraries.
here=$(dirname "$(realpath "$0")")
lib="$here/root/usr/lib/x86_64-linux-gnu"
export LD_LIBRARY_PATH="$lib:$lib/pulseaudio:$here/root/lib/x86_64-linux-gnu${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
exec "$here/root/usr/lib/chromium/chromium-headless-shell" "$@"
WRAPPER
chmod +x "$ROOT.partial/chromium"
reason=$(usable "$ROOT.partial/chromium") ||
    { echo "chromium-env: Debian's chromium-headless-shell, unpacked, is not usable either: $reason" >&2; exit 1; }
echo "chromium-env: installed $(version "$ROOT.partial/chromium") into $ROOT" >&2
finish_install "$ROOT" "Debian's chromium-headless-shell, unpacked ($(version "$ROOT.partial/chromium"))"
