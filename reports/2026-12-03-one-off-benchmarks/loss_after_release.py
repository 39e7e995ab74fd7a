"""Where a shipped look-ahead policy loses to ``replan``: the policy flown alone, beside the policy flown until each
instance's last release and then handed to ``replan``'s solver (beam 64, rank slack 0.5) over the then-complete
requests (docs/results.md, "The two-move look-ahead policy"). A diagnostic, not a method: it reads each instance's
last release time, which no online policy may know. Validation instances only:

    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/loss_after_release.py --policy berlin_lookahead1 --count 50
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch
import tyro

import uamfleet
from uamfleet.baselines.step_planner import SearchSettings, StepSearch, released_only
from uamfleet.instances import instance_for_policy, split_seeds
from uamfleet.rollout import fly


@dataclass
class Args:
    policy: str = "berlin"
    """a shipped policy's name (uamfleet.zoo.PRETRAINED)"""
    count: int = 50
    """first validation instances of the Berlin family"""
    beam: int = 64


class SolverAfterLastRelease:
    """The policy until the instance's last release, then the solver's plan over every request."""

    def __init__(self, policy: uamfleet.rl.policy.GreedyPolicy, beam: int) -> None:
        self.policy, self.beam = policy, beam

    def reset(self, env) -> None:  # type: ignore[no-untyped-def]
        self.env, self.plan = env, None
        self.policy.reset(env)
        s = env.state
        self.last_release = int(s.pax_release[0][s.pax_exists[0]].max())

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        if int(self.env.state.t[0]) >= self.last_release:
            if self.plan is None:
                found = StepSearch(self.env.cfg).solve(
                    released_only(self.env.state), [SearchSettings(beam=self.beam, rank_slack=0.5)]
                )
                self.plan = list(found.actions) if found is not None else []
            if self.plan:
                return np.array([[self.plan.pop(0)]])
        return self.policy(obs)


def main(args: Args) -> tuple[float, float]:
    torch.set_num_threads(1)
    policy = uamfleet.pretrained(args.policy)
    assert policy.trained_on is not None
    alone, handed, start = [], [], time.perf_counter()
    for seed in split_seeds("validation", args.count):
        cfg = policy.layout(instance_for_policy("berlin", seed, policy.trained_on))
        alone.append(float(fly(cfg, policy, seed=0).episode["distance_m"].sum()))
        handed.append(float(fly(cfg, SolverAfterLastRelease(policy, args.beam), seed=0).episode["distance_m"].sum()))
    wall = time.perf_counter() - start
    print(f"{args.policy} on the first {args.count} validation instances: alone {np.mean(alone):,.0f} m; until the "
          f"last release, then replan's solver: {np.mean(handed):,.0f} m ({wall:.0f} s)")  # fmt: skip
    return float(np.mean(alone)), float(np.mean(handed))


if __name__ == "__main__":
    main(tyro.cli(Args))
