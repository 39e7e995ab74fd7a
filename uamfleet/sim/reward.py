"""Named reward terms computed from step events (never from physics).

Each term is [E, A]; the reward of a taxi is their sum. Term ``name`` is weighted by ``RewardConfig.<name>``
(docs/rules.md, "Rewards").
"""

from __future__ import annotations

import functools
import math
from collections.abc import Callable
from typing import TYPE_CHECKING

import numpy as np
from numba import njit

from uamfleet.config import REWARD_TERMS, RewardConfig
from uamfleet.paths import DistanceFields, DistanceTable, table_for
from uamfleet.paths.distance_table import TableArrays, table_distance
from uamfleet.sim.pretyped import PreTyped
from uamfleet.sim.world import stop_of
from uamfleet.types import ON_BOARD, WAITING, FleetState, StepEvents

if TYPE_CHECKING:
    from uamfleet.sim.world import World


# Column of each term in the [E, A, len(REWARD_TERMS)] array, found by name (numba reads them as constants).
STEP = REWARD_TERMS.index("step")
EXPLORE = REWARD_TERMS.index("explore")
PICKUP = REWARD_TERMS.index("pickup")
DROPOFF = REWARD_TERMS.index("dropoff")
BLOCKED = REWARD_TERMS.index("blocked")
SHAPING = REWARD_TERMS.index("shaping")
SEPARATION = REWARD_TERMS.index("separation")
SHIELD = REWARD_TERMS.index("shield")
HOVER = REWARD_TERMS.index("hover")


def reward_terms(events: StepEvents, weights: RewardConfig, shaping: np.ndarray | None = None) -> np.ndarray:
    """[E, A, len(REWARD_TERMS)] weighted terms, column ``REWARD_TERMS.index(name)`` for term ``name``:

    ``step`` every step; ``explore``: ``explore`` on entering a new block, else ``explore_repeat * (visits - 1)``
    (the authors' code); ``pickup`` / ``dropoff`` per passenger; ``blocked`` per disallowed move; ``shaping`` as
    given (see :func:`shaping_term`); ``separation`` per taxi closer than the separation minimum to another after
    the step; ``shield`` per move the separation shield replaced, ``hover`` per step the taxi hovered.
    Each term is weighted by the :class:`RewardConfig` field of its name.
    """
    terms = _terms(
        events.blocked, events.block_visits, events.pickups, events.dropoffs, events.separation_violation,
        events.shield_intervened, events.hovered, *_weights(weights),
    )  # fmt: skip
    if shaping is not None:
        terms[..., SHAPING] = shaping
    return terms


@functools.lru_cache(maxsize=64)
def _weights(weights: RewardConfig) -> tuple[np.ndarray, float]:
    """The kernel's weights: [len(REWARD_TERMS)] (each term's weight, by name) and ``explore_repeat``; built once
    per (frozen, hashable) config instead of every step."""
    w = np.array([getattr(weights, name) for name in REWARD_TERMS], dtype=np.float64)
    w.setflags(write=False)  # shared between calls
    return w, float(weights.explore_repeat)


@njit(cache=True)
def _terms(
    blocked: np.ndarray,  # [E, A] bool, the move asked for was not allowed (a hover is not blocked)
    block_visits: np.ndarray,  # [E, A]
    pickups: np.ndarray,  # [E, A]
    dropoffs: np.ndarray,  # [E, A]
    separation: np.ndarray,  # [E, A] bool
    shield: np.ndarray,  # [E, A] bool
    hovered: np.ndarray,  # [E, A] bool
    w: np.ndarray,  # [len(REWARD_TERMS)]
    explore_repeat: float,
) -> np.ndarray:
    num_envs, num_taxis = blocked.shape
    out = np.zeros((num_envs, num_taxis, len(REWARD_TERMS)))
    for e in range(num_envs):
        for a in range(num_taxis):
            visits = block_visits[e, a]
            out[e, a, STEP] = w[STEP]
            out[e, a, EXPLORE] = w[EXPLORE] if visits == 1 else explore_repeat * (visits - 1)
            out[e, a, PICKUP] = w[PICKUP] * pickups[e, a]
            out[e, a, DROPOFF] = w[DROPOFF] * dropoffs[e, a]
            out[e, a, BLOCKED] = w[BLOCKED] if blocked[e, a] else 0.0
            out[e, a, SEPARATION] = w[SEPARATION] if separation[e, a] else 0.0
            out[e, a, SHIELD] = w[SHIELD] if shield[e, a] else 0.0
            out[e, a, HOVER] = w[HOVER] if hovered[e, a] else 0.0
    return out


def total_reward(terms: np.ndarray) -> np.ndarray:
    """[E, A] the reward: the terms [E, A, T] summed left to right, in the order of :data:`REWARD_TERMS`.

    Not ``terms.sum(-1)``: NumPy sums 8 or more values pairwise, in another order than fewer, so the terms added
    after the first seven (``shield``, ``hover``) would change the last bits of every reward even where they are
    0. Summed in order, a reward is bit for bit what it was with seven terms (the paper's scenarios reproduce).
    """
    total = np.empty(terms.shape[:-1], terms.dtype)
    _sum_in_order(terms.reshape(-1, terms.shape[-1]), total.reshape(-1))
    return total


@njit(cache=True)
def _sum_in_order(terms: np.ndarray, out: np.ndarray) -> None:
    """out[i] = terms[i, 0] + terms[i, 1] + ... left to right (the same additions, in the same order, as adding
    the columns one by one; one compiled loop instead of a NumPy call per term)."""
    for i in range(terms.shape[0]):
        total = terms[i, 0]
        for j in range(1, terms.shape[1]):
            total += terms[i, j]
        out[i] = total


DistanceTo = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``distance_to(goal [2], points [K, 2]) -> [K]`` metres from each point to the goal."""


def euclidean(goal: np.ndarray, points: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points - goal, axis=-1)


class Potential:
    """The shaping potential Phi [E, A] of a world under one ``RewardConfig.shaping_metric`` (docs/rules.md
    "Rewards"): minus the distance, in steps, from each taxi to its nearest actionable stop.

    ``"euclidean"`` (straight line) and ``"path"`` (feasible paths looked up in the world's
    :class:`~uamfleet.paths.DistanceTable`) run in one compiled kernel over all envs and taxis (:func:`_phi`);
    ``"path_exact"`` measures with :class:`~uamfleet.paths.DistanceFields` (a 10 m Dijkstra field per stop, in
    Python: exact on the raster graph but ~1,000x slower on random demand) through :func:`potential_reference`.
    The same object computes Phi before and after a step, so the shaping stays exactly potential-based.
    """

    def __init__(self, world: World, metric: str) -> None:
        self.metric = metric
        self.step_m = float(world.step_m)
        self._table: DistanceTable | None = None
        self._fields: DistanceFields | None = None
        self._phi = PreTyped(_phi)  # without numba typing the state on every call (uamfleet.sim.pretyped)
        if metric == "path":
            self._table = table_for(world)
        elif metric == "path_exact":
            self._fields = DistanceFields(world)
        elif metric != "euclidean":
            raise ValueError(f"shaping_metric={metric!r} is unknown; use 'path', 'path_exact' or 'euclidean'.")

    def __call__(self, state: FleetState) -> np.ndarray:
        if self._fields is not None:
            fields = self._fields
            return potential_reference(state, self.step_m, lambda goal, points: fields.remaining_m(goal, points))
        out = np.empty(state.free_seats.shape)
        table = self._table
        if table is None:
            self._phi(state, _NO_TABLE, False, self.step_m, out)
        elif not self._phi(state, table.arrays, True, self.step_m, out):
            # a stop whose table rows are not computed yet (a new instance): compute them, then again
            table.ensure(np.concatenate([state.pax_origin_m[state.pax_exists], state.pax_dest_m[state.pax_exists]]))
            self._phi(state, table.arrays, True, self.step_m, out)
        return out


_NO_TABLE = TableArrays(np.zeros((1, 1), dtype=np.float32), 1.0, 1, 1)


@njit(cache=True)
def _phi(
    s: FleetState,
    t: TableArrays,  # DistanceTable.arrays, or a dummy when not use_table
    use_table: bool,
    step_m: float,
    out: np.ndarray,  # [E, A]
) -> bool:
    """out[e, a] = Phi of taxi a of env e (see :class:`Potential`). Returns False when a table row was missing
    (then ``out`` is incomplete)."""
    num_envs, num_taxis = s.free_seats.shape
    num_pax = s.pax_status.shape[1]
    for e in range(num_envs):
        for a in range(num_taxis):
            x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
            nearest = math.inf
            for p in range(num_pax):
                # row_stop(s, e, a, p), without passing the state (that reference-counts its ~30 arrays per call)
                point = stop_of(s.pax_status[e, p], s.pax_taxi[e, p], s.free_seats[e, a], a, p)
                if point < 0:
                    continue
                stops = s.pax_dest_m if point % 2 else s.pax_origin_m
                gx, gy = stops[e, p, 0], stops[e, p, 1]
                if use_table:
                    d = table_distance(t, x, y, gx, gy)
                    if math.isnan(d):
                        return False
                else:
                    dx, dy = x - gx, y - gy
                    d = math.sqrt(dx * dx + dy * dy)
                nearest = min(nearest, d)
            out[e, a] = -nearest / step_m if nearest < math.inf else 0.0
    return True


def potential_reference(state: FleetState, step_m: float, distance_to: DistanceTo = euclidean) -> np.ndarray:
    """[E, A] shaping potential with any ``distance_to``, in numpy: the definition :class:`Potential`'s kernel
    implements (tests compare them), and the ``"path_exact"`` metric.

    Actionable stops: the destinations of its passengers on board, and, while it has a free seat, the origins of
    released passengers waiting. A taxi with nothing to do, or whose stops are all out of reach (distance
    ``inf``), has potential 0.
    """
    E, A = state.free_seats.shape
    P = state.pax_status.shape[1]
    mine = (state.pax_status == ON_BOARD)[:, None, :] & (state.pax_taxi[:, None, :] == np.arange(A)[None, :, None])
    waiting = (state.pax_status == WAITING)[:, None, :] & (state.free_seats[:, :, None] > 0)  # [E, A, P]
    nearest = np.full((E, A), np.inf)
    for actionable, stops in ((mine, state.pax_dest_m), (waiting, state.pax_origin_m)):
        for p in range(P):
            envs = np.flatnonzero(actionable[:, :, p].any(axis=1))
            if envs.size == 0:
                continue
            # envs that share the stop's coordinates (a fixed instance: all of them) need one distance query
            coords, group = np.unique(stops[envs, p], axis=0, return_inverse=True)
            for g, goal in enumerate(coords):
                sel = envs[group.reshape(-1) == g]
                d = distance_to(goal, state.pos_m[sel].reshape(-1, 2)).reshape(len(sel), A)  # [e, A]
                nearest[sel] = np.minimum(nearest[sel], np.where(actionable[sel, :, p], d, np.inf))
    return np.where(np.isfinite(nearest), -nearest / step_m, 0.0)


def shaping_term(phi_before: np.ndarray, phi_after: np.ndarray, done: np.ndarray, weights: RewardConfig) -> np.ndarray:
    """``w * (gamma * Phi(s') - Phi(s))`` with Phi(terminal) = 0 (Ng, Harada & Russell 1999)."""
    phi_next = np.where(done[:, None], 0.0, phi_after)
    return weights.shaping * (weights.shaping_gamma * phi_next - phi_before)
