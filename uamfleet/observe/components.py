"""The planner-derived components of the observation, each with ``prepare(state)`` and ``write(state, obs)``.

The observer runs every component's ``prepare`` once per ``observe``, before any kernel: the stop features fill the
distance-table rows of every existing stop there (:meth:`~uamfleet.paths.DistanceTable.ensure`, a no-op for rows
already filled), so that the kernels, which read those rows, find them. A kernel that still meets a missing row
is a bug: :class:`RuntimeError`, never a second call.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from uamfleet.observe import stops, window
from uamfleet.observe.lookahead import heading_lookahead
from uamfleet.paths import DistanceTable
from uamfleet.paths.distance_table import TableArrays, new_corners, prepare_corners
from uamfleet.sim.pretyped import PreTyped
from uamfleet.sim.world import World
from uamfleet.types import FleetState

_NO_CLAIMS = np.zeros((0, 0, 0, 0), np.int8)  # 0-size: the rivals kernel writes no claims


def _missing_row(kernel: str) -> RuntimeError:
    return RuntimeError(
        f"{kernel} read a distance-table row that the stop features' prepare() did not compute: a bug in "
        "uamfleet.observe.components (every existing stop's rows are filled before the kernels run)."
    )


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
    ``stop_claims`` (:mod:`uamfleet.observe.stops`), on the feasible-path distance table of the world."""

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
        if not stops.stop_features(state, arrays, table, obs["stop_paths"], obs["stop_heading_mask"]):
            raise _missing_row("stop_features")
        if self.rivals:
            claims = obs.get("stop_claims", _NO_CLAIMS)
            if not stops.stop_rivals(state, arrays, table, obs["stop_rivals"], claims):
                raise _missing_row("stop_rivals")


class LookaheadComponent:
    """``heading_lookahead`` at ``depth`` 1 or 2 (:mod:`uamfleet.observe.lookahead`); reads the rows the stop
    features prepared."""

    def __init__(self, world: World, table: DistanceTable, depth: int) -> None:
        self.world, self.table, self.depth = world, table, depth

    def prepare(self, state: FleetState) -> None:
        """Nothing: the stop features' rows are the ones it reads."""

    def write(self, state: FleetState, obs: dict[str, np.ndarray]) -> None:
        if not heading_lookahead(state, self.world.arrays, self.table.arrays, obs["heading_lookahead"], self.depth):
            raise _missing_row("heading_lookahead")


class WindowComponent:
    """The passenger window (:mod:`uamfleet.observe.window`): each taxi's ``size`` rows, by feasible-path distance
    on the stop features' table when there is one, else by straight line."""

    def __init__(self, size: int, num_passengers: int, table: DistanceTable | None) -> None:
        self.size, self.num_passengers, self.table = size, num_passengers, table

    def prepare(self, state: FleetState) -> None:
        """Nothing: the stop features' rows are the ones it reads."""

    def rows(self, state: FleetState) -> np.ndarray:
        """[E, A, K] int64: the state's passenger row in each slot of each taxi's window, -1 for an empty slot."""
        E, A = state.num_envs, state.num_taxis
        dist = np.full((E, A, self.num_passengers), np.inf)
        if self.table is None:
            window.straight_distances(state, dist)
        elif not window.path_distances(state, self.table.arrays, dist):
            raise _missing_row("the passenger window")
        rows = np.empty((E, A, self.size), np.int64)
        window.window_rows(state, dist, rows)
        return rows


__all__ = ["LookaheadComponent", "StopsComponent", "WindowComponent"]
