"""The look-ahead rule alone, beside the policy that learned from it: mean TD on validation instances.

The rule flies the heading of least ``heading_lookahead`` (each heading's move plus the shortest tour after it),
the prior's heading where it is among the least; nothing is learned. It is the reference the learned look-ahead
correction is read against (docs/results.md, "The look-ahead policy"); the first generalist (``berlin_stops``)
supplies the prior. Validation instances only (the test set is for reports):

    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/lookahead_rule.py --count 50
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import torch
import tyro

import uamfleet
from uamfleet.instances import instance_for_policy, split_seeds
from uamfleet.rollout import fly


@dataclass
class Args:
    count: int = 50
    """first validation instances of the Berlin family"""


class LookaheadRule:
    """The prior's heading unless another allowed heading has a smaller look-ahead; then the least one."""

    def __init__(self, prior: uamfleet.rl.policy.GreedyPolicy) -> None:
        self.prior = prior

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        heading = self.prior(obs)  # [1, 1]; the prior reads only its own fields
        look = obs["heading_lookahead"][0, 0]
        if look[heading[0, 0]] > 0.0:
            heading[0, 0] = int(np.argmin(look))  # not-allowed headings read LOOKAHEAD_CLIP: never the least
        return heading


def main(args: Args) -> float:
    torch.set_num_threads(1)
    prior = uamfleet.pretrained("berlin_stops")
    assert prior.trained_on is not None
    rule, start, distances = LookaheadRule(prior), time.perf_counter(), []
    for seed in split_seeds("validation", args.count):
        cfg = prior.layout(instance_for_policy("berlin", seed, prior.trained_on)).replace(heading_lookahead=True)
        distances.append(float(fly(cfg, rule, seed=0).episode["distance_m"].sum()))
    mean = float(np.mean(distances))
    print(f"look-ahead rule on the first {args.count} validation instances: mean TD {mean:,.0f} m "
          f"({time.perf_counter() - start:.0f} s)")  # fmt: skip
    return mean


if __name__ == "__main__":
    main(tyro.cli(Args))
