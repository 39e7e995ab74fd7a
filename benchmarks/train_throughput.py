"""PPO training throughput: agent-steps/s and updates/s of the whole loop (rollouts from the batched core, GAE,
Adam updates), per network variant and per number of data-parallel ranks, side by side in one run.

    OMP_NUM_THREADS=1 taskset -c 1 .venv/bin/python benchmarks/train_throughput.py            # variants, 1 rank
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/train_throughput.py --variants de_msfea --ranks 1 2
    .venv/bin/python benchmarks/train_throughput.py --device cuda --ranks 1 8 --num-envs 256   # a GPU machine
    .venv/bin/python benchmarks/train_throughput.py --scenario berlin_instances --thresholds -7 -6 -5 -4 -3 \
        --action-head stops --variants de_msfea --d-model 32 --num-envs 60 --num-steps 128 --num-minibatches 8 \
        --time-limit-steps 600 --shaping 0 --ranks 1 2   # the generalist's recipe; again with --threads 2
    OMP_NUM_THREADS=1 taskset -c 1 .venv/bin/python benchmarks/train_throughput.py --scenario berlin_fleet \
        --taxis 1 2 4 8 --variants de_msfea --d-model 32 --action-head stops --stop-prior nearest  # cost vs taxis

One rank is the plain ``train()`` (no torchrun); R > 1 ranks are R local processes with torchrun's
environment (gloo; with --device cuda they share the GPU), ``--num-envs`` and the batch being global, so
every row trains the same PPO problem. Rates are measured between the end of the first update (warm-up:
numba compilation, allocations) and the end of the last, so start-up and the final evaluation are excluded.
"CPU s/update/rank" is the CPU time the busiest rank spent per update: on a machine whose cores are shared
with other work, its ratio ("CPU speed-up") says what the ranks would gain on idle cores, before waiting.
``--taxis`` compares fleet sizes of one scenario (``num_taxis``; the ``*_fleet`` scenarios scale their demand
and passenger axis with it): "us/agent-step" is the wall time per agent-step and "vs first" its ratio to the
first size's, which grows no worse than linearly when it stays at or below the ratio of the sizes.
"""

from __future__ import annotations

import json
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path


from uamfleet.rl.distributed import launch_local
from uamfleet.rl.trainer import TrainArgs, train
from uamfleet.cli._common import run


@dataclass
class Args:
    variants: tuple[str, ...] = ("le", "de", "de_msfea", "full")
    ranks: tuple[int, ...] = (1,)
    """data-parallel world sizes to compare"""
    iterations: int = 4
    """PPO iterations per measurement (the first is warm-up and not timed)"""
    num_envs: int = 32
    """global env count (split among the ranks)"""
    num_steps: int = 64
    device: str = "cpu"
    threads: int = 1
    """torch CPU threads per rank"""
    scenario: str = "berlin_p4"
    taxis: tuple[int, ...] = ()
    """fleet sizes to compare (num_taxis); empty: the scenario's own"""
    action_head: str = "headings"
    stop_prior: str = "tour"
    d_model: int = 64
    thresholds: tuple[float, ...] = ()
    """a mixture over SINR thresholds (dB), as train/ppo.py --thresholds"""
    num_minibatches: int = 16
    update_epochs: int = 4
    """PPO epochs over each iteration's batch"""
    time_limit_steps: int = 200
    shaping: float = 50.0
    """0 turns the shaping term, and its path look-ups in every step, off"""
    heading_lookahead: bool = False
    env_workers: tuple[int, ...] = (0,)
    """env worker processes per rank to compare (TrainArgs.env_workers; 0: the envs in process); each setting is a
    row. "CPU s/update/rank" counts the trainer's process only, not its workers"""


def train_args(args: Args, variant: str, run_dir: Path, taxis: int | None = None, env_workers: int = 0) -> TrainArgs:
    return TrainArgs.from_flat(dict(
        scenario=args.scenario, num_taxis=taxis, action_head=args.action_head,
        stop_prior=args.stop_prior, d_model=args.d_model, variant=variant,
        total_timesteps=args.iterations * args.num_envs * args.num_steps * (taxis or 1), num_envs=args.num_envs,
        num_steps=args.num_steps, eval_every=0, checkpoint_every=10**9, run_dir=run_dir, run_name="bench",
        progress=False, tensorboard=False, threads=args.threads, device=args.device,
        thresholds=args.thresholds, num_minibatches=args.num_minibatches, update_epochs=args.update_epochs,
        time_limit_steps=args.time_limit_steps, shaping=args.shaping, heading_lookahead=args.heading_lookahead,
        env_workers=env_workers,
    ))  # fmt: skip


def _rank_main(args: Args, variant: str, run_dir: str, taxis: int | None = None, env_workers: int = 0) -> None:
    """Train; record each iteration's end as (wall s, this process's CPU s) in run_dir/times_rank<r>.json."""
    times: list[tuple[float, float]] = []
    result = train(train_args(args, variant, Path(run_dir), taxis, env_workers),
                   on_iteration=lambda _, __: times.append((time.perf_counter(), time.process_time())))  # fmt: skip
    (Path(run_dir) / f"times_rank{result.rank}.json").write_text(json.dumps(times))


def measure(
    args: Args, variant: str, ranks: int, taxis: int | None = None, env_workers: int = 0
) -> tuple[float, float, float]:
    """(agent-steps/s, updates/s, CPU s per update of the busiest rank), between the end of the first and of the
    last iteration."""
    with tempfile.TemporaryDirectory() as tmp:
        if ranks == 1:
            _rank_main(args, variant, tmp, taxis, env_workers)
        else:
            launch_local(ranks, _rank_main, args, variant, tmp, taxis, env_workers)
        times = [json.loads((Path(tmp) / f"times_rank{r}.json").read_text()) for r in range(ranks)]
    updates = len(times[0]) - 1
    seconds = times[0][-1][0] - times[0][0][0]
    cpu = max((t[-1][1] - t[0][1]) / updates for t in times)
    agents = taxis or 1
    return updates * args.num_envs * args.num_steps * agents / seconds, updates / seconds, cpu


def header(args: Args, batch_note: str, thread_note: str) -> str:
    return (f"{args.scenario}, {args.num_envs} envs x {args.num_steps} steps per iteration {batch_note}, "
            f"{args.update_epochs} epochs x {args.num_minibatches} minibatches, device {args.device}, "
            f"{args.threads} thread(s) {thread_note}, {args.iterations - 1} timed iterations")  # fmt: skip


def main(args: Args) -> list[dict[str, float | str | int]]:
    if args.iterations < 2:
        raise ValueError(f"iterations={args.iterations}: need >= 2 (the first is warm-up)")
    if args.taxis:
        return by_fleet_size(args)
    print(header(args, "(global)", "per rank"))
    print(f"{'variant':<10} {'ranks':>5} {'env workers':>11} {'agent-steps/s':>14} {'updates/s':>10} "
          f"{'speed-up':>9} {'CPU s/update/rank':>18} {'CPU speed-up':>13}")  # fmt: skip
    table: list[dict[str, float | str | int]] = []
    for variant in args.variants:
        base = base_cpu = None
        for ranks in args.ranks:
            for workers in args.env_workers:
                sps, ups, cpu = measure(args, variant, ranks, env_workers=workers)
                base, base_cpu = base or sps, base_cpu or cpu
                table.append({"variant": variant, "ranks": ranks, "env_workers": workers, "sps": sps, "ups": ups,
                              "speedup": sps / base, "cpu_per_update": cpu, "cpu_speedup": base_cpu / cpu})  # fmt: skip
                print(f"{variant:<10} {ranks:>5} {workers:>11} {sps:>14,.0f} {ups:>10.3f} {sps / base:>8.2f}x "
                      f"{cpu:>18.2f} {base_cpu / cpu:>12.2f}x", flush=True)  # fmt: skip
    return table


def by_fleet_size(args: Args) -> list[dict[str, float | str | int]]:
    """One rank, each variant at each fleet size of ``args.taxis``."""
    print(header(args, "(x taxis agent-steps)", f"head {args.action_head}"))
    print(f"{'variant':<10} {'taxis':>5} {'agent-steps/s':>14} {'us/agent-step':>14} {'vs first':>9} "
          f"{'taxis ratio':>12}")  # fmt: skip
    table: list[dict[str, float | str | int]] = []
    for variant in args.variants:
        first: tuple[int, float] | None = None
        for taxis in args.taxis:
            sps = measure(args, variant, 1, taxis)[0]
            us = 1e6 / sps
            first = first or (taxis, us)
            table.append({"variant": variant, "taxis": taxis, "sps": sps, "us_per_agent_step": us,
                          "cost_ratio": us / first[1], "taxis_ratio": taxis / first[0]})  # fmt: skip
            print(f"{variant:<10} {taxis:>5} {sps:>14,.0f} {us:>14.0f} {us / first[1]:>8.2f}x "
                  f"{taxis / first[0]:>11.0f}x", flush=True)  # fmt: skip
    return table


if __name__ == "__main__":
    raise SystemExit(run(main, Args, None, "benchmarks/train_throughput.py", __doc__))
