"""Solve time of the step-level planner ``best_known`` (its default search portfolio) on one core.

    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/step_planner_time.py            # 5-passenger Berlin test instances
    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/step_planner_time.py --count 5

Prints, per instance, each search's moves and seconds, the raster candidate's moves, and the total time of the
policy's ``reset`` (everything ``best_known`` computes before its first action).
"""

from __future__ import annotations

import time
from dataclasses import dataclass


from uamfleet.baselines.step_planner import CLAIRVOYANT_SETTINGS, StepPlannerPolicy, StepSearch
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import TEST_SEEDS, make_instance
from uamfleet.cli._common import run


@dataclass
class Args:
    count: int = 3
    """instances with ``passengers`` passengers (the first ones of the test split)"""
    passengers: int = 5
    feasibility: str = "endpoint_block"


def main(args: Args) -> None:
    found = 0
    for seed in TEST_SEEDS:
        if found == args.count:
            break
        cfg = make_instance("berlin", seed, feasibility=args.feasibility)  # type: ignore[arg-type]
        if len(cfg.requests or ()) != args.passengers:
            continue
        found += 1
        env = VectorEnv(cfg, 1, autoreset=False)
        env.reset(seed=0)
        search = StepSearch(cfg)
        parts = []
        for s in CLAIRVOYANT_SETTINGS:
            start = time.perf_counter()
            plan = search.solve(env.state, [s])
            parts.append(f"beam {s.beam} slack {s.rank_slack}: {plan.moves if plan else '-'} moves "
                         f"{time.perf_counter() - start:.1f} s")  # fmt: skip
        start = time.perf_counter()
        policy = StepPlannerPolicy("best_known")
        policy.reset(env)
        total = time.perf_counter() - start
        best = policy.plans[0]
        print(f"seed {seed} ({cfg.sinr_min_db:g} dB, {args.passengers} passengers): " + "; ".join(parts)
              + f" | best_known {best.moves} moves ({best.source}), whole reset {total:.1f} s", flush=True)  # fmt: skip


if __name__ == "__main__":
    raise SystemExit(run(main, Args, None, "reports/2026-12-03-one-off-benchmarks/step_planner_time.py", __doc__))
