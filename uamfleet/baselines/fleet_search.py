"""Search at decision time for fleets (``fleet_search(BASE)``): a schedule dispatcher improved by rollouts over
sampled futures.

Every ``every`` steps the search scores candidate dispatchers by rolling each forward in ``futures`` sampled
futures with the env's own step (a scratch :class:`~uamfleet.sim.core.Simulator` of the episode's rules, shield
included), and flies the candidate of least mean cost until the next decision. The candidates are the base
dispatcher (a :class:`~uamfleet.baselines.fleet_dispatch.ScheduleFleetPolicy`, e.g. the chosen
``batch_assignment_value:100+wait=1+release+price=1000+guard=600``) with its wait weight β as given (candidate 0)
and with each β of ``waits`` (how much a second of wait weighs against a second of ride in its schedules). So
the fleet leans towards short waits or short flights as the sampled demand ahead makes worth it, and never
switches away from the base unless the rollouts say so (ties go to candidate 0).

Each rollout starts from the base's own schedules (its routes, the requests it has seen) and runs the candidate for
``horizon`` steps (None: to the episode's end), scored by the fleet metric's two parts over that span: distance
flown (seconds at the env's speed) plus ``wait_cost`` times the seconds passengers spent waiting (released, not yet
picked up). Futures come from :class:`FleetDemand`, the demand law of the fleet instances
(:func:`uamfleet.instances.make_fleet_instance`) given what has been released: the search reads the simulator's
released requests only (:func:`known_state` blanks every hidden row before anything is sampled), the clock and the
taxis. The futures' trips are drawn among ``sites`` of the map's flyable sites, sampled uniformly once per map
(:meth:`FleetSearch.site_sample`): each site is equally likely, as in the instances, and every stop a rollout steers
to has its distance field made at reset instead of inside a decision. Every move it returns is one the separation
shield leaves as it is (:func:`shield_passed`): where the shield would turn or hold a taxi, the search asks for what
the shield would fly instead.
"""

from __future__ import annotations

import copy
import re
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from uamfleet.baselines import fleet_steering
from uamfleet.baselines.batch_assignment import BatchAssignmentPolicy
from uamfleet.baselines.demand_models import world_family
from uamfleet.baselines.fleet_dispatch import ScheduleFleetPolicy, check_wait_weight
from uamfleet.checks import MAX_SEED, MAX_TIME_LIMIT_STEPS, ConfigError, check_integer, check_number
from uamfleet.config import FLEET_ARRIVAL_WINDOW_S, EnvConfig, fleet_window_steps
from uamfleet.env.protocol import PolicyBase
from uamfleet.instances import FAMILIES, draw_trip
from uamfleet.paths import DistanceFields
from uamfleet.sim.core import Simulator
from uamfleet.sim.generator import flyable_sites
from uamfleet.sim.motion import shield_headings, stayed_steps
from uamfleet.types import HIDDEN, HOVER_ACTION, NUM_HEADINGS, WAITING, FleetState

MAX_FUTURES = 64
"""Upper bound of ``futures``: each future is one rollout per candidate."""
MAX_SITES = 4096
"""Upper bound of ``sites``: each is one distance field made at reset."""
MAX_CANDIDATES = 8
"""Upper bound of the candidates (the base and its ``waits``)."""
DEMANDS = ("true", "estimated")
"""The demand models a fleet search samples from: the instances' law (:class:`FleetDemand`) or the one estimated
from the requests released so far (:class:`EstimatedFleetDemand`)."""


@dataclass(frozen=True)
class FleetDemand:
    """What a fleet operator knows of its demand, as :func:`~uamfleet.instances.make_fleet_instance` draws it: the
    service has ``requests`` requests (the setting's count, e.g. 48 of ``4x48``), each released at a step drawn
    uniformly from 0 … ``window_steps`` − 1, each a trip between two of the flyable ``sites`` [S, 2] at least
    ``min_trip_m`` apart (origin uniform, destination uniform among the sites that far)."""

    requests: int
    window_steps: int
    min_trip_m: float
    sites: np.ndarray

    @classmethod
    def of_fleet(cls, cfg: EnvConfig, sites: np.ndarray, arrival_window_s: float) -> FleetDemand:
        """The demand of a fleet instance's service: its family's trips and the setting's count, read from the
        scenario name (``berlin_fleet4x48_seed3``: 48), over an arrival window of ``arrival_window_s``."""
        family = world_family(cfg, "fleet_search")
        setting = re.search(r"_fleet\d+x(\d+)_seed\d+$", cfg.scenario)
        if setting is None:
            raise ConfigError(
                f"fleet_search samples a fleet service's demand, and scenario {cfg.scenario!r} names no setting "
                "(<family>_fleet<taxis>x<requests>_seed<n>): fly it on uamfleet.instances.make_fleet_instance."
            )
        window = fleet_window_steps(cfg.slot_s, arrival_window_s)
        return cls(int(setting.group(1)), window, FAMILIES[family].min_trip_m, np.asarray(sites, dtype=float))

    def sample(self, known: FleetState, rng: np.random.Generator) -> FleetState:
        """A future of env 0 of ``known`` (:func:`known_state`): the requests still to come added as hidden rows,
        released at steps after now, with trips drawn as the instances draw them."""
        t = int(known.t[0])
        exists = known.pax_exists[0]
        more = self.requests - int(exists.sum())
        future = known.copy()
        if more <= 0:
            return future
        free = np.flatnonzero(~exists)
        if len(free) < more:
            raise ConfigError(f"the state has {len(free)} free passenger rows for {more} requests still to come: "
                              f"lay it out with max_passengers >= {self.requests}.")  # fmt: skip
        last = max(self.window_steps, t + 2)  # a request still hidden is released after now (at the latest: next)
        for row in free[:more]:
            origin, dest = draw_trip(rng, self.sites, self.min_trip_m)
            if dest is None:  # no site that far from this origin: the next one
                dest = (origin + 1) % len(self.sites)
            future.pax_exists[0, row] = True
            future.pax_release[0, row] = int(rng.integers(t + 1, last))
            future.pax_origin_m[0, row] = self.sites[origin]
            future.pax_dest_m[0, row] = self.sites[dest]
        return future


@dataclass(frozen=True)
class EstimatedFleetDemand:
    """A fleet demand model estimated from the requests released so far in the episode, knowing only the service's
    arrival window (its hours: releases at steps 0 … ``window_steps`` − 1) and the futures' ``sites``.

    - The release rate: the requests released at steps 0 … t over those t + 1 steps, a homogeneous rate (a Poisson
      process: the count still to come is drawn Poisson with the rate times the window's steps left, at most the
      free passenger rows; their release steps uniform over them).
    - The trips: with weight n (requests seen) against ``floor``, a seen request's origin and destination, each
      moved by a Gaussian of ``bandwidth_m`` and put on the nearest site (a kernel density on the sites); else a
      uniform site and a destination at least the shortest seen trip away (uniform among them).

    It reads ``known`` (:func:`known_state`) alone: the released rows, the clock."""

    window_steps: int
    sites: np.ndarray
    bandwidth_m: float = 300.0
    floor: float = 1.0

    def rate_per_step(self, known: FleetState) -> float:
        """Requests per step estimated at the clock of ``known``: those released by now over the steps seen."""
        seen = min(int(known.t[0]), self.window_steps - 1) + 1
        return float(np.count_nonzero(known.pax_exists[0])) / seen

    def sample(self, known: FleetState, rng: np.random.Generator) -> FleetState:
        """A future of env 0 of ``known``: the requests the estimated rate brings over the window's steps left, as
        hidden rows released after now, with trips from the kernel density of the seen ones."""
        t = int(known.t[0])
        exists = known.pax_exists[0]
        future = known.copy()
        left = self.window_steps - 1 - t
        if left <= 0:
            return future
        free = np.flatnonzero(~exists)
        more = min(int(rng.poisson(self.rate_per_step(known) * left)), len(free))
        origins, dests = known.pax_origin_m[0, exists], known.pax_dest_m[0, exists]
        shortest = float(np.min(np.linalg.norm(dests - origins, axis=-1))) if len(origins) else 0.0
        for row in free[:more]:
            future.pax_exists[0, row] = True
            future.pax_release[0, row] = int(rng.integers(t + 1, self.window_steps))
            if rng.random() * (len(origins) + self.floor) < len(origins):  # near a seen trip
                j = int(rng.integers(len(origins)))
                origin = self._nearest(origins[j] + rng.normal(0.0, self.bandwidth_m, 2))
                dest = self._nearest(dests[j] + rng.normal(0.0, self.bandwidth_m, 2))
                if dest == origin:
                    dest = (origin + 1) % len(self.sites)
            else:
                origin, far = draw_trip(rng, self.sites, max(shortest, 1.0))
                dest = far if far is not None else (origin + 1) % len(self.sites)
            future.pax_origin_m[0, row] = self.sites[origin]
            future.pax_dest_m[0, row] = self.sites[dest]
        return future

    def _nearest(self, point: np.ndarray) -> int:
        return int(np.argmin(np.linalg.norm(self.sites - point, axis=-1)))


def known_state(state: FleetState) -> FleetState:
    """Env 0 of ``state`` with only its released requests: every hidden row is emptied (not existing, no trip, no
    release step), so nothing of a request before its release is left to read."""
    known = state.take(np.array([0]))
    hidden = known.pax_status[0] == HIDDEN
    known.pax_exists[0, hidden] = False
    known.pax_release[0, hidden] = 0
    known.pax_origin_m[0, hidden] = 0.0
    known.pax_dest_m[0, hidden] = 0.0
    known.pax_taxi[0, hidden] = -1
    known.pax_pickup_step[0, hidden] = -1
    known.pax_dropoff_step[0, hidden] = -1
    known.stop_pair_m[:] = np.nan  # the stop features' cache (unknown: looked up again)
    known.stop_tour_key[:] = -1
    return known


def shield_passed(sim: Simulator, actions: np.ndarray) -> np.ndarray:
    """[1, A] ``actions`` of env 0 as the separation shield flies them (docs/rules.md "Separation shield"): a move
    the shield would turn aside becomes the heading it turns to, one it would hold becomes a hover (the hover
    action, or a forbidden heading in a world without it), so the shield intervenes in none. Without the shield:
    ``actions`` as they are."""
    out = np.array(actions, dtype=np.int64).reshape(1, -1)
    if sim.cfg.separation != "shield":
        return out
    s, taxis = sim.state, np.arange(sim.num_taxis)
    allowed = s.action_mask[0]
    flown = np.empty(sim.num_taxis, np.int64)
    for _ in range(4):  # a taxi moved apart (rule 7) may change whom a later taxi meets: passed again until fixed
        asked = out[0]
        shield_headings(s.pos_m[0], s.free_seats[0], stayed_steps(s.pos_m[0], s.history_m[0]), allowed, asked,
                        sim.world.arrays, flown)  # fmt: skip
        moves = (asked != HOVER_ACTION) & allowed[taxis, np.minimum(asked, NUM_HEADINGS - 1)]
        if np.array_equal(flown, np.where(moves, asked, -1)):
            return out
        out[0] = np.where(flown >= 0, flown, [_stay_action(sim, a, int(k)) for a, k in enumerate(asked)])
    return out


def _stay_action(sim: Simulator, taxi: int, asked: int) -> int:
    """An action that keeps ``taxi`` where it is: the hover, else a heading the mask forbids (``asked`` itself
    when it is one), else ``asked`` (no way to stay: the shield decides)."""
    if sim.cfg.hover_action:
        return HOVER_ACTION
    forbidden = np.flatnonzero(~sim.state.action_mask[0, taxi])
    if asked < NUM_HEADINGS and asked in forbidden:
        return asked
    return int(forbidden[0]) if forbidden.size else asked


@dataclass(frozen=True)
class Decision:
    """One search: at step ``t`` the mean cost of each candidate over the futures, the one chosen, and the wall
    and thread CPU seconds it took."""

    t: int
    mean_costs: tuple[float, ...]
    chosen: int
    wall_s: float
    cpu_s: float


class FleetSearch(PolicyBase):
    """``fleet_search(BASE)``: the schedule dispatcher ``base`` whose wait weight is chosen every ``every`` steps
    by rollouts over sampled futures (module docstring). ``decisions`` keeps every search of the episode."""

    def __init__(
        self, base: ScheduleFleetPolicy, waits: Sequence[float] = (0.0, 3.0), futures: int = 3,
        horizon: int | None = 10, every: int = 5, wait_cost: float = 1.0,
        arrival_window_s: float = FLEET_ARRIVAL_WINDOW_S, seed: int = 0, sites: int = 48, demand: str = "true",
        end_wait: float = 0.0, cpu_budget_s: float | None = None,
    ) -> None:  # fmt: skip
        if not isinstance(base, ScheduleFleetPolicy):
            raise ConfigError(f"fleet_search rolls a schedule dispatcher forward; base={base!r} is none (give e.g. "
                              "batch_assignment_value:100+wait=1+release+price=1000+guard=600).")  # fmt: skip
        weights = [base.wait_weight, *(check_wait_weight("waits", w) for w in waits)]
        self.wait_weights = tuple(dict.fromkeys(weights))  # candidate 0: the base as given; repeats dropped
        if len(self.wait_weights) > MAX_CANDIDATES:
            raise ConfigError(f"waits={tuple(waits)!r} makes {len(self.wait_weights)} candidates; at most "
                              f"{MAX_CANDIDATES} (e.g. waits=0;3).")  # fmt: skip
        self.futures = check_integer("futures", futures, 1, MAX_FUTURES, fix=" (e.g. 4)")
        if horizon is not None:
            horizon = check_integer("horizon", horizon, 1, MAX_TIME_LIMIT_STEPS, fix=" or None (to the end), e.g. 15")
        self.horizon = horizon
        self.every = check_integer("every", every, 1, MAX_TIME_LIMIT_STEPS, fix=" (steps between searches, e.g. 5)")
        self.wait_cost = check_number("wait_cost", wait_cost, minimum=0.0)
        self.arrival_window_s = check_number("arrival_window_s", arrival_window_s, positive=True)
        self.seed = check_integer("seed", seed, 0, MAX_SEED)
        self.sites = check_integer("sites", sites, 2, MAX_SITES, fix=" (sites the futures' trips are drawn among)")
        if demand not in DEMANDS:
            raise ConfigError(f"demand={demand!r} is unknown; choose one of {DEMANDS}.")
        self.demand_model = demand
        self.end_wait = check_number("end_wait", end_wait, minimum=0.0)
        if cpu_budget_s is not None:
            cpu_budget_s = check_number("cpu_budget_s", cpu_budget_s, positive=True)
        self.cpu_budget_s = cpu_budget_s
        self.base = base
        self.sim: Simulator | None = None
        # one unflown copy of the base per candidate, each reset on the scratch core for every rollout
        self.rollers = [copy.deepcopy(base) for _ in self.wait_weights]
        for roller, weight in zip(self.rollers, self.wait_weights, strict=True):
            roller.wait_weight = weight
        self.decisions: list[Decision] = []

    def reset(self, sim: Simulator) -> None:
        if sim.num_envs != 1:
            raise ValueError(f"FleetSearch drives a one-env core, got num_envs={sim.num_envs}")
        sites = self.site_sample(sim)
        self.demand: FleetDemand | EstimatedFleetDemand = (
            FleetDemand.of_fleet(sim.cfg, sites, self.arrival_window_s) if self.demand_model == "true"
            else EstimatedFleetDemand(fleet_window_steps(sim.cfg.slot_s, self.arrival_window_s), sites)
        )  # fmt: skip
        self.sim = sim
        self.base.wait_weight = self.wait_weights[0]
        self.base.reset(sim)
        self.fields: DistanceFields = self.base.fields  # rollouts steer by the same per-stop fields
        for site in self.demand.sites:  # each sampled stop's field made now, not inside a decision
            self.fields.remaining_m(site, site[None])
        self.scratch = Simulator(sim.cfg, 1, autoreset=False)
        self.scratch.reset(seed=0)  # its state is overwritten by a future before every rollout
        self.speed_mps = sim.cfg.step_m / sim.cfg.slot_s
        self.decisions = []

    def site_sample(self, sim: Simulator) -> np.ndarray:
        """[min(sites, S), 2] the flyable sites the futures' trips are drawn among: a uniform sample of the map's,
        drawn from ``seed`` alone (the same every episode of a map). Every stop of a rollout then steers by one of
        that many distance fields, made at reset (the map's ~1,000 sites' would take 5 s on Berlin, 110 s on the
        Detroit-like map, and more memory than a field cache holds there)."""
        every = flyable_sites(sim.world)
        if self.sites >= len(every):
            return every
        rng = np.random.default_rng([self.seed, len(every)])
        return every[np.sort(rng.choice(len(every), self.sites, replace=False))]

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        assert self.sim is not None, "call reset(sim) first (run_episode does)"
        if int(self.sim.state.t[0]) % self.every == 0:
            self.decide()
        return shield_passed(self.sim, self.base.act(obs))

    def decide(self) -> Decision:
        """Score every candidate in the same sampled futures and give the base the wait weight of the least mean
        cost (ties: the lowest index, the base as given first)."""
        assert self.sim is not None, "call reset(sim) first"
        start, cpu = time.perf_counter(), time.thread_time()
        t = int(self.sim.state.t[0])
        futures = self.sample_futures(np.random.default_rng([self.seed, t]))
        costs = []  # [futures flown, candidates]: every candidate in the same futures (common random numbers)
        for future in futures:
            costs.append([self.rollout(c, future) for c in range(len(self.rollers))])
            spent = time.thread_time() - cpu
            if self.cpu_budget_s is not None and spent * (len(costs) + 1) / len(costs) > self.cpu_budget_s:
                break  # one more future would likely overrun the budget: decide on those flown
        means = np.array(costs).mean(axis=0)
        chosen = int(np.argmin(means))
        self.base.wait_weight = self.wait_weights[chosen]
        decision = Decision(t, tuple(float(m) for m in means), chosen, time.perf_counter() - start,
                            time.thread_time() - cpu)  # fmt: skip
        self.decisions.append(decision)
        return decision

    def sample_futures(self, rng: np.random.Generator) -> list[FleetState]:
        """The futures every candidate is rolled in: ``futures`` draws of the demand model given the released
        requests alone (:func:`known_state`)."""
        assert self.sim is not None
        known = known_state(self.sim.state)
        return [self.demand.sample(known, rng) for _ in range(self.futures)]

    def rollout(self, candidate: int, future: FleetState) -> float:
        """Cost (s) of candidate ``candidate`` flown from the base's schedules in ``future`` for ``horizon`` steps:
        the distance flown at the env's speed plus ``wait_cost`` times the passengers' waiting seconds."""
        scratch, roller = self.scratch, self.rollers[candidate]
        for name, value in zip(FleetState._fields, future, strict=True):
            getattr(scratch.state, name)[:] = value
        scratch.needs_reset = False
        self.start_roller(roller)
        flown_before = float(scratch.state.distance_m[0].sum())
        waited_steps = 0
        steps = self.horizon if self.horizon is not None else scratch.cfg.time_limit_steps
        for _ in range(steps):
            waited_steps += int(np.count_nonzero(scratch.state.pax_status[0] == WAITING))
            _, terminated, truncated, _ = scratch.advance(roller.act({}), events=False)
            if terminated[0] or truncated[0]:
                break
        flown_s = (float(scratch.state.distance_m[0].sum()) - flown_before) / self.speed_mps
        cost = flown_s + self.wait_cost * waited_steps * scratch.cfg.slot_s
        if self.end_wait:  # the passengers still waiting at the horizon: their wait so far, as a debt the tail pays
            waiting = scratch.state.pax_status[0] == WAITING
            ages = int(scratch.state.t[0]) - scratch.state.pax_release[0, waiting]
            cost += self.end_wait * float(ages.sum()) * scratch.cfg.slot_s
        return cost

    def start_roller(self, roller: ScheduleFleetPolicy) -> None:
        """Reset ``roller`` on the scratch core, steering by the episode's fields and holding the base's schedules
        as they stand (its routes, the requests it has seen, where its idle taxis zig-zag)."""
        shared = dict(fleet_steering._LAST_FIELDS)  # reset() shares fields by instance: keep the real episode's
        # the schedules' reset alone: a valued batch's site remoteness (79 ms to make) is the base's, its sites fixed
        ScheduleFleetPolicy.reset(roller, self.scratch)
        fleet_steering._LAST_FIELDS.clear()
        fleet_steering._LAST_FIELDS.update(shared)
        roller.fields = self.fields
        if isinstance(roller, BatchAssignmentPolicy) and roller.value is not None:
            assert isinstance(self.base, BatchAssignmentPolicy)
            roller._remoteness = self.base._remoteness
            roller._dest_remoteness = roller._remoteness(roller.dest_m)
        roller.routes = [list(route) for route in self.base.routes]
        roller._seen = self.base._seen.copy()
        roller._idle_at = [None if p is None else p.copy() for p in self.base._idle_at]


__all__ = ["DEMANDS", "Decision", "EstimatedFleetDemand", "FleetDemand", "FleetSearch", "known_state", "shield_passed"]
