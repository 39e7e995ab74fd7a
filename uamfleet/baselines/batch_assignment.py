"""The schedule dispatchers: request insertion and batch (taxi, trip) assignment.

Both are :class:`~uamfleet.baselines.fleet_dispatch.ScheduleFleetPolicy` subclasses: per-taxi stop schedules,
sequenced exactly for the total ride time (plus β times the total wait with ``+wait=<β>``), repaired every step and
flown along feasible paths (:mod:`~uamfleet.baselines.fleet_dispatch`); they differ in how a released request joins
a schedule.

- :class:`InsertionPolicy` (``insertion``): each request, when released, goes to the taxi whose schedule cost grows
  least when the request is added and the taxi's stops are re-sequenced exactly (ties: lowest taxi index). A
  taxi with more than ``exact_limit`` passengers to serve keeps its order and gets the request's pick-up and
  drop-off at their cheapest positions instead (classic insertion; counted in ``stats["heuristic_inserts"]``).
- :class:`BatchAssignmentPolicy` (``batch_assignment``), in the style of Alonso-Mora et al. (PNAS 2017): every
  ``period`` steps, the released requests nobody has picked up yet are re-assigned. For each taxi, trips of up to
  ``seats`` such requests are built (from its ``max_requests_per_taxi`` cheapest single requests; every trip is
  feasible, since the exact sequencing respects capacity and precedence), each costed by the increase of the
  taxi's schedule cost when the trip joins its passengers on board. An integer programme
  (:func:`assign_trips`, ``scipy.optimize.milp`` / HiGHS) picks at most one trip per taxi and serves each request
  at most once, with ``penalty_s`` (10⁶ s) for every request left unassigned (it waits for the next batch), or
  with ``unassigned_price_s`` (``+price=<s>``) that price plus (1 + β) times the request's wait so far, so that a
  taxi is not made to take a second request whatever it costs; ``unassigned_guard_s`` (``+guard=<s>``) prices a
  request that has waited longer than it at ``penalty_s`` again, so no price starves it. With
  ``assign_on_release`` (``+release``) a batch also runs at every step where a request is released. With a learned
  ``value`` (``batch_assignment_value``, :mod:`~uamfleet.baselines.assignment_value`), each trip's cost is lowered
  by ``price_s`` times the value of the state it leaves the taxi in, relative to taking no new trip (NeurADP-style).
- :class:`RecordingAssignment`: ``batch_assignment`` that records the post-decision states and pick-ups the learned
  value is fitted from (``python -m train.assignment_value``).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence

import numpy as np
from scipy.optimize import Bounds, LinearConstraint, milp

from uamfleet.baselines.assignment_value import MAX_SECONDS, LinearValue, SiteRemoteness
from uamfleet.baselines.fleet_dispatch import ScheduleFleetPolicy, Stop
from uamfleet.checks import MAX_TIME_LIMIT_STEPS, ConfigError, check_flag, check_integer, check_number
from uamfleet.sim.core import Simulator
from uamfleet.sim.generator import flyable_sites
from uamfleet.types import ON_BOARD, WAITING

MAX_REQUESTS_PER_TAXI = 32
"""Upper bound of ``max_requests_per_taxi``: a batch builds every trip of up to ``seats`` of that many requests per
taxi (496 pairs, 35,960 quadruples at this bound), each sequenced exactly."""


def check_seconds(name: str, value: float, fix: str = "") -> float:
    """``value`` as a finite number of seconds in ``[0, MAX_SECONDS]``; ConfigError naming ``name`` otherwise."""
    value = check_number(name, value, minimum=0.0)
    if value > MAX_SECONDS:
        raise ConfigError(f"{name}={value!r} is too large: at most {MAX_SECONDS:g} s{fix}.")
    return value


class InsertionPolicy(ScheduleFleetPolicy):
    """``insertion``: each released request goes to the taxi whose schedule cost (total ride time) grows least
    with it, the taxi's stops re-sequenced exactly (module docstring)."""

    def dispatch(self, released: list[int]) -> None:
        for p in released:
            best: tuple[float, int, list[Stop]] | None = None
            for a in range(self.num_taxis):
                grow, route = self.insertion_cost(a, p)
                if best is None or grow < best[0] - 1e-9:
                    best = (grow, a, route)
            assert best is not None
            self.routes[best[1]] = best[2]

    def insertion_cost(self, taxi: int, passenger: int) -> tuple[float, list[Stop]]:
        """(increase of the taxi's schedule cost in seconds, new route) when ``passenger`` joins it."""
        waiting = self.waiting_of(taxi)
        old = self.schedule_cost(taxi, self.routes[taxi]) if self.routes[taxi] else self._riding_cost(taxi)
        if len(waiting) + len(self.on_board(taxi)) + 1 <= self.exact_limit:
            plan, route = self.sequence(taxi, [*waiting, passenger])
            return self.plan_cost(plan) - old, route
        cost, route = self.cheapest_insertion(taxi, passenger)
        return cost - old, route

    def _riding_cost(self, taxi: int) -> float:
        return self.plan_cost(self.sequence(taxi, [])[0]) if self.on_board(taxi) else 0.0


def assign_trips(
    trips: Sequence[tuple[int, tuple[int, ...], float]],
    num_taxis: int,
    requests: Sequence[int],
    penalty_s: float | Sequence[float],
) -> list[int]:
    """Indices of the chosen ``(taxi, requests of the trip, cost)`` rows: the exact optimum of

    minimise sum(cost · x) + sum of penalty_s over the requests not served, each taxi at most one trip, each
    request at most once, x binary; solved by ``scipy.optimize.milp`` (HiGHS). Ties are HiGHS's choice.
    ``penalty_s``: one price for every request, or one per request in the order of ``requests``."""
    if not trips:
        return []
    index = {r: i for i, r in enumerate(requests)}
    n = len(trips)
    if np.ndim(penalty_s) == 0:  # one price: the same sums as before per-request prices existed
        c = np.array([cost - float(penalty_s) * len(reqs) for _, reqs, cost in trips])  # type: ignore[arg-type]
    else:
        price = {r: float(p) for r, p in zip(requests, penalty_s, strict=True)}  # type: ignore[arg-type]
        c = np.array([cost - sum(price[r] for r in reqs) for _, reqs, cost in trips])
    a_taxi = np.zeros((num_taxis, n))
    a_req = np.zeros((len(requests), n))
    for k, (taxi, reqs, _) in enumerate(trips):
        a_taxi[taxi, k] = 1.0
        for r in reqs:
            a_req[index[r], k] = 1.0
    result = milp(
        c,
        integrality=np.ones(n),
        bounds=Bounds(0.0, 1.0),
        constraints=[LinearConstraint(a_taxi, -np.inf, 1.0), LinearConstraint(a_req, -np.inf, 1.0)],
    )
    if not result.success or result.x is None:
        raise RuntimeError(f"the trip assignment programme failed: {result.message}")
    return [k for k in range(n) if result.x[k] > 0.5]


class BatchAssignmentPolicy(ScheduleFleetPolicy):
    """``batch_assignment``: every ``period`` steps, the requests not yet picked up are re-assigned to taxis by an
    exact (taxi, trip) assignment (module docstring; Alonso-Mora et al., PNAS 2017)."""

    def __init__(
        self,
        period: int = 3,
        max_requests_per_taxi: int = 6,
        penalty_s: float = 1e6,
        exact_limit: int = 6,
        value: LinearValue | None = None,
        wait_weight: float = 0.0,
        assign_on_release: bool = False,
        unassigned_price_s: float | None = None,
        unassigned_guard_s: float | None = None,
        heading: str = "field",
    ) -> None:
        super().__init__(exact_limit, wait_weight, heading)
        # a request left unassigned costs this plus (1 + β) × the wait it has had (None: penalty_s for every one).
        # A trip's cost counts its riders' waits since their release, so a flat finite price would make a request
        # dearer to serve at every batch it waits and, once dearer than the price, never served; the wait so far
        # added to its price leaves only what is still to come to be weighed.
        if unassigned_price_s is not None:
            unassigned_price_s = check_seconds("unassigned_price_s", unassigned_price_s, " or None (penalty_s)")
        self.unassigned_price_s = unassigned_price_s
        # A finite price can still starve a request whose remaining trip costs more than the price at every batch
        # (a long ride, few taxis); past the guard its price is penalty_s again, so it is taken as soon as a taxi can.
        if unassigned_guard_s is not None:
            if unassigned_price_s is None:
                raise ConfigError(
                    f"unassigned_guard_s={unassigned_guard_s!r} bounds the wait unassigned_price_s prices, which is "
                    "None: give both, or neither."
                )
            unassigned_guard_s = check_seconds("unassigned_guard_s", unassigned_guard_s, " or None (no guard)")
        self.unassigned_guard_s = unassigned_guard_s
        # also re-assign at a step where a request is released: else it waits up to period - 1 steps for its taxi
        self.assign_on_release = check_flag("assign_on_release", assign_on_release)
        if value is not None and not isinstance(value, LinearValue):
            raise ConfigError(f"value={value!r} is a {type(value).__name__}; pass a LinearValue or None.")
        self.value = value  # a learned value of the state each trip leaves its taxi in (assignment_value); None: off
        self.period = check_integer("period", period, 1, MAX_TIME_LIMIT_STEPS, fix=" (steps between batches)")
        self.max_requests_per_taxi = check_integer(
            "max_requests_per_taxi", max_requests_per_taxi, 1, MAX_REQUESTS_PER_TAXI, fix=" (e.g. 6)"
        )
        self.penalty_s = check_seconds("penalty_s", penalty_s)
        if self.penalty_s == 0:
            raise ConfigError("penalty_s=0 must be > 0: a request left unassigned must cost something (e.g. 1e6).")

    def batch_due(self, released: list[int]) -> bool:
        """Whether a batch runs at this step: every ``period`` steps, and with ``assign_on_release`` at every step
        where a request is ``released``."""
        assert self.sim is not None
        return int(self.sim.state.t[0]) % self.period == 0 or (self.assign_on_release and bool(released))

    def dispatch(self, released: list[int]) -> None:
        assert self.sim is not None
        if not self.batch_due(released):
            return
        s = self.sim.state
        waiting = [int(p) for p in self.pax if s.pax_status[0, p] == WAITING]
        trips, routes, free_s = self.candidate_trips(waiting)
        idle_free_s = [0.0] * self.num_taxis  # when each taxi is free if it takes no new trip
        for a in range(self.num_taxis):
            plan, self.routes[a] = self.sequence(a, []) if self.on_board(a) else (None, [])
            idle_free_s[a] = plan.finish_s if plan is not None else self.now_s()
        if not waiting:
            return
        if self.value is not None:
            trips = self.valued_trips(trips, routes, free_s, idle_free_s)
        for k in assign_trips(trips, self.num_taxis, waiting, self.unassigned_prices(waiting)):
            self.routes[trips[k][0]] = routes[k]
        self.stats["assignments"] += 1

    def unassigned_prices(self, waiting: list[int]) -> float | list[float]:
        """What leaving each of the ``waiting`` requests out of this batch costs: ``penalty_s``, or with
        ``unassigned_price_s`` that price plus (1 + β) times the request's wait so far; past ``unassigned_guard_s``
        of wait, ``penalty_s`` again."""
        if self.unassigned_price_s is None:
            return self.penalty_s
        now, held = self.now_s(), 1.0 + self.wait_weight
        guard = math.inf if self.unassigned_guard_s is None else self.unassigned_guard_s
        waits = [now - float(self.release_s[r]) for r in waiting]
        return [self.penalty_s if wait > guard else self.unassigned_price_s + held * wait for wait in waits]

    def candidate_trips(
        self, waiting: list[int]
    ) -> tuple[list[tuple[int, tuple[int, ...], float]], list[list[Stop]], list[float]]:
        """Every taxi's feasible trips of up to ``seats`` waiting requests, with their cost increase, route and the
        time (s) the route ends."""
        trips: list[tuple[int, tuple[int, ...], float]] = []
        routes: list[list[Stop]] = []
        free_s: list[float] = []
        for a in range(self.num_taxis):
            riding = self.on_board(a)
            alone_and_singles = self.sequence_each(a, [[]] * bool(riding) + [[r] for r in waiting])
            base = self.plan_cost(alone_and_singles.pop(0)[0]) if riding else 0.0
            singles = [
                (self.plan_cost(plan) - base, r, route, plan.finish_s)
                for r, (plan, route) in zip(waiting, alone_and_singles, strict=True)
            ]
            singles.sort(key=lambda single: single[:2])
            chosen = sorted(r for _, r, _, _ in singles[: self.max_requests_per_taxi])
            for cost, r, route, finish_s in singles[: self.max_requests_per_taxi]:
                trips.append((a, (r,), cost))
                routes.append(route)
                free_s.append(finish_s)
            sizes = [size for size in range(2, self.seats + 1) if len(riding) + size <= self.exact_limit]
            combos = [combo for size in sizes for combo in itertools.combinations(chosen, size)]
            for combo, (plan, route) in zip(combos, self.sequence_each(a, combos), strict=True):
                trips.append((a, combo, self.plan_cost(plan) - base))
                routes.append(route)
                free_s.append(plan.finish_s)
        return trips, routes, free_s

    def now_s(self) -> float:
        assert self.sim is not None
        return float(self.sim.state.t[0]) * self.sim.cfg.slot_s

    def remoteness_after(self, taxi: int, route: Sequence[Stop]) -> float:
        """:class:`~uamfleet.baselines.assignment_value.SiteRemoteness` of where ``route`` leaves the taxi: its last
        stop (a drop-off), or where the taxi is when the route is empty."""
        assert self.sim is not None
        if route:
            return float(self._dest_remoteness[route[-1][0]])
        return float(self._remoteness(self.sim.state.pos_m[0, taxi])[0])

    def valued_trips(
        self,
        trips: list[tuple[int, tuple[int, ...], float]],
        routes: list[list[Stop]],
        free_s: list[float],
        idle_free_s: list[float],
    ) -> list[tuple[int, tuple[int, ...], float]]:
        """The trips with cost - price_s * (V(after the trip) - V(after no new trip)) (assignment_value)."""
        assert self.value is not None
        far = np.array([self.remoteness_after(a, route) for (a, _, _), route in zip(trips, routes, strict=True)])
        after = self.value.values(np.asarray(free_s), far)
        idle_far = np.array([self.remoteness_after(a, self.routes[a]) for a in range(self.num_taxis)])
        idle = self.value.values(np.asarray(idle_free_s), idle_far)
        price = self.value.price_s
        return [(a, reqs, cost - price * float(after[k] - idle[a])) for k, (a, reqs, cost) in enumerate(trips)]

    def reset(self, sim: Simulator) -> None:
        super().reset(sim)
        if self.value is not None:
            self.prepare_remoteness()

    def prepare_remoteness(self) -> None:
        """The site remoteness :meth:`remoteness_after` reads (the map's flyable sites; every destination's), for
        this episode: made at reset where a value prices the trips, or by a subclass that records it."""
        assert self.sim is not None
        self._remoteness = SiteRemoteness(flyable_sites(self.sim.world))
        self._dest_remoteness = self._remoteness(self.dest_m)


class RecordingAssignment(BatchAssignmentPolicy):
    """``batch_assignment`` (with or without a value, with its options) that records, at every batch that runs
    (:meth:`BatchAssignmentPolicy.batch_due`), each taxi's post-decision state and plan, and every pick-up
    (passenger, taxi, time)."""

    def reset(self, sim: Simulator) -> None:
        super().reset(sim)
        self.prepare_remoteness()  # recorded with or without a value
        self.decisions: list[tuple[int, float, float, float, tuple[int, ...]]] = []  # taxi, now, free, far, plan
        self.pickups: list[tuple[int, int, float]] = []  # passenger, taxi, time
        self._was_on_board = np.zeros(len(sim.state.pax_status[0]), dtype=bool)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        assert self.sim is not None
        s = self.sim.state
        on_board = s.pax_status[0] == ON_BOARD
        for p in np.flatnonzero(on_board & ~self._was_on_board):
            self.pickups.append((int(p), int(s.pax_taxi[0, p]), self.now_s()))
        self._was_on_board |= on_board
        return super().act(obs)

    def dispatch(self, released: list[int]) -> None:
        due = self.batch_due(released)  # asked before the batch: it reads the step, which the batch leaves alone
        super().dispatch(released)
        if not due:
            return
        now = self.now_s()
        for a in range(self.num_taxis):
            plan = tuple(sorted({p for p, _ in self.routes[a]} | set(self.on_board(a))))
            route = self.routes[a]
            free = self.sequence(a, self.waiting_of(a))[0].finish_s if route else now
            self.decisions.append((a, now, free, self.remoteness_after(a, route), plan))


__all__ = [
    "MAX_REQUESTS_PER_TAXI",
    "BatchAssignmentPolicy",
    "InsertionPolicy",
    "RecordingAssignment",
    "assign_trips",
    "check_seconds",
]
