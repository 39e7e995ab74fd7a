"""Compiled (numba) loops over [env, taxi, passenger]: the only implementation of the motion, boarding and
observation rules (``docs/rules.md``): the observation kernels here, the motion kernels (the step, the action mask,
the separation shield) in :mod:`uamfleet.sim.motion`, re-exported here. :mod:`uamfleet.sim.dynamics` and
:mod:`uamfleet.env.observer` are their documented entry points; nothing else re-implements them.

The boundary is typed: a kernel takes the state whole (:class:`uamfleet.types.FleetState`), the world's arrays
whole (:class:`uamfleet.sim.arrays.WorldArrays`) and returns the step's events as one
:class:`uamfleet.types.StepEvents`. All are NamedTuples of arrays, which numba compiles field by field.

Why compiled: a step is a few dozen small operations per taxi. As numpy calls each costs microseconds of
overhead, which capped a one-env step at ~1.7k steps/s; as one loop it is memory-bound and fast for any
batch size. ``cache=True`` stores the machine code next to this file, so only the first run compiles.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
from numba import njit

from uamfleet.env.tours import (
    MAX_EXACT_STOPS,
    _nearest_stop_tour,
    _pending_key,
    _shortest_rests,
    _stop_distance,
    _stop_distances,
)
from uamfleet.paths.distance_table import (
    Corners,
    TableArrays,
    corner_distance,
    new_corners,
    prepare_corners,
)
from uamfleet.sim.arrays import RULE_ENDPOINT_BLOCK, RULE_SEGMENT_RASTER, WorldArrays
from uamfleet.sim.motion import action_mask, block_of, separation, shield_headings, step
from uamfleet.sim.world import stop_of
from uamfleet.types import (
    DELIVERED,
    HIDDEN,
    HIST_DX,
    HIST_DY,
    HIST_FREE_SEATS,
    NUM_HEADINGS,
    NUM_PASSENGER_FEATURES,
    ON_BOARD,
    OTHER_DX,
    OTHER_DY,
    OTHER_FREE_SEATS,
    PAX_AGE,
    PAX_DELIVERED,
    PAX_DEST_DX,
    PAX_DEST_DY,
    PAX_DIST_TO_DEST,
    PAX_DIST_TO_ORIGIN,
    PAX_ON_BOARD_OTHER,
    PAX_ON_BOARD_SELF,
    PAX_ORIGIN_DX,
    PAX_ORIGIN_DY,
    PAX_TRIP_LENGTH,
    PAX_WAITING,
    SELF_FREE_SEATS,
    SELF_TIME,
    SELF_X,
    SELF_Y,
    STOP_CLAIMED_BY_ME,
    STOP_CLAIMED_BY_OTHER,
    STOP_PATH_CLIP,
    STOP_PATH_TO_STOP,
    STOP_RIDE_PATH,
    STOP_RIVAL_PATH,
    STOP_RIVALS_NEARER,
    STOP_TOUR_VIA_STOP,
    WAITING,
    FleetState,
)


@njit(cache=True)
def observe(
    s: FleetState,
    w: WorldArrays,
    # outputs, [E, A, ...] (the fields of the observation dict)
    o_self: np.ndarray,  # [E, A, len(SELF_FEATURES)]
    o_history: np.ndarray,  # [E, A, H, len(HISTORY_FEATURES)]
    o_pax: np.ndarray,  # [E, A, P, NUM_PASSENGER_FEATURES]
    o_pax_mask: np.ndarray,  # [E, A, P] int8
    o_sinr: np.ndarray,  # [E, A, k, k]
    o_visit: np.ndarray,  # [E, A, k, k]
    o_others: np.ndarray,  # [E, A, max(A-1, 1), len(OTHER_FEATURES)]
    o_others_mask: np.ndarray,  # [E, A, max(A-1, 1)] int8
    o_mask: np.ndarray,  # [E, A, NUM_HEADINGS] int8
) -> None:
    """The observation of every taxi (docs/rules.md "Observation"), written into the ``o_*`` arrays (C-contiguous:
    the patches are written through flat views of them). Each part is one pass over all envs and taxis: a call
    per taxi would pass (and reference-count) every array of the state each time, ten times the work."""
    _observe_own(s, w, o_self, o_history, o_mask)
    _observe_passengers(s, w, o_pax, o_pax_mask)
    _observe_others(s, w, o_others, o_others_mask)
    _patches(s, w, o_sinr, o_visit)


@njit(cache=True)
def _observe_own(s: FleetState, w: WorldArrays, o_self: np.ndarray, o_history: np.ndarray, o_mask: np.ndarray) -> None:
    """Each taxi's ``self`` row, its ``history`` (positions relative to where it is now) and allowed headings."""
    side_m, seats = w.side_m, w.seats
    for e in range(s.history_m.shape[0]):
        for a in range(s.history_m.shape[1]):
            x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
            o_self[e, a, SELF_X] = x / side_m
            o_self[e, a, SELF_Y] = y / side_m
            o_self[e, a, SELF_FREE_SEATS] = s.free_seats[e, a] / seats
            o_self[e, a, SELF_TIME] = min(s.t[e] / w.time_limit_steps, 1.0)
            for h in range(s.history_m.shape[2]):
                o_history[e, a, h, HIST_DX] = (s.history_m[e, a, h, 0] - x) / side_m
                o_history[e, a, h, HIST_DY] = (s.history_m[e, a, h, 1] - y) / side_m
                o_history[e, a, h, HIST_FREE_SEATS] = s.history_seats[e, a, h] / seats
            for h in range(NUM_HEADINGS):
                o_mask[e, a, h] = 1 if s.action_mask[e, a, h] else 0


@njit(cache=True)
def _observe_passengers(s: FleetState, w: WorldArrays, o_pax: np.ndarray, o_pax_mask: np.ndarray) -> None:
    """Each passenger row as each taxi sees it (zeros and mask 0 while hidden or absent)."""
    side_m, time_limit = w.side_m, w.time_limit_steps
    for e in range(s.pos_m.shape[0]):
        t = s.t[e]
        for a in range(s.pos_m.shape[1]):
            x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
            for p in range(s.pax_status.shape[1]):
                row = o_pax[e, a, p]
                status = s.pax_status[e, p]
                if status == HIDDEN or not s.pax_exists[e, p]:
                    o_pax_mask[e, a, p] = 0
                    for f in range(NUM_PASSENGER_FEATURES):
                        row[f] = 0.0
                    continue
                o_pax_mask[e, a, p] = 1
                odx, ody = (s.pax_origin_m[e, p, 0] - x) / side_m, (s.pax_origin_m[e, p, 1] - y) / side_m
                ddx, ddy = (s.pax_dest_m[e, p, 0] - x) / side_m, (s.pax_dest_m[e, p, 1] - y) / side_m
                tdx, tdy = ddx - odx, ddy - ody
                mine = s.pax_taxi[e, p] == a
                row[PAX_ORIGIN_DX] = odx
                row[PAX_ORIGIN_DY] = ody
                row[PAX_DEST_DX] = ddx
                row[PAX_DEST_DY] = ddy
                row[PAX_DIST_TO_ORIGIN] = math.sqrt(odx * odx + ody * ody)
                row[PAX_DIST_TO_DEST] = math.sqrt(ddx * ddx + ddy * ddy)
                row[PAX_TRIP_LENGTH] = math.sqrt(tdx * tdx + tdy * tdy)
                row[PAX_WAITING] = 1.0 if status == WAITING else 0.0
                row[PAX_ON_BOARD_SELF] = 1.0 if status == ON_BOARD and mine else 0.0
                row[PAX_ON_BOARD_OTHER] = 1.0 if status == ON_BOARD and not mine else 0.0
                row[PAX_DELIVERED] = 1.0 if status == DELIVERED else 0.0
                row[PAX_AGE] = min(max((t - s.pax_release[e, p]) / time_limit, 0.0), 1.0)


@njit(cache=True)
def _observe_others(s: FleetState, w: WorldArrays, o_others: np.ndarray, o_others_mask: np.ndarray) -> None:
    """The other taxis as each taxi sees them, in taxi order; the rows past them zero and masked."""
    num_taxis = s.pos_m.shape[1]
    for e in range(s.pos_m.shape[0]):
        for a in range(num_taxis):
            x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
            n = 0
            for b in range(num_taxis):
                if b == a:
                    continue
                o_others[e, a, n, OTHER_DX] = (s.pos_m[e, b, 0] - x) / w.side_m
                o_others[e, a, n, OTHER_DY] = (s.pos_m[e, b, 1] - y) / w.side_m
                o_others[e, a, n, OTHER_FREE_SEATS] = s.free_seats[e, b] / w.seats
                o_others_mask[e, a, n] = 1
                n += 1
            for m in range(n, o_others.shape[2]):
                for f in range(o_others.shape[3]):
                    o_others[e, a, m, f] = 0.0
                o_others_mask[e, a, m] = 0


@njit(cache=True)
def _patches(s: FleetState, w: WorldArrays, o_sinr: np.ndarray, o_visit: np.ndarray) -> None:
    """The k x k SINR and visit-ratio patches around each taxi's block ([E, A, k, k] each).

    Patch rows bx .. bx + k - 1 of the padded arrays are blocks bx - patch_lo .. bx + k - patch_lo - 1. Written
    with unsigned flat indices: numba then checks no negative index, and the copy runs 2x faster than with
    [e, a, i, j] indexing. ``visits / steps`` is computed in float32: both are integers below 2**24
    (``EnvConfig.time_limit_steps`` is), so it equals the float64 quotient rounded to float32 (double rounding
    is innocuous for division when 53 >= 2 * 24 + 2; Figueroa 1995).
    """
    num_envs, num_taxis = s.pos_m.shape[0], s.pos_m.shape[1]
    k = np.uint64(o_sinr.shape[2])
    src = w.sinr_patch_source
    nbx, nby = src.shape[0] - o_sinr.shape[2], src.shape[1] - o_sinr.shape[2]
    src_ny = np.uint64(src.shape[1])
    cells = np.uint64(s.visits.shape[2] * s.visits.shape[3])  # padded blocks per taxi
    src_flat, visits_flat = src.ravel(), s.visits.ravel()
    sinr_flat, visit_flat = o_sinr.ravel(), o_visit.ravel()
    one = np.float32(1.0)
    for e in range(num_envs):
        steps = np.float32(max(s.t[e], 1))
        for a in range(num_taxis):
            n = np.uint64(e * num_taxis + a)
            bx = np.uint64(block_of(s.pos_m[e, a, 0], w.block_m, nbx))
            by = np.uint64(block_of(s.pos_m[e, a, 1], w.block_m, nby))
            for i in range(k):
                cell = (bx + i) * src_ny + by  # first cell of patch row i in the padded [nbx + k, nby + k] grid
                out = (n * k + i) * k
                for j in range(k):
                    sinr_flat[out + j] = src_flat[cell + j]
                for j in range(k):
                    visit_flat[out + j] = min(np.float32(visits_flat[n * cells + cell + j]) / steps, one)


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
def stop_features(
    s: FleetState,
    w: WorldArrays,
    t: TableArrays,  # DistanceTable.arrays
    o_paths: np.ndarray,  # [E, A, P, len(STOP_PATH_FEATURES)] float32 out
    o_heading: np.ndarray,  # [E, A, P, NUM_HEADINGS] int8 out
) -> bool:
    """Each taxi's feasible-path view of its stops (docs/rules.md "Observation", ``stop_features``).

    Row p of taxi a is *actionable* when p waits and a has a free seat (stop: p's origin) or p rides in a
    (stop: p's destination). ``o_paths[..., STOP_PATH_TO_STOP]``: the feasible-path distance from the taxi to that
    stop; ``[..., STOP_RIDE_PATH]``: from p's origin to p's destination (the ride still to fly once p is aboard);
    ``[..., STOP_TOUR_VIA_STOP]``: the shortest whole tour through every stop the taxi knows of when that stop is flown
    to first (:func:`_shortest_rests`, exact up to :data:`MAX_EXACT_STOPS` pending stops; beyond, the
    nearest-stop order after it, :func:`_nearest_stop_tour`; both kept per taxi until its stops or seats change,
    :func:`_update_rests`); all in map sides, clipped to
    :data:`STOP_PATH_CLIP`. ``o_heading``: one-hot, the allowed heading that makes most
    progress along the feasible path to the stop (the move plus the distance left after it; a move ending
    within the pick-up radius costs the move only); all zero for a row that is not actionable. Distances are
    the table's (:func:`uamfleet.paths.distance_table.table_distance`). Returns False, leaving the outputs
    incomplete, when a table row is not computed yet (the caller fills the rows and calls again).
    """
    num_envs, num_taxis = s.free_seats.shape
    num_pax = s.pax_status.shape[1]
    pts = np.empty((2 * num_pax, 2))
    taxi, stop = new_corners(NUM_HEADINGS + 1), new_corners(1)  # look-up scratch (:func:`_stop_rows`)
    moves = MoveGeometry(w.moves_m, w.step_m, w.radius_m)
    bounds = np.empty(NUM_HEADINGS)  # scratch of the progress headings
    for e in range(num_envs):
        memo = s.stop_pair_m[e]  # [2P, 2P] kept across steps: the stops never move within an episode
        for p in range(num_pax):
            pts[2 * p] = s.pax_origin_m[e, p]
            pts[2 * p + 1] = s.pax_dest_m[e, p]
        for a in range(num_taxis):
            key = _pending_key(s.pax_exists, s.pax_status, s.pax_taxi, s.free_seats, e, a)
            if s.stop_tour_key[e, a] != key and _update_rests(s, e, a, memo, pts, t) < 0:  # kept while valid
                return False
            rows = StopRows(s.pax_exists[e], s.pax_status[e], s.pax_taxi[e], s.free_seats[e], s.stop_tour_m[e, a])
            allowed = s.action_mask[e, a]
            if not _stop_rows(rows, moves, w.side_m, a, s.pos_m[e, a], allowed, memo, pts, t, o_paths[e, a],
                              o_heading[e, a], taxi, stop, bounds):  # fmt: skip
                return False
    return True


@njit(cache=True, inline="always")
def _stop_rows(
    rows: StopRows, moves: MoveGeometry, side: float, a: int, pos: np.ndarray, allowed: np.ndarray, memo: np.ndarray,
    pts: np.ndarray, t: TableArrays, o_paths: np.ndarray, o_heading: np.ndarray, taxi: Corners, stop: Corners,
    bounds: np.ndarray,
) -> bool:  # fmt: skip
    """Taxi a's stop-feature rows (``o_paths`` [P, ...], ``o_heading`` [P, 16]: zeros for a passenger hidden,
    absent or delivered; only the ride for a row that is not actionable); False when a table row it reads is not
    computed yet. One call per taxi, not per row, and with the arrays it reads rather than the state: a call that
    passes the state reference-counts each of its ~30 arrays. ``taxi`` and ``stop`` are scratch for the look-ups
    (:func:`prepare_moves`): the taxi's position and move ends, and the row's stop, are each prepared once;
    ``bounds`` for the progress heading's (:func:`_progress_heading_prepared`)."""
    x, y = pos[0], pos[1]
    prepared = False
    for p in range(rows.statuses.size):
        o_heading[p, :] = 0
        o_paths[p, STOP_PATH_TO_STOP] = 0.0
        o_paths[p, STOP_RIDE_PATH] = 0.0
        o_paths[p, STOP_TOUR_VIA_STOP] = 0.0
        status = rows.statuses[p]
        if not rows.exists[p] or status == HIDDEN or status == DELIVERED:
            continue
        trip = memo[2 * p, 2 * p + 1]  # kept per episode: read in place, a call costs more than the read
        if math.isnan(trip):
            trip = _stop_distance(memo, pts, 2 * p, 2 * p + 1, t)
            if math.isnan(trip):
                return False
        o_paths[p, STOP_RIDE_PATH] = min(trip / side, STOP_PATH_CLIP)
        point = stop_of(status, rows.carriers[p], rows.free_seats[a], a, p)
        if point < 0:
            continue
        gx, gy = pts[point, 0], pts[point, 1]
        if not prepared:
            prepare_moves(moves.moves_m, t, x, y, taxi)
            prepared = True
        prepare_corners(t, gx, gy, stop, 0)
        here = corner_distance(t, taxi, NUM_HEADINGS, stop, 0, x, y, gx, gy)
        if math.isnan(here):
            return False
        o_paths[p, STOP_PATH_TO_STOP] = min(here / side, STOP_PATH_CLIP)
        rest = rows.tour_rests[point]
        o_paths[p, STOP_TOUR_VIA_STOP] = min((here + rest) / side, STOP_PATH_CLIP)
        best = _progress_heading_prepared(allowed, moves, t, x, y, gx, gy, taxi, stop, 0, bounds)  # rows read above
        if best >= 0:
            o_heading[p, best] = 1
    return True


@njit(cache=True)
def _update_rests(
    s: FleetState, e: int, a: int, memo: np.ndarray, pts: np.ndarray, t: TableArrays,
) -> int:  # fmt: skip
    """Bring taxi a's tour rests (``s.stop_tour_m``) up to date: the exact shortest ones, or beyond
    :data:`MAX_EXACT_STOPS` pending stops the nearest-stop order's (:func:`_nearest_stop_tour`) of every stop
    the taxi's rows offer. Both change only when a stop or seat does, so they are kept in the state under the key
    of what they were computed for. 1: the rests are in the state; -1: a table row is missing."""
    key = _pending_key(s.pax_exists, s.pax_status, s.pax_taxi, s.free_seats, e, a)
    if s.stop_tour_key[e, a] == key:
        return 1
    found = _shortest_rests(s, e, a, memo, pts, t, s.stop_tour_m[e, a])
    if found == 0:
        return -1
    if found == -1 and not _nearest_rests(s, e, a, memo, pts, t, s.stop_tour_m[e, a]):
        s.stop_tour_key[e, a] = -1
        return -1
    s.stop_tour_key[e, a] = key
    return 1


@njit(cache=True)
def _nearest_rests(
    s: FleetState, e: int, a: int, memo: np.ndarray, pts: np.ndarray, t: TableArrays, out: np.ndarray,
) -> bool:  # fmt: skip
    """out[point] = :func:`_nearest_stop_tour` after each stop taxi a's rows offer
    (:func:`uamfleet.sim.world.row_stop`: its riders' destinations, the waiting passengers' origins while a seat is
    free); False when a table row is missing. The distances between the taxi's stops are read from the memo once,
    into a local matrix every tour scans."""
    num_pax = s.pax_status.shape[1]
    stops = np.empty(2 * num_pax, np.int64)
    pending = np.empty(2 * num_pax, np.int8)
    m = 0
    for p in range(num_pax):
        if s.pax_status[e, p] == WAITING and s.pax_exists[e, p]:
            stops[m], pending[m], stops[m + 1], pending[m + 1] = 2 * p, 1, 2 * p + 1, 0
            m += 2
        elif s.pax_status[e, p] == ON_BOARD and s.pax_exists[e, p] and s.pax_taxi[e, p] == a:
            stops[m], pending[m] = 2 * p + 1, 1
            m += 1
    dist = np.empty((m, m))
    if not _stop_distances(memo, pts, stops, m, t, dist):
        return False
    todo = np.empty(m, np.int64)  # scratch of the tours (:func:`_nearest_stop_tour`)
    seats = s.free_seats[e, a]
    for k in range(m):
        if pending[k] and (stops[k] % 2 == 1 or seats > 0):  # an offered stop (row_stop)
            out[stops[k]] = _nearest_stop_tour(dist, stops[:m], pending, k, seats, todo)
    return True


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


@njit(cache=True)
def stop_rivals(
    s: FleetState,
    w: WorldArrays,
    t: TableArrays,  # DistanceTable.arrays
    o_rivals: np.ndarray,  # [E, A, P, len(STOP_RIVAL_FEATURES)] float32 out
    o_claims: np.ndarray,  # [E, A, P, len(STOP_CLAIM_FEATURES)] int8 out, or a 0-size array: no claims
) -> bool:
    """What the other taxis of a fleet offer for each waiting passenger (docs/rules.md "Observation").

    For taxi a and a ``WAITING`` row p: ``o_rivals[..., STOP_RIVAL_PATH]`` is the feasible-path distance from p's
    origin to the nearest *other* taxi with a free seat (map sides, :data:`STOP_PATH_CLIP` when there is none);
    ``[..., STOP_RIVALS_NEARER]`` the share of the other taxis with a free seat that are nearer to it than a (0: a is
    the nearest, or the only one). Zero for rows that are not waiting.

    ``o_claims`` (when not empty): the nearest-first matching of taxis with a free seat to waiting passengers
    (pairs taken in order of feasible-path distance, each taxi and each passenger at most once):
    ``o_claims[e, a, p, STOP_CLAIMED_BY_ME]`` = 1 when p is matched to a, ``[..., STOP_CLAIMED_BY_OTHER]`` = 1
    when p is matched to another taxi.
    Returns False when a table row is missing.
    """
    num_envs, num_taxis = s.free_seats.shape
    num_pax = s.pax_status.shape[1]
    side = w.side_m
    claims = o_claims.shape[0] > 0
    dist = np.empty((num_taxis, num_pax))  # [A, P] taxi -> waiting origin, inf for other rows
    taxis, origin = new_corners(num_taxis), new_corners(1)  # look-ups prepared once per point
    for e in range(num_envs):
        for b in range(num_taxis):
            prepare_corners(t, s.pos_m[e, b, 0], s.pos_m[e, b, 1], taxis, b)
        for p in range(num_pax):
            waiting = s.pax_exists[e, p] and s.pax_status[e, p] == WAITING
            ox, oy = s.pax_origin_m[e, p, 0], s.pax_origin_m[e, p, 1]
            if waiting:
                prepare_corners(t, ox, oy, origin, 0)
            for b in range(num_taxis):
                if not waiting:
                    dist[b, p] = math.inf
                    continue
                d = corner_distance(t, taxis, b, origin, 0, s.pos_m[e, b, 0], s.pos_m[e, b, 1], ox, oy)
                if math.isnan(d):
                    return False
                dist[b, p] = d
            for a in range(num_taxis):
                if not waiting:
                    o_rivals[e, a, p, STOP_RIVAL_PATH] = 0.0
                    o_rivals[e, a, p, STOP_RIVALS_NEARER] = 0.0
                    continue
                nearest, nearer, free_others = math.inf, 0, 0
                for b in range(num_taxis):
                    if b == a or s.free_seats[e, b] <= 0:
                        continue
                    free_others += 1
                    nearest = min(nearest, dist[b, p])
                    if dist[b, p] < dist[a, p]:
                        nearer += 1
                o_rivals[e, a, p, STOP_RIVAL_PATH] = min(nearest / side, STOP_PATH_CLIP)
                o_rivals[e, a, p, STOP_RIVALS_NEARER] = nearer / free_others if free_others > 0 else 0.0
        if claims:
            _nearest_first_claims(dist, s.free_seats[e], o_claims[e])
    return True


@njit(cache=True)
def hover_headings(s: FleetState, w: WorldArrays, out: np.ndarray) -> None:
    """out[e, a] (int8 [E, A, 16], one-hot): the allowed heading whose endpoint is nearest the taxi's position one
    step ago, so that two such moves in a row hover about a point (as the fleet dispatchers' idle taxis do); the
    lowest allowed heading at the first step, all zero when no move is allowed."""
    num_envs, num_taxis = s.free_seats.shape
    out[:] = 0
    for e in range(num_envs):
        for a in range(num_taxis):
            x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
            px, py = s.history_m[e, a, 0, 0], s.history_m[e, a, 0, 1]
            best, best_d = -1, math.inf
            for h in range(NUM_HEADINGS):
                if not s.action_mask[e, a, h]:
                    continue
                d = (x + w.moves_m[h, 0] - px) ** 2 + (y + w.moves_m[h, 1] - py) ** 2
                if d < best_d - 1e-9:
                    best, best_d = h, d
            if best >= 0:
                out[e, a, best] = 1


@njit(cache=True)
def _nearest_first_claims(dist: np.ndarray, free_seats: np.ndarray, out: np.ndarray) -> None:
    """Greedy matching of taxis with a free seat to waiting passengers, nearest pair first (ties: lower taxi,
    then lower row); ``dist`` [A, P] is inf for rows that are not waiting. out [A, P, STOP_CLAIM_FEATURES]."""
    num_taxis, num_pax = dist.shape
    out[:] = 0
    order = np.argsort(dist.ravel(), kind="mergesort")  # stable: ties in (taxi, row) order
    taxi_done = np.zeros(num_taxis, np.bool_)
    pax_done = np.zeros(num_pax, np.bool_)
    for flat in order:
        a, p = flat // num_pax, flat % num_pax
        if math.isinf(dist[a, p]):
            break  # only rows that are not waiting are left
        if taxi_done[a] or pax_done[p] or free_seats[a] <= 0:
            continue
        taxi_done[a] = True
        pax_done[p] = True
        for b in range(num_taxis):
            out[b, p, STOP_CLAIMED_BY_ME if b == a else STOP_CLAIMED_BY_OTHER] = 1


# The motion kernels live in uamfleet.sim.motion, the world's arrays in uamfleet.sim.arrays; both import from here.
__all__ = [
    "MAX_EXACT_STOPS",
    "RULE_ENDPOINT_BLOCK",
    "RULE_SEGMENT_RASTER",
    "WorldArrays",
    "action_mask",
    "hover_headings",
    "observe",
    "separation",
    "shield_headings",
    "step",
    "stop_features",
    "stop_rivals",
]
