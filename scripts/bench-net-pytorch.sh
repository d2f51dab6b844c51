#!/usr/bin/env bash
# The PyTorch side of the net's speed ratio (BENCHMARKS.md, "The net"):
# the matseg package's PyTorch net (matseg.net) in the project's .venv
# (scripts/python-env.sh puts the whole torch 2.11.0 there; the package is
# built and installed from ./python when it is not), timed as
# `matseg bench-net` times the Rust net, for each ARGS line given on
# standard input, e.g.
#   printf '%s\n' '--encoder mobilenet-v2 --side 256' | scripts/bench-net-pytorch.sh
set -euo pipefail
cd "$(dirname "$0")/.."
scripts/python-env.sh
if ! .venv/bin/python -c 'import matseg.net' 2>/dev/null; then
    MATURIN_PEP517_ARGS="--features torch" .venv/bin/pip install --quiet --disable-pip-version-check ./python
fi
while read -r line; do
    # shellcheck disable=SC2086
    .venv/bin/python scripts/bench-net-pytorch.py $line
done
