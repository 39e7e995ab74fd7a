"""The one-step look-ahead of every heading on the taxi's shortest tour (compiled): the ``heading_lookahead``
observation field (``EnvConfig.heading_lookahead``; docs/rules.md "Observation").

For each allowed heading h of taxi a, the move's end q_h is served as the step would serve it (drop-offs of a's
riders within the pick-up radius, then the lowest-index waiting passengers within it while a seat is free; other
taxis are not simulated), and the cost of h is the move plus the shortest tour from q_h through every stop a still
knows of afterwards (:func:`uamfleet.observe.tours._shortest_rests` over the stops left, exact up to
:data:`~uamfleet.observe.tours.MAX_EXACT_STOPS`, else the nearest-stop order). The field holds each heading's cost
minus the cheapest heading's, in moves (``step_m``), clipped to :data:`~uamfleet.types.LOOKAHEAD_CLIP`; a heading
that is not allowed reads the clip; a taxi with no stop to fly to reads zeros.

Why: the stop head's prior flies each stop's single progress heading, and every heading that ends within the pick-up
radius costs the same to it, so where the taxi enters a stop's radius (and leaves for the next stop) is decided by
heading order. The tour after the move measures exactly that choice; the stop features measure only the tour from
the stop's centre. A heading with value 0 here is as good as the best one-step choice on the known stops.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from uamfleet.observe.moves import StopRows, prepare_moves
from uamfleet.observe.tours import _nearest_rests, _shortest_rests
from uamfleet.paths.distance_table import (
    Corners,
    DistanceTable,
    MissingTableRow,
    TableArrays,
    corner_distance,
    new_corners,
    prepare_corners,
    table_distance,
)
from uamfleet.sim.arrays import WorldArrays
from uamfleet.sim.motion import action_mask
from uamfleet.sim.world import World, stop_of
from uamfleet.types import DELIVERED, LOOKAHEAD_CLIP, NUM_HEADINGS, ON_BOARD, WAITING, FleetState


@njit(cache=True)
def heading_lookahead(
    s: FleetState, w: WorldArrays, t: TableArrays, o_look: np.ndarray, depth: int = 1
) -> bool:  # fmt: skip
    """Write ``o_look`` [E, A, 16] (module docstring). The taxis' kept tour rests (``s.stop_tour_m``) must be up to
    date: call after :func:`uamfleet.observe.stops.stop_features` has succeeded. ``depth`` 2 costs each heading by its
    move plus the best allowed second move from its end and the tour after both (:func:`_two_move_costs`). Returns
    False when a table row it reads is not computed yet (the caller fills the rows and calls again)."""
    num_envs, num_taxis = s.free_seats.shape
    num_pax = s.pax_status.shape[1]
    pts = np.empty((2 * num_pax, 2))
    scratch = _new_scratch(num_pax)
    inner = _new_scratch(num_pax) if depth > 1 else scratch
    cost = np.empty(NUM_HEADINGS)
    for e in range(num_envs):
        for p in range(num_pax):
            pts[2 * p] = s.pax_origin_m[e, p]
            pts[2 * p + 1] = s.pax_dest_m[e, p]
        for a in range(num_taxis):
            if depth > 1:
                found = _two_move_costs(s, w, t, e, a, pts, scratch, inner, cost)
            else:
                found = _heading_costs(s, w, t, e, a, pts, scratch, cost)
            if found < 0:
                return False
            _write_excess(s.action_mask[e, a], cost, found == 1, w.step_m, o_look[e, a])
    return True


@njit(cache=True)
def _two_move_costs(
    s: FleetState, w: WorldArrays, t: TableArrays, e: int, a: int, pts: np.ndarray, scratch: _Scratch,
    inner: _Scratch, cost: np.ndarray,
) -> int:  # fmt: skip
    """cost[h]: heading h's move plus the least, over the second moves allowed from its end, of that move and the
    shortest tour after it (each move's end served as the step serves it); the move alone when it serves every
    stop; inf when no second move is allowed. Same returns as :func:`_heading_costs`.

    The one-move costs from the move's end are :func:`_heading_costs` itself, run on the state as the move leaves
    it: the taxi moved there, its stops served, its action mask and kept tour rests those of that state (the
    rests after a served set computed once per distinct set); everything is put back before the next heading."""
    rows = StopRows(s.pax_exists[e], s.pax_status[e], s.pax_taxi[e], s.free_seats[e], s.stop_tour_m[e, a])
    if not _has_stop(rows, a):
        return 0
    x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
    mask = s.action_mask[e, a].copy()
    kept = rows.tour_rests.copy()
    end, end_mask = np.empty((1, 2)), np.empty((1, NUM_HEADINGS), s.action_mask.dtype)
    second = np.empty(NUM_HEADINGS)
    reach = w.radius_m + 1e-9
    num_sets, found = 0, 1
    for h in range(NUM_HEADINGS):
        cost[h] = math.inf
        if not mask[h]:
            continue
        qx, qy = x + w.moves_m[h, 0], y + w.moves_m[h, 1]
        served = _serve_at(rows, a, pts, qx, qy, reach, scratch.undo)
        if served:
            k = _matching_set(scratch.undo, scratch.served_undo, num_sets)
            if k < 0:
                k, num_sets = num_sets, num_sets + 1
                scratch.served_undo[k] = scratch.undo
                scratch.served_found[k] = _rests_after_serving(s, e, a, pts, t, scratch.served_rests[k])
            if scratch.served_found[k] != 1:
                found = -1
            rows.tour_rests[:] = scratch.served_rests[k]
        if found == 1:
            end[0, 0], end[0, 1] = qx, qy
            action_mask(end, w, end_mask)
            s.pos_m[e, a, 0], s.pos_m[e, a, 1] = qx, qy
            s.action_mask[e, a] = end_mask[0]
            after = _heading_costs(s, w, t, e, a, pts, inner, second)
            s.pos_m[e, a, 0], s.pos_m[e, a, 1] = x, y
            s.action_mask[e, a] = mask
            if after < 0:
                found = -1
            elif after == 0:  # the move serves every stop the taxi knows of
                cost[h] = w.step_m
            else:
                least = math.inf
                for h2 in range(NUM_HEADINGS):
                    if end_mask[0, h2] and second[h2] < least:
                        least = second[h2]
                cost[h] = w.step_m + least
        if served:
            rows.tour_rests[:] = kept
            _unserve(rows, a, scratch.undo)
        if found < 0:
            return -1
    return 1


class _Scratch(NamedTuple):
    """Work arrays of :func:`_heading_costs`, allocated once per call of :func:`heading_lookahead`."""

    stops: np.ndarray  # [2P] the offered stop points, least straight-line bound first (:func:`_offered_by_bound`)
    bound: np.ndarray  # [2P] their straight-line distance from the taxi plus their kept tour rest
    undo: np.ndarray  # [P] what a hypothetical move served (:func:`_serve_at`)
    served_undo: np.ndarray  # [16, P] each distinct served set met at this taxi (its undo record) ...
    served_rests: np.ndarray  # [16, 2P] ... the tour rests after it ...
    served_found: np.ndarray  # [16] ... and what computing them returned (1, 0: a table row missing)
    moves: Corners  # the look-ups from the taxi's 16 move ends, prepared (:func:`uamfleet.observe.moves.prepare_moves`)
    stop_corners: Corners  # ... and towards the offered stops, in the order of ``stops``


@njit(cache=True)
def _new_scratch(num_pax: int) -> _Scratch:
    return _Scratch(
        stops=np.empty(2 * num_pax, np.int64), bound=np.empty(2 * num_pax),
        undo=np.empty(num_pax, np.int64), served_undo=np.empty((NUM_HEADINGS, num_pax), np.int64),
        served_rests=np.empty((NUM_HEADINGS, 2 * num_pax)), served_found=np.empty(NUM_HEADINGS, np.int64),
        moves=new_corners(NUM_HEADINGS + 1), stop_corners=new_corners(2 * num_pax),
    )  # fmt: skip


SURE_M = 1e-3
"""Slack (metres) on the triangle inequality where a bound decides to skip work: float rounding on map coordinates
is ~1e-12 m, so a skip it allows is also allowed exactly, and what is computed is the same as without the skip."""


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
    s: FleetState, w: WorldArrays, t: TableArrays, e: int, a: int, pts: np.ndarray, scratch: _Scratch,
    cost: np.ndarray,
) -> int:  # fmt: skip
    """cost[h]: heading h's move plus the shortest tour from its end (module docstring), for the allowed headings.
    Returns 1, 0 when taxi a has no stop to fly to (cost untouched), -1 when a table row is missing.

    Three shortcuts, none of which changes a number: a move that serves nothing leaves the kept rests, and the
    tour from its end looks up only the stops whose straight-line bound can still win (:func:`_tour_from_bounded`);
    moves are tested for serving only when some stop lies within reach of a move's end; the moves that serve the
    same stops share one computation of the tours after them (the served state is the same)."""
    # the rows as views, which the helpers (called per heading) take rather than the state: a call that passes the
    # state reference-counts each of its ~30 arrays (~0.25 µs); _serve_at writes through them
    rows = StopRows(s.pax_exists[e], s.pax_status[e], s.pax_taxi[e], s.free_seats[e], s.stop_tour_m[e, a])
    if not _has_stop(rows, a):
        return 0
    x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
    kept = rows.tour_rests
    m = _offered_by_bound(rows, a, x, y, pts, kept, scratch.stops, scratch.bound)
    prepare_moves(w.moves_m, t, x, y, scratch.moves)
    for k in range(m):
        prepare_corners(t, pts[scratch.stops[k], 0], pts[scratch.stops[k], 1], scratch.stop_corners, k)
    reach = w.radius_m + 1e-9
    may_serve = _stop_within(rows, a, x, y, pts, reach + _longest_move(w.moves_m) + SURE_M)
    num_sets = 0  # distinct served sets met so far at this taxi
    for h in range(NUM_HEADINGS):
        cost[h] = math.inf
        if not s.action_mask[e, a, h]:
            continue
        qx, qy = x + w.moves_m[h, 0], y + w.moves_m[h, 1]
        if may_serve and _serve_at(rows, a, pts, qx, qy, reach, scratch.undo):  # the stops left: their own tours
            k = _matching_set(scratch.undo, scratch.served_undo, num_sets)
            if k < 0:
                k, num_sets = num_sets, num_sets + 1
                scratch.served_undo[k] = scratch.undo
                scratch.served_found[k] = _rests_after_serving(s, e, a, pts, t, scratch.served_rests[k])
            rests = scratch.served_rests[k]
            tour = _tour_from(rows, a, qx, qy, pts, rests, t) if scratch.served_found[k] == 1 else math.nan
            _unserve(rows, a, scratch.undo)
        else:  # nothing served: the kept rests hold
            move_m = math.sqrt(w.moves_m[h, 0] ** 2 + w.moves_m[h, 1] ** 2)
            tour = _tour_from_bounded(t, qx, qy, h, pts, kept, scratch.stops, scratch.bound, m, move_m,
                                      scratch.moves, scratch.stop_corners)  # fmt: skip
        if math.isnan(tour):
            return -1
        cost[h] = w.step_m + tour
    return 1


@njit(cache=True)
def _rests_after_serving(s: FleetState, e: int, a: int, pts: np.ndarray, t: TableArrays, out: np.ndarray) -> int:
    """Taxi a's tour rests in the (served) state into ``out``, as :func:`uamfleet.observe.stops.stop_features` keeps
    them: exact, else the nearest-stop order's. 1, or 0 when a table row is missing."""
    memo = s.stop_pair_m[e]
    found = _shortest_rests(s, e, a, memo, pts, t, out)
    if found == -1:
        found = 1 if _nearest_rests(s, e, a, memo, pts, t, out) else 0
    return found


@njit(cache=True, inline="always")
def _matching_set(undo: np.ndarray, served_undo: np.ndarray, num_sets: int) -> int:
    """The index of the served set recorded as ``undo`` among the first ``num_sets``, or -1."""
    for k in range(num_sets):
        same = True
        for p in range(undo.size):
            if served_undo[k, p] != undo[p]:
                same = False
                break
        if same:
            return k
    return -1


@njit(cache=True, inline="always")
def _longest_move(moves_m: np.ndarray) -> float:
    longest = 0.0
    for h in range(NUM_HEADINGS):
        longest = max(longest, math.sqrt(moves_m[h, 0] ** 2 + moves_m[h, 1] ** 2))
    return longest


@njit(cache=True, inline="always")
def _stop_within(rows: StopRows, a: int, x: float, y: float, pts: np.ndarray, reach: float) -> bool:
    """Whether a stop :func:`_serve_at` could serve (a's riders' destinations, the waiting origins) lies within
    ``reach`` of (x, y)."""
    for p in range(rows.statuses.size):
        if not rows.exists[p]:
            continue
        if rows.statuses[p] == ON_BOARD and rows.carriers[p] == a:
            point = 2 * p + 1
        elif rows.statuses[p] == WAITING:
            point = 2 * p
        else:
            continue
        if math.hypot(x - pts[point, 0], y - pts[point, 1]) <= reach:
            return True
    return False


@njit(cache=True, inline="always")
def _offered_by_bound(
    rows: StopRows, a: int, x: float, y: float, pts: np.ndarray, rests: np.ndarray, stops: np.ndarray, bound: np.ndarray
) -> int:
    """The stops taxi a's rows offer (:func:`uamfleet.sim.world.row_stop`) into ``stops``, sorted by ``bound``:
    the straight line from (x, y) plus the stop's tour rest (insertion sort: a few dozen stops at most). Their
    number."""
    m = 0
    for p in range(rows.statuses.size):
        point = _offered(rows, a, p)
        if point < 0:
            continue
        value = math.hypot(x - pts[point, 0], y - pts[point, 1]) + rests[point]
        k = m
        while k > 0 and bound[k - 1] > value:
            stops[k], bound[k] = stops[k - 1], bound[k - 1]
            k -= 1
        stops[k], bound[k] = point, value
        m += 1
    return m


@njit(cache=True, inline="always")
def _tour_from_bounded(
    t: TableArrays, qx: float, qy: float, h: int, pts: np.ndarray, rests: np.ndarray, stops: np.ndarray,
    bound: np.ndarray, m: int, move_m: float, moves: Corners, stop_corners: Corners,
) -> float:  # fmt: skip
    """:func:`_tour_from` from (qx, qy), the end of move h (``move_m`` long), over the offered stops
    (:func:`_offered_by_bound`; look-ups prepared in ``moves`` and ``stop_corners``), with the same result: a stop
    is looked up only when its straight line from (qx, qy) plus its rest is below the best so far (the table
    distance is at least that straight line, in the same float operations,
    :func:`uamfleet.paths.distance_table.table_distance`), and the scan stops where the taxi's bound less the move
    exceeds the best (triangle inequality: so does every later stop's)."""
    if m == 0:
        return 0.0
    best = math.inf
    for k in range(m):
        if bound[k] - move_m - SURE_M > best:
            break
        point = stops[k]
        gx, gy = pts[point, 0], pts[point, 1]
        dx, dy = qx - gx, qy - gy
        rest = rests[point]
        if math.sqrt(dx * dx + dy * dy) + rest >= best:
            continue
        d = corner_distance(t, moves, h, stop_corners, k, qx, qy, gx, gy)
        if math.isnan(d):
            return math.nan
        best = min(best, d + rest)
    return best


@njit(cache=True, inline="always")
def _has_stop(rows: StopRows, a: int) -> bool:
    """Whether any row offers taxi a a stop (:func:`uamfleet.sim.world.row_stop`)."""
    for p in range(rows.statuses.size):
        if _offered(rows, a, p) >= 0:
            return True
    return False


@njit(cache=True, inline="always")
def _offered(rows: StopRows, a: int, p: int) -> int:
    """The stop row p offers taxi a (:func:`uamfleet.sim.world.row_stop`), -1 for none or an absent row."""
    return stop_of(rows.statuses[p], rows.carriers[p], rows.free_seats[a], a, p) if rows.exists[p] else -1


@njit(cache=True, inline="always")
def _tour_from(
    rows: StopRows, a: int, qx: float, qy: float, pts: np.ndarray, rests: np.ndarray, t: TableArrays
) -> float:
    """The shortest tour from (qx, qy) through taxi a's stops: the least table distance to a stop a row offers plus
    the tour's rest after it (``rests``); 0 when no stop is left; NaN when a table row is missing."""
    best, any_stop = math.inf, False
    for p in range(rows.statuses.size):
        point = _offered(rows, a, p)
        if point < 0:
            continue
        any_stop = True
        d = table_distance(t, qx, qy, pts[point, 0], pts[point, 1])
        if math.isnan(d):
            return math.nan
        best = min(best, d + rests[point])
    return best if any_stop else 0.0


@njit(cache=True, inline="always")
def _serve_at(rows: StopRows, a: int, pts: np.ndarray, qx: float, qy: float, reach: float, undo: np.ndarray) -> bool:
    """Serve taxi a's stops within ``reach`` of (qx, qy) in the state, as the step's drop-offs and pick-ups would
    (without other taxis); ``undo`` [P] records each row's change for :func:`_unserve` (0 none, 1 dropped off,
    2 picked up). Returns whether anything was served."""
    served = False
    for p in range(rows.statuses.size):
        undo[p] = 0
        if rows.exists[p] and rows.statuses[p] == ON_BOARD and rows.carriers[p] == a:
            if math.hypot(qx - pts[2 * p + 1, 0], qy - pts[2 * p + 1, 1]) <= reach:
                rows.statuses[p] = DELIVERED
                rows.free_seats[a] += 1
                undo[p], served = 1, True
    for p in range(rows.statuses.size):
        if rows.free_seats[a] == 0:
            break
        if rows.exists[p] and rows.statuses[p] == WAITING:
            if math.hypot(qx - pts[2 * p, 0], qy - pts[2 * p, 1]) <= reach:
                rows.statuses[p] = ON_BOARD
                rows.free_seats[a] -= 1
                undo[p], served = 2 + rows.carriers[p] + 1, True  # 2 + (old carrier + 1): restored by _unserve
                rows.carriers[p] = a
    return served


@njit(cache=True, inline="always")
def _unserve(rows: StopRows, a: int, undo: np.ndarray) -> None:
    """Undo :func:`_serve_at`."""
    for p in range(rows.statuses.size):
        if undo[p] == 1:
            rows.statuses[p] = ON_BOARD
            rows.free_seats[a] -= 1
        elif undo[p] >= 2:
            rows.statuses[p] = WAITING
            rows.free_seats[a] += 1
            rows.carriers[p] = undo[p] - 3


class LookaheadComponent:
    """``heading_lookahead`` at ``depth`` 1 or 2; reads the rows the stop features prepared
    (:class:`uamfleet.observe.stops.StopsComponent`)."""

    def __init__(self, world: World, table: DistanceTable, depth: int) -> None:
        self.world, self.table, self.depth = world, table, depth

    def prepare(self, state: FleetState) -> None:
        """Nothing: the stop features' rows are the ones it reads."""

    def write(self, state: FleetState, obs: dict[str, np.ndarray]) -> None:
        if not heading_lookahead(state, self.world.arrays, self.table.arrays, obs["heading_lookahead"], self.depth):
            raise MissingTableRow("heading_lookahead")


__all__ = ["LookaheadComponent", "heading_lookahead"]
