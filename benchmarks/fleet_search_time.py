"""CPU seconds of each search of a fleet search (``fleet_search(BASE)``, uamfleet/baselines/fleet_search.py), on
one core: the thread CPU and wall seconds of every search (``FleetSearch.decisions``) over a few validation
episodes, as the fleet benchmark flies them (shield, hover action, the instance's stop fields made first).

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/fleet_search_time.py --taxis 8 --requests 96 --count 2 \\
        --names "fleet_search:demand=estimated,futures=2,end_wait=1"

(a fleet search named without a base searches over the chosen dispatcher,
``batch_assignment_value:100+wait=1+release+price=1000+guard=600``).

It prints, per method, the searches' p50 / p95 / max CPU seconds and how many took over ``--budget-s``, and writes
one row per search to ``--out-csv`` when given.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
import tyro

from uamfleet.baselines.assignment_value import CHOSEN_DISPATCHER
from uamfleet.baselines.fleet_steering import shared_fields
from uamfleet.config import EnvConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.io import write_csv_atomic
from uamfleet.policies import make_named
from uamfleet.rollout import Trajectory, run_episode


@dataclass
class Args:
    names: tuple[str, ...] = (f"fleet_search({CHOSEN_DISPATCHER})",)
    """the fleet searches to time, by their recorded names"""
    family: str = "berlin"
    taxis: int = 8
    requests: int = 96
    count: int = 2
    """validation episodes per method"""
    first: int = 0
    budget_s: float = 1.0
    out_csv: Path | None = None


def fly_fleet(cfg: EnvConfig, policy: Any) -> Trajectory:
    """One episode of ``policy`` on the fleet instance ``cfg`` as the fleet benchmark flies it: the instance's stop
    fields made first (untimed), shared by every dispatcher."""
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    shared_fields(env.sim, warm=True)
    return run_episode(env, policy, seed=0)


def searches_of(args: Args, name: str) -> list[dict[str, Any]]:
    """Every search of ``name`` on ``args.count`` validation episodes (one row per search)."""
    rows = []
    for seed in split_seeds("validation", args.count, args.first):
        cfg = make_fleet_instance(args.family, seed, args.taxis, args.requests, separation="shield", hover_action=True)
        policy = make_named(name)
        fly_fleet(cfg, policy)
        for d in policy.decisions:
            rows.append({"name": name, "family": args.family, "taxis": args.taxis, "requests": args.requests,
                         "seed": seed, "t": d.t, "chosen": d.chosen, "wall_s": d.wall_s, "cpu_s": d.cpu_s})  # fmt: skip
    return rows


def main(args: Args) -> list[dict[str, Any]]:
    torch.set_num_threads(1)
    rows: list[dict[str, Any]] = []
    print(f"{args.family} {args.taxis} x {args.requests}, validation episodes from "
          f"{split_seeds('validation', 1, args.first)[0]}, {args.count} per method")  # fmt: skip
    for name in args.names:
        part = searches_of(args, name)
        rows += part
        cpu = np.array([r["cpu_s"] for r in part])
        wall = np.array([r["wall_s"] for r in part])
        print(f"{name}\n  {len(cpu)} searches: CPU p50 {np.median(cpu):.3f} p95 {np.percentile(cpu, 95):.3f} "
              f"max {cpu.max():.3f} s, {int((cpu > args.budget_s).sum())} over {args.budget_s:g} s; "
              f"wall p50 {np.median(wall):.3f} max {wall.max():.3f} s", flush=True)  # fmt: skip
    if args.out_csv is not None:
        write_csv_atomic(args.out_csv, rows, list(rows[0]))
    return rows


if __name__ == "__main__":
    main(tyro.cli(Args))
