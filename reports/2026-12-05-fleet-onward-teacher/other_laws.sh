#!/usr/bin/env bash
# heading=onward against the chosen dispatcher on demand and maps neither was chosen on (test split, 50 episodes
# each): Berlin 8x96 released over 5 minutes instead of 10 (twice the rate), and the Munich map at 4x48.
# usage: OUT_DIR=/tmp/law bash reports/2026-12-05-fleet-onward-teacher/other_laws.sh
set -euo pipefail
out=${OUT_DIR:-/tmp/law}; mkdir -p "$out"
py=${PYTHON:-python}
chosen="batch_assignment_value:100+wait=1+release+price=1000+guard=600"
onward="batch_assignment_value:value_price_s=100,wait=1,release=true,unassigned_price_s=1000,unassigned_guard_s=600,heading=onward"
common=(--split test --count 50 --dispatchers "$chosen" "$onward" --separation shield --hover-action --jobs 1)
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE
$py -m uamfleet fleet-bench --settings 8x96 --arrival-window-s 300 "${common[@]}" --out-csv "$out/berlin_8x96_300s.csv" &
$py -m uamfleet fleet-bench --map munich --settings 4x48 "${common[@]}" --out-csv "$out/munich_4x48.csv"
wait
