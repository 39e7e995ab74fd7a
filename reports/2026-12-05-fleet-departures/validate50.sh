#!/usr/bin/env bash
# Fly one fleet method on validation episodes 0-49 of each issue-42 setting (Berlin 4x48 and Detroit 4x24 in one
# process, Berlin 8x96 in another, side by side), as reports/2026-12-04-fleet-val50/ flew the candidates there.
# usage: OUT_DIR=/tmp/val bash reports/2026-12-05-fleet-departures/validate50.sh TAG "METHOD NAME"
set -euo pipefail
tag=$1; name=$2
out=${OUT_DIR:-/tmp/val}; mkdir -p "$out"
py=${PYTHON:-python}
common=(--split validation --count 50 --dispatchers "$name" --separation shield --hover-action --jobs 1)
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE
( $py -m uamfleet fleet-bench --settings 4x48 "${common[@]}" --out-csv "$out/${tag}_4x48.csv"
  $py -m uamfleet fleet-bench --family detroit3gpp --settings 4x24 "${common[@]}" --out-csv "$out/${tag}_detroit.csv" ) &
$py -m uamfleet fleet-bench --settings 8x96 "${common[@]}" --out-csv "$out/${tag}_8x96.csv"
wait
