# shellcheck shell=bash
# Sourced by the scripts that provide programs in the project's git-ignored
# .venv (chromium-env.sh, ffmpeg-env.sh). Where this machine has no usable
# program of its own, they install Debian's without root: the .deb files
# are fetched with `apt-get download` and unpacked. On a fresh
# machine whose apt lists are empty, the lists are refreshed into
# .venv/apt (again without root). Run from the repository's root.

# apt's options for the private lists and cache under .venv/apt (made by
# apt_refresh, before any use).
APT_PRIVATE=(-o "Dir::State::Lists=$(realpath -m .venv/apt/lists)"
             -o "Dir::Cache=$(realpath -m .venv/apt/cache)" -o Debug::NoLocking=1)

# apt_refresh: the private lists refreshed (once a run).
apt_refresh() {
    if [ -z "${APT_REFRESHED:-}" ]; then
        mkdir -p .venv/apt/lists/partial .venv/apt/cache/archives/partial
        apt-get "${APT_PRIVATE[@]}" update >/dev/null
        APT_REFRESHED=1
    fi
}

# apt_missing PACKAGE: what installing PACKAGE would add to this machine
# (PACKAGE and the dependencies it lacks, one a line; apt's simulation
# needs no root), by this machine's lists, else by the private ones. When
# PACKAGE is installed already (but its program is not the usable one on
# the PATH), that would be nothing: then PACKAGE alone, over this
# machine's libraries. Nothing when apt knows no PACKAGE.
apt_missing() {
    local packages
    packages=$(apt_simulate "$1" || true)
    if [ -z "$packages" ] &&
        dpkg-query -W -f='${Status}\n' "$1" 2>/dev/null | grep -q ' installed$'; then
        echo "$1"
        return
    fi
    if [ -z "$packages" ]; then
        apt_refresh
        packages=$(apt_simulate "$1" "${APT_PRIVATE[@]}" || true)
    fi
    echo "$packages"
}

# apt_simulate PACKAGE [APT_OPTION...]: the packages apt would install
# with PACKAGE (its recommendations left out).
apt_simulate() {
    local package=$1
    shift
    apt-get "$@" -s install --no-install-recommends "$package" 2>/dev/null |
        awk '/^Inst /{print $2}'
}

# unpack_debs TARGET PACKAGE...: downloads the PACKAGEs' .deb files (from
# this machine's lists, else the private ones) into TARGET.debs and unpacks
# them all into TARGET. TARGET lies in the install's .partial folder, so an
# interrupted download goes with it.
unpack_debs() {
    local target=$1
    shift
    local debs="$target.debs"
    rm -rf "$debs"
    mkdir -p "$debs"
    if ! (cd "$debs" && apt-get download "$@" >/dev/null 2>&1); then
        apt_refresh
        (cd "$debs" && apt-get "${APT_PRIVATE[@]}" download "$@" >/dev/null)
    fi
    for deb in "$debs"/*.deb; do
        dpkg-deb -x "$deb" "$target"
    done
    rm -rf "$debs"
}

# finish_install ROOT [WHAT]: ROOT.partial, complete, marked installed
# (its `installed` file says WHAT was chosen) and moved to ROOT (so an
# interrupted install is never taken for a finished one).
finish_install() {
    echo "${2:-}" > "$1.partial/installed"
    rm -rf "$1"
    mv "$1.partial" "$1"
}
