#!/usr/bin/env bash
# One-step set-up on a fresh machine: a virtual environment in .venv with uamfleet (editable), its dev tools and
# the documentation site's builder (extras dev and docs).
#
#   bash scripts/setup.sh                  # CPU build of torch (the default; all this project needs)
#   bash scripts/setup.sh --torch cuda     # the default index's build instead (CUDA on Linux), for a GPU
#   UAMFLEET_TORCH=cuda bash scripts/setup.sh
#   bash scripts/setup.sh --rt             # also the extra 'rt' (Sionna RT: ray-traced maps, uamfleet-radio-map)
#
# torch is installed first, pinned to $TORCH_VERSION, so that `pip install -e .` finds it satisfied: an unpinned
# torch from the default index (PyPI) is the CUDA build on Linux, several GB of packages.
# CPU build: first the pinned CPU wheel ("X+cpu") from pip's configured sources (a local wheel or mirror, when
# the machine has one: seconds, no download), else PyTorch's CPU wheel index (download.pytorch.org/whl/cpu).
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
TORCH_VERSION=2.13.0
TORCH_CPU_INDEX=https://download.pytorch.org/whl/cpu
MODE=${UAMFLEET_TORCH:-cpu}
EXTRAS=dev,docs

usage() { echo "usage: bash scripts/setup.sh [--torch cpu|cuda] [--rt]   (or UAMFLEET_TORCH=cpu|cuda; default cpu)" >&2; }
while [ $# -gt 0 ]; do
    case "$1" in
        --torch) [ $# -ge 2 ] || { usage; exit 2; }; MODE=$2; shift 2 ;;
        --torch=*) MODE=${1#--torch=}; shift ;;
        --rt) EXTRAS=dev,docs,rt; shift ;;
        -h|--help) usage; exit 0 ;;
        *) echo "setup.sh: unknown argument '$1'" >&2; usage; exit 2 ;;
    esac
done
case "$MODE" in
    cpu|cuda) ;;
    *) echo "setup.sh: torch build '$MODE' is unknown; use cpu or cuda" >&2; usage; exit 2 ;;
esac

[ -x .venv/bin/python ] || "$PYTHON" -m venv .venv
PIP=(.venv/bin/python -m pip install --quiet)
"${PIP[@]}" --upgrade pip

# The torch already in .venv, as "<version> <cpu|cuda>", or "none".
torch_build() {
    .venv/bin/python - <<'EOF' 2>/dev/null || echo none
import importlib.util

if importlib.util.find_spec("torch") is None:
    print("none")
else:
    import torch

    print(torch.__version__.split("+")[0], "cuda" if torch.version.cuda else "cpu")
EOF
}

installed=$(torch_build)
if [ "$installed" != "$TORCH_VERSION $MODE" ]; then
    if [ "$installed" != none ]; then
        echo "setup.sh: replacing torch $installed with the $MODE build of $TORCH_VERSION"
        .venv/bin/python -m pip uninstall --quiet --yes torch
    fi
    if [ "$MODE" = cpu ]; then
        if ! "${PIP[@]}" "torch==${TORCH_VERSION}+cpu" 2>/dev/null; then
            echo "setup.sh: no CPU wheel torch==${TORCH_VERSION}+cpu in pip's configured sources; using $TORCH_CPU_INDEX"
            "${PIP[@]}" --index-url "$TORCH_CPU_INDEX" "torch==${TORCH_VERSION}"
        fi
    else
        "${PIP[@]}" "torch==${TORCH_VERSION}"
    fi
    installed=$(torch_build)
fi
echo "setup.sh: torch $installed build"
if [ "$installed" != "$TORCH_VERSION $MODE" ]; then
    echo "setup.sh: warning: asked for the $MODE build of torch $TORCH_VERSION, got '$installed'" >&2
fi
if [ "$EXTRAS" = dev,docs,rt ]; then
    bash scripts/rt.sh --llvm
fi
.venv/bin/python -m pip install --quiet -e ".[$EXTRAS]"
# Compile the numba kernels into their on-disk cache now (about a minute once per machine and source change), so
# the first command after set-up starts at once: the first training iteration came 40 s after the command on a
# fresh machine, 16 s with the kernels cached (docs/benchmarks.md, "first training on a fresh machine").
.venv/bin/python -m uamfleet.warmup
