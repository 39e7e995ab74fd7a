#!/usr/bin/env bash
# The chosen dispatcher with heading=onward on the 100 test episodes of each issue-42 setting, with the flags of the
# chosen dispatcher's own test rows (docs/results/fleet_assignment_guard_test100.csv); Berlin in one process, Detroit
# in another. Rows in $OUT_DIR/onward_test_{berlin,detroit}.csv.
# usage: OUT_DIR=/tmp/test bash reports/2026-12-05-fleet-headings/test100.sh
set -euo pipefail
out=${OUT_DIR:-/tmp/test}; mkdir -p "$out"
py=${PYTHON:-python}
name="batch_assignment_value:value_price_s=100,wait=1,release=true,unassigned_price_s=1000,unassigned_guard_s=600,heading=onward"
common=(--count 100 --dispatchers "$name" --separation shield --hover-action --jobs 1)
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE
$py -m uamfleet fleet-bench --family detroit3gpp --settings 4x24 "${common[@]}" --out-csv "$out/onward_test_detroit.csv" &
$py -m uamfleet fleet-bench --settings 4x48 8x96 "${common[@]}" --out-csv "$out/onward_test_berlin.csv"
wait
