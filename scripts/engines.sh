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

# uamfleet's own requirements (pyproject.toml's dependencies and the dev extra), one a line
requirements=$("$PYTHON" - <<'PY'
import tomllib

project = tomllib.load(open("pyproject.toml", "rb"))["project"]
print("\n".join(project["dependencies"] + project["optional-dependencies"]["dev"]))
PY
)
stamp="python $("$PYTHON" -c 'import sys; print(sys.version.split()[0])') torch $TORCH_VERSION ray $RAY_VERSION \
torchrl $TORCHRL_VERSION requirements $(echo "$requirements" | sha256sum | cut -c1-16)"
if [ ! -f "$VENV/.stamp" ] || [ "$(cat "$VENV/.stamp")" != "$stamp" ]; then
    echo "engines.sh: setting up $VENV (ray[rllib]==$RAY_VERSION, torchrl==$TORCHRL_VERSION, torch==$TORCH_VERSION)"
    rm -rf "$VENV"
    mkdir -p "$(dirname "$VENV")"
    "$PYTHON" -m venv "$VENV"
    PIP=("$VENV/bin/python" -m pip install --quiet)
    "${PIP[@]}" --upgrade pip
    if ! "${PIP[@]}" "torch==${TORCH_VERSION}+cpu" 2>/dev/null; then
        "${PIP[@]}" --index-url https://download.pytorch.org/whl/cpu "torch==${TORCH_VERSION}"
    fi
    mapfile -t reqs <<< "$requirements"
    "${PIP[@]}" "torch==${TORCH_VERSION}" "ray[rllib]==${RAY_VERSION}" "torchrl==${TORCHRL_VERSION}" "${reqs[@]}"
    echo "$stamp" > "$VENV/.stamp"
fi
"$VENV/bin/python" -c 'import ray, torchrl, gymnasium; print("engines.sh: ray", ray.__version__, "torchrl", torchrl.__version__, "gymnasium", gymnasium.__version__)'
[ "${1:-}" = --setup ] && exit 0
# Both engines are installed here, so a skipped engine test is a failure (UAMFLEET_REQUIRE_ENGINES).
# `python -m pytest` from the repository root imports this checkout's uamfleet.
UAMFLEET_REQUIRE_ENGINES=1 "$VENV/bin/python" -m pytest -q -p no:cacheprovider tests/engines
