#!/usr/bin/env bash
# One-step set-up on a fresh machine: a virtual environment in .venv with uamfleet (editable) and its dev tools.
# torch is pinned first to the CPU build 2.13.0: on these machines pip takes it from a local wheel in seconds,
# while an unpinned torch would pull several GB of CUDA packages.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
.venv/bin/python -m pip install --quiet --upgrade pip
.venv/bin/python -m pip install --quiet "torch==2.13.0"
.venv/bin/python -m pip install --quiet -e '.[dev]'
