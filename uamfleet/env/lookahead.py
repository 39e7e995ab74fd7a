"""The one-step look-ahead of every heading on the taxi's shortest tour (compiled): the ``heading_lookahead``
observation field (``EnvConfig.heading_lookahead``; docs/rules.md "Observation").

For each allowed heading h of taxi a, the move's end q_h is served as the step would serve it (drop-offs of a's
riders within the pick-up radius, then the lowest-index waiting passengers within it while a seat is free; other
taxis are not simulated), and the cost of h is the move plus the shortest tour from q_h through every stop a still
knows of afterwards (:func:`uamfleet.env.tours._shortest_rests` over the stops left, exact up to
:data:`~uamfleet.env.tours.MAX_EXACT_STOPS`, else the nearest-stop order). The field holds each heading's cost
minus the cheapest heading's, in moves (``step_m``), clipped to :data:`~uamfleet.types.LOOKAHEAD_CLIP`; a heading
that is not allowed reads the clip; a taxi with no stop to fly to reads zeros.

Why: the stop head's prior flies each stop's single progress heading, and every heading that ends within the pick-up
radius costs the same to it, so where the taxi enters a stop's radius (and leaves for the next stop) is decided by
heading order. The tour after the move measures exactly that choice; the stop features measure only the tour from
the stop's centre. A heading with value 0 here is as good as the best one-step choice on the known stops.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from uamfleet.env.arrays import WorldArrays
from uamfleet.env.kernels import _nearest_rests, row_stop
from uamfleet.env.tours import _shortest_rests
from uamfleet.paths.distance_table import TableArrays, table_distance
from uamfleet.types import DELIVERED, LOOKAHEAD_CLIP, NUM_HEADINGS, ON_BOARD, WAITING, FleetState


@njit(cache=True)
def heading_lookahead(s: FleetState, w: WorldArrays, t: TableArrays, o_look: np.ndarray) -> bool:
    """Write ``o_look`` [E, A, 16] (module docstring). The taxis' kept tour rests (``s.stop_tour_m``) must be up to
    date: call after :func:`uamfleet.env.kernels.stop_features` has succeeded. Returns False when a table row it
    reads is not computed yet (the caller fills the rows and calls again)."""
    num_envs, num_taxis = s.free_seats.shape
    num_pax = s.pax_status.shape[1]
    pts = np.empty((2 * num_pax, 2))
    rests = np.empty(2 * num_pax)  # scratch: the tour rests after a move that serves a stop
    undo = np.empty(num_pax, np.int64)  # scratch: what a hypothetical move served
    cost = np.empty(NUM_HEADINGS)
    for e in range(num_envs):
        for p in range(num_pax):
            pts[2 * p] = s.pax_origin_m[e, p]
            pts[2 * p + 1] = s.pax_dest_m[e, p]
        for a in range(num_taxis):
            found = _heading_costs(s, w, t, e, a, pts, rests, undo, cost)
            if found < 0:
                return False
            _write_excess(s.action_mask[e, a], cost, found == 1, w.step_m, o_look[e, a])
    return True


@njit(cache=True)
def _write_excess(allowed: np.ndarray, cost: np.ndarray, any_stop: bool, step_m: float, out: np.ndarray) -> None:
    """out[h] = (cost[h] - the least allowed cost) / step_m, clipped; the clip where h is not allowed or costs inf;
    zeros when the taxi has no stop (``any_stop`` False) or no allowed heading reaches one."""
    least = math.inf
    for h in range(NUM_HEADINGS):
        if allowed[h] and cost[h] < least:
            least = cost[h]
    for h in range(NUM_HEADINGS):
        if not any_stop or least == math.inf:
            out[h] = 0.0
        elif not allowed[h] or cost[h] == math.inf:
            out[h] = LOOKAHEAD_CLIP
        else:
            out[h] = min((cost[h] - least) / step_m, LOOKAHEAD_CLIP)


@njit(cache=True)
def _heading_costs(
    s: FleetState, w: WorldArrays, t: TableArrays, e: int, a: int, pts: np.ndarray, rests: np.ndarray,
    undo: np.ndarray, cost: np.ndarray,
) -> int:  # fmt: skip
    """cost[h]: heading h's move plus the shortest tour from its end (module docstring), for the allowed headings.
    Returns 1, 0 when taxi a has no stop to fly to (cost untouched), -1 when a table row is missing."""
    if not _has_stop(s, e, a):
        return 0
    memo = s.stop_pair_m[e]
    x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
    for h in range(NUM_HEADINGS):
        cost[h] = math.inf
        if not s.action_mask[e, a, h]:
            continue
        qx, qy = x + w.moves_m[h, 0], y + w.moves_m[h, 1]
        if _serve_at(s, e, a, qx, qy, w.radius_m + 1e-9, undo):  # the stops left after the move: tours from scratch
            found = _shortest_rests(s, e, a, memo, pts, t, rests)
            if found == -1:
                found = 1 if _nearest_rests(s, e, a, memo, pts, t, rests) else 0
            tour = _tour_from(s, e, a, qx, qy, pts, rests, t) if found == 1 else math.nan
            _unserve(s, e, a, undo)
        else:  # nothing served: the kept rests hold
            tour = _tour_from(s, e, a, qx, qy, pts, s.stop_tour_m[e, a], t)
        if math.isnan(tour):
            return -1
        cost[h] = w.step_m + tour
    return 1


@njit(cache=True)
def _has_stop(s: FleetState, e: int, a: int) -> bool:
    """Whether any row offers taxi a a stop (:func:`uamfleet.env.kernels.row_stop`)."""
    for p in range(s.pax_status.shape[1]):
        if s.pax_exists[e, p] and row_stop(s, e, a, p) >= 0:
            return True
    return False


@njit(cache=True)
def _tour_from(
    s: FleetState, e: int, a: int, qx: float, qy: float, pts: np.ndarray, rests: np.ndarray, t: TableArrays
) -> float:
    """The shortest tour from (qx, qy) through taxi a's stops: the least table distance to a stop a row offers plus
    the tour's rest after it (``rests``); 0 when no stop is left; NaN when a table row is missing."""
    best, any_stop = math.inf, False
    for p in range(s.pax_status.shape[1]):
        if not s.pax_exists[e, p]:
            continue
        point = row_stop(s, e, a, p)
        if point < 0:
            continue
        any_stop = True
        d = table_distance(t, qx, qy, pts[point, 0], pts[point, 1])
        if math.isnan(d):
            return math.nan
        best = min(best, d + rests[point])
    return best if any_stop else 0.0


@njit(cache=True)
def _serve_at(s: FleetState, e: int, a: int, qx: float, qy: float, reach: float, undo: np.ndarray) -> bool:
    """Serve taxi a's stops within ``reach`` of (qx, qy) in the state, as the step's drop-offs and pick-ups would
    (without other taxis); ``undo`` [P] records each row's change for :func:`_unserve` (0 none, 1 dropped off,
    2 picked up). Returns whether anything was served."""
    served = False
    for p in range(s.pax_status.shape[1]):
        undo[p] = 0
        if s.pax_exists[e, p] and s.pax_status[e, p] == ON_BOARD and s.pax_taxi[e, p] == a:
            if math.hypot(qx - s.pax_dest_m[e, p, 0], qy - s.pax_dest_m[e, p, 1]) <= reach:
                s.pax_status[e, p] = DELIVERED
                s.free_seats[e, a] += 1
                undo[p], served = 1, True
    for p in range(s.pax_status.shape[1]):
        if s.free_seats[e, a] == 0:
            break
        if s.pax_exists[e, p] and s.pax_status[e, p] == WAITING:
            if math.hypot(qx - s.pax_origin_m[e, p, 0], qy - s.pax_origin_m[e, p, 1]) <= reach:
                s.pax_status[e, p] = ON_BOARD
                s.free_seats[e, a] -= 1
                undo[p], served = 2 + s.pax_taxi[e, p] + 1, True  # 2 + (old carrier + 1): restored by _unserve
                s.pax_taxi[e, p] = a
    return served


@njit(cache=True)
def _unserve(s: FleetState, e: int, a: int, undo: np.ndarray) -> None:
    """Undo :func:`_serve_at`."""
    for p in range(s.pax_status.shape[1]):
        if undo[p] == 1:
            s.pax_status[e, p] = ON_BOARD
            s.free_seats[e, a] -= 1
        elif undo[p] >= 2:
            s.pax_status[e, p] = WAITING
            s.free_seats[e, a] += 1
            s.pax_taxi[e, p] = undo[p] - 3


__all__ = ["heading_lookahead"]
