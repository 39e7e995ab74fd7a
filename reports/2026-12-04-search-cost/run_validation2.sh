#!/bin/bash
# The fleet search with the estimated demand model on the validation episodes, one run after another (one core).
set -x
export PYTHONPATH=$PWD OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE
PY=/work/main/.venv/bin/python
R=reports/2026-12-04-search-cost
V='fleet_search:demand=estimated,futures=2,waits=3,end_wait=1(batch_assignment_value:100+wait=1+release+price=1000+guard=600)'
while kill -0 "$1" 2>/dev/null; do sleep 5; done  # the timing run (benchmarks/fleet_search_time.py) first
nice -n 10 $PY -m uamfleet.cli.fleet_benchmark --settings 4x48 --split validation --count 20 --dispatchers "$V" \
    --separation shield --hover-action --jobs 1 --out-csv docs/results/fleet_search_est_val_4x48.csv
nice -n 10 $PY -m uamfleet.cli.fleet_benchmark --family detroit3gpp --settings 4x24 --split validation --count 20 --dispatchers "$V" \
    --separation shield --hover-action --jobs 1 --out-csv docs/results/fleet_search_est_val_detroit.csv
nice -n 10 $PY -m uamfleet.cli.fleet_benchmark --settings 8x96 --split validation --count 10 --dispatchers "$V" \
    --separation shield --hover-action --jobs 1 --out-csv docs/results/fleet_search_est_val_8x96.csv
nice -n 10 $PY benchmarks/fleet_search_peak.py --count 6 \
    --names batch_assignment_value:100+wait=1+release+price=1000+guard=600 "$V" "${V/demand=estimated/demand=true}" \
    --out-csv docs/results/fleet_search_peak_val_4x48.csv
