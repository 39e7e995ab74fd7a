"""Decision time of ``fleet_search`` per search step: wall and thread CPU seconds of every search of a few
validation episodes, written as a CSV (one row per search).

    PYTHONPATH=. OMP_NUM_THREADS=1 python reports/2026-12-04-fleet-search/decision_time.py \
        --family berlin --taxis 8 --requests 96 --count 2 --out decision_time_8x96.csv
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

from uamfleet.baselines.fleet_steering import shared_fields
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.io import write_csv_atomic
from uamfleet.policies import make_named
from uamfleet.rollout import run_episode

NAME = "fleet_search(batch_assignment_value:100+wait=1+release+price=1000+guard=600)"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--family", default="berlin")
    parser.add_argument("--taxis", type=int, default=8)
    parser.add_argument("--requests", type=int, default=96)
    parser.add_argument("--count", type=int, default=2)
    parser.add_argument("--out", type=Path, required=True)
    args = parser.parse_args()
    rows = []
    for seed in split_seeds("validation", args.count):
        cfg = make_fleet_instance(args.family, seed, args.taxis, args.requests, separation="shield", hover_action=True)
        env = VectorEnv(cfg, num_envs=1, autoreset=False)
        env.reset(seed=0)
        shared_fields(env.sim, warm=True)  # as the fleet benchmark: the instance's stop fields before it flies
        policy = make_named(NAME)
        run_episode(env, policy, seed=0)
        for d in policy.decisions:
            rows.append({"family": args.family, "taxis": args.taxis, "requests": args.requests, "seed": seed,
                         "t": d.t, "chosen": d.chosen, "wall_s": d.wall_s, "cpu_s": d.cpu_s})  # fmt: skip
        wall = np.array([d.wall_s for d in policy.decisions])
        cpu = np.array([d.cpu_s for d in policy.decisions])
        print(f"seed {seed}: {len(wall)} searches, wall p50 {np.median(wall):.3f} max {wall.max():.3f} s, "
              f"CPU p50 {np.median(cpu):.3f} max {cpu.max():.3f} s", flush=True)  # fmt: skip
    write_csv_atomic(args.out, rows, list(rows[0]))


if __name__ == "__main__":
    main()
