# Sourced by the scripts that install Debian packages into the project's
# git-ignored .venv without root (chromium-env.sh, ffmpeg-env.sh): the
# .deb files are fetched with `apt-get download` and unpacked. On a fresh
# machine whose apt lists are empty, the lists are refreshed into
# .venv/apt (again without root). Run from the repository's root.

mkdir -p .venv/apt/lists/partial .venv/apt/cache/archives/partial
# apt's options for the private lists and cache under .venv/apt.
APT_PRIVATE=(-o "Dir::State::Lists=$(realpath .venv/apt/lists)"
             -o "Dir::Cache=$(realpath .venv/apt/cache)" -o Debug::NoLocking=1)

# apt_refresh: the private lists refreshed (once a run).
apt_refresh() {
    if [ -z "${APT_REFRESHED:-}" ]; then
        apt-get "${APT_PRIVATE[@]}" update >/dev/null
        APT_REFRESHED=1
    fi
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

# finish_install ROOT: ROOT.partial, complete, marked installed and moved
# to ROOT (so an interrupted install is never taken for a finished one).
finish_install() {
    touch "$1.partial/installed"
    rm -rf "$1"
    mv "$1.partial" "$1"
}
