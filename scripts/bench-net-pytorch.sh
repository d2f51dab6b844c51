#!/usr/bin/env bash
# The PyTorch side of the net's speed ratio (BENCHMARKS.md, "The net"):
# installs torch 2.11.0 with its dependencies from PyPI into a throw-away
# venv (target/pytorch-venv, git-ignored, ~4.5 GB) and times the same net as
# `matseg bench-net` for each ARGS line given on standard input, e.g.
#   printf '%s\n' '--encoder mobilenet-v2 --side 256' | scripts/bench-net-pytorch.sh
set -euo pipefail
cd "$(dirname "$0")/.."
venv=target/pytorch-venv
if [ ! -x "$venv/bin/python" ] || ! "$venv/bin/python" -c 'import torch' 2>/dev/null; then
    python3 -m venv "$venv"
    "$venv/bin/pip" install --quiet torch==2.11.0 numpy
fi
while read -r line; do
    # shellcheck disable=SC2086
    "$venv/bin/python" scripts/bench-net-pytorch.py $line
done
