"""The passenger window (``EnvConfig.passenger_window`` = K; docs/rules.md "Passenger window"): which K passenger
rows each taxi observes, so that the observation's passenger axis is K however many requests an episode has.

The rule, per taxi: first the passengers on board this taxi (in request order; at most ``seats`` <= K), then the
``WAITING`` requests (released, not picked up) nearest to the taxi, nearest first: by the feasible-path distance
from the taxi to the request's origin where the config observes stop features (the same distance table and look-up
as ``stop_paths`` and the claims, :func:`uamfleet.paths.distance_table.table_distance`; unreachable origins last),
else by the straight line; ties by request index. Slots left over are empty (mask 0, zero rows). Requests on board
another taxi, delivered or not yet released are not observed under a window.

Because the claims rank the same pairs by the same distance, a taxi's claimed request (``stop_claims``) is always
in its window when K >= seats + A - 1 (A taxis): only its riders (at most seats - 1 while it has a free seat) and
requests claimed by other taxis (at most A - 1) can rank before it.

The observer computes every field for every passenger of the state (:func:`uamfleet.observe.spec.computed_layout`),
then picks each taxi's rows of every field with a passenger axis
(:data:`uamfleet.observe.spec.PASSENGER_AXIS_FIELDS`) with :func:`take_rows`; the rows' values are those of the full
observation (so ``tour_via_stop`` and ``heading_lookahead`` still count every stop the taxi knows of).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np
from numba import njit

from uamfleet.paths.distance_table import DistanceTable, MissingTableRow, TableArrays, table_distance
from uamfleet.types import ON_BOARD, WAITING, FleetState


@njit(cache=True)
def path_distances(s: FleetState, t: TableArrays, out: np.ndarray) -> bool:
    """out[e, a, p] (float64 [E, A, P]): the table distance (metres) from taxi a to the origin of each ``WAITING``
    request p (``inf`` when unreachable); other rows are not written. False when a table row is not computed yet
    (the caller ensures the stops' rows and calls again)."""
    num_envs, num_taxis = s.free_seats.shape
    for e in range(num_envs):
        for p in range(s.pax_status.shape[1]):
            if not (s.pax_exists[e, p] and s.pax_status[e, p] == WAITING):
                continue
            ox, oy = s.pax_origin_m[e, p, 0], s.pax_origin_m[e, p, 1]
            for a in range(num_taxis):
                d = table_distance(t, s.pos_m[e, a, 0], s.pos_m[e, a, 1], ox, oy)
                if math.isnan(d):
                    return False
                out[e, a, p] = d
    return True


@njit(cache=True)
def straight_distances(s: FleetState, out: np.ndarray) -> None:
    """out[e, a, p]: the straight-line distance (metres) from taxi a to the origin of each ``WAITING`` request p
    (other rows are not written): the window's measure without stop features."""
    num_envs, num_taxis = s.free_seats.shape
    for e in range(num_envs):
        for p in range(s.pax_status.shape[1]):
            if not (s.pax_exists[e, p] and s.pax_status[e, p] == WAITING):
                continue
            for a in range(num_taxis):
                dx = s.pax_origin_m[e, p, 0] - s.pos_m[e, a, 0]
                dy = s.pax_origin_m[e, p, 1] - s.pos_m[e, a, 1]
                out[e, a, p] = math.sqrt(dx * dx + dy * dy)


@njit(cache=True)
def window_rows(s: FleetState, dist: np.ndarray, out: np.ndarray) -> None:
    """out[e, a, j] (int64 [E, A, K]): the request (state row) in slot j of taxi a's window, -1 for an empty slot,
    by the module's rule; ``dist`` [E, A, P] is :func:`path_distances` or :func:`straight_distances`."""
    num_envs, num_taxis, K = out.shape
    num_pax = s.pax_status.shape[1]
    waiting = np.empty(num_pax, np.int64)
    key = np.empty(num_pax)
    for e in range(num_envs):
        for a in range(num_taxis):
            n = 0
            for p in range(num_pax):
                if n < K and s.pax_exists[e, p] and s.pax_status[e, p] == ON_BOARD and s.pax_taxi[e, p] == a:
                    out[e, a, n] = p
                    n += 1
            m = 0
            for p in range(num_pax):
                if s.pax_exists[e, p] and s.pax_status[e, p] == WAITING:
                    waiting[m], key[m] = p, dist[e, a, p]
                    m += 1
            order = np.argsort(key[:m], kind="mergesort")  # stable: equal distances stay in request order
            for i in range(min(m, K - n)):
                out[e, a, n] = waiting[order[i]]
                n += 1
            for j in range(n, K):
                out[e, a, j] = -1


def take_rows(full: dict[str, np.ndarray], rows: np.ndarray, names: Iterable[str]) -> dict[str, np.ndarray]:
    """``{name: full[name][e, a, rows[e, a]]}`` for the fields ``names`` (each ``[E, A, P, ...]``): the window's
    rows of each, zero where ``rows`` is -1 (an empty slot)."""
    empty = rows < 0
    index = np.where(empty, 0, rows)
    out = {}
    for name in names:
        value = full[name]
        picked = np.take_along_axis(value, index.reshape(index.shape + (1,) * (value.ndim - 3)), axis=2)
        picked[empty] = 0
        out[name] = picked
    return out


class WindowComponent:
    """Each taxi's ``size`` rows, by feasible-path distance on the stop features' table when there is one, else by
    straight line."""

    def __init__(self, size: int, num_passengers: int, table: DistanceTable | None) -> None:
        self.size, self.num_passengers, self.table = size, num_passengers, table

    def prepare(self, state: FleetState) -> None:
        """Nothing: the stop features' rows are the ones it reads."""

    def rows(self, state: FleetState) -> np.ndarray:
        """[E, A, K] int64: the state's passenger row in each slot of each taxi's window, -1 for an empty slot."""
        E, A = state.num_envs, state.num_taxis
        dist = np.full((E, A, self.num_passengers), np.inf)
        if self.table is None:
            straight_distances(state, dist)
        elif not path_distances(state, self.table.arrays, dist):
            raise MissingTableRow("the passenger window")
        rows = np.empty((E, A, self.size), np.int64)
        window_rows(state, dist, rows)
        return rows


__all__ = ["WindowComponent", "path_distances", "straight_distances", "take_rows", "window_rows"]
