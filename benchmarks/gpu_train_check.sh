#!/usr/bin/env bash
# PPO training checks for a GPU machine, one command of about 5 minutes (16 CPU cores, one GPU):
#   (a) sanity on CUDA: the seeded-determinism and must-learn tests (tests/rl/test_ppo.py run with the trainer's
#       device "auto" = cuda), the 2-rank data-parallel tests (gloo, CPU), and torchrun with one NCCL rank on the
#       GPU, trained, then resumed;
#   (b) training throughput with 1 GPU rank;
#   (c) 1 GPU + 8 CPU env ranks: 8 torchrun-style ranks, each stepping 1/8 of the envs on its own core with a
#       replica of the network on the one GPU (gloo all-reduce through host memory); then 8 CPU-only ranks;
#   (d) the generalist's recipe (issue 24's GPU target) on 1 GPU rank at 1,020 envs, its envs stepped in process
#       or by 7 or 14 env worker processes (--env-workers), the network alone on the GPU.
# The table of (b) and (c) is printed at the end and everything is written to $OUT (default out/gpu_check).
#
# The GPU image has torch with CUDA but not gymnasium, pettingzoo or tyro, and may not reach PyPI. Put their
# wheels in build/whl (ignored by git) on the development machine first and carry that folder along:
#   .venv/bin/python -m pip download --no-deps --only-binary=:all: --python-version 3.12 -d build/whl \
#       gymnasium==1.4.0 pettingzoo==1.27.0 farama-notifications==0.0.4 tyro==1.0.17 docstring-parser typeguard==4.6.1
#   then on the GPU machine: bash benchmarks/gpu_train_check.sh
# Without them it tries pip, then scripts/setup.sh (a CPU torch: the CUDA parts are then skipped, and said so).
set -uo pipefail
cd "$(dirname "$0")/.."
OUT=${OUT:-out/gpu_check}
mkdir -p "$OUT"
exec > >(tee "$OUT/gpu_train_check.log") 2>&1
export PYTHONUNBUFFERED=1 OMP_NUM_THREADS=1 PYTHONPATH="$PWD${PYTHONPATH:+:$PYTHONPATH}"
START=$SECONDS
step() { echo; echo "=== $* ($((SECONDS - START)) s)"; }

step "python with torch"
PY=""
for cand in .venv/bin/python python3 python; do
  if command -v "$cand" >/dev/null 2>&1 && "$cand" -c "import torch" 2>/dev/null; then PY=$cand; break; fi
done
ready() { [ -n "$PY" ] && "$PY" -c "import torch, numpy, numba, scipy, gymnasium, pettingzoo, tyro, tqdm" 2>/dev/null; }
if [ -n "$PY" ] && ! ready && ls build/whl/*.whl >/dev/null 2>&1; then
  "$PY" -m pip install -q --no-index --no-deps --no-compile --target /tmp/uamfleet_site build/whl/*.whl \
    && export PYTHONPATH="$PYTHONPATH:/tmp/uamfleet_site"
fi
if [ -n "$PY" ] && ! ready; then
  "$PY" -m pip install -q --retries 0 --timeout 10 --target /tmp/uamfleet_site gymnasium pettingzoo tyro 2>/dev/null \
    && export PYTHONPATH="$PYTHONPATH:/tmp/uamfleet_site"
fi
if ! ready; then
  echo "no python with uamfleet's dependencies: running scripts/setup.sh (CPU torch)"
  bash scripts/setup.sh && PY=.venv/bin/python
fi
ready || { echo "FAILED: cannot import uamfleet's dependencies (see this script's header)"; exit 1; }
CUDA=$("$PY" -c "import torch; print(int(torch.cuda.is_available()))")
"$PY" -c "import torch, numpy, numba; print('torch', torch.__version__, 'numpy', numpy.__version__, 'numba',
numba.__version__, 'cuda', torch.cuda.get_device_name(0) if torch.cuda.is_available() else None)"
echo "python $PY, $(nproc --all) CPU cores (nproc alone obeys OMP_NUM_THREADS=1), CUDA available: $CUDA"
command -v nvidia-smi >/dev/null && nvidia-smi -L
FAILED=0

step "(a) determinism + must-learn (device auto = $([ "$CUDA" = 1 ] && echo cuda || echo cpu)), 2-rank data-parallel tests"
timeout 200 "$PY" -m pytest -q -p no:cacheprovider -m "slow or not slow" tests/rl/test_ppo.py tests/rl/test_distributed.py \
  -k "identical_losses or must_learn or distributed" 2>&1 | tail -15 || FAILED=1

RUNS=$(mktemp -d)
if [ "$CUDA" = 1 ]; then
  step "(a) torchrun, one NCCL rank on cuda:0: 2 iterations, then --resume to 3"
  common=(train/ppo.py --device cuda --num-envs 16 --num-steps 32 --eval-every 0 --run-dir "$RUNS" --run-name nccl
          --no-progress --no-tensorboard)
  timeout 120 "$PY" -m torch.distributed.run --standalone --nproc_per_node=1 "${common[@]}" --total-timesteps 1024 \
    && timeout 120 "$PY" -m torch.distributed.run --standalone --nproc_per_node=1 "${common[@]}" \
      --total-timesteps 1536 --resume || FAILED=1
  cut -d, -f1-3 "$RUNS/nccl/progress.csv"
fi

bench() { timeout 150 "$PY" benchmarks/train_throughput.py --iterations 3 --num-envs 256 --num-steps 64 "$@"; }
if [ "$CUDA" = 1 ]; then
  step "(b) 1 GPU rank and (c) 1 GPU + 8 CPU env ranks (8 ranks share the GPU), 256 envs x 64 steps"
  bench --device cuda --variants de_msfea --ranks 1 8 | tee "$OUT/throughput_gpu.txt" || FAILED=1
  bench --device cuda --variants full --ranks 1 | grep -E "^full " | tee -a "$OUT/throughput_gpu.txt" || FAILED=1
fi
if [ "$CUDA" = 1 ]; then
  # issue 24's GPU recipe: the generalist's recipe, one GPU rank, 1,020 envs stepped in process or by env workers
  # (uamfleet.env.workers: one process per core, observations through shared memory); 8 x 128 = 1,020 envs x 64
  # steps per update (65,280 agent-steps), 4 epochs x 8 minibatches
  step "(d) the generalist's recipe on 1 GPU rank, 1,020 envs x 64 steps, env workers 0 / 7 / 14"
  timeout 420 "$PY" benchmarks/train_throughput.py --iterations 3 --device cuda --scenario berlin_instances \
    --thresholds -7 -6 -5 -4 -3 --action-head stops --variants de_msfea --d-model 32 --num-envs 1020 --num-steps 64 \
    --num-minibatches 8 --time-limit-steps 600 --shaping 0 --env-workers 0 7 14 | tee "$OUT/throughput_workers.txt" \
    || FAILED=1
fi
step "(c') 8 CPU-only ranks (gloo), same problem"
bench --device cpu --variants de_msfea --ranks 8 | tee "$OUT/throughput_cpu8.txt" || FAILED=1

step "summary"
echo "256 envs x 64 steps per update, 4 epochs x 16 minibatches; last column: device"
echo "variant    ranks  agent-steps/s  updates/s  speed-up  CPU s/update/rank  CPU speed-up"
grep -h -E "^(le|de|de_msfea|full) " "$OUT"/throughput_gpu.txt 2>/dev/null | sed 's/$/   cuda/'
grep -h -E "^(le|de|de_msfea|full) " "$OUT"/throughput_cpu8.txt 2>/dev/null | sed 's/$/   cpu/'
echo "the generalist's recipe, 1,020 envs x 64 steps, 1 GPU rank; the third column: env workers"
grep -h -E "^de_msfea " "$OUT"/throughput_workers.txt 2>/dev/null
rm -rf "$RUNS"
echo "done in $((SECONDS - START)) s; $([ $FAILED = 0 ] && echo 'all checks passed' || echo 'SOME CHECKS FAILED')"
exit $FAILED
