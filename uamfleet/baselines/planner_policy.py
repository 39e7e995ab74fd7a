"""Raster planners as policies: a stop plan on raster paths, flown through the same environment as every policy.

Planners (the paper's baseline code was never published; these follow its text):

- ``cptsp``: capacity 1 (flown with ``seats=1``), best order of the requests known at the start, late
  requests appended in release order.
- ``pdpcc``: capacity 2 pickup-and-delivery with precedence, best sequence of the requests known at the
  start, late requests appended, never re-planned.
- ``raster_replan``: the best stop order re-solved from the current state (position, passengers on board,
  waiting ones) whenever a request is released.
- ``raster_opt``: clairvoyant: every request and its release time known at the start; the stop order is
  exact **for raster paths**, but the tour flown in the env's 16-heading steps is *not* the optimum of the
  env's own moves, nor a lower bound: learned policies and the step-level search
  (:mod:`uamfleet.baselines.step_planner`: ``best_known``, with a valid lower bound) fly shorter tours.
- ``straight``: a given stop order (default: ``raster_opt``'s) flown in straight lines, ignoring SINR (flown
  with the threshold switched off; measure its connectivity against the real threshold).

"Best" means the earliest completion (makespan), with travel times from shortest feasible paths on the
raster graph of the env's flyable cells (:mod:`uamfleet.paths.grid_graph`) at the env's speed.

Flying a plan: each taxi's target is the first stop of its plan that it can act on (a pick-up while it has a
free seat, a drop-off of a passenger it carries); among the allowed headings it takes the one whose endpoint
is closest to the target along feasible paths (a Dijkstra distance field per target). Boarding is automatic
in the env, so a passenger met on the way boards early; the plan then simply skips that pick-up.
"""

from __future__ import annotations

import itertools
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import numpy as np

from uamfleet.baselines.sequencing import Plan, solve_pdp
from uamfleet.config import EnvConfig
from uamfleet.env.protocol import PolicyBase
from uamfleet.paths import DistanceFields, StopPaths
from uamfleet.presets import make_config
from uamfleet.sim.core import Simulator
from uamfleet.types import HIDDEN, ON_BOARD, WAITING

PLANNERS: tuple[str, ...] = ("cptsp", "pdpcc", "raster_replan", "raster_opt", "straight")

NO_SINR_DB = -1000.0
"""Threshold that makes every cell flyable: the straight-line baseline flies with it."""


def planner_env_overrides(planner: str) -> dict[str, Any]:
    """Config overrides a planner is flown with (capacity 1 for CPTSP, SINR ignored for straight lines)."""
    if planner not in PLANNERS:
        raise ValueError(f"unknown planner {planner!r}; choose one of {PLANNERS}.")
    overrides: dict[str, dict[str, Any]] = {"cptsp": {"seats": 1}, "straight": {"sinr_min_db": NO_SINR_DB}}
    return overrides.get(planner, {})


def require_one_taxi_env(sim: Simulator, planner: str, policy_class: str) -> None:
    """What every single-taxi planner checks at ``reset(sim)``: one env of one taxi, already reset."""
    if sim.num_envs != 1 or sim.num_taxis != 1:
        raise ValueError(
            f"planner {planner!r} flies one taxi in one env; got num_envs={sim.num_envs}, "
            f"num_taxis={sim.num_taxis}. (Fleet dispatch is not one of these single-taxi baselines.)"
        )
    if sim.needs_reset:
        raise RuntimeError(f"reset the simulator before the planner: {policy_class}.reset(sim) reads its instance.")


class FlightConfigs(NamedTuple):
    flown: EnvConfig  # the rules the policy flies under
    scored: EnvConfig  # the rules its metrics are read against (the scenario's own threshold and seats)


def planner_configs(scenario: str | EnvConfig, policy: str, **overrides: Any) -> FlightConfigs:
    """The configs a policy flies under and is scored against, on ``scenario`` with config ``overrides``.

    A planner of :data:`PLANNERS` flies with its :func:`planner_env_overrides` (one seat for CPTSP, SINR
    ignored for the straight line) and is scored against the scenario's own rules (``scored.sinr_min_db`` is
    the threshold its connectivity is measured against); any other policy flies under the scored config."""
    scored = make_config(scenario, **overrides)
    own = planner_env_overrides(policy) if policy in PLANNERS else {}
    return FlightConfigs(make_config(scenario, **{**overrides, **own}) if own else scored, scored)


def _sub_plan(
    dist_m: np.ndarray, speed_mps: float, release_s: np.ndarray, passengers: list[int], capacity: int, wait: bool
) -> tuple[Plan, list[tuple[int, str]]]:
    nodes = [0] + [n for i in passengers for n in (1 + 2 * i, 2 + 2 * i)]
    release = [float(release_s[i]) if wait else 0.0 for i in passengers]
    plan = solve_pdp(dist_m[np.ix_(nodes, nodes)], speed_mps, release, capacity=capacity)
    return plan, [(passengers[p], kind) for p, kind in plan.stops]


def offline_plan(
    dist_m: np.ndarray, speed_mps: float, release_s: np.ndarray, capacity: int
) -> tuple[Plan, list[tuple[int, str]]]:
    """CPTSP (capacity 1) / PDPCC (capacity 2): the best order of the requests known at the start (release 0);
    the later ones are appended by :func:`append_late` when they arrive. Stop matrix: node 0 = start,
    1 + 2i / 2 + 2i = origin / destination of passenger i."""
    known = [i for i in range(len(release_s)) if release_s[i] <= 0]
    return _sub_plan(dist_m, speed_mps, release_s, known, capacity, wait=False)


def clairvoyant_plan(
    dist_m: np.ndarray, speed_mps: float, release_s: np.ndarray, capacity: int
) -> tuple[Plan, list[tuple[int, str]]]:
    """raster_opt: every request and its release time known at the start; the earliest completion on raster
    paths (exact for that model, not for the env's moves)."""
    return _sub_plan(dist_m, speed_mps, release_s, list(range(len(release_s))), capacity, wait=True)


def append_late(passengers: list[int], release_s: np.ndarray) -> list[tuple[int, str]]:
    """Stops appended for requests that arrive after the plan was made: in release order, each served alone
    (pick-up then drop-off), as the paper describes its offline baselines."""
    order = sorted(passengers, key=lambda p: (float(release_s[p]), p))
    return [stop for p in order for stop in ((p, "pickup"), (p, "dropoff"))]


@dataclass
class _TaxiPlan:
    stops: list[tuple[int, str]] = field(default_factory=list)


class PlannerPolicy(PolicyBase):
    """One of :data:`PLANNERS` as a policy for a one-taxi, one-env core (``VectorEnv(cfg, 1, autoreset=False)``).

    After an episode, ``planned`` holds every plan made (for reports) and ``stop_paths`` the shortest paths
    between the instance's stops (start, origins, destinations) at the env's threshold.
    """

    def __init__(self, planner: str, order: list[tuple[int, str]] | None = None) -> None:
        if planner not in PLANNERS:
            raise ValueError(f"unknown planner {planner!r}; choose one of {PLANNERS}.")
        self.planner = planner
        self.order = order
        self.sim: Simulator | None = None
        self.planned: list[Plan] = []
        self.plan = _TaxiPlan()

    # ---- episode start -------------------------------------------------------------------------------
    def reset(self, sim: Simulator) -> None:
        require_one_taxi_env(sim, self.planner, type(self).__name__)
        self.sim = sim
        self.world = sim.world
        self.fields = DistanceFields(sim.world) if self.planner != "straight" else None
        self.graph = self.fields.graph if self.fields is not None else None
        self.planned = []
        s = sim.state
        self.num_pax = int(s.pax_exists[0].sum())
        self.release_s = s.pax_release[0, : self.num_pax] * sim.cfg.slot_s
        self.speed_mps = sim.cfg.step_m / sim.cfg.slot_s
        self.stops_m = np.concatenate(
            [s.pos_m[0, :1], np.stack([s.pax_origin_m[0], s.pax_dest_m[0]], axis=1)[: self.num_pax].reshape(-1, 2)]
        )  # node 0 = start, 1 + 2i = origin of i, 2 + 2i = destination of i
        labels = ["start"] + [f"{kind} of passenger {i} (P{i + 1})" for i in range(self.num_pax)
                              for kind in ("origin", "destination")]  # fmt: skip
        if self.graph is not None:
            self.stop_paths: StopPaths | None = self.graph.shortest_paths(self.stops_m, labels)
            dist = self.stop_paths.distance_m
        else:
            self.stop_paths = None
            dist = np.linalg.norm(self.stops_m[:, None] - self.stops_m[None], axis=-1)
        self.dist_m = dist
        self._seen = s.pax_status[0, : self.num_pax] != HIDDEN
        self.plan = _TaxiPlan(self._initial_plan())

    def _initial_plan(self) -> list[tuple[int, str]]:
        if self.planner in ("cptsp", "pdpcc", "raster_replan"):
            capacity = 1 if self.planner == "cptsp" else 2
            plan, stops = offline_plan(self.dist_m, self.speed_mps, self.release_s, capacity)
        elif self.order is not None:
            return list(self.order)
        else:
            plan, stops = clairvoyant_plan(self.dist_m, self.speed_mps, self.release_s, capacity=2)
        self.planned.append(plan)
        return stops

    # ---- acting ----------------------------------------------------------------------------------------
    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        assert self.sim is not None, "call reset(sim) first (run_episode does)"
        s = self.sim.state
        status = s.pax_status[0, : self.num_pax]
        newly = (status != HIDDEN) & ~self._seen
        if newly.any():
            self._on_release([int(i) for i in np.flatnonzero(newly)])
            self._seen |= newly
        target = self._target()
        pos = s.pos_m[0, 0]
        mask = s.action_mask[0, 0]
        if target is None:  # nothing to do now: stay close to where we are
            target = pos
        if self.fields is None:  # straight line: the nearest endpoint as the crow flies
            cost = np.linalg.norm(pos + self.world.moves_m - target, axis=-1)
            return np.array([[int(np.argmin(np.where(mask, cost, np.inf)))]])
        return np.array([[self.fields.heading(pos, mask, target)]])

    def _on_release(self, passengers: list[int]) -> None:
        if self.planner in ("cptsp", "pdpcc"):
            self.plan.stops += append_late(passengers, self.release_s)
        elif self.planner == "raster_replan":
            self.plan.stops = self._replan()

    def _replan(self) -> list[tuple[int, str]]:
        """Exact re-optimisation from the current position with who is on board and who waits."""
        assert self.sim is not None and self.graph is not None
        s = self.sim.state
        status = s.pax_status[0, : self.num_pax]
        active = [i for i in range(self.num_pax) if status[i] in (WAITING, ON_BOARD)]
        points = np.concatenate([s.pos_m[0, :1], self.stops_m[1:][np.ravel([[2 * i, 2 * i + 1] for i in active])]])
        if not active:
            return []
        paths = self.graph.shortest_paths(points)
        on_board = [bool(status[i] == ON_BOARD) for i in active]
        plan = solve_pdp(paths.distance_m, self.speed_mps, [0.0] * len(active), capacity=self.sim.cfg.seats,
                         on_board=on_board, start_s=float(s.t[0]) * self.sim.cfg.slot_s)  # fmt: skip
        self.planned.append(plan)
        return [(active[p], kind) for p, kind in plan.stops]

    def _target(self) -> np.ndarray | None:
        assert self.sim is not None
        s = self.sim.state
        status, carrier = s.pax_status[0], s.pax_taxi[0]
        free = int(s.free_seats[0, 0])
        for passenger, kind in self.plan.stops:
            if kind == "pickup" and status[passenger] in (HIDDEN, WAITING) and free > 0:
                return np.asarray(s.pax_origin_m[0, passenger])
            if kind == "dropoff" and status[passenger] == ON_BOARD and carrier[passenger] == 0:
                return np.asarray(s.pax_dest_m[0, passenger])
        return None


def exact_stop_length(service_order: list[tuple[int, str]], dist_m: np.ndarray) -> float:
    """Length of the path from the start through the exact stops in the order they were served, from a stop
    distance matrix (node 0 = start, 1 + 2i / 2 + 2i = origin / destination of i): with a planner's
    ``dist_m`` that is the shortest feasible path (what the paper's baselines report, as opposed to the
    distance flown in steps), or the straight-line length for the straight-line baseline."""
    nodes = [0] + [1 + 2 * p if kind == "pickup" else 2 + 2 * p for p, kind in service_order]
    return float(sum(dist_m[a, b] for a, b in itertools.pairwise(nodes)))


def service_order(picked_steps: np.ndarray, dropped_steps: np.ndarray) -> list[tuple[int, str]]:
    """Stops in the order they happened (at the same step drop-offs come first, as in the env; then by
    passenger index). Steps are -1 for stops that never happened."""
    events = [(int(t), 1, p, "pickup") for p, t in enumerate(picked_steps) if t >= 0]
    events += [(int(t), 0, p, "dropoff") for p, t in enumerate(dropped_steps) if t >= 0]
    return [(p, kind) for _, _, p, kind in sorted(events)]


__all__ = [
    "PLANNERS",
    "PlannerPolicy",
    "append_late",
    "clairvoyant_plan",
    "exact_stop_length",
    "offline_plan",
    "planner_env_overrides",
    "service_order",
]
