"""Why the network cannot take a sixth of the dispatcher's labels: each label of one DAgger labelling that the
shipped fleet network gives a log-probability at or below PRIOR_FLOOR (e^-12), put in one category.

    PYTHONPATH=$PWD python reports/2026-12-04-fleet-labels/breakdown.py [--episodes-per-setting 2] [--seed 0]

Round 0 of ``uamfleet fleet-imitate`` (beta 1: the dispatcher flies every step, the default mixture, training seeds of
``--seed``), the start ``berlin_fleet`` reading 24 passenger rows. Categories, in this order:

- ``hover_stop_open``: the dispatcher hovers while the network reads a stop it may fly to (its hover is closed);
- ``step_aside``: the dispatcher's taxi has nothing to do but steps out of a busy taxi's way (``make_way``);
- ``outside_window``: heading for a stop of its schedule that is in none of the taxi's 24 rows;
- ``stop_weighed_out``: heading for a stop the taxi reads, on the network's own heading for it, but the network
  weighs that stop at most e^-12 (the nearness prior, the claims);
- ``path_tie``: heading for a stop the taxi reads, not the network's heading for it, but as short a way there by
  the dispatcher's own path fields (within 1 m);
- ``path_disagrees``: the same, the dispatcher's heading strictly shorter by its fields (the fields and the
  observation's distance table rank the moves differently);
- ``other``: none of these.

For the labels of the last four kinds, it also counts how many the stop label (``stop_labels``: the network's heading
for the dispatcher's stop) brings above the floor, and how many of the ruled-out labels are masked outright
(log-probability at or below MASKED_LOG_PROB: no gradient reaches them) rather than merely improbable.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter

import numpy as np

from uamfleet.rl.fleet_imitation import (
    MASKED_LOG_PROB,
    FleetImitationArgs,
    fleet_policy,
    label_episode,
    make_teacher,
    stop_points,
    training_episodes,
)
from uamfleet.rl.heads import PRIOR_FLOOR
from uamfleet.types import HOVER_ACTION, STOP_CLAIMED_BY_OTHER

TIE_M = 1.0


class Breakdown:
    """A :data:`~uamfleet.rl.fleet_imitation.StepWatch` counting the ruled-out labels by category."""

    def __init__(self) -> None:
        self.counts: Counter[str] = Counter()

    def __call__(self, env, obs, teacher, actions, log_probs) -> None:
        A = len(actions)
        self.counts["labels"] += A
        out = log_probs[np.arange(A), actions] <= PRIOR_FLOOR
        if not out.any():
            return
        rows, points = stop_points(env)
        heading_of = obs["stop_heading_mask"][0]
        open_stop = heading_of.any(-1) & (
            obs["stop_claims"][0][..., STOP_CLAIMED_BY_OTHER] == 0
        )  # [A, K] actionable, not claimed
        for a in np.flatnonzero(out):
            self.counts["ruled_out"] += 1
            self.counts["masked"] += int(log_probs[a, actions[a]] <= MASKED_LOG_PROB)
            kind = self.kind(env, teacher, a, int(actions[a]), rows, points, heading_of, open_stop, log_probs)
            self.counts[kind] += 1

    def kind(self, env, teacher, a, action, rows, points, heading_of, open_stop, log_probs) -> str:
        target = teacher.target(a)
        if action == HOVER_ACTION:
            return "hover_stop_open" if open_stop[a].any() else "other"
        if target is None:
            return "step_aside"
        serves = (rows[a] >= 0) & heading_of[a].any(-1) & np.all(np.abs(points[a] - target) < 1e-6, axis=-1)
        if not serves.any():
            return "outside_window"
        env_heading = int(np.argmax(heading_of[a, np.argmax(serves)]))
        relabel_fits = bool(log_probs[a, env_heading] > PRIOR_FLOOR)
        if env_heading == action:
            kind = "stop_weighed_out"
        else:
            pos = env.state.pos_m[0, a]
            cost = teacher.fields.remaining_m(target, pos + env.world.moves_m[[action, env_heading]])
            kind = "path_tie" if abs(cost[0] - cost[1]) <= TIE_M else "path_disagrees"
        self.counts[f"{kind}_fitted_as_stop_label"] += relabel_fits
        return kind


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--episodes-per-setting", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0)
    opts = parser.parse_args()
    args = FleetImitationArgs(episodes_per_setting=opts.episodes_per_setting, seed=opts.seed)
    policy = fleet_policy(args.init, args.passenger_window)
    watch = Breakdown()
    rng = np.random.default_rng(args.seed)
    for cfg in training_episodes(args, 0):
        label_episode(cfg, policy, make_teacher(args.teacher, cfg.num_taxis), 1.0, rng, watch=watch)
        print(cfg.num_taxis, dict(watch.counts), flush=True)
    print(json.dumps(dict(watch.counts), indent=1))


if __name__ == "__main__":
    main()
