"""How much the fleet search could gain if it knew the future: ``fleet_search`` with its sampled futures replaced
by the episode's true one (every hidden request as the simulator holds it, released at its own step).

  oracle_search:over=chosen,horizon=10   the chosen dispatcher; candidates: its wait weight 1 (as given), 0 and 3
  oracle_search:over=onward,horizon=40   the same over batch_assignment_value with heading=onward
  oracle_search:over=onward,horizon=40,prices=0;300   also the learned value priced at 0 s and 300 s (base: 100 s)
  oracle_search:over=onward,horizon=40,pins=true      candidates are assignments: one of the 2 newest waiting
                                                       requests pinned to one of the 3 other taxis nearest it
  horizon=0 rolls to the episode's end; wait_cost=0 scores distance alone (the rest of the episode's flight)
  truth=false,futures=3 the same candidates in 3 futures sampled from the instances' law (a search, no foresight)

Every ``every`` (5) steps each candidate is rolled ``horizon`` steps in the true future with the env's own step
(FleetSearch.rollout, unchanged) and the least cost is flown until the next search. This reads requests before
their release: it is a bound on what better futures could buy the search over these candidates, not a method.

usage: python reports/2026-12-05-fleet-foresight/oracle_search.py <fleet-bench arguments>, e.g.
  --settings 4x48 --split validation --count 20 --separation shield --hover-action --jobs 1 \
  --dispatchers oracle_search:over=chosen,horizon=10 --out-csv /tmp/fs/oracle_c10_4x48.csv
(the names are registered when this file is imported, as in reports/2026-12-05-fleet-headings/variants.py).
"""

from __future__ import annotations

import copy
import sys
import types
from dataclasses import dataclass

import numpy as np

from uamfleet.baselines.fleet_search import Decision, FleetSearch
from uamfleet.baselines.sequencing import PICKUP
from uamfleet.cli import fleet_benchmark
from uamfleet.policies import make_flown
from uamfleet.policies.registry import register
from uamfleet.types import WAITING, FleetState

BASES = {
    "chosen": "batch_assignment_value:100+wait=1+release+price=1000+guard=600",
    "onward": "batch_assignment_value:value_price_s=100,wait=1,release=true,unassigned_price_s=1000,"
    "unassigned_guard_s=600,heading=onward",
}


class OracleFleetSearch(FleetSearch):
    """FleetSearch whose one future is the true one (module docstring)."""

    def sample_futures(self, rng: np.random.Generator) -> list[FleetState]:
        assert self.sim is not None
        return [FleetState(*(np.array(v, copy=True) for v in self.sim.state))]


class KnobSearch(FleetSearch):
    """The fleet search whose candidates also change the price of the learned value in the assignment: candidate
    0 the base as given, then wait weights 0 and 3 at the base's value price, then value prices ``prices`` at the
    base's wait weight (``knobs``)."""

    def __init__(self, base, prices: tuple[float, ...], **kw) -> None:
        super().__init__(base, **kw)
        assert base.value is not None
        self.knobs = [(w, base.value.price_s) for w in self.wait_weights] + [(base.wait_weight, p) for p in prices]
        extra = [copy.deepcopy(base) for _ in prices]
        self.rollers = self.rollers + extra
        for roller, (weight, price) in zip(self.rollers, self.knobs, strict=True):
            roller.wait_weight, roller.value = weight, base.value.with_price(price)
        self.wait_weights = tuple(w for w, _ in self.knobs)
        self.base_value = base.value

    def reset(self, sim) -> None:
        self.base.value = self.base_value  # the base as given at every episode's start
        super().reset(sim)

    def decide(self) -> Decision:
        decision = super().decide()
        weight, price = self.knobs[decision.chosen]
        self.base.wait_weight, self.base.value = weight, self.base.value.with_price(price)
        return decision


class OracleKnobSearch(OracleFleetSearch, KnobSearch):
    """:class:`KnobSearch` in the true future."""


def _pinned_trips(self, waiting):
    """BatchAssignmentPolicy.candidate_trips without the trips that give a pinned request to another taxi than its
    pin (bound to a dispatcher instance by :class:`OracleAssignmentSearch`)."""
    trips, routes, free_s = type(self).candidate_trips(self, waiting)
    keep = [k for k, (a, requests, _) in enumerate(trips) if all(self.pins.get(r, a) == a for r in requests)]
    return [trips[k] for k in keep], [routes[k] for k in keep], [free_s[k] for k in keep]


def _batch_now(policy) -> None:
    """Run the dispatcher's batch assignment now, whether or not one is due."""
    due = policy.batch_due
    policy.batch_due = lambda released: True
    try:
        policy.dispatch([])
    finally:
        policy.batch_due = due


class OracleAssignmentSearch(OracleFleetSearch):
    """The oracle search whose candidates are assignments: candidate 0 the base as it flies; each other candidate
    pins one of the ``newest`` most recently released waiting requests to one of the ``taxis`` other taxis nearest
    its origin (a batch is run at once with the pin, and the pin holds ``pin_steps`` steps or until the pick-up)."""

    def __init__(self, base, newest: int = 2, taxis: int = 3, pin_steps: int = 40, **kw) -> None:
        super().__init__(base, waits=(), **kw)
        self.newest, self.taxis, self.pin_steps = newest, taxis, pin_steps
        base.pins = {}
        base.candidate_trips = types.MethodType(_pinned_trips, base)
        self._pool = [copy.deepcopy(base) for _ in range(1 + newest * taxis)]
        self.pinned_at: dict[int, int] = {}

    def reset(self, sim) -> None:
        self.base.pins, self.pinned_at = {}, {}
        super().reset(sim)

    def candidates(self) -> list[tuple[int, int] | None]:
        s, base = self.sim.state, self.base
        waiting = np.flatnonzero(s.pax_status[0] == WAITING)
        owner = {p: a for a, route in enumerate(base.routes) for p, kind in route if kind == PICKUP}
        newest = sorted((p for p in waiting if p not in base.pins), key=lambda p: -s.pax_release[0, p])[: self.newest]
        out: list[tuple[int, int] | None] = [None]
        for p in newest:
            gaps = np.linalg.norm(s.pos_m[0] - s.pax_origin_m[0, p], axis=-1)
            others = [int(a) for a in np.argsort(gaps, kind="stable") if a != owner.get(int(p), -1)]
            out += [(int(p), a) for a in others[: self.taxis]]
        return out

    def decide(self) -> Decision:
        s, t = self.sim.state, int(self.sim.state.t[0])
        for p in [p for p, at in self.pinned_at.items() if t - at >= self.pin_steps or s.pax_status[0, p] != WAITING]:
            self.base.pins.pop(p, None)
            del self.pinned_at[p]
        self._options = self.candidates()
        self.rollers = self._pool[: len(self._options)]  # FleetSearch.decide rolls every roller
        self.wait_weights = (self.base.wait_weight,) * len(self._options)
        decision = super().decide()
        if self._options[decision.chosen] is not None:
            p, a = self._options[decision.chosen]
            self.base.pins[p], self.pinned_at[p] = a, t
            _batch_now(self.base)
        return decision

    def start_roller(self, roller) -> None:
        super().start_roller(roller)
        k = self.rollers.index(roller)
        roller.pins = dict(self.base.pins)
        if self._options[k] is not None:
            p, a = self._options[k]
            roller.pins[p] = a
            _batch_now(roller)


@dataclass(frozen=True)
class OracleOptions:
    over: str = "chosen"
    horizon: int = 10
    every: int = 5
    prices: str = ""  # value prices (s) as extra candidates, e.g. "0;300"
    pins: bool = False  # candidates are assignments instead (OracleAssignmentSearch)
    wait_cost: float = 1.0  # weight of a second of waiting against a second of flight in a rollout's cost
    truth: bool = True  # false: the package's sampled futures (``futures`` of them), no foresight
    futures: int = 3


def _make(o: OracleOptions) -> OracleFleetSearch:
    kw = {
        "futures": 1 if o.truth else o.futures,
        "horizon": o.horizon or None,  # 0: to the episode's end
        "every": o.every,
        "wait_cost": o.wait_cost,
    }
    if o.pins:
        return OracleAssignmentSearch(make_flown(BASES[o.over]), **kw)
    if o.prices:
        prices = tuple(float(p) for p in o.prices.split(";"))
        knobs = OracleKnobSearch if o.truth else KnobSearch
        return knobs(make_flown(BASES[o.over]), prices, waits=(0.0, 3.0), **kw)
    return OracleFleetSearch(make_flown(BASES[o.over]), waits=(0.0, 3.0), **kw)


register("oracle_search", "dispatcher", OracleOptions, lambda o, _b: _make(o))

if __name__ == "__main__":
    sys.exit(fleet_benchmark.cli(sys.argv[1:]))
