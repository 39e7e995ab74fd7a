"""Step-level planners: searches over the environment's own moves (16 headings of ``step_m``), not over a raster.

Two planners, both flown through the same env and scored with the same metrics as every other policy:

- ``best_known`` (clairvoyant): every request and its release time known at the start. A beam search over
  sequences of the env's actions, run for a few ranking settings; the shortest plan found is flown (the raster
  planner ``raster_opt`` replayed through the env is one of the candidates, so ``best_known`` is never longer
  than it). It is **not** proven optimal: positions are continuous and the beam keeps a bounded number of
  states per step. It is reported beside :func:`lower_bound_m`, so that lower bound <= optimum <= best known.
- ``replan`` (online): the same search from the current state (position, passengers on board and waiting)
  over the requests released so far, re-run whenever a request is released.

**The search.** A state is one copy of the env's state (a row of a :class:`~uamfleet.types.FleetState`):
the transition is the env's own :meth:`VectorEnv.step <uamfleet.env.vector_env.VectorEnv.step>` on a batch of
copies (every state of the beam times the 16 headings), so the feasibility rule, pick-up radius, seat limit
and release rule are exactly the core's (one implementation of each rule). A heading the rule forbids leaves
the taxi in place: that is how a plan waits for a release. Layer t holds states after t steps; children are
deduplicated by (position floored to a ``cell_m`` grid, who is waiting / on board / delivered) keeping the fewest
moves, ranked by ``f = moves * step_m + h`` and the best ``beam`` kept. ``h`` is an exact dynamic program
over the remaining stops (pick-up before drop-off, the seat limit) on feasible-path distances (Dijkstra on
the raster graph, :mod:`uamfleet.paths`), the leg to the first of them less ``rank_slack`` x the pick-up
radius (a stop is reached anywhere within the radius). Waiting is kept only while a request is still to be
released. A child whose passengers are all delivered is a complete plan; the search ends when no state can
beat the best complete plan (``moves * step_m + h`` with the full slack) or at the time limit.

**The lower bound** (:func:`lower_bound_m`) is an exact DP over every stop order (precedence, seats) of
straight-line legs between the discs of radius ``radius_m`` around the stops: any flight that delivers everyone
passes within the radius of each stop in some such order, and a straight line is never longer than a flown
path; the moves between two consecutive stops are whole steps, so each leg is rounded up to whole steps. It
ignores SINR, so it is loose where the threshold forces detours.
"""

from __future__ import annotations

import functools
import math
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np
from numba import njit

from uamfleet.baselines.planner_policy import PlannerPolicy, require_one_taxi_env
from uamfleet.config import NUM_HEADINGS, EnvConfig, RewardConfig
from uamfleet.env.protocol import PolicyBase
from uamfleet.env.vector_env import VectorEnv
from uamfleet.paths import DistanceFields
from uamfleet.sim.core import Simulator
from uamfleet.types import DELIVERED, HIDDEN, ON_BOARD, FleetState

STEP_PLANNERS: tuple[str, ...] = ("replan", "best_known")
"""Planners of this module (names accepted by :class:`StepPlannerPolicy`)."""

SEARCH_STATE_FIELDS = ("t", "pos_m", "free_seats", "distance_m", "action_mask", "pax_exists", "pax_release",
                       "pax_origin_m", "pax_dest_m", "pax_status", "pax_taxi", "pax_pickup_step",
                       "pax_dropoff_step")  # fmt: skip
"""The FleetState fields that decide the future of a one-taxi episode (history and visit counts do not)."""


@dataclass(frozen=True)
class SearchSettings:
    """One beam search: ``beam`` states kept per step, duplicates merged on a ``cell_m`` grid, ranking slack
    ``rank_slack`` on the leg to the next stop (0: it must be reached exactly; 1: anywhere within the radius)."""

    beam: int = 512
    cell_m: float = 1.0
    rank_slack: float = 0.5

    def __post_init__(self) -> None:
        if self.beam < 1 or not self.cell_m > 0 or not 0 <= self.rank_slack <= 1:
            raise ValueError(
                f"SearchSettings(beam={self.beam}, cell_m={self.cell_m}, rank_slack={self.rank_slack}): need "
                "beam >= 1, cell_m > 0 and 0 <= rank_slack <= 1."
            )


CLAIRVOYANT_SETTINGS: tuple[SearchSettings, ...] = (
    SearchSettings(beam=256, rank_slack=1.0),
    SearchSettings(beam=256, rank_slack=0.0),
    SearchSettings(beam=1024, rank_slack=0.5),
)
"""The portfolio ``best_known`` runs (the shortest result wins)."""

REPLAN_SETTINGS: tuple[SearchSettings, ...] = (SearchSettings(beam=128, rank_slack=0.5),)
"""What ``replan`` runs at every release (smaller: it is an online decision)."""


@dataclass
class StepPlan:
    """A plan of env actions from a state: ``actions`` [T] headings; ``moves`` of them fly (the others wait)."""

    actions: list[int]
    moves: int
    steps: int
    solve_s: float
    source: str
    settings: SearchSettings | None = None

    def td_m(self, step_m: float) -> float:
        return self.moves * step_m


def released_only(state: FleetState) -> FleetState:
    """A copy of ``state`` in which only the released requests exist: what an online planner knows."""
    known = state.copy()
    known.pax_exists[:] &= known.pax_status != HIDDEN
    return known


# ---- the stop-order dynamic programs --------------------------------------------------------------------


def _codes(num_pax: int) -> np.ndarray:
    """[3^P, P] passenger phase of every state code: 0 = to pick up, 1 = on board, 2 = delivered."""
    return np.array(np.unravel_index(np.arange(3**num_pax), (3,) * num_pax)).T.copy()


@functools.lru_cache(maxsize=32)
def _transitions(num_pax: int, seats: int) -> tuple[np.ndarray, np.ndarray]:
    """(``after`` [3^P, 2P]: the code once stop s is served from a code, -1 where s may not be next; ``done``
    [3^P]: whether everyone is delivered). They depend on P and the seats only, so they are made once (read-only)."""
    phases = _codes(num_pax)
    weights = 3 ** np.arange(num_pax - 1, -1, -1)
    after = np.full((3**num_pax, 2 * num_pax), -1, dtype=np.int64)
    for code in range(3**num_pax):
        ph = phases[code]
        on_board = int(np.sum(ph == 1))
        for i in range(num_pax):
            if ph[i] == 0 and on_board < seats:
                after[code, 2 * i] = code + weights[i]
            elif ph[i] == 1:
                after[code, 2 * i + 1] = code + weights[i]
    done = np.all(phases == 2, axis=1)
    after.setflags(write=False)
    done.setflags(write=False)
    return after, done


def remaining_tables(
    stop_dist_m: np.ndarray, seats: int, leg_slack_m: float, step_m: float | None = None
) -> tuple[np.ndarray, np.ndarray]:
    """DP over the stops still to serve (stop 2i = origin of i, 2i + 1 = its destination).

    Returns ``next_cost`` [3^P, 2P]: for a state code and a stop s that may be served next, the least length
    of the rest of the tour after s (legs ``max(D - leg_slack_m, 0)``), and inf where s may not be next; and
    ``after`` [3^P, 2P]: the code once s is served (-1 where not allowed). Codes: sum phase_i * 3^(P-1-i).
    With ``step_m``, every leg is rounded up to whole steps (a leg between two stops is flown in whole moves).
    Compiled (:func:`_tour_rests`); ``after`` is shared between calls and read-only.
    """
    num_stops = stop_dist_m.shape[0]
    after, done = _transitions(num_stops // 2, seats)
    legs = np.maximum(stop_dist_m - leg_slack_m, 0.0)
    if step_m is not None:
        legs = step_m * np.ceil(legs / step_m - 1e-9)
    return _tour_rests(after, done, np.ascontiguousarray(legs, dtype=np.float64)), after


@njit(cache=True)
def _tour_rests(after: np.ndarray, done: np.ndarray, legs: np.ndarray) -> np.ndarray:
    """``next_cost`` of :func:`remaining_tables`: rest[c, s], the least length after serving s with the code now
    c, is 0 once everyone is delivered, else the least legs[s, s2] + rest[after[c, s2], s2]. Serving a stop only
    raises the code, so the codes are filled from the last down; the same sums as a recursion, the same numbers."""
    num_codes, num_stops = after.shape
    rest = np.empty((num_codes, num_stops))
    for code in range(num_codes - 1, -1, -1):
        for s in range(num_stops):
            best = 0.0 if done[code] else math.inf
            for s2 in range(num_stops):
                nxt = after[code, s2]
                if nxt >= 0:
                    value = legs[s, s2] + rest[nxt, s2]
                    if value < best:
                        best = value
            rest[code, s] = best
    next_cost = np.full((num_codes, num_stops), math.inf)
    for code in range(num_codes):
        for s in range(num_stops):
            if after[code, s] >= 0:
                next_cost[code, s] = rest[after[code, s], s]
    return next_cost


def state_codes(status: np.ndarray, exists: np.ndarray) -> np.ndarray:
    """[N] state codes from env passenger status [N, P] (padding rows count as delivered)."""
    phase = np.where(status == ON_BOARD, 1, np.where((status == DELIVERED) | ~exists, 2, 0))
    weights = 3 ** np.arange(status.shape[1] - 1, -1, -1)
    return phase @ weights


def lower_bound_m(start_m: np.ndarray, stops_m: np.ndarray, seats: int, radius_m: float, step_m: float) -> float:
    """A valid lower bound on the distance flown by any policy that delivers every passenger.

    ``stops_m`` [2P, 2]: origin and destination of each passenger in turn. Exact DP over the stop orders
    (precedence, ``seats``) of straight-line legs between discs of ``radius_m`` around the stops (the first leg
    from the start point to the first disc), each leg rounded up to whole steps of ``step_m``: stops are served
    at step endpoints, so the moves between two consecutive stops are a whole number, each at most ``step_m``
    long."""
    stops_m = np.asarray(stops_m, float)
    dist = np.linalg.norm(stops_m[:, None] - stops_m[None], axis=-1)
    next_cost, _ = remaining_tables(dist, seats, 2.0 * radius_m, step_m)
    first = np.maximum(np.linalg.norm(stops_m - np.asarray(start_m, float), axis=-1) - radius_m, 0.0)
    first = step_m * np.ceil(first / step_m - 1e-9)
    return float(np.min(first + next_cost[0]))


def instance_lower_bound_m(cfg: EnvConfig) -> float:
    """:func:`lower_bound_m` of a one-taxi config with a fixed start and fixed requests."""
    if cfg.starts_m is None or cfg.requests is None or cfg.num_taxis != 1:
        raise ValueError("instance_lower_bound_m needs one taxi, fixed starts_m and fixed requests.")
    stops = np.array([p for r in cfg.requests for p in (r.origin_m, r.destination_m)])
    return lower_bound_m(np.array(cfg.starts_m[0]), stops, cfg.seats, cfg.radius_m, cfg.step_m)


# ---- the beam search -------------------------------------------------------------------------------------


@dataclass
class _Layer:
    parent: np.ndarray  # [K] row of the beam each child was expanded from
    action: np.ndarray  # [K] heading taken
    chosen: np.ndarray = field(default_factory=lambda: np.empty(0, np.int64))  # [N'] children kept as next beam


@dataclass
class StepSearch:
    """Beam searches over the env's actions for one config (one taxi). Reuse it for many solves of that config."""

    cfg: EnvConfig
    scratch_envs: int = 0
    _env: VectorEnv | None = field(default=None, repr=False)
    _last_stops: tuple[bytes, np.ndarray] | None = field(default=None, repr=False)

    def __post_init__(self) -> None:
        if self.cfg.num_taxis != 1:
            raise ValueError(f"step-level planners fly one taxi; got num_taxis={self.cfg.num_taxis}.")
        # The scratch core: same rules; no shaping, no truncation (the largest time limit the config allows), the
        # smallest observation parts (no stop features: the search reads states and events, never observations).
        self.scratch_cfg = self.cfg.replace(
            patch_size=1, history_len=1, time_limit_steps=2**24 - 1, max_block_visits=None, reward=RewardConfig(),
            stop_features=False, stop_claims=False, heading_lookahead=False,
        )  # fmt: skip
        self.fields = DistanceFields(VectorEnv(self.scratch_cfg, 1).world)
        self.step_m = self.cfg.step_m
        self.radius_m = self.cfg.radius_m

    def _scratch(self, num_envs: int) -> VectorEnv:
        if self._env is None or self._env.num_envs < num_envs:
            self._env = VectorEnv(self.scratch_cfg, num_envs=num_envs, autoreset=True)
            self._env.reset(seed=0)
        return self._env

    def solve(
        self, state: FleetState, settings: Sequence[SearchSettings], env_index: int = 0, upper_moves: int | None = None
    ) -> StepPlan | None:
        """The shortest plan found (fewest moves, then fewest steps) from env ``env_index`` of ``state`` until
        every passenger that exists there is delivered; None if none was found within the time limit."""
        best: StepPlan | None = None
        for s in settings:
            plan = self._beam(state, env_index, s, best.moves if best is not None else upper_moves)
            if plan is not None and (best is None or (plan.moves, plan.steps) < (best.moves, best.steps)):
                best = plan
        return best

    def _stop_distances(self, stops: np.ndarray) -> np.ndarray:
        """[S, S] feasible-path distances between ``stops`` [S, 2]; the last set is kept, since a replan between
        two releases (and every setting of one solve) asks for the same stops again."""
        key = stops.tobytes()
        if self._last_stops is None or self._last_stops[0] != key:
            self._last_stops = (key, self.fields.stop_distances(stops))
        return self._last_stops[1]

    def _beam(self, state: FleetState, e: int, settings: SearchSettings, upper_moves: int | None) -> StepPlan | None:
        start = time.perf_counter()
        beam = {k: getattr(state, k)[e : e + 1].copy() for k in SEARCH_STATE_FIELDS}
        exists = beam["pax_exists"][0]
        num_pax = int(np.flatnonzero(exists).max()) + 1 if exists.any() else 0
        if num_pax == 0 or np.all(beam["pax_status"][0, :num_pax][exists[:num_pax]] == DELIVERED):
            return StepPlan([], 0, 0, 0.0, "beam", settings)
        stops = np.stack([beam["pax_origin_m"][0, :num_pax], beam["pax_dest_m"][0, :num_pax]], axis=1).reshape(-1, 2)
        stop_dist = self._stop_distances(stops)
        rank_next, _ = remaining_tables(stop_dist, self.cfg.seats, 0.0)
        bound_next, _ = remaining_tables(stop_dist, self.cfg.seats, 2.0 * self.radius_m)
        tables = _Heuristic(stops, rank_next, bound_next)
        g = np.zeros(1, np.int64)
        layers: list[_Layer] = []
        best: tuple[int, int, int] | None = None  # (moves, layer, index in that layer's children)
        best_moves = upper_moves if upper_moves is not None else np.iinfo(np.int64).max
        limit = int(self.cfg.time_limit_steps - beam["t"][0])
        env = self._scratch(settings.beam * NUM_HEADINGS)
        for depth in range(limit):
            g_kid, done, useful = _expand(env, beam, g, layers)
            if done.any():
                idx = np.flatnonzero(done)
                i = int(idx[np.argmin(g_kid[idx])])
                if g_kid[i] < best_moves:
                    best_moves, best = int(g_kid[i]), (int(g_kid[i]), depth, i)
            live = np.flatnonzero(~done & useful)
            if not len(live):
                break
            chosen = self._select(env, live, g_kid, best_moves, tables, settings)
            if chosen is None:
                break
            layers[-1].chosen = chosen
            beam = {k: getattr(env.state, k)[chosen].copy() for k in SEARCH_STATE_FIELDS}
            g = g_kid[chosen]
        if best is None:
            return None
        plan = _backtrack(layers, best[1], best[2])
        return StepPlan(plan, best[0], len(plan), time.perf_counter() - start, "beam", settings)

    def _select(
        self, env: VectorEnv, live: np.ndarray, g_kid: np.ndarray, best_moves: int, tables: _Heuristic,
        settings: SearchSettings,
    ) -> np.ndarray | None:  # fmt: skip
        """The next beam among the ``live`` children: those whose lower bound can still beat ``best_moves``,
        one per (cell, passenger phases) with the best ranking estimate f, the ``settings.beam`` lowest f;
        None when no child is hopeful."""
        num_pax = len(tables.stops) // 2
        pos = env.state.pos_m[live, 0]
        status = env.state.pax_status[live, :num_pax]
        codes = state_codes(status, env.state.pax_exists[live, :num_pax])
        d = self.fields.remaining_many(tables.stops, pos)  # [L, 2P]
        first_rank = np.maximum(d - settings.rank_slack * self.radius_m, 0.0)
        h_rank = np.min(first_rank + tables.rank_next[codes], axis=1)
        h_bound = np.min(np.maximum(d - self.radius_m, 0.0) + tables.bound_next[codes], axis=1)
        g_live = g_kid[live]
        f_bound = g_live * self.step_m + h_bound
        hopeful = f_bound < best_moves * self.step_m - 1e-6
        live, pos, codes, g_live = live[hopeful], pos[hopeful], codes[hopeful], g_live[hopeful]
        f = g_live * self.step_m + h_rank[hopeful]
        if not len(live):
            return None
        # duplicates: same cell and same passenger phases; keep the best f (ties: fewer moves)
        cell = np.floor(pos / settings.cell_m).astype(np.int64)
        order = np.lexsort((g_live, f, codes, cell[:, 1], cell[:, 0]))
        key = np.stack([cell[order, 0], cell[order, 1], codes[order]], axis=1)
        first = np.ones(len(order), bool)
        first[1:] = np.any(key[1:] != key[:-1], axis=1)
        unique = order[first]
        keep = unique[np.argsort(f[unique], kind="stable")[: settings.beam]]
        return live[keep]


class _Heuristic(NamedTuple):
    """What the beam's estimates read: the stops [2P, 2] and the remaining-tour tables of the passenger phases
    (``rank_next`` ranks the children, ``bound_next`` is a lower bound that prunes them)."""

    stops: np.ndarray
    rank_next: np.ndarray
    bound_next: np.ndarray


def _expand(
    env: VectorEnv, beam: dict[str, np.ndarray], g: np.ndarray, layers: list[_Layer]
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Every heading from every beam state in one batched step of ``env``; records the layer. Returns the
    children's moves so far, which of them finished the episode, and which are worth keeping."""
    n = len(g)
    kids = n * NUM_HEADINGS
    rows = np.concatenate([np.repeat(np.arange(n), NUM_HEADINGS), np.zeros(env.num_envs - kids, np.int64)])
    for name in SEARCH_STATE_FIELDS:
        getattr(env.state, name)[:] = beam[name][rows]
    actions = np.concatenate([np.tile(np.arange(NUM_HEADINGS), n), np.zeros(env.num_envs - kids, np.int64)])
    _, _, terminated, _, info = env.step(actions[:, None])
    ev = info["events"]
    g_kid = g[rows[:kids]] + ev.moved[:kids, 0]
    layers.append(_Layer(parent=rows[:kids], action=actions[:kids]))
    done = terminated[:kids]
    # Waiting (a forbidden heading: the taxi stays) only helps while a request is still to be released;
    # afterwards a state that waits ties with its parent forever and would stall the beam.
    hidden = np.any((beam["pax_status"] == HIDDEN) & beam["pax_exists"], axis=1)[rows[:kids]]
    useful = ev.moved[:kids, 0] | hidden | done
    return g_kid, done, useful


def _backtrack(layers: list[_Layer], depth: int, child: int) -> list[int]:
    """Actions from the root to child ``child`` of search depth ``depth``."""
    actions: list[int] = []
    for d in range(depth, -1, -1):
        actions.append(int(layers[d].action[child]))
        row = int(layers[d].parent[child])
        if d > 0:
            child = int(layers[d - 1].chosen[row])
    return actions[::-1]


# ---- as policies ------------------------------------------------------------------------------------------


def raster_opt_actions(cfg: EnvConfig) -> list[int]:
    """The actions ``raster_opt`` flies on ``cfg`` until its last drop-off (a candidate for ``best_known``)."""
    # Flown here rather than with uamfleet.rollout.fly, which sits a layer above the baselines.
    env, policy = VectorEnv(cfg, num_envs=1, autoreset=False), PlannerPolicy("raster_opt")
    obs, _ = env.reset(seed=0)
    policy.reset(env.sim)
    actions: list[int] = []
    while True:
        chosen = np.asarray(policy(obs)).reshape(1, 1)
        obs, _, terminated, truncated, _ = env.step(chosen)
        actions.append(int(chosen[0, 0]))
        if terminated[0] or truncated[0]:
            return actions if terminated[0] else []


class StepPlannerPolicy(PolicyBase):
    """``best_known`` or ``replan`` (:data:`STEP_PLANNERS`) as a policy for a one-taxi, one-env core.

    After an episode, ``plans`` holds every plan made (with its solve time) and, for ``best_known``,
    ``lower_bound_m`` the instance's lower bound (:func:`lower_bound_m`)."""

    def __init__(self, planner: str, settings: Sequence[SearchSettings] | None = None) -> None:
        if planner not in STEP_PLANNERS:
            raise ValueError(f"unknown step-level planner {planner!r}; choose one of {STEP_PLANNERS}.")
        self.planner = planner
        default = CLAIRVOYANT_SETTINGS if planner == "best_known" else REPLAN_SETTINGS
        self.settings = tuple(settings) if settings is not None else default
        self.sim: Simulator | None = None
        self.plans: list[StepPlan] = []
        self.queue: list[int] = []
        self.lower_bound_m = math.nan

    def reset(self, sim: Simulator) -> None:
        require_one_taxi_env(sim, self.planner, type(self).__name__)
        self.sim = sim
        self.search = StepSearch(sim.cfg)
        self.plans = []
        s = sim.state
        self._seen = s.pax_status[0] != HIDDEN
        exists = s.pax_exists[0]
        stops = np.stack([s.pax_origin_m[0, exists], s.pax_dest_m[0, exists]], axis=1).reshape(-1, 2)
        cfg = sim.cfg
        self.lower_bound_m = lower_bound_m(s.pos_m[0, 0], stops, cfg.seats, cfg.radius_m, cfg.step_m)
        if self.planner == "best_known":
            self.queue = self._clairvoyant()
        else:
            self.queue = self._replan()

    def _clairvoyant(self) -> list[int]:
        assert self.sim is not None
        start = time.perf_counter()
        plan = self.search.solve(self.sim.state, self.settings)
        candidates = [plan] if plan is not None else []
        if self.sim.cfg.starts_m is not None and self.sim.cfg.requests is not None:
            raster = raster_opt_actions(self.sim.cfg)
            if raster:
                moves = self._count_moves(raster)
                candidates.append(StepPlan(raster, moves, len(raster), 0.0, "raster_opt"))
        if not candidates:
            return []
        best = min(candidates, key=lambda p: (p.moves, p.steps))
        best.solve_s = time.perf_counter() - start
        self.plans.append(best)
        return list(best.actions)

    def _count_moves(self, actions: list[int]) -> int:
        """Moves a fixed action sequence flies from this episode's start (replayed in a scratch core)."""
        assert self.sim is not None
        env = VectorEnv(self.search.scratch_cfg, 1, autoreset=False)
        env.reset(seed=0)
        moves = 0
        for a in actions:
            _, _, term, trunc, info = env.step(np.array([[a]]))
            moves += int(info["events"].moved[0, 0])
            if term[0] or trunc[0]:
                break
        return moves

    def _replan(self) -> list[int]:
        """The step-level search from the current state over the requests released so far."""
        assert self.sim is not None
        known = released_only(self.sim.state)
        plan = self.search.solve(known, self.settings)
        if plan is None:  # a wider, slack-free search before giving up
            wider = [SearchSettings(4 * s.beam, s.cell_m, 0.0) for s in self.settings]
            plan = self.search.solve(known, wider)
        if plan is None:
            return []
        self.plans.append(plan)
        return list(plan.actions)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        assert self.sim is not None, "call reset(sim) first (run_episode does)"
        s = self.sim.state
        newly = (s.pax_status[0] != HIDDEN) & ~self._seen
        if newly.any():
            self._seen |= newly
            if self.planner == "replan":
                self.queue = self._replan()
        if self.queue:
            return np.array([[self.queue.pop(0)]])
        return np.array([[self._wait_action(s.action_mask[0, 0], int(s.t[0]))]])

    @staticmethod
    def _wait_action(mask: np.ndarray, t: int) -> int:
        """Nothing to do yet: a forbidden heading keeps the taxi in place; if every heading is allowed, fly
        back and forth (heading 0, then 8)."""
        blocked = np.flatnonzero(~mask)
        if len(blocked):
            return int(blocked[0])
        return 0 if t % 2 == 0 else 8
