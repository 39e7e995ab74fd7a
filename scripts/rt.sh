#!/usr/bin/env bash
# Ray-traced maps (uamfleet.radio.raytrace, uamfleet-radio-map): Sionna RT and the LLVM it needs, and their tests.
#
#   bash scripts/rt.sh            # LLVM if missing, the rt venv (cached: a second run skips it), tests/radio/test_raytrace.py
#   bash scripts/rt.sh --setup    # LLVM and the venv only
#   bash scripts/rt.sh --llvm     # only the system LLVM (scripts/setup.sh --rt calls this)
#
# Sionna RT runs on the CPU through Dr.Jit's LLVM backend, which loads the system's libLLVM. Debian 12's default
# LLVM 14/15 fail inside Dr.Jit ("LLVM ERROR: Cannot select: ... fminimum"); Debian's libllvm19 works, so it is
# installed with apt-get when no libLLVM 19 is found (as root, or through sudo), and the script says so.
# The venv ($UAMFLEET_RT_VENV, default ~/.cache/uamfleet-rt/venv) is cached outside the repository as the engines'
# is (scripts/cached_venv.sh): uamfleet's dependencies, the dev and rt extras and sionna-rt, rebuilt when a pinned
# version, python or uamfleet's dependency list changes.
set -euo pipefail
cd "$(dirname "$0")/.."
PYTHON=${PYTHON:-python3}
VENV=${UAMFLEET_RT_VENV:-${XDG_CACHE_HOME:-$HOME/.cache}/uamfleet-rt/venv}
TORCH_VERSION=2.13.0
SIONNA_RT_VERSION=2.2.0
LLVM_PACKAGE=libllvm19

ensure_llvm() {
    if ldconfig -p 2>/dev/null | grep -Eq 'libLLVM(\.so\.|-)(19|2[0-9])'; then
        return 0
    fi
    local sudo=()
    [ "$(id -u)" = 0 ] || sudo=(sudo)
    echo "rt.sh: no libLLVM 19 found (Dr.Jit fails with Debian 12's LLVM 14/15); installing Debian's $LLVM_PACKAGE with apt-get"
    if ! command -v apt-get >/dev/null; then
        echo "rt.sh: apt-get is missing; install LLVM 19 or newer with your system's package manager" >&2
        exit 1
    fi
    if ! apt-cache show "$LLVM_PACKAGE" >/dev/null 2>&1; then
        "${sudo[@]}" apt-get update -qq
    fi
    DEBIAN_FRONTEND=noninteractive "${sudo[@]}" apt-get install -y -qq "$LLVM_PACKAGE" >/dev/null
}

ensure_llvm
[ "${1:-}" = --llvm ] && exit 0

# shellcheck source=scripts/cached_venv.sh
source scripts/cached_venv.sh
requirements=$(uamfleet_requirements dev rt)
stamp=$(venv_stamp "torch $TORCH_VERSION sionna-rt $SIONNA_RT_VERSION" "$requirements")
cached_venv rt.sh "$VENV" "$stamp" "$TORCH_VERSION" "$requirements" "sionna-rt==${SIONNA_RT_VERSION}"
"$VENV/bin/python" -c 'import sionna.rt, mitsuba; print("rt.sh: sionna-rt", sionna.rt.__version__, "mitsuba variant", mitsuba.variant())'
[ "${1:-}" = --setup ] && exit 0
# Sionna is installed here, so a skipped ray-tracing test is a failure (UAMFLEET_REQUIRE_RT).
# `python -m pytest` from the repository root imports this checkout's uamfleet.
UAMFLEET_REQUIRE_RT=1 "$VENV/bin/python" -m pytest -q -p no:cacheprovider tests/radio/test_raytrace.py
