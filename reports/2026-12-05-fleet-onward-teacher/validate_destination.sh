#!/usr/bin/env bash
# destination_rule.py's heading_destination on validation episodes 0-49 of each issue-42 setting, as
# reports/2026-12-05-fleet-departures/validate50.sh flies a method; rows in $OUT_DIR/dest_<setting>.csv.
set -euo pipefail
here=$(dirname "$0")
out=${OUT_DIR:-/tmp/val}; mkdir -p "$out"
py=${PYTHON:-python}
common=(--split validation --count 50 --dispatchers heading_destination --separation shield --hover-action --jobs 1)
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE PYTHONPATH=${PYTHONPATH:-.}
( $py "$here/destination_rule.py" --settings 4x48 "${common[@]}" --out-csv "$out/dest_4x48.csv"
  $py "$here/destination_rule.py" --family detroit3gpp --settings 4x24 "${common[@]}" --out-csv "$out/dest_detroit.csv" ) &
$py "$here/destination_rule.py" --settings 8x96 "${common[@]}" --out-csv "$out/dest_8x96.csv"
wait
