#!/bin/bash
# More validation episodes once run_validation3.sh is done (the session had time left): Detroit-like 10..19,
# Berlin 8 x 96 4..9, the peak-release episodes 3..5.
set -x
export PYTHONPATH=$PWD OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE
PY=/work/main/.venv/bin/python
V='fleet_search:demand=estimated,futures=2,waits=3,end_wait=1(batch_assignment_value:100+wait=1+release+price=1000+guard=600)'
while kill -0 "$1" 2>/dev/null; do sleep 5; done  # run_validation3.sh first
nice -n 10 $PY -m uamfleet.cli.fleet_benchmark --settings 8x96 --split validation --first 4 --count 6 --dispatchers "$V" \
    --separation shield --hover-action --jobs 1 --out-csv docs/results/fleet_search_est_val_8x96_b.csv
nice -n 10 $PY benchmarks/fleet_search_peak.py --first 3 --count 3 \
    --names batch_assignment_value:100+wait=1+release+price=1000+guard=600 "$V" "${V/demand=estimated/demand=true}" \
    --out-csv docs/results/fleet_search_peak_val_4x48_b.csv
nice -n 10 $PY -m uamfleet.cli.fleet_benchmark --family detroit3gpp --settings 4x24 --split validation --first 10 --count 10 --dispatchers "$V" \
    --separation shield --hover-action --jobs 1 --out-csv docs/results/fleet_search_est_val_detroit_b.csv
