#!/usr/bin/env bash
# A fleet method on test episodes 0-49 of two settings no method was chosen on, as
# reports/2026-12-05-fleet-onward-teacher/other_laws.sh flew the dispatchers: Berlin 8x96 with the requests released
# over 5 minutes, and the Munich map at 4x48. Rows in $OUT_DIR/<TAG>_{berlin5min,munich}.csv.
# usage: OUT_DIR=/tmp/law bash reports/2026-12-05-fleet-onward-marks/other_laws.sh TAG "METHOD NAME"
set -euo pipefail
tag=$1; name=$2
out=${OUT_DIR:-/tmp/law}; mkdir -p "$out"
py=${PYTHON:-python}
common=(--split test --count 50 --dispatchers "$name" --separation shield --hover-action --jobs 1)
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE
$py -m uamfleet fleet-bench --settings 8x96 --arrival-window-s 300 "${common[@]}" --out-csv "$out/${tag}_berlin5min.csv" &
$py -m uamfleet fleet-bench --map munich --settings 4x48 "${common[@]}" --out-csv "$out/${tag}_munich.csv"
wait
