#!/usr/bin/env bash
# Fly oracle searches on validation episodes 0-19 of Berlin 4x48 and Detroit 4x24, side by side (one process
# each; Berlin 8x96 was left out: about 5 min an episode). usage: OUT_DIR=/tmp/fs bash run_val20.sh NAME...
set -euo pipefail
out=${OUT_DIR:-/tmp/fs}; mkdir -p "$out"
py=${PYTHON:-python}
here=$(dirname "$0")
export OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE
common=(--split validation --count 20 --separation shield --hover-action --jobs 1 --dispatchers "$@")
$py "$here/oracle_search.py" --settings 4x48 "${common[@]}" --out-csv "$out/oracle_4x48.csv" &
$py "$here/oracle_search.py" --family detroit3gpp --settings 4x24 "${common[@]}" --out-csv "$out/oracle_detroit.csv"
wait
