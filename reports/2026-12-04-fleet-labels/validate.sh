#!/usr/bin/env bash
# Fly checkpoints on the first 20 validation episodes of each issue-42 setting (Berlin 4x48, 8x96, Detroit 4x24), as
# docs/results/tables.toml `fleet_dagger_validation` does; one CSV per setting in $OUT_DIR (default /tmp/fl_val).
# usage: OUT_DIR=/tmp/fl_val bash reports/2026-12-04-fleet-labels/validate.sh TAG ckpt.pt [ckpt.pt ...]
set -euo pipefail
tag=$1; shift
out=${OUT_DIR:-/tmp/fl_val}; mkdir -p "$out"
py=${PYTHON:-python}
common=(--split validation --count 20 --dispatchers --checkpoints "$@" --passenger-window 24 --separation shield
        --hover-action --jobs 1)
OMP_NUM_THREADS=1 $py -m uamfleet fleet-bench --settings 4x48 "${common[@]}" --out-csv "$out/${tag}_4x48.csv"
OMP_NUM_THREADS=1 $py -m uamfleet fleet-bench --family detroit3gpp --settings 4x24 "${common[@]}" --out-csv "$out/${tag}_detroit.csv"
OMP_NUM_THREADS=1 $py -m uamfleet fleet-bench --settings 8x96 "${common[@]}" --out-csv "$out/${tag}_8x96.csv"
