#!/usr/bin/env bash
# Fly fleet_claims checkpoints on the first 20 validation episodes of each issue-42 setting (Berlin 4x48, 8x96,
# Detroit 4x24), the protocol of reports/2026-12-04-fleet-labels/validate.sh with the policy named as a dispatcher
# (the chosen dispatcher runs alongside it); one CSV per setting in $OUT_DIR (default /tmp/fc_val).
# usage: OUT_DIR=/tmp/fc_val bash reports/2026-12-04-fleet-claims/validate.sh TAG ckpt.pt [ckpt.pt ...]
set -euo pipefail
tag=$1; shift
out=${OUT_DIR:-/tmp/fc_val}; mkdir -p "$out"
py=${PYTHON:-python}
names=(); for ckpt in "$@"; do names+=("fleet_claims:source=$ckpt"); done
common=(--split validation --count 20 --dispatchers "${names[@]}" --separation shield --hover-action --jobs 1)
OMP_NUM_THREADS=1 $py -m uamfleet fleet-bench --settings 4x48 "${common[@]}" --out-csv "$out/${tag}_4x48.csv"
OMP_NUM_THREADS=1 $py -m uamfleet fleet-bench --family detroit3gpp --settings 4x24 "${common[@]}" --out-csv "$out/${tag}_detroit.csv"
OMP_NUM_THREADS=1 $py -m uamfleet fleet-bench --settings 8x96 "${common[@]}" --out-csv "$out/${tag}_8x96.csv"
