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

from uamfleet.baselines.fleet_steering import fleet_actions
from uamfleet.baselines.sequencing import PICKUP
from uamfleet.cli import fleet_benchmark
from uamfleet.policies import make_flown
from uamfleet.policies.registry import register
from uamfleet.sim.core import Simulator

CHOSEN = "batch_assignment_value:100+wait=1+release+price=1000+guard=600"


class DestinationHeading:
    """The chosen dispatcher, the move that makes a pick-up aimed at that rider's destination (module docstring):
    the package's onward steering (``fleet_actions``) with the rider's destination as the point after a pick-up and
    none after a drop-off."""

    def __init__(self) -> None:
        self.dispatcher = make_flown(CHOSEN)

    def reset(self, sim: Simulator) -> None:
        self.dispatcher.reset(sim)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        d = self.dispatcher
        d.act(obs)  # its schedules advance by this step; its own moves are replaced below
        stops = [d.next_stop(a) for a in range(d.num_taxis)]
        targets = [None if stop is None else d.stop_point(stop) for stop in stops]
        onwards = [d.dest_m[stop[0]] if stop is not None and stop[1] == PICKUP else None for stop in stops]
        return fleet_actions(d.sim, d.fields, d._idle_at, targets, None, onwards)


@dataclass(frozen=True)
class DestinationOptions:
    pass


register("heading_destination", "dispatcher", DestinationOptions, lambda _o, _b: DestinationHeading())

if __name__ == "__main__":
    sys.exit(fleet_benchmark.cli(sys.argv[1:]))
