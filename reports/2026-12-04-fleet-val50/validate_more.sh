#!/usr/bin/env bash
# Fly a fleet_claims checkpoint (or, with TAG "dispatcher" and no checkpoint, the chosen dispatcher) on validation
# episodes 20-49 of each issue-42 setting (Berlin 4x48, 8x96, Detroit 4x24): the 30 episodes after those of
# reports/2026-12-04-fleet-claims/validate.sh, so that the two together give 50 paired episodes per setting.
# usage: OUT_DIR=/tmp/fa/val bash reports/2026-12-04-fleet-val50/validate_more.sh TAG [ckpt.pt]
set -euo pipefail
tag=$1
out=${OUT_DIR:-/tmp/fa/val}; mkdir -p "$out"
py=${PYTHON:-python}
if [ "$tag" = dispatcher ]; then
  name="batch_assignment_value:100+wait=1+release+price=1000+guard=600"
else
  name="fleet_claims:source=$2"
fi
common=(--split validation --first 20 --count 30 --dispatchers "$name" --separation shield --hover-action --jobs 1)
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE
$py -m uamfleet fleet-bench --settings 4x48 "${common[@]}" --out-csv "$out/${tag}_more_4x48.csv"
$py -m uamfleet fleet-bench --family detroit3gpp --settings 4x24 "${common[@]}" --out-csv "$out/${tag}_more_detroit.csv"
$py -m uamfleet fleet-bench --settings 8x96 "${common[@]}" --out-csv "$out/${tag}_more_8x96.csv"
