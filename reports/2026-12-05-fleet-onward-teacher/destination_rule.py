"""Does a heading rule that reads no schedule keep the onward dispatcher's gain? ``heading=onward`` aims the move
that makes a stop at the next stop on the taxi's schedule, which only the dispatcher knows. A stop row of the
observation knows less: for a pick-up, the rider's own destination. Rule ``own_destination``: the chosen dispatcher
(its schedules and targets as it keeps them), each busy taxi flown by the field rule except on the move that makes
a pick-up, where of the moves ending within the pick-up radius it flies the one whose end is nearest that rider's
destination (by the destination's distance field); a drop-off is made by the field rule.

usage: python reports/2026-12-05-fleet-onward-teacher/destination_rule.py <fleet-bench arguments>, e.g.
  --settings 4x48 --split validation --count 50 --separation shield --hover-action --jobs 1 \
  --dispatchers heading_destination --out-csv /tmp/val/dest_4x48.csv
(registered when this file is imported, so the benchmark's worker processes know the name).
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from uamfleet.baselines.fleet_steering import make_way
from uamfleet.baselines.sequencing import PICKUP
from uamfleet.cli import fleet_benchmark
from uamfleet.policies import make_flown
from uamfleet.policies.registry import register
from uamfleet.sim.core import Simulator
from uamfleet.types import HOVER_ACTION

CHOSEN = "batch_assignment_value:100+wait=1+release+price=1000+guard=600"


class DestinationHeading:
    """The chosen dispatcher, the move that makes a pick-up aimed at that rider's destination (module docstring)."""

    def __init__(self) -> None:
        self.dispatcher = make_flown(CHOSEN)
        self.aimed = 0  # pick-up moves this rule changed, for the record

    def reset(self, sim: Simulator) -> None:
        self.dispatcher.reset(sim)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        d = self.dispatcher
        moves = d.act(obs).copy()  # its schedules advance; idle taxis hover or step aside as it flies them
        sim = d.sim
        s, world = sim.state, sim.world
        targets = [d.target(a) for a in range(d.num_taxis)]
        for a, goal in enumerate(targets):
            stop = d.next_stop(a)
            if goal is None or stop is None or stop[1] != PICKUP:
                continue
            ends = s.pos_m[0, a] + world.moves_m  # [16, 2]
            within = s.action_mask[0, a][: len(ends)] & (np.linalg.norm(ends - goal, axis=-1) <= sim.cfg.radius_m)
            if within.any():
                left = d.fields.remaining_m(d.dest_m[stop[0]], ends)
                choice = int(np.argmin(np.where(within, left, np.inf)))
                self.aimed += choice != moves[0, a]
                moves[0, a] = choice
        if sim.cfg.separation == "shield":  # idle taxis step aside from the busy taxis' moves as flown now
            idle = [t is None for t in targets]
            moves[0, idle] = np.where(sim.cfg.hover_action, HOVER_ACTION, moves[0, idle])
            make_way(sim, moves[0], idle, d._idle_at)
        return moves


@dataclass(frozen=True)
class DestinationOptions:
    pass


register("heading_destination", "dispatcher", DestinationOptions, lambda _o, _b: DestinationHeading())

if __name__ == "__main__":
    sys.exit(fleet_benchmark.cli(sys.argv[1:]))
