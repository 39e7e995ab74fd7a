"""PPO training throughput: agent-steps/s and updates/s of the whole loop (rollouts from the batched core, GAE,
Adam updates), per network variant and per number of data-parallel ranks, side by side in one run.

    OMP_NUM_THREADS=1 taskset -c 1 .venv/bin/python benchmarks/train_throughput.py            # variants, 1 rank
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/train_throughput.py --variants de_msfea --ranks 1 2
    .venv/bin/python benchmarks/train_throughput.py --device cuda --ranks 1 8 --num-envs 256   # a GPU machine

One rank is the plain ``train()`` (no torchrun); R > 1 ranks are R local processes with torchrun's
environment (gloo; with --device cuda they share the GPU), ``--num-envs`` and the batch being global, so
every row trains the same PPO problem. Rates are measured between the end of the first iteration (warm-up:
numba compilation, allocations) and the end of the last, so start-up and the final evaluation are excluded.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import tyro

from uamfleet.rl.distributed import launch_local
from uamfleet.rl.trainer import TrainArgs, read_progress, train


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


def train_args(args: Args, variant: str, run_dir: Path) -> TrainArgs:
    return TrainArgs(
        variant=variant,  # type: ignore[arg-type]
        total_timesteps=args.iterations * args.num_envs * args.num_steps, num_envs=args.num_envs,
        num_steps=args.num_steps, eval_every=0, checkpoint_every=10**9, run_dir=run_dir, run_name="bench",
        progress=False, tensorboard=False, threads=args.threads, device=args.device,  # type: ignore[arg-type]
    )  # fmt: skip


def _rank_main(args: Args, variant: str, run_dir: str) -> None:
    train(train_args(args, variant, Path(run_dir)))


def measure(args: Args, variant: str, ranks: int) -> tuple[float, float]:
    """(agent-steps/s, updates/s) between the end of the first and of the last iteration."""
    with tempfile.TemporaryDirectory() as tmp:
        if ranks == 1:
            train(train_args(args, variant, Path(tmp)))
        else:
            launch_local(ranks, _rank_main, args, variant, tmp)
        rows = read_progress(Path(tmp) / "bench" / "progress.csv")
    first, last = rows[0], rows[-1]
    seconds = last["wall_s"] - first["wall_s"]
    return (last["global_step"] - first["global_step"]) / seconds, (last["iteration"] - first["iteration"]) / seconds


def main(args: Args) -> list[dict[str, float | str | int]]:
    if args.iterations < 2:
        raise ValueError(f"iterations={args.iterations}: need >= 2 (the first is warm-up)")
    defaults = TrainArgs()
    print(f"berlin_p4, {args.num_envs} envs (global) x {args.num_steps} steps per iteration, "
          f"{defaults.update_epochs} epochs x {defaults.num_minibatches} minibatches, device {args.device}, "
          f"{args.threads} thread(s) per rank, {args.iterations - 1} timed iterations")  # fmt: skip
    print(f"{'variant':<10} {'ranks':>5} {'agent-steps/s':>14} {'updates/s':>10} {'speed-up':>9}")
    table: list[dict[str, float | str | int]] = []
    for variant in args.variants:
        base = None
        for ranks in args.ranks:
            sps, ups = measure(args, variant, ranks)
            base = base or sps
            table.append({"variant": variant, "ranks": ranks, "sps": sps, "ups": ups, "speedup": sps / base})
            print(f"{variant:<10} {ranks:>5} {sps:>14,.0f} {ups:>10.3f} {sps / base:>8.2f}x", flush=True)
    return table


if __name__ == "__main__":
    main(tyro.cli(Args))
