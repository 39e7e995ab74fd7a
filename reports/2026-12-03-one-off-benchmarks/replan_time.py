"""Time of the online step-level search ``replan`` (or ``replan_futures``) on one core.

    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/replan_time.py --family berlin --count 8
    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/replan_time.py --family detroit3gpp --count 4
    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/replan_time.py --method replan_futures --count 3

Flies ``replan`` on the first ``--count`` test instances of a family and prints each instance's thread CPU seconds
(its searches, the distance fields they read included), its solves' longest, and the total distance flown, so a
run against another checkout (``benchmarks/run_against.py``) shows both the time and that the flights are the same.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

from uamfleet.baselines.anticipation import AnticipatingReplan, DemandPrior
from uamfleet.baselines.step_planner import SearchSettings, StepPlannerPolicy
from uamfleet.cli._common import run
from uamfleet.instances import make_instance, split_seeds
from uamfleet.rollout import fly


@dataclass
class Args:
    family: str = "berlin"
    count: int = 8
    """the first instances of the test split"""
    method: Literal["replan", "replan_futures"] = "replan"
    """``replan`` (the benchmark's: beam 64, rank slack 1.0) or ``replan_futures`` (the benchmark's defaults)"""


def main(args: Args) -> None:
    total_cpu, total_m = 0.0, 0.0
    for seed in split_seeds("test", args.count):
        cfg = make_instance(args.family, seed)
        policy: StepPlannerPolicy | AnticipatingReplan
        if args.method == "replan":
            policy = StepPlannerPolicy("replan", [SearchSettings(64, rank_slack=1.0)])
        else:
            policy = AnticipatingReplan(DemandPrior.of_family(args.family, cfg))
        start = time.thread_time()
        traj = fly(cfg, policy)
        cpu = time.thread_time() - start
        if isinstance(policy, StepPlannerPolicy):
            longest = max((p.solve_s for p in policy.plans), default=0.0)
        else:  # its decisions: (step, candidates, chosen, mean moves, committed, wall s)
            longest = max((p[5] for p in policy.plans), default=0.0)
        total_cpu, total_m = total_cpu + cpu, total_m + float(traj.episode["distance_m"].sum())
        print(f"{seed}: {len(policy.plans)} solves, {cpu:.2f} s CPU, longest solve {longest:.2f} s wall, "
              f"{traj.episode['distance_m'].sum():.0f} m", flush=True)  # fmt: skip
    print(f"{args.method}, {args.family}, {args.count} instances: {total_cpu:.1f} s CPU in all, {total_m:,.0f} m flown "
          "in all")  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(run(main, Args, None, "reports/2026-12-03-one-off-benchmarks/replan_time.py", __doc__))
