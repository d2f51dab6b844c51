#!/usr/bin/env bash
# The Python package built without libtorch, installed with pip into a
# virtual environment that has no torch, and its tests that need no torch:
# it describes, selects, tracks and scores on the pure-Rust engine, and the
# parts that need PyTorch say what to install (docs/python.md).
#
# The environment is target/python-without-torch (git-ignored, made once
# from .venv's Python with numpy, pytest and Pillow, the versions
# scripts/python-env.sh pins); the package is built in the dev profile,
# sharing the Rust tests' build folder. Run from .ci/run after them (the
# tests compare the package with target/debug/matseg).
set -euo pipefail
cd "$(dirname "$0")/.."
VENV=target/python-without-torch
PACKAGES=("numpy==2.4.6" "pytest==9.2.0" "pillow==13.0.0")
if [ ! -x "$VENV/bin/python" ]; then
    echo "test-python-without-torch: making $VENV (once)" >&2
    .venv/bin/python -m venv "$VENV"
    "$VENV/bin/pip" install --quiet --disable-pip-version-check "${PACKAGES[@]}"
fi
MATURIN_PEP517_ARGS="--profile dev" "$VENV/bin/pip" install --quiet --disable-pip-version-check ./python
if "$VENV/bin/python" -c 'import torch' 2>/dev/null; then
    echo "test-python-without-torch: torch is importable in $VENV; it must not be" >&2
    exit 1
fi
"$VENV/bin/python" -m pytest -q -p no:cacheprovider \
    python/tests/test_without_torch.py python/tests/test_model.py python/tests/test_track.py \
    python/tests/test_evaluate.py python/tests/test_generator.py
