"""The training envs stepped in process and by env worker processes (``--env-workers``), side by side in one run:
agent-steps/s of the step alone (``venv.step``: dynamics, rewards, stop features, look-ahead, observations,
autoreset, and with workers the round trip and the copies out of shared memory), for the generalist's training
envs (``berlin_instances`` at five thresholds, its observation; ``--heading-lookahead`` adds the shipped policy's
input). Actions are random allowed headings drawn outside the timed calls; the first steps are not timed.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/env_workers.py --num-envs 60 1020 --workers 0 1 2
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from uamfleet.cli._common import run
from uamfleet.env.backends import make_vector
from uamfleet.paths import table_for
from uamfleet.rl.checkpoint import run_config
from uamfleet.rl.collector import training_configs
from uamfleet.rl.trainer import TrainArgs
from uamfleet.sim.world import World


@dataclass
class Args:
    num_envs: tuple[int, ...] = (60, 1020)
    workers: tuple[int, ...] = (0, 1, 2)
    """env worker processes (0: the envs in process)"""
    steps: int = 200
    """timed steps per row"""
    warmup: int = 20
    heading_lookahead: bool = False
    lookahead_depth: int = 1
    copy: bool = False
    """the workers' observations copied out of shared memory (ShardedVectorEnv's copy); the trainer's is False"""


def training_envs_configs(args: Args) -> list:
    train_args = TrainArgs.from_flat(dict(
        scenario="berlin_instances", thresholds=(-7.0, -6.0, -5.0, -4.0, -3.0), action_head="stops",
        time_limit_steps=600, shaping=0.0, heading_lookahead=args.heading_lookahead,
        lookahead_depth=args.lookahead_depth,
    ))  # fmt: skip
    cfg = run_config(train_args, "berlin_instances", training=True)
    return training_configs(train_args, cfg, "berlin_instances")


def measure(cfgs: list, num_envs: int, workers: int, args: Args) -> float:
    venv = make_vector(cfgs, num_envs, "workers" if workers else "mixture", workers=workers, copy=args.copy)
    try:
        obs, _ = venv.reset(seed=0)
        rng = np.random.default_rng(0)
        elapsed = 0.0
        for step in range(args.warmup + args.steps):
            mask = obs["action_mask"][:, 0]  # [E, 16]
            scores = np.where(mask, rng.random(mask.shape), -1.0)
            actions = scores.argmax(axis=1)[:, None]
            start = time.perf_counter()
            obs = venv.step(actions)[0]
            if step >= args.warmup:
                elapsed += time.perf_counter() - start
    finally:
        venv.close()
    return args.steps * num_envs / elapsed


def main(args: Args) -> list[dict[str, float]]:
    cfgs = training_envs_configs(args)
    for cfg in cfgs:  # the distance tables from the disk cache (or filled once), outside the timing
        table_for(World(cfg)).fill()
    depth = args.lookahead_depth if args.heading_lookahead else "off"
    print(f"the generalist's training envs (berlin_instances, 5 thresholds, look-ahead {depth}); "
          f"{args.steps} timed steps per row")  # fmt: skip
    print(f"{'envs':>6} {'workers':>8} {'agent-steps/s':>14} {'vs in process':>14}")
    rows = []
    for num_envs in args.num_envs:
        base = None
        for workers in args.workers:
            sps = measure(cfgs, num_envs, workers, args)
            base = base or sps
            rows.append({"num_envs": num_envs, "workers": workers, "sps": sps})
            print(f"{num_envs:>6} {workers:>8} {sps:>14,.0f} {sps / base:>13.2f}x", flush=True)
    return rows


if __name__ == "__main__":
    raise SystemExit(run(main, Args, None, "benchmarks/env_workers.py", __doc__))
