#!/usr/bin/env bash
# heading=onward with the value refit on its own episodes (one step of policy iteration, refit_onward.json) on
# validation episodes 0-49 of each issue-42 setting; rows in $OUT_DIR/refit_<setting>.csv, named <dispatcher>@refit_onward.
# usage: OUT_DIR=/tmp/val VALUE=/tmp/refit/refit_onward.json bash reports/2026-12-05-fleet-onward-teacher/validate_refit.sh
set -euo pipefail
out=${OUT_DIR:-/tmp/val}; mkdir -p "$out"
py=${PYTHON:-python}
onward="batch_assignment_value:value_price_s=100,wait=1,release=true,unassigned_price_s=1000,unassigned_guard_s=600,heading=onward"
common=(--split validation --count 50 --dispatchers "$onward" --assignment-value "${VALUE:?the refit value file}"
        --separation shield --hover-action --jobs 1)
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE
( $py -m uamfleet fleet-bench --settings 4x48 "${common[@]}" --out-csv "$out/refit_4x48.csv"
  $py -m uamfleet fleet-bench --family detroit3gpp --settings 4x24 "${common[@]}" --out-csv "$out/refit_detroit.csv" ) &
$py -m uamfleet fleet-bench --settings 8x96 "${common[@]}" --out-csv "$out/refit_8x96.csv"
wait
