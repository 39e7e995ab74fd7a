#!/bin/bash
# alternate the new (cligrammar) and old (dc50a8b) trees on the generalist's recipe
export OMP_WAIT_POLICY=PASSIVE
PY=/work/main/.venv/bin/python
RECIPE="--scenario berlin_instances --thresholds -7 -6 -5 -4 -3 --action-head stops --variants de_msfea --d-model 32 --num-envs 60 --num-steps 128 --num-minibatches 8 --time-limit-steps 600 --shaping 0"
one() { # tree tag threads ranks...
  local tree=$1 tag=$2 th=$3; shift 3
  echo "=== $tag threads=$th ranks=$* $(date -u +%H:%M:%S) uptime:$(uptime | sed 's/.*load average//')"
  (cd $tree && PYTHONPATH=$tree timeout 900 $PY benchmarks/train_throughput.py $RECIPE --ranks "$@" --threads $th 2>&1 | grep -v Warning)
  echo "--- end $(date -u +%H:%M:%S) uptime:$(uptime | sed 's/.*load average//')"
}
one /work/wt/cligrammar new 1 1 --iterations 2
one /work/wt/tp_old old 1 1 --iterations 2
for r in 1 2 3; do
  for th in 1 2; do
    one /work/wt/cligrammar new $th 1 2
    one /work/wt/tp_old old $th 1 2
  done
done
echo ALLDONE
