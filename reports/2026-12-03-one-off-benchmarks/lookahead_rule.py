"""The look-ahead rule alone, beside the policies that learned from it: mean TD on Berlin instances.

The rule flies the heading of least ``heading_lookahead`` (each heading's move, with ``--depth 2`` also the best
second move, plus the shortest tour after it); nothing is learned. Ties among the least headings go to a policy:
``--ties prior`` (the default) to the first generalist ``berlin_stops``'s heading where it is among the least, else
the lowest; ``--ties policy`` to the shipped policy's logits (``uamfleet.pretrained("berlin")``). It is the
reference the learned look-ahead correction is read against (docs/results.md, "The two-move look-ahead policy"):

    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/lookahead_rule.py --count 50                  # validation
    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/lookahead_rule.py --split test --count 200 --depth 2 --ties policy
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Literal

import numpy as np
import torch
import tyro

import uamfleet
from uamfleet.instances import fly_instances, split_seeds


@dataclass
class Args:
    count: int = 50
    """first instances of the split (Berlin family)"""
    split: Literal["validation", "test"] = "validation"
    depth: int = 1
    """the look-ahead's depth (EnvConfig.lookahead_depth: 1 or 2)"""
    ties: Literal["prior", "policy"] = "prior"


class LookaheadRule:
    """The least look-ahead heading; among equal ones the tie-breaker's (its heading, or its highest logit)."""

    def __init__(self, breaker: uamfleet.rl.policy.GreedyPolicy, by_logits: bool) -> None:
        self.breaker, self.by_logits = breaker, by_logits

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        look = np.where(obs["action_mask"][:, 0] > 0, obs["heading_lookahead"][:, 0].astype(float), np.inf)  # [E, 16]
        least = look.min(-1, keepdims=True)
        if self.by_logits:
            scores = self.breaker.logits_of(self.breaker.network_input(obs)).numpy()  # [E, 16]
        else:  # the prior reads only its own fields
            scores = np.zeros_like(look)
            scores[np.arange(len(look)), self.breaker(obs)[:, 0]] = 1.0
        heading = np.where(look <= least + 1e-6, scores, -np.inf).argmax(-1)
        no_stop = ~np.isfinite(least[:, 0]) | (obs["heading_lookahead"][:, 0].max(-1) == 0)
        return np.where(no_stop, scores.argmax(-1), heading)[:, None]


def main(args: Args) -> float:
    torch.set_num_threads(1)
    shipped = uamfleet.pretrained("berlin")
    breaker = shipped if args.ties == "policy" else uamfleet.pretrained("berlin_stops")
    breaker.loop_guard = None  # the rule is read alone
    assert shipped.trained_on is not None
    like = shipped.trained_on.replace(lookahead_depth=args.depth)
    start = time.perf_counter()
    _, distances = fly_instances(LookaheadRule(breaker, args.ties == "policy"), "berlin",
                                 split_seeds(args.split, args.count), like)  # fmt: skip
    mean = float(np.mean(distances))
    print(f"look-ahead rule, depth {args.depth}, ties to the {args.ties}, on the first {args.count} {args.split} "
          f"instances: mean TD {mean:,.1f} m ({time.perf_counter() - start:.0f} s)")  # fmt: skip
    return mean


if __name__ == "__main__":
    main(tyro.cli(Args))
