"""Named reward terms computed from step events (never from physics).

Each term is [E, A]; the reward of a taxi is their sum. Term ``name`` is weighted by ``RewardConfig.<name>``
(docs/rules.md, "Rewards").
"""

from __future__ import annotations

import functools
from collections.abc import Callable

import numpy as np
from numba import njit

from uamfleet.config import REWARD_TERMS, RewardConfig
from uamfleet.types import ON_BOARD, WAITING, FleetState, StepEvents


# Column of each term in the [E, A, len(REWARD_TERMS)] array, found by name (numba reads them as constants).
STEP = REWARD_TERMS.index("step")
EXPLORE = REWARD_TERMS.index("explore")
PICKUP = REWARD_TERMS.index("pickup")
DROPOFF = REWARD_TERMS.index("dropoff")
BLOCKED = REWARD_TERMS.index("blocked")
SHAPING = REWARD_TERMS.index("shaping")


def reward_terms(events: StepEvents, weights: RewardConfig, shaping: np.ndarray | None = None) -> np.ndarray:
    """[E, A, len(REWARD_TERMS)] weighted terms, column ``REWARD_TERMS.index(name)`` for term ``name``:

    ``step`` every step; ``explore``: ``explore`` on entering a new block, else ``explore_repeat * (visits - 1)``
    (the authors' code); ``pickup`` / ``dropoff`` per passenger; ``blocked`` per disallowed move; ``shaping`` as
    given (see :func:`shaping_term`). Each term is weighted by the :class:`RewardConfig` field of its name.
    """
    terms = _terms(events.moved, events.block_visits, events.pickups, events.dropoffs, *_weights(weights))
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
    moved: np.ndarray,  # [E, A] bool
    block_visits: np.ndarray,  # [E, A]
    pickups: np.ndarray,  # [E, A]
    dropoffs: np.ndarray,  # [E, A]
    w: np.ndarray,  # [len(REWARD_TERMS)]
    explore_repeat: float,
) -> np.ndarray:
    num_envs, num_taxis = moved.shape
    out = np.zeros((num_envs, num_taxis, len(REWARD_TERMS)))
    for e in range(num_envs):
        for a in range(num_taxis):
            visits = block_visits[e, a]
            out[e, a, STEP] = w[STEP]
            out[e, a, EXPLORE] = w[EXPLORE] if visits == 1 else explore_repeat * (visits - 1)
            out[e, a, PICKUP] = w[PICKUP] * pickups[e, a]
            out[e, a, DROPOFF] = w[DROPOFF] * dropoffs[e, a]
            out[e, a, BLOCKED] = 0.0 if moved[e, a] else w[BLOCKED]
    return out


DistanceTo = Callable[[np.ndarray, np.ndarray], np.ndarray]
"""``distance_to(goal [2], points [K, 2]) -> [K]`` metres from each point to the goal."""


def euclidean(goal: np.ndarray, points: np.ndarray) -> np.ndarray:
    return np.linalg.norm(points - goal, axis=-1)


def potential(state: FleetState, step_m: float, distance_to: DistanceTo = euclidean) -> np.ndarray:
    """[E, A] shaping potential: minus the distance (in steps) from each taxi to its nearest actionable stop.

    Actionable stops: the destinations of its passengers on board, and, while it has a free seat, the origins of
    released passengers waiting. A taxi with nothing to do has potential 0. ``distance_to`` measures the
    distance: straight-line, or along feasible paths (``RewardConfig.shaping_metric = "path"``), which has no
    local optimum at the edge of a no-fly area (a straight-line potential rewards pressing against it).
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
