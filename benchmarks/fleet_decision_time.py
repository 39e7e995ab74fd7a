"""Decision time of a fleet dispatcher per taxi and step, thread CPU of its calls, on validation fleet episodes.

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_decision_time.py --family berlin --setting 8x96 --count 2
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/fleet_decision_time.py --dispatcher learned --setting 32x1000 \
        --arrival-window-s 10800 --count 1        # the shipped fleet policy, a passenger window of 24 rows
    .venv/bin/python benchmarks/run_against.py <other checkout> benchmarks/fleet_decision_time.py ...   # paired

Flies the dispatcher (default: ``batch_assignment_value:100+wait=1+release``, the loaded one the committed timings
were measured with; the chosen one adds ``+price=1000+guard=600``, docs/results.md) under the shield with the hover
action, as the fleet benchmark does (every stop's field computed first, untimed), and prints each episode's TD and
median wait (so a run against another checkout shows the flights are the same) and the thread CPU per taxi and step
of the dispatcher's calls: mean, p50, p95, max, and the share of steps over 1 ms. ``--dispatcher learned`` flies
``uamfleet.pretrained("berlin_fleet")`` reading ``--passenger-window`` rows (one torch thread), as the fleet
benchmark flies it.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
import torch

from uamfleet.baselines.fleet_steering import shared_fields
from uamfleet.cli.fleet_benchmark import _learned, setting_size
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import FLEET_ARRIVAL_WINDOW_S, make_fleet_instance, split_seeds
from uamfleet.metrics import episode_metrics
from uamfleet.policies import make_flown
from uamfleet.rollout import fly
from uamfleet.sim.core import Simulator
from uamfleet.zoo import pretrained_path


class Timed:
    """A policy's calls, timed by thread CPU; flown reading what the policy reads (its spec)."""

    def __init__(self, policy) -> None:  # type: ignore[no-untyped-def]
        self.policy, self.cpu_s = policy, []
        self.spec = getattr(policy, "spec", None)

    def reset(self, sim: Simulator) -> None:
        self.policy.reset(sim)

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        start = time.thread_time()
        action = self.policy(obs)
        self.cpu_s.append(time.thread_time() - start)
        return action


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--family", default="berlin")
    parser.add_argument("--setting", default="8x96")
    parser.add_argument("--count", type=int, default=2)
    parser.add_argument("--dispatcher", default="batch_assignment_value:100+wait=1+release", help="or learned")
    parser.add_argument("--arrival-window-s", type=float, default=FLEET_ARRIVAL_WINDOW_S)
    parser.add_argument("--passenger-window", type=int, default=24, help="rows the learned policy reads")
    args = parser.parse_args()
    torch.set_num_threads(1)
    taxis, requests = setting_size(args.setting)
    per_taxi_ms = []
    for seed in split_seeds("validation", args.count):
        cfg = make_fleet_instance(args.family, seed, taxis, requests, arrival_window_s=args.arrival_window_s,
                                  separation="shield", hover_action=True)  # fmt: skip
        env = VectorEnv(cfg, num_envs=1, autoreset=False)
        env.reset(seed=0)
        if args.dispatcher == "learned":  # it reads the env's distance table, not the dispatchers' fields
            policy = _learned(pretrained_path("berlin_fleet"), taxis, requests, args.passenger_window)
        else:
            shared_fields(env.sim, warm=True)
            policy = make_flown(args.dispatcher, num_taxis=taxis)
        timed = Timed(policy)
        m = episode_metrics(fly(cfg, timed), cfg.radio)
        ms = np.asarray(timed.cpu_s) * 1000.0 / taxis
        per_taxi_ms.append(ms)
        print(f"{seed}: TD {m.td_m:.0f} m, wait p50 {m.wait_p50_s:.1f} s; ms per taxi and step: mean {ms.mean():.3f}, "
              f"p50 {np.median(ms):.3f}, max {ms.max():.1f}", flush=True)  # fmt: skip
    ms = np.concatenate(per_taxi_ms)
    print(f"{args.family} {args.setting} {args.dispatcher}: {len(ms)} steps; thread CPU ms per taxi and step: mean "
          f"{ms.mean():.3f}, p50 {np.median(ms):.3f}, p95 {np.percentile(ms, 95):.2f}, max {ms.max():.1f}; "
          f"steps over 1 ms: {100 * (ms > 1).mean():.0f} %")  # fmt: skip


if __name__ == "__main__":
    main()
