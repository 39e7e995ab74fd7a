"""The schedule dispatchers' common part over the batched core: schedules, their options, and flying them.

A schedule dispatcher keeps a stop schedule per taxi and flies it like
:class:`~uamfleet.baselines.planner_policy.PlannerPolicy`: each taxi heads, along feasible paths
(:class:`~uamfleet.paths.DistanceFields`), for the first stop of its schedule it can act on (a pick-up while it has
a free seat, a drop-off of a passenger it carries). Schedules are sequenced exactly by
:func:`~uamfleet.baselines.sequencing.solve_pdp` with the ``"ride"`` objective: the **total ride time** (drop-off −
request, summed over the taxi's passengers, on board ones included) from the current step, over a stop distance
matrix of feasible-path distances (the distance fields the taxis steer by) at the env's speed. A schedule's cost is
that total ride time; "how much a schedule grows" is the increase of it (seconds), so wait and detour both count.
With a wait weight β (``wait_weight``; a name's ``+wait=<β>``) a schedule costs its total ride time plus β times its
total wait (pick-up − request), sequenced exactly for that cost: a service that weighs waiting above riding.

The dispatchers themselves (:class:`ScheduleFleetPolicy` subclasses) differ only in how a released request joins
a schedule: :class:`~uamfleet.baselines.batch_assignment.InsertionPolicy` (``insertion``) and
:class:`~uamfleet.baselines.batch_assignment.BatchAssignmentPolicy` (``batch_assignment``, and with a learned value
``batch_assignment_value``) in :mod:`~uamfleet.baselines.batch_assignment`. Their names may carry options
(:func:`split_options`).

How each taxi flies toward its stop (the ``heading`` rule, a name's ``heading=<rule>``), idles and makes way for
another: :mod:`~uamfleet.baselines.fleet_steering`.

Boarding is automatic in the env: a taxi that passes a waiting passenger within the pick-up radius takes them
even if another taxi was assigned; schedules are repaired every step (the other taxi drops the stops, the carrier
re-sequences its schedule with the new drop-off; above ``exact_limit`` passengers it drops them first). So does a
taxi whose route no longer fits its seats because it boarded a planned passenger early.
"""

from __future__ import annotations

import itertools
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from uamfleet.baselines.assignment_value import MAX_SECONDS
from uamfleet.baselines.sequencing import DROPOFF, MAX_PASSENGERS, PICKUP, Plan, solve_in_order, solve_pdp_each
from uamfleet.checks import ConfigError, check_integer, check_number
from uamfleet.env.protocol import PolicyBase
from uamfleet.baselines.fleet_steering import check_heading, fleet_actions, shared_fields
from uamfleet.paths import table_for
from uamfleet.sim.core import Simulator
from uamfleet.types import DELIVERED, HIDDEN, ON_BOARD, WAITING

SCHEDULE_DISPATCHERS: tuple[str, ...] = ("insertion", "batch_assignment")
"""The schedule dispatchers (:mod:`~uamfleet.baselines.batch_assignment`), whose names take the options of
:func:`split_options`; with the learned value, ``batch_assignment_value`` too
(:data:`~uamfleet.baselines.assignment_value.VALUE_DISPATCHER`)."""
Stop = tuple[int, str]  # (passenger, "pickup" | "dropoff")

OPTION_SEPARATOR = "+"
"""A schedule dispatcher's name may carry options after ``+``: ``+wait=<β>`` (its schedules cost the total ride
time plus β times the total wait, pick-up − request) and, for the batch assignments, ``+release`` (it also
re-assigns at every step where a request is released, not only every ``period`` steps) and ``+price=<s>`` (a
request a batch leaves unassigned costs ``<s>`` plus (1 + β) times the wait it has had, instead of ``penalty_s``)
with ``+guard=<s>`` (past ``<s>`` of wait, ``penalty_s`` again); e.g. ``insertion+wait=1``,
``batch_assignment_value:100+wait=1+release``, ``batch_assignment_value:100+wait=1+release+price=1000+guard=600``."""


MAX_WAIT_WEIGHT = 1000.0
"""Upper bound of the wait weight β (``wait_weight``, ``+wait=<β>``): a second of wait at most 1,000 s of ride."""


def check_wait_weight(name: str, value: float) -> float:
    """``value`` as a wait weight β in ``[0, MAX_WAIT_WEIGHT]``; ConfigError naming ``name`` otherwise."""
    value = check_number(name, value, minimum=0.0)
    if value > MAX_WAIT_WEIGHT:
        raise ConfigError(f"{name}={value!r} is too large: at most {MAX_WAIT_WEIGHT:g} (0: plain total ride time).")
    return value


@dataclass(frozen=True)
class DispatchOptions:
    """The options a dispatcher's name carries (:data:`OPTION_SEPARATOR`); the defaults are the plain dispatcher."""

    wait_weight: float = 0.0
    assign_on_release: bool = False
    unassigned_price_s: float | None = None  # None: every request left unassigned costs penalty_s (10^6 s)
    unassigned_guard_s: float | None = None  # with a price: a request that has waited longer costs penalty_s again


def _option_number(
    name: str, base: str, option: str, text: str, meaning: str, example: str, most: float = MAX_SECONDS
) -> float:
    """The finite number in ``[0, most]`` of ``+option=<text>`` in the dispatcher ``name``; ConfigError naming the
    fix else."""
    try:
        value = float(text)
    except ValueError:
        value = float("nan")
    if not (np.isfinite(value) and 0 <= value <= most):
        raise ConfigError(
            f"dispatcher {name!r}: +{option}=<…> takes a finite number in [0, {most:g}] ({meaning}), e.g. "
            f"{base}+{option}={example}"
        )
    return value


def split_options(name: str) -> tuple[str, DispatchOptions]:
    """(dispatcher name without its options, the options) of a name such as ``batch_assignment+wait=1+release``;
    an option given twice is refused."""
    if not isinstance(name, str):
        raise ConfigError(f"dispatcher {name!r} is a {type(name).__name__}; name one, e.g. 'batch_assignment'.")
    base, *given = name.split(OPTION_SEPARATOR)
    wait_weight, on_release, price, guard = 0.0, False, None, None
    seen: dict[str, str] = {}
    for option in given:
        key, sep, text = option.partition("=")
        if key in seen:
            raise ConfigError(
                f"dispatcher {name!r}: +{seen[key]} and +{option} both set {key}; give each option once "
                f"(e.g. {base}+{seen[key]})"
            )
        seen[key] = option
        if key == "wait" and sep:
            meaning = "seconds of ride time per second of wait"
            wait_weight = _option_number(name, base, key, text, meaning, "1", MAX_WAIT_WEIGHT)
        elif key == "price" and sep:
            price = _option_number(name, base, key, text, "seconds per request left unassigned", "1000")
        elif key == "guard" and sep:
            guard = _option_number(name, base, key, text, "seconds of wait after which a request must be taken", "600")
        elif option == "release":
            on_release = True
        else:
            raise ValueError(
                f"dispatcher {name!r}: unknown option {option!r}; a schedule dispatcher takes +wait=<β> and, the "
                f"batch assignments, +release, +price=<s> and +guard=<s> (e.g. {base}+wait=1+release)"
            )
    if guard is not None and price is None:
        raise ValueError(
            f"dispatcher {name!r}: +guard=<s> bounds how long +price=<s> may leave a request out; give both (e.g. "
            f"{base}+price=1000+guard=600), or neither (every request left out then costs 10^6 s)"
        )
    return base, DispatchOptions(wait_weight, on_release, price, guard)


_SetKey = tuple[int, tuple[int, ...]]  # (taxi, waiting passengers): one set of ScheduleFleetPolicy.sequence_each


class ScheduleFleetPolicy(PolicyBase):
    """Base of the dispatchers: per-taxi schedules, repaired every step and flown along feasible paths.

    Subclasses implement :meth:`dispatch` (called every step with the passengers released since the last call):
    :mod:`~uamfleet.baselines.batch_assignment`.
    ``stats`` counts the DP solves, heuristic insertions and assignment programmes of the episode.
    """

    def __init__(self, exact_limit: int = 6, wait_weight: float = 0.0, heading: str = "field") -> None:
        self.exact_limit = check_integer("exact_limit", exact_limit, 1, MAX_PASSENGERS, fix=" (solve_pdp's limit)")
        # β: a schedule costs its total ride time + β · its total wait
        self.wait_weight = check_wait_weight("wait_weight", wait_weight)
        self.heading = check_heading(heading)
        self.sim: Simulator | None = None

    # ---- episode start -------------------------------------------------------------------------------
    def reset(self, sim: Simulator) -> None:
        if sim.num_envs != 1:
            raise ValueError(f"{type(self).__name__} drives a one-env core, got num_envs={sim.num_envs}")
        self.sim = sim
        self.fields = shared_fields(sim)
        self._table = table_for(sim.world) if self.heading == "table" else None
        s = sim.state
        self.num_taxis = sim.num_taxis
        self._idle_at: list[np.ndarray | None] = [None] * sim.num_taxis  # where an idle taxi zig-zags (no hover action)
        self.pax = np.flatnonzero(s.pax_exists[0])
        self.release_s = s.pax_release[0].astype(float) * sim.cfg.slot_s
        self.speed_mps = sim.cfg.step_m / sim.cfg.slot_s
        self.seats = sim.cfg.seats
        self.origin_m, self.dest_m = s.pax_origin_m[0].copy(), s.pax_dest_m[0].copy()
        # feasible-path distances, looked up once: stop to stop, by column (stop row 2p: origin of p, 2p + 1: its
        # destination; column j, [2P] from every stop to stop j, is looked up the first time stop j is asked for and
        # dropped once its passenger is delivered, so memory follows the open requests, not the episode's: a
        # [2P, 2P] matrix was 32 MB at 1,000 requests), and [A, 2P] from each taxi's position to every active
        # stop, for one decision (_taxi_key: the state it holds for, _this_decision)
        self._every_stop = np.stack([self.origin_m, self.dest_m], axis=1).reshape(-1, 2)
        self._to_stop: dict[int, np.ndarray] = {}
        self._taxi_key: tuple[int, bytes] | None = None
        self._taxi_to_stop = np.zeros((sim.num_taxis, len(self._every_stop)))
        self._taxi_known = np.zeros(len(self._every_stop), dtype=bool)
        self._riding: list[list[int] | None] = [None] * sim.num_taxis  # on_board(taxi), for the same decision
        self._sequenced: dict[tuple[int, tuple[int, ...]], tuple[Plan, list[Stop]]] = {}  # sequence(), the same
        self.routes: list[list[Stop]] = [[] for _ in range(self.num_taxis)]
        self._seen = np.zeros(len(s.pax_status[0]), dtype=bool)  # the first call dispatches step-0 requests
        self.stats = {"dp_solves": 0, "heuristic_inserts": 0, "assignments": 0}

    # ---- distances -------------------------------------------------------------------------------------
    def _this_decision(self) -> None:
        """Forget the per-decision look-ups (taxi to stop distances, who rides with whom) once the env has changed:
        they hold while the step, the taxis' positions and the passengers' statuses and carriers are those they
        were made for."""
        assert self.sim is not None
        s = self.sim.state
        key = (int(s.t[0]), s.pos_m[0].tobytes() + s.pax_status[0].tobytes() + s.pax_taxi[0].tobytes())
        if key != self._taxi_key:
            self._taxi_key = key
            self._taxi_known[:] = False
            self._riding = [None] * self.num_taxis
            self._sequenced = {}

    def _stop_rows(self, passengers: Sequence[int] | np.ndarray) -> np.ndarray:
        """[2N] the stop rows of the passengers in :mod:`~uamfleet.baselines.sequencing`'s node order: origin of
        each at 2p, destination at 2p + 1."""
        return (2 * np.asarray(passengers, dtype=np.int64)[:, None] + np.arange(2)).reshape(-1)

    def _from_taxis(self, rows: np.ndarray) -> np.ndarray:
        """[A, len(rows)] feasible-path distance from every taxi's position now to the stops ``rows``. A miss looks
        up every active (waiting or riding) passenger's stops for every taxi in one compiled pass: a batch asks for
        them all, and each entry is the same number :meth:`DistanceFields.remaining_m` gives alone."""
        assert self.sim is not None
        self._this_decision()
        if not self._taxi_known[rows].all():
            s = self.sim.state
            active = (s.pax_status[0] == WAITING) | (s.pax_status[0] == ON_BOARD)
            need = np.union1d(self._stop_rows(np.flatnonzero(active)), rows)
            need = need[~self._taxi_known[need]]
            self._taxi_to_stop[:, need] = self.fields.remaining_many(self._every_stop[need], s.pos_m[0])
            self._taxi_known[need] = True
        return self._taxi_to_stop[:, rows]

    def _between_stops(self, rows: np.ndarray) -> np.ndarray:
        """[len(rows), len(rows)] feasible-path distance from stop to stop (each column looked up once while its
        passenger is open, from every stop at once)."""
        missing = np.unique([j for j in rows.tolist() if j not in self._to_stop])
        if missing.size:
            columns = self.fields.remaining_many(self._every_stop[missing], self._every_stop)  # [2P, missing]
            self._to_stop.update((int(j), columns[:, i].copy()) for i, j in enumerate(missing))
        if not rows.size:
            return np.zeros((0, 0))
        return np.stack([self._to_stop[j][rows] for j in rows.tolist()], axis=1)

    def _forget_delivered(self, status: np.ndarray) -> None:
        """Drop the stop-to-stop columns of delivered passengers: no schedule asks for their stops again."""
        for j in [j for j in self._to_stop if status[j // 2] == DELIVERED]:
            del self._to_stop[j]

    def stop_matrix(self, taxi: int, passengers: Sequence[int]) -> np.ndarray:
        """[1 + 2N, 1 + 2N] distances in :mod:`~uamfleet.baselines.sequencing`'s node order: the taxi's position,
        then origin / destination of each passenger."""
        assert self.sim is not None
        rows = self._stop_rows(passengers)
        dist = np.zeros((1 + len(rows), 1 + len(rows)))  # column 0 (back to the taxi) stays 0: no stop leads there
        dist[0, 1:] = self._from_taxis(rows)[taxi]
        dist[1:, 1:] = self._between_stops(rows)
        np.fill_diagonal(dist, 0.0)
        return dist

    # ---- schedules -------------------------------------------------------------------------------------
    def on_board(self, taxi: int) -> list[int]:
        """The taxi's riders, ascending (a new list; looked up once a decision)."""
        assert self.sim is not None
        self._this_decision()
        riding = self._riding[taxi]
        if riding is None:
            s = self.sim.state
            on = (s.pax_status[0, self.pax] == ON_BOARD) & (s.pax_taxi[0, self.pax] == taxi)
            riding = self._riding[taxi] = self.pax[on].tolist()  # ascending, as self.pax
        return list(riding)

    def waiting_of(self, taxi: int) -> list[int]:
        """Waiting passengers whose pick-up is on the taxi's schedule."""
        return [p for p, kind in self.routes[taxi] if kind == PICKUP]

    def plan_cost(self, plan: Plan) -> float:
        """A schedule's cost (s): its total ride time, plus ``wait_weight`` times its total wait."""
        return plan.total_ride_s + self.wait_weight * plan.total_wait_s  # β = 0: the ride time, bit for bit

    def sequence(self, taxi: int, waiting: Sequence[int]) -> tuple[Plan, list[Stop]]:
        """The exact best schedule (least :meth:`plan_cost`) of the taxi's passengers on board plus ``waiting``
        (solved once a decision: a batch asks for a taxi's riders alone twice)."""
        return self.sequence_each(taxi, [waiting])[0]

    def sequence_each(self, taxi: int, waiting_sets: Sequence[Sequence[int]]) -> list[tuple[Plan, list[Stop]]]:
        """:meth:`sequence` of each set of waiting passengers. The sets not yet solved this decision are solved over
        one stop matrix of the taxi's riders and all their passengers (:func:`solve_pdp_each`: the same plans as
        one matrix per set), all but a set not in ascending order, which is solved alone as it is given."""
        assert self.sim is not None
        self._this_decision()
        keys = [(taxi, tuple(int(p) for p in waiting)) for waiting in waiting_sets]
        todo = [key for key in dict.fromkeys(keys) if key not in self._sequenced]
        if todo:
            self._solve_sets(taxi, todo)
        return [(plan, list(route)) for plan, route in (self._sequenced[key] for key in keys)]

    def _solve_sets(self, taxi: int, todo: list[_SetKey]) -> None:
        """Solves each set of ``todo`` into :attr:`_sequenced`: first each set whose new passengers are not in
        ascending order, alone, then all the others over one joined stop matrix."""
        riding = self.on_board(taxi)
        joined: list[tuple[_SetKey, list[int]]] = []
        alone: list[tuple[_SetKey, list[int]]] = []
        for key in todo:
            new = [p for p in key[1] if p not in riding]
            (joined if all(a < b for a, b in itertools.pairwise(new)) else alone).append((key, new))
        for key, new in alone:
            (self._sequenced[key],) = self._solved(taxi, riding, riding + new, [list(range(len(riding + new)))])
        if joined:
            self._solve_joined(taxi, riding, joined)

    def _solve_joined(self, taxi: int, riding: list[int], joined: list[tuple[_SetKey, list[int]]]) -> None:
        """Solves the sets of ``joined`` (key, new passengers ascending) over one stop matrix of the riders and every
        new passenger of them, into :attr:`_sequenced`."""
        extra = sorted({p for _, new in joined for p in new})
        index = {p: len(riding) + i for i, p in enumerate(extra)}
        subsets = [list(range(len(riding))) + [index[p] for p in new] for _, new in joined]
        solved = self._solved(taxi, riding, riding + extra, subsets)
        self._sequenced.update(zip([key for key, _ in joined], solved, strict=True))

    def _solved(
        self, taxi: int, riding: list[int], passengers: list[int], subsets: list[list[int]]
    ) -> list[tuple[Plan, list[Stop]]]:
        """(plan, route) of each subset of ``passengers`` (riders first; indices, ascending, each with every rider)."""
        assert self.sim is not None
        plans = solve_pdp_each(
            self.stop_matrix(taxi, passengers),
            self.speed_mps,
            [float(self.release_s[p]) for p in passengers],
            subsets,
            capacity=self.seats,
            on_board=[p in riding for p in passengers],
            start_s=float(self.sim.state.t[0]) * self.sim.cfg.slot_s,
            objective="ride",
            wait_weight=self.wait_weight,
        )
        self.stats["dp_solves"] += len(subsets)
        return [
            (plan, [(passengers[subset[i]], kind) for i, kind in plan.stops])
            for subset, plan in zip(subsets, plans, strict=True)
        ]

    def schedule_cost(self, taxi: int, route: Sequence[Stop]) -> float:
        """:meth:`plan_cost` (s) of the taxi's passengers when it flies ``route`` from now."""
        assert self.sim is not None
        riding = self.on_board(taxi)
        passengers = riding + [p for p, kind in route if kind == PICKUP]
        index = {p: i for i, p in enumerate(passengers)}
        plan = solve_in_order(
            self.stop_matrix(taxi, passengers),
            self.speed_mps,
            [float(self.release_s[p]) for p in passengers],
            [(index[p], kind) for p, kind in route],
            start_s=float(self.sim.state.t[0]) * self.sim.cfg.slot_s,
            on_board=[p in riding for p in passengers],
            capacity=self.seats,
        )
        return self.plan_cost(plan)

    def cheapest_insertion(self, taxi: int, passenger: int) -> tuple[float, list[Stop]]:
        """(schedule cost, route) with the passenger's pick-up and drop-off at their cheapest positions of the
        taxi's current route (its order kept); for taxis with more than ``exact_limit`` passengers."""
        route = self.routes[taxi]
        best: tuple[float, list[Stop]] | None = None
        for i in range(len(route) + 1):
            for j in range(i, len(route) + 1):
                cand = [*route[:i], (passenger, PICKUP), *route[i:j], (passenger, DROPOFF), *route[j:]]
                try:
                    cost = self.schedule_cost(taxi, cand)
                except ValueError:  # over capacity somewhere
                    continue
                if best is None or cost < best[0] - 1e-9:
                    best = (cost, cand)
        assert best is not None, "appending pick-up and drop-off at the end is always feasible"
        self.stats["heuristic_inserts"] += 1
        return best

    def _repair(self) -> None:
        """Drop served stops; a taxi that boarded someone not on its schedule re-sequences with the drop-off."""
        assert self.sim is not None
        s = self.sim.state
        status, carrier = s.pax_status[0], s.pax_taxi[0]
        self._forget_delivered(status)
        for a in range(self.num_taxis):
            kept = self._open_stops(a, status, carrier)
            self.routes[a] = kept
            riding = self.on_board(a)
            missing = [p for p in riding if (p, DROPOFF) not in kept]
            if missing or not self._fits(riding, kept):  # boarded someone unplanned, or a planned one early
                self.routes[a] = self._resequenced(a, riding, missing, kept)

    def _open_stops(self, taxi: int, status: np.ndarray, carrier: np.ndarray) -> list[Stop]:
        """The taxi's route without its served stops: pick-ups of passengers still waiting, drop-offs of those
        waiting or on board this taxi; a drop-off stays only with its pick-up or its passenger on board."""

        def open_stop(p: int, kind: str) -> bool:
            if kind == PICKUP:
                return bool(status[p] == WAITING)
            return bool(status[p] == WAITING or (status[p] == ON_BOARD and carrier[p] == taxi))

        kept = [(p, kind) for p, kind in self.routes[taxi] if open_stop(p, kind)]
        picks = {p for p, kind in kept if kind == PICKUP}
        return [(p, k) for p, k in kept if k == PICKUP or p in picks or status[p] == ON_BOARD]

    def _resequenced(self, taxi: int, riding: list[int], missing: list[int], kept: list[Stop]) -> list[Stop]:
        """A new route for a taxi whose schedule no longer fits who is on board: the exact schedule when small
        enough, else everyone on board dropped first (the pick-ups after that fit the seats)."""
        waiting = self.waiting_of(taxi)
        if len(waiting) + len(riding) <= self.exact_limit:
            return self.sequence(taxi, waiting)[1]
        first = [(p, DROPOFF) for p in missing] + [st for st in kept if st[1] == DROPOFF and st[0] in riding]
        return first + [st for st in kept if st not in first]

    def _fits(self, riding: list[int], route: Sequence[Stop]) -> bool:
        """True if the route never has more than ``seats`` on board, starting with ``riding``."""
        on = len(riding)
        for _, kind in route:
            on += 1 if kind == PICKUP else -1
            if on > self.seats:
                return False
        return True

    # ---- acting ----------------------------------------------------------------------------------------
    def dispatch(self, released: list[int]) -> None:
        raise NotImplementedError

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        assert self.sim is not None, "call reset(sim) first (run_episode does)"
        s = self.sim.state
        newly = (s.pax_status[0] != HIDDEN) & ~self._seen
        self._seen |= newly
        self._repair()
        self.dispatch([int(p) for p in np.flatnonzero(newly)])
        if self.heading != "onward":
            targets = [self.target(a) for a in range(self.num_taxis)]
            return fleet_actions(self.sim, self.fields, self._idle_at, targets, self._table)
        pairs = [self.target_and_after(a) for a in range(self.num_taxis)]  # the schedule walked once per taxi
        targets, onwards = [target for target, _ in pairs], [after for _, after in pairs]
        return fleet_actions(self.sim, self.fields, self._idle_at, targets, self._table, onwards)

    def target(self, taxi: int) -> np.ndarray | None:
        """The point of the first stop of the taxi's schedule it can act on now (:meth:`next_stop`)."""
        stop = self.next_stop(taxi)
        return None if stop is None else self.stop_point(stop)

    def stop_after(self, taxi: int) -> np.ndarray | None:
        """The point of the stop after :meth:`next_stop` on the taxi's schedule; None when that is its last (or it
        has none)."""
        return self.target_and_after(taxi)[1]

    def target_and_after(self, taxi: int) -> tuple[np.ndarray | None, np.ndarray | None]:
        """(:meth:`target`, :meth:`stop_after`) from one walk of the taxi's schedule."""
        stop, route = self.next_stop(taxi), self.routes[taxi]
        if stop is None:
            return None, None
        following = route.index(stop) + 1
        return self.stop_point(stop), (self.stop_point(route[following]) if following < len(route) else None)

    def stop_point(self, stop: Stop) -> np.ndarray:
        """Where ``stop`` is: its passenger's origin for a pick-up, destination for a drop-off."""
        p, kind = stop
        return self.origin_m[p] if kind == PICKUP else self.dest_m[p]

    def next_stop(self, taxi: int) -> Stop | None:
        """The first stop of the taxi's schedule it can act on now: a pick-up while it has a free seat, a drop-off
        of a passenger it carries."""
        assert self.sim is not None
        s = self.sim.state
        free = int(s.free_seats[0, taxi])
        for p, kind in self.routes[taxi]:
            if kind == PICKUP and s.pax_status[0, p] == WAITING and free > 0:
                return p, kind
            if kind == DROPOFF and s.pax_status[0, p] == ON_BOARD and s.pax_taxi[0, p] == taxi:
                return p, kind
        return None

    def check_schedules(self) -> None:
        """Raise AssertionError if a schedule breaks precedence or capacity or two taxis share a request."""
        assert self.sim is not None
        owners: dict[int, int] = {}
        for a, route in enumerate(self.routes):
            riding = set(self.on_board(a))
            for p, kind in route:
                if kind == PICKUP:
                    assert p not in owners, f"passenger {p} on the schedules of taxis {owners[p]} and {a}"
                    owners[p] = a
                    riding.add(p)
                    assert len(riding) <= self.seats, f"taxi {a}'s schedule exceeds {self.seats} seats"
                else:
                    assert p in riding, f"taxi {a} drops passenger {p} before picking them up"
                    riding.discard(p)
            assert not riding, f"taxi {a}'s schedule never drops {sorted(riding)}"


__all__ = [
    "OPTION_SEPARATOR",
    "SCHEDULE_DISPATCHERS",
    "DispatchOptions",
    "ScheduleFleetPolicy",
    "check_wait_weight",
    "split_options",
]
