"""One move's geometry on the distance table (compiled): the look-ups from a taxi's 16 move ends
(:func:`prepare_moves`), each move's cost and lower bound, and the allowed heading that makes most progress along
the feasible path to a stop (:func:`_progress_heading`). The stop features (:mod:`uamfleet.observe.stops`) and the
look-ahead (:mod:`uamfleet.observe.lookahead`) read them."""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from uamfleet.paths.distance_table import (
    Corners,
    DistanceTable,
    TableArrays,
    corner_distance,
    new_corners,
    prepare_corners,
)
from uamfleet.sim.arrays import WorldArrays
from uamfleet.types import NUM_HEADINGS

__all__ = ["MoveGeometry", "StopRows", "prepare_moves", "progress_heading"]


class StopRows(NamedTuple):
    """What :func:`_stop_rows` reads of env e's state for taxi a: views of ``pax_exists[e]``, ``pax_status[e]``,
    ``pax_taxi[e]``, ``free_seats[e]`` and the taxi's kept tour rests ``stop_tour_m[e, a]``."""

    exists: np.ndarray  # [P]
    statuses: np.ndarray  # [P]
    carriers: np.ndarray  # [P]
    free_seats: np.ndarray  # [A]
    tour_rests: np.ndarray  # [2P]


class MoveGeometry(NamedTuple):
    """What the move costs read of :class:`WorldArrays`: passed in its place in per-row and per-move calls, which
    would reference-count each of the world's arrays on every call."""

    moves_m: np.ndarray  # [NUM_HEADINGS, 2]
    step_m: float
    radius_m: float


@njit(cache=True)
def _progress_heading(
    allowed: np.ndarray, w: WorldArrays, t: TableArrays, x: float, y: float, gx: float, gy: float
) -> int:
    """The allowed heading from (x, y) with the least move + table distance left to (gx, gy) (the move alone when it
    ends within the pick-up radius), ties to the lowest heading; -1 when none is allowed or reachable. The stop's
    table rows must be computed (the caller has read them). Prepares its own look-ups; a kernel that has them
    calls :func:`_progress_heading_prepared`."""
    taxi, stop = new_corners(NUM_HEADINGS + 1), new_corners(1)
    prepare_moves(w.moves_m, t, x, y, taxi)
    prepare_corners(t, gx, gy, stop, 0)
    return _progress_heading_prepared(allowed, MoveGeometry(w.moves_m, w.step_m, w.radius_m), t, x, y, gx, gy, taxi,
                                      stop, 0, np.empty(NUM_HEADINGS))  # fmt: skip


def progress_heading(
    table: DistanceTable, w: WorldArrays, allowed: np.ndarray, pos: np.ndarray, goal: np.ndarray
) -> int:
    """The heading ``stop_heading_mask`` marks for a stop at ``goal`` (:func:`_progress_heading`), from Python: the
    table rows it reads are computed first. A fleet dispatcher flying ``heading="table"`` steers by it."""
    table.ensure(goal)
    x, y, gx, gy = float(pos[0]), float(pos[1]), float(goal[0]), float(goal[1])
    return int(_progress_heading(np.ascontiguousarray(allowed), w, table.arrays, x, y, gx, gy))


@njit(cache=True, inline="always")
def prepare_moves(moves_m: np.ndarray, t: TableArrays, x: float, y: float, taxi: Corners) -> None:
    """Prepare the look-ups from the ends of the 16 moves from (x, y) (slots 0-15, the same float operations as the
    moves' costs) and from (x, y) itself (slot 16) in ``taxi`` (:func:`uamfleet.paths.distance_table.Corners`)."""
    for h in range(NUM_HEADINGS):
        prepare_corners(t, x + moves_m[h, 0], y + moves_m[h, 1], taxi, h)
    prepare_corners(t, x, y, taxi, NUM_HEADINGS)


@njit(cache=True, inline="always")
def _progress_heading_prepared(
    allowed: np.ndarray, w: MoveGeometry, t: TableArrays, x: float, y: float, gx: float, gy: float, taxi: Corners,
    stop: Corners, j: int, bounds: np.ndarray,
) -> int:  # fmt: skip
    """:func:`_progress_heading`, its look-ups prepared: the taxi's moves in ``taxi`` (:func:`prepare_moves`), the
    stop (gx, gy) in slot j of ``stop``; ``bounds`` [16] is scratch (each move's bound, computed once).

    A move costs at least ``step_m`` + its end's straight-line distance to the stop (:func:`_move_bound`; the table
    distance never undercuts the straight line), so the move with the least bound is costed first and a move
    whose bound cannot beat the best so far is never looked up: the same heading as costing all 16 in order, for
    a few look-ups instead of 16."""
    first = _least_bound_move(allowed, w, x, y, gx, gy, bounds)
    if first < 0:
        return -1
    best, best_cost = first, _move_cost(w, t, x, y, first, gx, gy, taxi, stop, j)
    if best_cost == math.inf:
        best = -1
    for h in range(NUM_HEADINGS):
        if not allowed[h] or h == first:
            continue
        bound = bounds[h]
        if bound > best_cost or (bound == best_cost and h > best):
            continue  # its cost is >= bound: it cannot win, not even a tie
        cost = _move_cost(w, t, x, y, h, gx, gy, taxi, stop, j)
        if cost < best_cost or (cost == best_cost and cost < math.inf and h < best):
            best, best_cost = h, cost
    return best


@njit(cache=True, inline="always")
def _least_bound_move(
    allowed: np.ndarray, w: MoveGeometry, x: float, y: float, gx: float, gy: float, bounds: np.ndarray
) -> int:
    """The allowed heading of least :func:`_move_bound` (the lowest of equal ones); -1 when none is allowed. Each
    allowed move's bound goes into ``bounds``."""
    first, first_bound = -1, math.inf
    for h in range(NUM_HEADINGS):
        if allowed[h]:
            bound = _move_bound(w, x, y, h, gx, gy)
            bounds[h] = bound
            if bound < first_bound:
                first, first_bound = h, bound
    return first


@njit(cache=True, inline="always")
def _move_bound(w: MoveGeometry, x: float, y: float, h: int, gx: float, gy: float) -> float:
    """A lower bound of :func:`_move_cost`, in the same float operations: the move plus the straight line left."""
    qx, qy = x + w.moves_m[h, 0], y + w.moves_m[h, 1]
    if (qx - gx) ** 2 + (qy - gy) ** 2 <= w.radius_m * w.radius_m:
        return w.step_m
    dx, dy = qx - gx, qy - gy
    return w.step_m + math.sqrt(dx * dx + dy * dy)


@njit(cache=True, inline="always")
def _move_cost(
    w: MoveGeometry, t: TableArrays, x: float, y: float, h: int, gx: float, gy: float, taxi: Corners, stop: Corners,
    j: int,
) -> float:  # fmt: skip
    """Heading h's move plus the table distance left from its end to (gx, gy); the move alone within the
    pick-up radius (look-ups prepared: :func:`_progress_heading_prepared`)."""
    qx, qy = x + w.moves_m[h, 0], y + w.moves_m[h, 1]
    if (qx - gx) ** 2 + (qy - gy) ** 2 <= w.radius_m * w.radius_m:
        return w.step_m
    return w.step_m + corner_distance(t, taxi, h, stop, j, qx, qy, gx, gy)
