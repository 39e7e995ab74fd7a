"""PPO training throughput per network variant: agent-steps per second of rollout + update, on one CPU thread
(or the GPU with --device cuda).

    taskset -c 1 .venv/bin/python benchmarks/train_throughput.py
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import tyro

from uamfleet.rl.trainer import TrainArgs, train


@dataclass
class Args:
    variants: tuple[str, ...] = ("le", "de", "de_msfea", "full")
    iterations: int = 3
    num_envs: int = 32
    num_steps: int = 64
    device: str = "cpu"
    threads: int = 1


def main(args: Args) -> None:
    defaults = TrainArgs()
    print(f"berlin_p4, {args.num_envs} envs x {args.num_steps} steps per iteration, {defaults.update_epochs} epochs "
          f"x {defaults.num_minibatches} minibatches, device {args.device}, {args.threads} thread(s)")  # fmt: skip
    print(f"{'variant':<10} {'agent-steps/s':>14}")
    for variant in args.variants:
        with tempfile.TemporaryDirectory() as tmp:
            result = train(TrainArgs(
                variant=variant,  # type: ignore[arg-type]
                total_timesteps=args.iterations * args.num_envs * args.num_steps, num_envs=args.num_envs,
                num_steps=args.num_steps, eval_every=0, run_dir=Path(tmp), progress=False, tensorboard=False,
                threads=args.threads, device=args.device,  # type: ignore[arg-type]
            ))  # fmt: skip
        # the final greedy evaluation is included in wall_s; it is a small share of 3 iterations
        print(f"{variant:<10} {result.global_step / result.wall_s:>14,.0f}")


if __name__ == "__main__":
    main(tyro.cli(Args))
