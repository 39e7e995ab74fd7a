#!/usr/bin/env bash
# The engines a user moves to (docs/scaling.md): RLlib and TorchRL, end to end, in a venv of their own.
#
#   bash scripts/engines.sh            # set up the engines venv (cached: a second run skips it), run tests/engines
#   bash scripts/engines.sh --setup    # set up only
#
# Why a separate venv: ray[rllib] pins an older gymnasium than the one .venv gets (ray 2.60.0: gymnasium==1.2.2),
# so the two cannot share .venv. The venv lives outside the repository ($UAMFLEET_ENGINES_VENV, default
# ~/.cache/uamfleet-engines/venv) so that every clone on the machine, CI's fresh ones included, reuses it; it holds
# uamfleet's dependencies but not uamfleet, which the tests import from this checkout. It is rebuilt when a pinned
# version, python or uamfleet's dependency list changes (its .stamp holds them). torch is pinned first, as in
# scripts/setup.sh, so that no package pulls a CUDA build.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
VENV=${UAMFLEET_ENGINES_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/uamfleet-engines/venv}
TORCH_VERSION=2.13.0
RAY_VERSION=2.60.0
TORCHRL_VERSION=0.14.1

# shellcheck source=scripts/cached_venv.sh
source scripts/cached_venv.sh
requirements=$(uamfleet_requirements dev)
stamp=$(venv_stamp "torch $TORCH_VERSION ray $RAY_VERSION torchrl $TORCHRL_VERSION" "$requirements")
cached_venv engines.sh "$VENV" "$stamp" "$TORCH_VERSION" "$requirements" "ray[rllib]==${RAY_VERSION}" \
    "torchrl==${TORCHRL_VERSION}"
"$VENV/bin/python" -c 'import ray, torchrl, gymnasium; print("engines.sh: ray", ray.__version__, "torchrl", torchrl.__version__, "gymnasium", gymnasium.__version__)'
[ "${1:-}" = --setup ] && exit 0
# Both engines are installed here, so a skipped engine test is a failure (UAMFLEET_REQUIRE_ENGINES).
# `python -m pytest` from the repository root imports this checkout's uamfleet.
UAMFLEET_REQUIRE_ENGINES=1 "$VENV/bin/python" -m pytest -q -p no:cacheprovider tests/engines
