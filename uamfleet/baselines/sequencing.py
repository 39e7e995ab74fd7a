"""Exact sequencing of one taxi's pick-ups and drop-offs over a stop distance matrix: CPTSP, PDPCC, the raster
planners' REPLAN and clairvoyant order; exact for the matrix, not for the env's 16-heading moves.

Node indexing: 0 is the taxi's current position; passenger ``i`` (0-based) has origin node ``1 + 2i`` and
destination node ``2 + 2i``. ``dist_m[a, b]`` is the flight distance from node a to node b (any metric, e.g.
:class:`~uamfleet.paths.grid_graph.StopPaths` distances). The taxi flies at ``speed_mps`` and waits at an
origin until the passenger's release (request) time.

Objectives and ties (deterministic): ``"makespan"`` minimises the time of the last stop, then the total ride
time, then the node sequence lexicographically; ``"distance"`` minimises the distance flown, then the
makespan, the ride time and the sequence; ``"ride"`` minimises the total ride time (drop-off − request, summed
over the passengers; what the fleet dispatchers minimise), then the makespan, then the sequence; with a
``wait_weight`` β > 0 it minimises the ride time plus β times the total wait (pick-up − request), a service that
weighs a rider's wait above her time on board. Times and
distances are compared rounded to 1e-6 (s or m), so that mathematically equal totals summed in different orders
tie instead of being split by round-off.

:func:`solve_pdp` is a label-setting dynamic programme over (status of each passenger in {waiting, on board,
delivered}, last node). A state keeps every label (time, ride, distance, sequence) that no other label
dominates; since the taxi may wait, arriving earlier is never worse, which makes the pruning exact for the
lexicographic objectives above. ``tests/baselines/pdp_oracle.py`` enumerates every sequence and is its
independent check. Measured on random instances: N = 6 in ~0.01-0.03 s, N = 8 in ~0.15-0.4 s; the limit is
:data:`MAX_PASSENGERS` = 8 (the state space grows as 3^N·(2N+1)).
"""

from __future__ import annotations

import itertools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from numba import njit

OBJECTIVES: tuple[str, ...] = ("makespan", "distance", "ride")
MAX_PASSENGERS = 8  # 3^8 statuses x 17 last nodes: ~0.2-0.4 s in pure Python; beyond, use an insertion heuristic
PICKUP, DROPOFF = "pickup", "dropoff"
_KEY_DECIMALS = 6
# A label whose accumulated ride time or distance is worse by more than this can never tie after rounding,
# whatever the rest of the sequence: it is dominated regardless of its sequence.
_GAP = 1e-3


@dataclass(frozen=True)
class Plan:
    """A visiting order and its schedule. Times in seconds, distances in metres."""

    stops: tuple[tuple[int, str], ...]  # ((passenger, "pickup" | "dropoff"), ...) in visiting order
    nodes: tuple[int, ...]  # node index of each stop
    arrival_s: tuple[float, ...]  # when each stop is served (pick-ups wait for the release)
    finish_s: float  # time of the last stop (start_s for an empty plan)
    distance_m: float  # flown from node 0 through every stop
    total_ride_s: float  # sum over passengers dropped in this plan of (drop-off time - release)
    total_wait_s: float  # sum over passengers picked up in this plan of (pick-up time - release)


@dataclass(frozen=True)
class _Problem:
    travel_s: list[list[float]]  # [S][S] dist / speed
    dist_m: list[list[float]]  # [S][S]
    release_s: tuple[float, ...]  # [N]
    active: tuple[int, ...]  # passengers still to serve (not done), ascending
    on_board: frozenset[int]
    capacity: int
    start_s: float
    objective: str
    wait_weight: float = 0.0  # "ride" objective only: β of ride + β · wait
    # the same matrices as arrays, for the compiled DP (the lists serve the Python arithmetic of _advance)
    travel_array: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), compare=False, repr=False)
    dist_array: np.ndarray = field(default_factory=lambda: np.zeros((0, 0)), compare=False, repr=False)


def _flag_list(values: Sequence[bool] | None, n: int, what: str) -> list[bool]:
    if values is None:
        return [False] * n
    flags = [bool(v) for v in values]
    if len(flags) != n:
        raise ValueError(f"{what} has {len(flags)} entries but release_s has {n}; pass one flag per passenger")
    return flags


def _problem(
    dist_m: np.ndarray,
    speed_mps: float,
    release_s: Sequence[float],
    capacity: int,
    on_board: Sequence[bool] | None,
    done: Sequence[bool] | None,
    start_s: float,
    objective: str,
    wait_weight: float = 0.0,
) -> _Problem:
    release = tuple(float(r) for r in release_s)
    n = len(release)
    dist = _check_distances(dist_m, n)
    speed, start = _check_times(speed_mps, release, capacity, objective, start_s)
    beta = _check_wait_weight(wait_weight, objective)
    board, finished = _check_flags(on_board, done, n, capacity)
    travel = dist / speed
    return _Problem(
        travel_s=travel.tolist(),
        dist_m=dist.tolist(),
        release_s=release,
        active=tuple(i for i in range(n) if not finished[i]),
        on_board=frozenset(i for i in range(n) if board[i]),
        capacity=int(capacity),
        start_s=start,
        objective=objective,
        wait_weight=beta,
        travel_array=travel,
        dist_array=np.ascontiguousarray(dist),
    )


def _check_times(
    speed_mps: float, release: tuple[float, ...], capacity: int, objective: str, start_s: float
) -> tuple[float, float]:
    """The speed, release times, seats, objective and start time checked in that order: (speed, start time)."""
    speed = float(speed_mps)
    if not (math.isfinite(speed) and speed > 0):
        raise ValueError(f"speed_mps must be a finite number > 0, got {speed_mps!r}")
    if not all(math.isfinite(r) for r in release):
        raise ValueError(f"release_s must be finite times in seconds, got {list(release)}")
    if int(capacity) != capacity or capacity < 1:
        raise ValueError(f"capacity must be an integer >= 1 (seats), got {capacity!r}")
    if objective not in OBJECTIVES:
        raise ValueError(f"unknown objective {objective!r}; choose one of {', '.join(map(repr, OBJECTIVES))}")
    start = float(start_s)
    if not math.isfinite(start):
        raise ValueError(f"start_s must be a finite time in seconds, got {start_s!r}")
    return speed, start


def _check_wait_weight(wait_weight: float, objective: str) -> float:
    """β of the "ride" objective as a float: finite, >= 0, and 0 under any other objective."""
    beta = float(wait_weight)
    if not (math.isfinite(beta) and beta >= 0):
        raise ValueError(
            f"wait_weight must be a finite number >= 0 (seconds of ride per second of wait), got {wait_weight!r}"
        )
    if beta and objective != "ride":
        raise ValueError(
            f"wait_weight={wait_weight} weighs waits in the 'ride' objective; objective={objective!r} has none: "
            "pass objective='ride' or wait_weight=0"
        )
    return beta


def _check_distances(dist_m: np.ndarray, n: int) -> np.ndarray:
    """The [1 + 2N, 1 + 2N] matrix of finite, non-negative distances (node 0 the taxi, then origin and
    destination of each passenger), as float64."""
    dist = np.asarray(dist_m, dtype=np.float64)
    if dist.ndim != 2 or dist.shape[0] != dist.shape[1]:
        raise ValueError(f"dist_m must be a square [S, S] matrix, got shape {dist.shape}")
    if dist.shape[0] != 1 + 2 * n:
        raise ValueError(
            f"dist_m has {dist.shape[0]} nodes but {n} passengers need 1 + 2N = {1 + 2 * n} "
            "(node 0 = taxi, 1 + 2i = origin i, 2 + 2i = destination i)"
        )
    if not np.isfinite(dist).all():
        raise ValueError("dist_m has non-finite entries; every pair of stops needs a finite flight distance")
    if (dist < 0).any():
        a, b = np.argwhere(dist < 0)[0]
        raise ValueError(f"dist_m[{a}, {b}] = {dist[a, b]} is negative; distances must be >= 0 metres")
    return dist


def _check_flags(
    on_board: Sequence[bool] | None, done: Sequence[bool] | None, n: int, capacity: int
) -> tuple[list[bool], list[bool]]:
    """(on board, done) per passenger: never both, and no more on board than seats."""
    board = _flag_list(on_board, n, "on_board")
    finished = _flag_list(done, n, "done")
    both = [i for i in range(n) if board[i] and finished[i]]
    if both:
        raise ValueError(f"passenger {both[0]} is marked both on_board and done; a passenger is one or the other")
    if sum(board) > capacity:
        raise ValueError(f"{sum(board)} passengers are on board but capacity is {capacity}; raise capacity")
    return board, finished


def _node(passenger: int, kind: str) -> int:
    return 1 + 2 * passenger + (kind == DROPOFF)


def _stop(node: int) -> tuple[int, str]:
    return ((node - 1) // 2, PICKUP if node % 2 == 1 else DROPOFF)


# -- one schedule arithmetic: solve_in_order and the test oracle add as the DP (its compiled twin _advanced) --
def _advance(pb: _Problem, t: float, ride: float, dist: float, last: int, node: int) -> tuple[float, float, float]:
    """Fly from ``last`` to ``node``: the new time, ride cost (ride time, plus the weighted wait with a
    ``wait_weight``) and distance."""
    t = t + pb.travel_s[last][node]
    passenger = (node - 1) // 2
    if node % 2 == 1:
        t = max(t, pb.release_s[passenger])
        if pb.wait_weight:
            ride = ride + pb.wait_weight * (t - pb.release_s[passenger])
    else:
        ride = ride + (t - pb.release_s[passenger])
    return t, ride, dist + pb.dist_m[last][node]


def _key(pb: _Problem, t: float, ride: float, dist: float, nodes: tuple[int, ...]) -> tuple[object, ...]:
    r = _KEY_DECIMALS
    if pb.objective == "makespan":
        return (round(t, r), round(ride, r), nodes)
    if pb.objective == "ride":
        return (round(ride, r), round(t, r), nodes)
    return (round(dist, r), round(t, r), round(ride, r), nodes)


def _plan(pb: _Problem, nodes: Sequence[int]) -> Plan:
    t, ride, dist, wait, last = pb.start_s, 0.0, 0.0, 0.0, 0
    arrival = []
    for node in nodes:
        t, _, dist = _advance(pb, t, 0.0, dist, last, node)
        passenger = (node - 1) // 2
        if node % 2 == 1:
            wait += t - pb.release_s[passenger]
        else:  # the ride time alone, added as _advance adds it (the same sum when wait_weight is 0)
            ride = ride + (t - pb.release_s[passenger])
        arrival.append(t)
        last = node
    return Plan(
        stops=tuple(_stop(v) for v in nodes),
        nodes=tuple(nodes),
        arrival_s=tuple(arrival),
        finish_s=t,
        distance_m=dist,
        total_ride_s=ride,
        total_wait_s=wait,
    )


# -- exact DP -----------------------------------------------------------------------------------------------
def _dp(pb: _Problem, serve: tuple[int, ...] | None = None) -> tuple[int, ...]:
    """The best node sequence: the labels of every final (status, last stop) from :func:`_dp_labels` (compiled),
    the least by :func:`_key` (in Python: its rounding is Python's). ``serve``: the passengers to serve, if not
    ``pb.active`` (the others left out as if done)."""
    serve = pb.active if serve is None else serve
    active = np.array(serve, dtype=np.int64)
    board = np.array([i in pb.on_board for i in serve], dtype=np.bool_)
    t, ride, dist, seq = _dp_labels(
        pb.travel_array, pb.dist_array, np.array(pb.release_s), active, board, pb.capacity,
        pb.start_s, OBJECTIVES.index(pb.objective), pb.wait_weight, _GAP,
    )  # fmt: skip
    finals = zip(t.tolist(), ride.tolist(), dist.tolist(), map(tuple, seq.tolist()), strict=True)
    best = min(finals, key=lambda lab: _key(pb, *lab))
    return best[3]


@njit(cache=True)
def _dp_labels(
    travel: np.ndarray, dist_m: np.ndarray, release: np.ndarray, active: np.ndarray, board: np.ndarray,
    capacity: int, start_s: float, objective: int, beta: float, gap: float, bucket_room: int = 4,
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:  # fmt: skip
    """The exact DP over (passenger statuses, last stop) with labels (time, ride cost, distance, node sequence),
    layer by layer, a label dropped when another of its bucket dominates it (:func:`_label_dominates`), in one fixed
    order (states in first-reached order, moves by passenger, labels in bucket order), on which the surviving
    labels depend. Returns the final layer's labels: time [L], ride [L], distance [L], sequences [L, D].

    Plain arrays throughout (a state's statuses are a row, its bucket a row of label ids): a state is found by its
    (statuses, last stop) code in one table for all layers (a layer's codes differ from every other layer's, their
    digits summing to the stops served), since typed dicts and lists cost more than the DP itself on the 1–4
    passenger problems a dispatcher solves by the hundred per batch. ``bucket_room``: the labels a bucket's row
    holds before the layer's rows are widened (a test sets 1 to take that path often)."""
    num = len(active)
    status0 = board.astype(np.int64)  # 1: on board, 0: to pick up
    depth = 2 * num - int(status0.sum())  # stops still to serve
    pow3 = 3 ** np.arange(num)
    width = 2 * num + 1  # last stop of a state: 0, or 1 + 2k (pick-up of active passenger k), 2 + 2k (its drop-off)
    where = np.full(3**num * width, -1, np.int64)  # (status code, last stop) -> the state's index in its layer
    # label store (grows): time, ride, distance, sequence
    lt, lr, ld = np.empty(64), np.empty(64), np.empty(64)
    lseq = np.zeros((64, max(depth, 1)), np.int64)
    used = 1
    lt[0], lr[0], ld[0] = start_s, 0.0, 0.0
    # a layer: its states in first-reached order (status rows, last node) and each state's bucket (label ids)
    st_status = status0.reshape(1, num).copy()
    st_last = np.zeros(1, np.int64)
    st_bucket = np.zeros((1, bucket_room), np.int64)  # rows widen when a bucket outgrows them
    st_count = np.ones(1, np.int64)
    for level in range(depth):
        room = len(st_last) * num  # at most one new state per (state, passenger)
        n_status = np.empty((room, num), np.int64)
        n_last = np.empty(room, np.int64)
        n_bucket = np.empty((room, st_bucket.shape[1]), np.int64)
        n_count = np.zeros(room, np.int64)
        states = 0
        for si in range(len(st_last)):
            last = st_last[si]
            free = capacity
            code = 0
            for k in range(num):
                free -= st_status[si, k] == 1
                code += st_status[si, k] * pow3[k]
            for k in range(num):
                node = _next_node(st_status[si, k], free, active[k])
                if node < 0:
                    continue
                key = (code + pow3[k]) * width + 1 + 2 * k + st_status[si, k]  # (the new statuses, this stop)
                b = where[key]
                if b < 0:
                    b = states
                    where[key] = b
                    n_status[b] = st_status[si]
                    n_status[b, k] += 1
                    n_last[b] = node
                    states += 1
                for j in range(st_count[si]):
                    a = st_bucket[si, j]
                    if used == len(lt):  # grow the store
                        lt, lr, ld, lseq = _grown(lt, lr, ld, lseq, used)
                    lt[used], lr[used], ld[used] = _advanced(lt[a], lr[a], ld[a], last, node, travel, dist_m, release,
                                                             beta)  # fmt: skip
                    lseq[used, :level] = lseq[a, :level]
                    lseq[used, level] = node
                    count = _with_label(n_bucket[b], n_count[b], used, lt, lr, ld, lseq, level + 1, objective, gap)
                    if count:  # the new label survived: the bucket now holds ``count`` labels, itself the last
                        if count > n_bucket.shape[1]:  # a full row that dropped none: widen, then append
                            wider = np.empty((room, 2 * n_bucket.shape[1]), np.int64)
                            wider[:, : n_bucket.shape[1]] = n_bucket
                            n_bucket = wider
                            n_bucket[b, count - 1] = used
                        n_count[b] = count
                        used += 1
        st_status, st_last = n_status[:states], n_last[:states]
        st_bucket, st_count = n_bucket[:states], n_count[:states]
    return _final_labels(st_bucket, st_count, lt, lr, ld, lseq, depth)


@njit(cache=True)
def _final_labels(
    bucket: np.ndarray, count: np.ndarray, lt: np.ndarray, lr: np.ndarray, ld: np.ndarray, lseq: np.ndarray, depth: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The labels of the last layer's buckets, in order, as arrays."""
    total = int(count.sum())
    out_t, out_r, out_d = np.empty(total), np.empty(total), np.empty(total)
    out_seq = np.zeros((total, depth), np.int64)
    i = 0
    for s in range(len(count)):
        for j in range(count[s]):
            a = bucket[s, j]
            out_t[i], out_r[i], out_d[i] = lt[a], lr[a], ld[a]
            out_seq[i] = lseq[a, :depth]
            i += 1
    return out_t, out_r, out_d, out_seq


@njit(cache=True)
def _next_node(status: int, free: int, passenger: int) -> int:
    """The node a passenger of this status may be served at next (pick-up if waiting and a seat is free, drop-off
    if on board), -1 if none."""
    if status == 0 and free > 0:
        return 1 + 2 * passenger
    if status == 1:
        return 2 + 2 * passenger
    return -1


@njit(cache=True)
def _advanced(
    t: float, ride: float, dist: float, last: int, node: int, travel: np.ndarray, dist_m: np.ndarray,
    release: np.ndarray, beta: float,
) -> tuple[float, float, float]:  # fmt: skip
    """:func:`_advance`, compiled: the same operations in the same order."""
    passenger = (node - 1) // 2
    t = t + travel[last, node]
    if node % 2 == 1:
        if release[passenger] > t:
            t = release[passenger]
        if beta != 0.0:
            ride = ride + beta * (t - release[passenger])
    else:
        ride = ride + (t - release[passenger])
    return t, ride, dist + dist_m[last, node]


@njit(cache=True)
def _grown(
    lt: np.ndarray, lr: np.ndarray, ld: np.ndarray, lseq: np.ndarray, used: int
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """The label store with twice the room."""
    cap = 2 * len(lt)
    lt2, lr2, ld2 = np.empty(cap), np.empty(cap), np.empty(cap)
    lt2[:used], lr2[:used], ld2[:used] = lt[:used], lr[:used], ld[:used]
    seq2 = np.zeros((cap, lseq.shape[1]), np.int64)
    seq2[:used] = lseq[:used]
    return lt2, lr2, ld2, seq2


@njit(cache=True)
def _with_label(
    bucket: np.ndarray, count: int, new: int, lt: np.ndarray, lr: np.ndarray, ld: np.ndarray, lseq: np.ndarray,
    length: int, objective: int, gap: float,
) -> int:  # fmt: skip
    """0 if a label of the bucket's first ``count`` dominates ``new`` (the bucket untouched); else the number of
    labels it holds once those ``new`` dominates are dropped (the survivors kept in their order) and ``new``
    appended; they are written to ``bucket`` in place where it has room for them all."""
    for q in range(count):
        if _label_dominates(bucket[q], new, lt, lr, ld, lseq, length, objective, gap):
            return 0
    kept = 0
    for q in range(count):
        if not _label_dominates(new, bucket[q], lt, lr, ld, lseq, length, objective, gap):
            if kept < len(bucket):
                bucket[kept] = bucket[q]
            kept += 1
    if kept < len(bucket):
        bucket[kept] = new
    return kept + 1


@njit(cache=True)
def _label_dominates(
    a: int, b: int, lt: np.ndarray, lr: np.ndarray, ld: np.ndarray, lseq: np.ndarray, length: int, objective: int,
    gap: float,
) -> bool:  # fmt: skip
    """True if every completion of label ``a`` is at least as good as the same completion of label ``b``
    (objective 1: distance, as ``OBJECTIVES``' index).

    Completions are monotone in time, ride and distance (float addition and max are monotone), so ``a`` no
    worse on all three suffices when its node sequence is smaller (final ties go to it); otherwise a gap in an
    accumulated sum (ride, or distance when it is the objective) that rounding cannot close is needed — a gap in
    time can be closed by waiting for a release."""
    if lt[a] > lt[b] or lr[a] > lr[b]:
        return False
    if objective == 1 and ld[a] > ld[b]:
        return False
    smaller = False
    for i in range(length):
        if lseq[a, i] != lseq[b, i]:
            smaller = lseq[a, i] < lseq[b, i]
            break
    if smaller or lr[b] - lr[a] > gap:
        return True
    return objective == 1 and ld[b] - ld[a] > gap


def solve_pdp(
    dist_m: np.ndarray,
    speed_mps: float,
    release_s: Sequence[float],
    *,
    capacity: int = 2,
    on_board: Sequence[bool] | None = None,
    done: Sequence[bool] | None = None,
    start_s: float = 0.0,
    objective: str = "makespan",
    wait_weight: float = 0.0,
) -> Plan:
    """Optimal pick-up and drop-off order for one taxi (exact DP; see the module docstring).

    ``release_s[i]`` is passenger i's request time (a pick-up waits for it); ``on_board`` passengers need only
    their drop-off, ``done`` passengers are ignored; ``wait_weight`` (``"ride"`` only) adds β · wait to the ride
    time minimised (the plan's ``total_ride_s`` and ``total_wait_s`` stay the plain totals). Raises ValueError for
    malformed input or more than :data:`MAX_PASSENGERS` passengers still to serve.
    """
    pb = _problem(dist_m, speed_mps, release_s, capacity, on_board, done, start_s, objective, wait_weight)
    if len(pb.active) > MAX_PASSENGERS:
        raise ValueError(
            f"solve_pdp is exact and exponential: N = {len(pb.active)} passengers to serve exceeds "
            f"{MAX_PASSENGERS}; use an insertion heuristic for larger instances"
        )
    return _plan(pb, _dp(pb))


def solve_pdp_each(
    dist_m: np.ndarray,
    speed_mps: float,
    release_s: Sequence[float],
    subsets: Sequence[Sequence[int]],
    *,
    capacity: int = 2,
    on_board: Sequence[bool] | None = None,
    start_s: float = 0.0,
    objective: str = "makespan",
    wait_weight: float = 0.0,
) -> list[Plan]:
    """:func:`solve_pdp` of each subset of the passengers as a problem of its own, the input checked once: plan k is
    ``solve_pdp(dist_m[np.ix_(nodes, nodes)], speed_mps, [release_s[i] for i in subsets[k]], ...)`` with node 0 and
    the subset's stops as ``nodes``, so its passenger i is ``subsets[k][i]`` (a dispatcher costs every candidate trip
    of a taxi over one matrix).

    Each subset lists passengers in ascending order and holds every ``on_board`` one; the DP then visits the same
    states, moves and labels as on the subset's own matrix (its node numbers map in order), so the plans are the
    same to the bit."""
    pb = _problem(dist_m, speed_mps, release_s, capacity, on_board, None, start_s, objective, wait_weight)
    n = len(pb.release_s)
    plans = []
    for k, subset in enumerate(subsets):
        members = tuple(int(i) for i in subset)
        if any(b <= a for a, b in itertools.pairwise(members)) or not all(0 <= i < n for i in members):
            raise ValueError(f"subsets[{k}] = {list(subset)} must list passengers of [0, {n - 1}] in ascending order")
        if not pb.on_board <= set(members):
            raise ValueError(
                f"subsets[{k}] = {list(subset)} leaves out passengers on board {sorted(pb.on_board - set(members))}; "
                "a passenger on board must be served in every subset"
            )
        if len(members) > MAX_PASSENGERS:
            raise ValueError(f"subsets[{k}] has {len(members)} passengers, more than solve_pdp's {MAX_PASSENGERS}")
        # the whole matrix with the others left out, as solve_pdp's ``done``: its plan in the whole's numbering
        whole = _plan(pb, _dp(pb, members))
        within = {i: j for j, i in enumerate(members)}
        stops = tuple((within[i], kind) for i, kind in whole.stops)
        nodes = tuple(_node(i, kind) for i, kind in stops)
        plans.append(Plan(stops, nodes, whole.arrival_s, whole.finish_s, whole.distance_m, whole.total_ride_s,
                          whole.total_wait_s))  # fmt: skip
    return plans


def solve_in_order(
    dist_m: np.ndarray,
    speed_mps: float,
    release_s: Sequence[float],
    order: Sequence[tuple[int, str]],
    *,
    start_s: float = 0.0,
    on_board: Sequence[bool] | None = None,
    done: Sequence[bool] | None = None,
    capacity: int = 2,
) -> Plan:
    """Schedule a given stop order (appending late requests, flying the straight-line baseline).

    The order must serve every passenger that is not done exactly once: a pick-up (unless on board) before
    its drop-off, never more than ``capacity`` on board. Raises ValueError naming the offending stop.
    """
    pb = _problem(dist_m, speed_mps, release_s, capacity, on_board, done, start_s, "makespan")
    n = len(pb.release_s)
    riding = set(pb.on_board)
    served: set[tuple[int, str]] = set()
    nodes = []
    for pos, stop in enumerate(order):
        try:
            passenger, kind = int(stop[0]), str(stop[1])
        except (TypeError, ValueError, IndexError):
            raise ValueError(f"order[{pos}] = {stop!r} is not a (passenger, 'pickup' | 'dropoff') pair") from None
        what = f"order[{pos}] = ({passenger}, {kind!r})"
        if kind not in (PICKUP, DROPOFF):
            raise ValueError(f"{what}: kind must be 'pickup' or 'dropoff'")
        if not 0 <= passenger < n:
            raise ValueError(f"{what}: passenger must lie in [0, {n - 1}]")
        if passenger not in pb.active:
            raise ValueError(f"{what}: passenger {passenger} is already done; leave them out of the order")
        if (passenger, kind) in served or (kind == PICKUP and passenger in pb.on_board):
            raise ValueError(f"{what}: this stop was already served; each stop appears once")
        if kind == PICKUP:
            if len(riding) >= pb.capacity:
                raise ValueError(f"{what}: the taxi is full ({pb.capacity} seats); drop someone off first")
            riding.add(passenger)
        else:
            if passenger not in riding:
                raise ValueError(f"{what}: drop-off before pick-up; put ({passenger}, 'pickup') earlier")
            riding.remove(passenger)
        served.add((passenger, kind))
        nodes.append(_node(passenger, kind))
    for i in pb.active:
        if (i, DROPOFF) not in served:
            needs = f"({i}, 'dropoff')" if i in riding else f"({i}, 'pickup') and ({i}, 'dropoff')"
            raise ValueError(f"order never delivers passenger {i}; add {needs}")
    return _plan(pb, nodes)
