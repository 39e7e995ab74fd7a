#!/usr/bin/env bash
# How many past episodes the estimated model needs: fit on 50 / 200 / 2,000 train episodes (500: run.sh), check
# on the same 200 validation episodes. Models go to /tmp (not kept). Run from the repository root.
set -euo pipefail
export OMP_WAIT_POLICY=PASSIVE
for f in berlin_stream berlin_peak berlin_burst; do
  for n in 50 200 2000; do
    echo "== $f $n"
    python -m uamfleet demand fit --family "$f" --split train --count "$n" --out "/tmp/demand_${f}_${n}.json" --overwrite
    python -m uamfleet demand check --model "/tmp/demand_${f}_${n}.json" --family "$f" --split validation --count 200
  done
done
