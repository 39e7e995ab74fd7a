#!/usr/bin/env bash
# A claims fleet policy with onward marks (fleet_claims:...,heading=onward) on the 100 test episodes of each issue-42
# setting, with the flags of the chosen dispatcher's own test rows (docs/results/fleet_assignment_guard_test100.csv);
# Berlin in one process, Detroit in another. Rows in $OUT_DIR/<TAG>_test_{berlin,detroit}.csv.
# usage: OUT_DIR=/tmp/test bash reports/2026-12-05-fleet-onward-marks/test100.sh TAG "METHOD NAME"
set -euo pipefail
tag=$1; name=$2
out=${OUT_DIR:-/tmp/test}; mkdir -p "$out"
py=${PYTHON:-python}
common=(--count 100 --dispatchers "$name" --separation shield --hover-action --jobs 1)
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE
$py -m uamfleet fleet-bench --family detroit3gpp --settings 4x24 "${common[@]}" --out-csv "$out/${tag}_test_detroit.csv" &
$py -m uamfleet fleet-bench --settings 4x48 8x96 "${common[@]}" --out-csv "$out/${tag}_test_berlin.csv"
wait
