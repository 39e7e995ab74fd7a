"""Hindsight labels for a learned knob controller (issue 42, item 2: expert iteration from the fleet search).

On training episodes only, ``heading=onward`` flies as it is (its knobs never switched), and every ``every`` (10)
steps each of the 5 knob candidates of the foresight study (wait weight 1, 0, 3 at value price 100 s; value price
0 s and 300 s at wait weight 1) is rolled from the current state to the episode's end in the episode's true
future, scored by distance alone (``oracle_search.py``'s ``OracleKnobSearch``, unchanged rollouts). Each record
keeps the state at the decision, the dispatcher's schedules and the 5 costs (s of flight). A controller fitted on
them (``fit.py``) predicts from the state alone, so it reads no request before its release when it flies.

usage: LABELS_OUT=/tmp/kc/berlin.pkl python reports/2026-12-05-knob-controller/label.py --split train \
    --settings 4x48 --count 40 --separation shield --hover-action --jobs 1 --dispatchers knob_labels \
    --out-csv /tmp/kc/berlin.csv
"""

from __future__ import annotations

import os
import pickle
import sys
from dataclasses import dataclass

from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "2026-12-05-fleet-foresight"))

from oracle_search import BASES, OracleKnobSearch

from uamfleet.baselines.fleet_search import Decision, FleetSearch
from uamfleet.cli import fleet_benchmark
from uamfleet.policies import make_flown
from uamfleet.policies.registry import register


def _append(record: dict) -> None:
    """One record appended to the file named by $LABELS_OUT (read back with :func:`read_records`). The episodes
    fly in fleet-bench's worker process, so each record is written as it is made."""
    with open(os.environ["LABELS_OUT"], "ab") as f:
        pickle.dump(record, f)


def read_records(path: str) -> list[dict]:
    out = []
    with open(path, "rb") as f:
        while True:
            try:
                out.append(pickle.load(f))
            except (EOFError, pickle.UnpicklingError):  # the end, or a record still being written
                return out


class LabelKnobSearch(OracleKnobSearch):
    """Scores the knobs in the true future to the end, records them, and keeps the base's knobs."""

    def reset(self, sim) -> None:
        self.episode = f"{os.getpid()}-{id(sim)}-{int(sim.state.pax_origin_m[0, 0, 0])}"
        super().reset(sim)

    def rollout(self, candidate: int, future) -> float:
        """The base's rollout (distance alone, wait_cost 0), and beside it the passengers' total wait at its end
        (s, from release to pick-up, or to the end for one still waiting), kept in ``self.waits_s``."""
        cost = super().rollout(candidate, future)
        end = self.scratch.state
        exists = end.pax_exists[0] & (end.pax_release[0] >= 0)
        until = np.where(end.pax_pickup_step[0] >= 0, end.pax_pickup_step[0], end.t[0])
        self.waits_s.append(float(((until - end.pax_release[0])[exists]).sum()) * self.scratch.cfg.slot_s)
        return cost

    def decide(self) -> Decision:
        self.waits_s: list[float] = []
        s = self.sim.state
        snapshot = {name: np.array(getattr(s, name)[0], copy=True) for name in s._fields}
        routes = [[(int(p), str(k)) for p, k in route] for route in self.base.routes]
        decision = FleetSearch.decide(self)  # the true future's costs; then back to the base's knobs
        weight, price = self.knobs[0]
        self.base.wait_weight, self.base.value = weight, self.base.value.with_price(price)
        _append(
            {
                "episode": self.episode,
                "t": decision.t,
                "costs_s": decision.mean_costs,
                "waits_s": tuple(self.waits_s),
                "knobs": list(self.knobs),
                "state": snapshot,
                "routes": routes,
                "time_limit_steps": self.sim.cfg.time_limit_steps,
                "slot_s": self.sim.cfg.slot_s,
                "step_m": self.sim.cfg.step_m,
                "side_m": float(self.sim.world.arrays.side_m),
            }
        )
        return decision


@dataclass(frozen=True)
class LabelOptions:
    every: int = 10


register(
    "knob_labels", "dispatcher", LabelOptions,
    lambda o, _b: LabelKnobSearch(make_flown(BASES["onward"]), (0.0, 300.0), waits=(0.0, 3.0), futures=1,
                                  horizon=None, every=o.every, wait_cost=0.0),
)  # fmt: skip

if __name__ == "__main__":
    sys.exit(fleet_benchmark.cli(sys.argv[1:]))
