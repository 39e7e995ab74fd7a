# Sourced by scripts/engines.sh and scripts/rt.sh: a venv outside the repository that every clone on the machine,
# CI's fresh ones included, reuses; it holds uamfleet's dependencies but not uamfleet, which the tests import from
# the checkout (`python -m pytest` from the repository root). Run from the repository root, with $PYTHON set.

# pyproject.toml's dependencies and those of the extras named, one a line.
uamfleet_requirements() {
    "$PYTHON" - "$@" <<'PY'
import sys
import tomllib

project = tomllib.load(open("pyproject.toml", "rb"))["project"]
extras = project["optional-dependencies"]
print("\n".join(project["dependencies"] + [r for extra in sys.argv[1:] for r in extras[extra]]))
PY
}

# What a venv is built from: python's version, the pins ("torch 2.13.0 ray 2.60.0"), a hash of the requirements.
venv_stamp() {
    local pins=$1 requirements=$2
    echo "python $("$PYTHON" -c 'import sys; print(sys.version.split()[0])') $pins requirements \
$(echo "$requirements" | sha256sum | cut -c1-16)"
}

# cached_venv WHO VENV STAMP TORCH_VERSION REQUIREMENTS PACKAGE...: (re)build VENV unless VENV/.stamp is STAMP.
# torch is pinned first, the CPU build from pip's configured sources, else PyTorch's CPU index, so that no package
# pulls a CUDA build; then the PACKAGEs and the REQUIREMENTS (one a line). The stamp is written last, so an
# interrupted build is redone.
cached_venv() {
    local who=$1 venv=$2 stamp=$3 torch=$4 requirements=$5
    shift 5
    if [ -f "$venv/.stamp" ] && [ "$(cat "$venv/.stamp")" = "$stamp" ]; then
        return 0
    fi
    echo "$who: setting up $venv ($* torch==$torch)"
    rm -rf "$venv"
    mkdir -p "$(dirname "$venv")"
    "$PYTHON" -m venv "$venv"
    local pip=("$venv/bin/python" -m pip install --quiet) reqs
    "${pip[@]}" --upgrade pip
    if ! "${pip[@]}" "torch==${torch}+cpu" 2>/dev/null; then
        "${pip[@]}" --index-url https://download.pytorch.org/whl/cpu "torch==${torch}"
    fi
    mapfile -t reqs <<< "$requirements"
    "${pip[@]}" "torch==${torch}" "$@" "${reqs[@]}"
    echo "$stamp" > "$venv/.stamp"
}
