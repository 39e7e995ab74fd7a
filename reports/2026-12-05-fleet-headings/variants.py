"""Which part of the observation's heading rule moves the chosen dispatcher's distance and waits: the two rules
(module docstring of uamfleet.baselines.fleet_dispatch) differ in the distance they read (the stop's distance field
or the block table) and in the moves that end within the pick-up radius (the field rule: the end nearest the stop
by its field; the table rule: any such move costs the move alone, so the lowest heading wins). Two crossings:

  heading_variant:rule=table_nearest   the table's distance, and within the radius the end nearest the stop
  heading_variant:rule=field_lowest    the field's distance, and within the radius the lowest heading
  heading_variant:rule=field_following the field's distance, and within the radius the end nearest the stop after
                                       this one on the taxi's schedule (by that stop's field; none: the field rule)
  heading_variant:rule=field / table   controls: the dispatcher's own rule and heading=table, through this wrapper

usage: python reports/2026-12-05-fleet-headings/variants.py <fleet-bench arguments>, e.g.
  --settings 4x48 --split validation --count 50 --separation shield --hover-action --jobs 1 \
  --dispatchers heading_variant:rule=table_nearest --out-csv /tmp/val/tn_4x48.csv
(the names are registered when this file is imported, so the benchmark's worker processes, which import it as
their main module, know them too). reports/2026-12-05-fleet-headings/README.md.
"""

from __future__ import annotations

import sys
from dataclasses import dataclass

import numpy as np

from uamfleet.baselines.fleet_steering import make_way
from uamfleet.cli import fleet_benchmark
from uamfleet.observe.moves import progress_heading
from uamfleet.paths import table_for
from uamfleet.policies import make_flown
from uamfleet.policies.registry import register
from uamfleet.sim.core import Simulator
from uamfleet.types import HOVER_ACTION

CHOSEN = "batch_assignment_value:100+wait=1+release+price=1000+guard=600"
RULES = ("table_nearest", "field_lowest", "field_following", "field", "table")


class HeadingVariant:
    """The chosen dispatcher (its schedules and targets as it keeps them), each busy taxi flown by ``rule``."""

    def __init__(self, rule: str) -> None:
        assert rule in RULES, rule
        self.rule, self.dispatcher = rule, make_flown(CHOSEN)

    def reset(self, sim: Simulator) -> None:
        self.dispatcher.reset(sim)
        self.table = table_for(sim.world)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        d = self.dispatcher
        moves = d.act(obs).copy()  # its schedules advance; idle taxis hover or step aside as it flies them
        sim = d.sim
        s, world = sim.state, sim.world
        targets = [d.target(a) for a in range(d.num_taxis)]
        for a, goal in enumerate(targets):
            if goal is None or self.rule == "field":
                continue
            pos, allowed = s.pos_m[0, a], s.action_mask[0, a]
            ends = pos + world.moves_m  # [16, 2]
            gap = np.linalg.norm(ends - goal, axis=-1)
            within = allowed[: len(ends)] & (gap <= sim.cfg.radius_m)
            if within.any() and self.rule == "field_following":
                after = d.stop_after(a)  # the package's heading=onward reads the same stop
                if after is not None:
                    left = d.fields.remaining_m(after, ends)
                    moves[0, a] = int(np.argmin(np.where(within, left, np.inf)))
            elif within.any() and self.rule != "table":
                moves[0, a] = (
                    int(np.argmin(np.where(within, gap, np.inf)))
                    if self.rule == "table_nearest"
                    else int(np.flatnonzero(within)[0])
                )
            elif self.rule in ("table_nearest", "table"):
                heading = progress_heading(self.table, world.arrays, allowed, pos, goal)
                moves[0, a] = heading if heading >= 0 else moves[0, a]
            # field_lowest beyond the radius: the dispatcher's own field move, already in moves
        if sim.cfg.separation == "shield":  # idle taxis step aside from the busy taxis' moves as flown now
            idle = [t is None for t in targets]
            moves[0, idle] = np.where(sim.cfg.hover_action, HOVER_ACTION, moves[0, idle])
            make_way(sim, moves[0], idle, d._idle_at)
        return moves


@dataclass(frozen=True)
class VariantOptions:
    rule: str = "table_nearest"


register("heading_variant", "dispatcher", VariantOptions, lambda o, _b: HeadingVariant(o.rule))

if __name__ == "__main__":
    sys.exit(fleet_benchmark.cli(sys.argv[1:]))
