#!/usr/bin/env bash
# Prepares the project's git-ignored .venv for the Python package's tests
# (python/tests): the whole torch 2.11.0 (`import torch` needs its CUDA
# libraries even on a CPU: scripts/torch-env.sh --cuda) and the packages
# the tests exercise, and the linter and type checker, pinned. A no-op
# once done.
#
# The package itself is built and installed by `.ci/run` after the Rust
# tests (`pip install ./python` with its `torch` feature, reusing their
# build folder).
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/torch-env.sh --cuda

PACKAGES=(
    "numpy==2.4.6"
    "pytest==9.2.0"
    "pillow==13.0.0"
    "onnx==1.23.2"
    "onnxscript==0.7.2"
    "onnxruntime==1.32.0"
    "ray==2.60.0"
    # The package's linter and type checker (.ci/run runs both).
    "ruff==0.17.6"
    "mypy==2.4.1"
)
STAMP=".venv/matseg-python-test-deps-$(printf '%s\n' "${PACKAGES[@]}" | sha256sum | cut -c1-12)"
if [ ! -f "$STAMP" ]; then
    echo "python-env: installing the Python tests' packages into .venv (once)" >&2
    .venv/bin/pip install --quiet --disable-pip-version-check "${PACKAGES[@]}"
    touch "$STAMP"
fi
