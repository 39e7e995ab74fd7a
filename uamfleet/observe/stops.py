"""The stop features (compiled; docs/rules.md "Observation", ``stop_features``): each taxi's feasible-path view of
its stops (:func:`stop_features`: ``stop_paths``, ``stop_heading_mask``) and, in a fleet, what the other taxis
offer for each waiting passenger (:func:`stop_rivals`: ``stop_rivals``, ``stop_claims``). The tours behind
``STOP_TOUR_VIA_STOP`` are :mod:`uamfleet.observe.tours`'s, the moves' geometry :mod:`uamfleet.observe.moves`'s.
:class:`StopsComponent` is what the observer (:class:`uamfleet.observe.observer.Observer`) runs: its ``prepare``
fills the distance-table rows of every existing stop before any kernel reads them, its ``write`` runs the kernels."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from uamfleet.observe.moves import MoveGeometry, StopRows, _progress_heading_prepared, prepare_moves
from uamfleet.observe.tours import _pending_key, _stop_distance, _update_rests
from uamfleet.paths.distance_table import (
    Corners,
    DistanceTable,
    MissingTableRow,
    TableArrays,
    corner_distance,
    new_corners,
    prepare_corners,
)
from uamfleet.sim.arrays import WorldArrays
from uamfleet.sim.pretyped import PreTyped
from uamfleet.sim.world import World, stop_of
from uamfleet.types import (
    DELIVERED,
    HIDDEN,
    NUM_HEADINGS,
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

__all__ = ["StopsComponent", "stop_features", "stop_rivals", "stop_rows_missing"]


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
    to first (:func:`~uamfleet.observe.tours._shortest_rests`, exact up to
    :data:`~uamfleet.observe.tours.MAX_EXACT_STOPS` pending stops; beyond, the nearest-stop order after it,
    :func:`~uamfleet.observe.tours._nearest_stop_tour`; both kept per taxi until its stops or seats change,
    :func:`~uamfleet.observe.tours._update_rests`); all in map sides, clipped to
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


_NO_CLAIMS = np.zeros((0, 0, 0, 0), np.int8)  # 0-size: the rivals kernel writes no claims


@njit(cache=True)
def stop_rows_missing(s: FleetState, t: TableArrays) -> bool:
    """True when a table row that a lookup towards an existing request's origin or destination reads is not
    computed yet (NaN)."""
    corners = new_corners(1)
    for e in range(s.pax_exists.shape[0]):
        for p in range(s.pax_exists.shape[1]):
            if not s.pax_exists[e, p]:
                continue
            for stop in (s.pax_origin_m, s.pax_dest_m):
                prepare_corners(t, stop[e, p, 0], stop[e, p, 1], corners, 0)
                for c in range(corners.used[0]):
                    if math.isnan(t.distance_m[corners.cells[0, c], 0]):
                        return True
    return False


class StopsComponent:
    """``stop_paths`` and ``stop_heading_mask``, with ``rivals`` also ``stop_rivals``, with ``claims`` also
    ``stop_claims``, on the feasible-path distance table of the world."""

    def __init__(self, world: World, table: DistanceTable, rivals: bool) -> None:
        self.world, self.table, self.rivals = world, table, rivals
        self._missing = PreTyped(stop_rows_missing)

    def prepare(self, state: FleetState) -> None:
        """Fill the table rows of the origin and destination of every existing request (a compiled lookup of
        their rows first: nothing more when every row is there)."""
        if self._missing(state, self.table.arrays):
            exists = state.pax_exists
            self.table.ensure(np.concatenate([state.pax_origin_m[exists], state.pax_dest_m[exists]]))

    def write(self, state: FleetState, obs: dict[str, np.ndarray]) -> None:
        arrays, table = self.world.arrays, self.table.arrays
        if not stop_features(state, arrays, table, obs["stop_paths"], obs["stop_heading_mask"]):
            raise MissingTableRow("stop_features")
        if self.rivals:
            claims = obs.get("stop_claims", _NO_CLAIMS)
            if not stop_rivals(state, arrays, table, obs["stop_rivals"], claims):
                raise MissingTableRow("stop_rivals")
