#!/bin/bash
# Waits for the R0 sweep's seed 11, stops that sweep, then alternates R1 and R0 seed by seed (one training at a time).
cd /tmp/recipe_screen
while [ ! -s r0.csv ]; do sleep 5; done
DRIVER=$(cat r0.pid)
CHILD=$(pgrep -P $DRIVER)
kill $DRIVER; [ -n "$CHILD" ] && kill $CHILD
echo "stopped R0 sweep driver $DRIVER child $CHILD at $(date -u)"
cd /tmp/recipe_screen/code_r1
export OMP_WAIT_POLICY=PASSIVE
for s in 11 12 13 14 15 16 17 18 19 20; do
  nice -n 5 /work/main/.venv/bin/python benchmarks/quickstart_seeds.py --recipe scratch-first-delivery --seeds $s --run-dir /tmp/recipe_screen/r1 --out-csv /tmp/recipe_screen/r1.csv
  if [ $s -gt 11 ]; then
    nice -n 5 /work/main/.venv/bin/python benchmarks/quickstart_seeds.py --recipe scratch --seeds $s --run-dir /tmp/recipe_screen/r0 --out-csv /tmp/recipe_screen/r0.csv
  fi
done
echo "done $(date -u)"
