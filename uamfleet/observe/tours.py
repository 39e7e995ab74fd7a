"""The shortest tours behind the stop features (compiled): for a taxi, the length of the rest of the shortest tour
through every stop it knows of after flying to each one first — an exact dynamic programme over subsets of its pending
stops (up to :data:`MAX_EXACT_STOPS`), else the nearest-stop order — and the keys that say when a taxi's kept tours
are still valid (:func:`_update_rests`). :func:`uamfleet.observe.stops.stop_features` and the look-ahead
(:mod:`uamfleet.observe.lookahead`) are their callers (docs/rules.md, "Observation")."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from uamfleet.paths.distance_table import TableArrays, corner_distance, new_corners, prepare_corners, table_distance
from uamfleet.types import DELIVERED, ON_BOARD, WAITING, FleetState


@njit(cache=True)
def _stop_distance(memo: np.ndarray, pts: np.ndarray, i: int, j: int, t: TableArrays) -> float:
    """Table distance from point i to point j of ``pts`` [2P, 2] (origin 2p, destination 2p + 1), memoised."""
    d = memo[i, j]
    if math.isnan(d):
        d = table_distance(t, pts[i, 0], pts[i, 1], pts[j, 0], pts[j, 1])
        memo[i, j] = d
    return d


@njit(cache=True)
def _stop_distances(memo: np.ndarray, pts: np.ndarray, stops: np.ndarray, m: int, t: TableArrays,
                    dist: np.ndarray) -> bool:  # fmt: skip
    """dist[i, j] = :func:`_stop_distance` from stop point ``stops[i]`` to ``stops[j]`` (0 on the diagonal) for the
    first m stops; False when a table row is missing. The pairs not in the memo yet (a new request's, with every
    other stop) are looked up with each point's corners prepared once (:func:`corner_distance`: the same numbers
    as :func:`table_distance`) and kept in the memo."""
    corners = new_corners(m)
    prepared = False
    for i in range(m):
        for j in range(m):
            if i == j:
                dist[i, j] = 0.0
                continue
            d = memo[stops[i], stops[j]]
            if math.isnan(d):
                if not prepared:
                    for k in range(m):
                        prepare_corners(t, pts[stops[k], 0], pts[stops[k], 1], corners, k)
                    prepared = True
                a, b = pts[stops[i]], pts[stops[j]]
                d = corner_distance(t, corners, i, corners, j, a[0], a[1], b[0], b[1])
                memo[stops[i], stops[j]] = d
                if math.isnan(d):
                    return False
            dist[i, j] = d
    return True


MAX_EXACT_STOPS = 12
"""Up to this many stops still to visit, ``tour_via_stop`` is the shortest tour (exact dynamic programme over
subsets); beyond, the nearest-stop order's."""


@njit(cache=True, inline="always")
def _pending_key(
    exists: np.ndarray, statuses: np.ndarray, carriers: np.ndarray, free_seats: np.ndarray, e: int, a: int
) -> int:
    """A number that changes whenever taxi a's tours can change: its stops still to visit (bits over the 2P stop
    points) and its free seats. On a passenger axis too long for a bit per stop (2P > 56), a count of the episode's
    status changes instead (:func:`_progress_key`). Takes the state's arrays (``pax_exists``, ``pax_status``,
    ``pax_taxi``, ``free_seats``), not the state: a call that passes the state reference-counts its ~30 arrays."""
    num_pax = statuses.shape[1]
    if 2 * num_pax > 56:
        return _progress_key(exists, statuses, carriers, free_seats, e, a)
    key = 0
    for p in range(num_pax):
        if not exists[e, p]:
            continue
        if statuses[e, p] == WAITING:
            key |= 3 << (2 * p)
        elif statuses[e, p] == ON_BOARD and carriers[e, p] == a:
            key |= 2 << (2 * p)
    return key | (free_seats[e, a] << (2 * num_pax)) | (1 << 60)


@njit(cache=True, inline="always")
def _progress_key(
    exists: np.ndarray, statuses: np.ndarray, carriers: np.ndarray, free_seats: np.ndarray, e: int, a: int
) -> int:
    """Env e's progress as a key of taxi a's tours, for any passenger axis: within an episode a passenger's status
    only moves forward (HIDDEN 0, WAITING 1, ON_BOARD 2, DELIVERED 3; the carrier is set on the way) and the kept
    key is cleared with the stops (``generator``), so the sum of the statuses takes a new value at every change
    of any passenger's (and with it every change of the taxi's stops or seats). Another taxi's drop-off changes
    nothing of taxi a's tours: it counts as still on board. A status-weighted sum of the row numbers and the free
    seats go in too, so that a state edited by hand still changes its key. Bit 61 keeps it apart from
    :func:`_pending_key`'s keys."""
    total, weighted = 0, 0
    for p in range(statuses.shape[1]):
        if exists[e, p]:
            status = statuses[e, p]
            if status == DELIVERED and carriers[e, p] != a:
                status = ON_BOARD
            total += status
            weighted += (p + 1) * status
    return (total & 0xFFFFF) | ((weighted & 0xFFFFFFFF) << 20) | ((free_seats[e, a] & 0xFF) << 52) | (1 << 61)


@njit(cache=True)
def _shortest_rests(
    s: FleetState, e: int, a: int, memo: np.ndarray, pts: np.ndarray, t: TableArrays, out: np.ndarray,
) -> int:  # fmt: skip
    """out[point] = the shortest rest of taxi a's tour after it reaches stop ``point`` first (2p: p's origin, 2p + 1:
    her destination), through every stop it knows of (its riders' destinations, the waiting passengers' origins
    and destinations), pick-up before drop-off, never more riders than seats: a dynamic programme over the
    subsets of stops still to visit. Returns 1, 0 when a table row is missing, -1 when more than
    :data:`MAX_EXACT_STOPS` stops are pending (``out`` untouched)."""
    ids = np.empty(MAX_EXACT_STOPS, np.int64)  # stop point of each local stop
    origin_of = np.empty(MAX_EXACT_STOPS, np.int64)  # for a waiting passenger's destination: her origin's index
    n = _pending_stops(s, e, a, ids, origin_of)
    if n < 0:
        return -1
    dist = np.empty((n, n))
    if not _stop_distances(memo, pts, ids, n, t, dist):
        return 0
    rest = _subset_rests(dist, ids, origin_of, n, s.free_seats[e, a])
    full = (1 << n) - 1
    for i in range(n):
        out[ids[i]] = rest[full ^ (1 << i), i]
    return 1


@njit(cache=True)
def _pending_stops(s: FleetState, e: int, a: int, ids: np.ndarray, origin_of: np.ndarray) -> int:
    """Taxi a's stops still to visit into ``ids`` (stop points) and ``origin_of`` (for a waiting passenger's
    destination, her origin's index; else -1); their number, or -1 beyond :data:`MAX_EXACT_STOPS`."""
    n = 0
    for p in range(s.pax_status.shape[1]):
        if not s.pax_exists[e, p]:
            continue
        if s.pax_status[e, p] == WAITING:
            if n + 2 > MAX_EXACT_STOPS:
                return -1
            ids[n], origin_of[n], ids[n + 1], origin_of[n + 1] = 2 * p, -1, 2 * p + 1, n
            n += 2
        elif s.pax_status[e, p] == ON_BOARD and s.pax_taxi[e, p] == a:
            if n + 1 > MAX_EXACT_STOPS:
                return -1
            ids[n], origin_of[n] = 2 * p + 1, -1
            n += 1
    return n


@njit(cache=True)
def _subset_rests(dist: np.ndarray, ids: np.ndarray, origin_of: np.ndarray, n: int, seats: int) -> np.ndarray:
    """rest[R, i]: the shortest rest from local stop i with the stops of bit set R still to visit (pick-up before
    drop-off; an origin only with a free seat, ``seats`` being free before any of the n stops).

    Only the sets R a tour can leave are computed: where a waiting passenger's origin is still to visit, so is her
    destination (the recursion from the full set reads no other; the rest stay inf). With k waiting passengers
    that is 3**k of the 4**k sets. Likewise only the stops i that can be visited just before R: not an origin
    whose destination is done, not a destination whose origin is still to visit."""
    rest = np.full((1 << n, n), math.inf)
    origins = 0  # bits of the origins whose destination is pending too (then at the origin's bit + 1)
    after = np.zeros(n, np.int64)  # after[j]: the bit of the origin destination j must wait for (0: none)
    for k in range(n):
        if ids[k] % 2 == 0:
            origins |= 1 << k
        elif origin_of[k] >= 0:
            after[k] = 1 << origin_of[k]
    nexts = np.empty(n, np.int64)  # the stops that may come first from set R ...
    after_next = np.empty(n)  # ... and the rest after each: shared by every stop i before R
    for remaining in range(1 << n):  # R \ {j} < R: every rest needed is computed before it is read
        if ((remaining & origins) << 1) & ~remaining:
            continue  # an origin pending without its destination: no tour gets here
        count = _next_stops(remaining, ids, after, n, seats, nexts)
        for q in range(count):
            j = nexts[q]
            after_next[q] = rest[remaining ^ (1 << j), j]
        for i in range(n):
            if (remaining >> i) & 1:
                continue
            if remaining & after[i] or ((origins >> i) & 1 and not (remaining >> (i + 1)) & 1):
                continue  # i cannot be visited just before R (no tour reads this rest)
            if remaining == 0:
                rest[remaining, i] = 0.0
                continue
            best = math.inf
            for q in range(count):  # the next stops in ascending order, as the sums were always taken
                best = min(best, dist[i, nexts[q]] + after_next[q])
            rest[remaining, i] = best
    return rest


@njit(cache=True, inline="always")
def _next_stops(remaining: int, ids: np.ndarray, after: np.ndarray, n: int, seats: int, out: np.ndarray) -> int:
    """The stops of set R that may come next (:func:`_subset_rests`), ascending, into ``out``; their number: a
    drop-off whose pick-up is done, a pick-up while a seat is free once the stops outside R are visited."""
    free = seats
    for k in range(n):
        if not (remaining >> k) & 1:
            free += 1 if ids[k] % 2 else -1
    count = 0
    for j in range(n):
        if (remaining >> j) & 1 and not remaining & after[j] and (ids[j] % 2 == 1 or free > 0):
            out[count] = j
            count += 1
    return count


@njit(cache=True)
def _nearest_stop_tour(dist: np.ndarray, stops: np.ndarray, pending: np.ndarray, first: int, seats: int,
                       todo: np.ndarray) -> float:  # fmt: skip
    """Length of the rest of a taxi's tour after it reaches local stop ``first``, flown in nearest-stop order
    through every stop it knows of (:func:`_nearest_rests`: ``stops`` [m] its stop points, ascending, a waiting
    passenger's destination right after her origin; ``dist`` [m, m] between them; ``pending`` [m] 1 for the stops
    to visit from the start, 0 for the destinations of passengers not aboard yet; ``seats`` free at the start).
    Pick-up before drop-off, an origin only while a seat is free; ties go to the lowest stop point. ``todo`` [m]
    is scratch: the local stops still to visit, in no order (each leg scans only those, and a visited one is
    swapped out), so a tie is decided by the index, not by the scan's order."""
    m = stops.size
    live = 0
    for i in range(m):
        if pending[i] and i != first:
            todo[live] = i
            live += 1
    if stops[first] % 2 == 0:  # boarding: her destination joins the tour
        todo[live] = first + 1
        live += 1
        seats -= 1
    else:
        seats += 1
    total, here = 0.0, first
    while True:
        best, best_d, slot = -1, math.inf, -1
        for k in range(live):
            i = todo[k]
            if stops[i] % 2 == 0 and seats <= 0:
                continue
            d = dist[here, i]
            if d < best_d or (d == best_d and i < best):
                best, best_d, slot = i, d, k
        if best < 0:
            return total
        total += best_d
        here = best
        live -= 1
        todo[slot] = todo[live]
        if stops[best] % 2 == 0:
            todo[live] = best + 1
            live += 1
            seats -= 1
        else:
            seats += 1


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
