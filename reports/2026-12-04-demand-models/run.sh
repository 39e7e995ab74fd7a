#!/usr/bin/env bash
# The figures of README.md: per new family, fit on 500 train episodes, check on 200 validation episodes.
# Run from the repository root: bash reports/2026-12-04-demand-models/run.sh
set -euo pipefail
export OMP_WAIT_POLICY=PASSIVE
here=reports/2026-12-04-demand-models
for f in berlin_stream berlin_peak berlin_burst; do
  echo "== $f"
  python -m uamfleet demand fit --family "$f" --split train --count 500 --out "$here/$f.json" --overwrite
  python -m uamfleet demand check --model "$here/$f.json" --family "$f" --split validation --count 200
done
