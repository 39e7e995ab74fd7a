"""Shortest SINR-feasible paths on a raster: feasible cells -> lattice graph -> Dijkstra.

Nodes are raster cells (flat index ``ix * ny + iy``), edges join the centres of feasible cells. The
8-connected lattice has the 8 neighbours; the 16-connected one adds the 8 knight moves (±1, ±2), (±2, ±1),
which brings the worst-case detour over any-angle paths from 8.2 % down to 2.7 %.

**Edge rule** (one rule for every move): an edge exists when every cell whose *closed* square the straight
segment between the two centres meets is feasible. Concretely:

- orthogonal move: the two endpoint cells only;
- diagonal move ``(a, b)``: also ``(i + a, j)`` and ``(i, j + b)`` — the segment passes exactly through their
  shared corner, and a path sampled there (nearest cell, ties to the higher index, as
  :meth:`RadioMap.cell_index` does) reads one of them, so the lattice never cuts such a corner;
- knight move ``(a, 2b)``: also ``(i, j + b)`` and ``(i + a, j + b)`` (and ``(i + a', j)``, ``(i + a', j + b)``
  for ``(2a', b)``) — the two cells the segment crosses between its endpoints.

The rule is decided from this table (exact geometry, no sampling), so a path is feasible under every
nearest-cell sampling of its segments.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np
import scipy.sparse as sp
from scipy.sparse import csgraph
from scipy.spatial import cKDTree

from uamfleet.radio.radio_map import BlockMap, RadioMap
from uamfleet.paths.bucket_dijkstra import Lattice, lattice_distances

CONNECTIVITIES: tuple[int, ...] = (8, 16)
_CACHE_DECIMALS = 6  # stops equal to the micrometre share one cached result
_CACHE_SIZE = 256  # results kept per graph (oldest dropped first); each holds only S^2 short node paths

# Moves in one half-plane; the reverse of each is added when the graph is built (the graph is undirected).
_MOVES_8: tuple[tuple[int, int], ...] = ((1, 0), (0, 1), (1, 1), (1, -1))
_MOVES_KNIGHT: tuple[tuple[int, int], ...] = ((1, 2), (2, 1), (2, -1), (1, -2))


class UnreachableStopError(ValueError):
    """A stop that no feasible path reaches: it lies in (or too far from) infeasible cells, or is walled off."""


def crossed_cells(di: int, dj: int) -> tuple[tuple[int, int], ...]:
    """Cells (relative to the start cell) besides both endpoints whose closed square the move's segment meets."""
    adi, adj = abs(di), abs(dj)
    if adi + adj == 1:
        return ()
    if adi == adj == 1:
        return ((di, 0), (0, dj))
    if (adi, adj) == (1, 2):
        return ((0, dj // 2), (di, dj // 2))
    if (adi, adj) == (2, 1):
        return ((di // 2, 0), (di // 2, dj))
    raise ValueError(f"move ({di}, {dj}) is not a lattice move; use one of the 8- or 16-connected offsets")


def lattice_moves(connectivity: int) -> tuple[tuple[int, int], ...]:
    """All moves (both directions) of the 8- or 16-connected lattice."""
    if connectivity not in CONNECTIVITIES:
        raise ValueError(f"connectivity must be 8 or 16, got {connectivity!r}")
    half = _MOVES_8 + (_MOVES_KNIGHT if connectivity == 16 else ())
    return half + tuple((-a, -b) for a, b in half)


@dataclass(frozen=True, eq=False)
class StopPaths:
    """All-pairs shortest feasible paths between a few stops.

    ``distance_m[i, j]`` is the length of :meth:`path` ``(i, j)``: the straight leg from stop i to its node's
    cell centre, the lattice path, and the straight leg from the last centre to stop j (0 on the diagonal).
    """

    points_m: np.ndarray  # [S, 2] the stops as given
    distance_m: np.ndarray  # [S, S] metres, symmetric
    _node_paths: dict[tuple[int, int], np.ndarray] = field(repr=False)  # (i, j), i < j -> [K, 2] centres
    nodes: np.ndarray = field(repr=False)  # [S] graph node of each stop

    @property
    def num_stops(self) -> int:
        return int(self.points_m.shape[0])

    def path(self, i: int, j: int) -> np.ndarray:
        """[K, 2] polyline from ``points_m[i]`` to ``points_m[j]`` through the cell centres of the path.

        Consecutive duplicates (a stop exactly at its cell centre) are dropped, so the polyline length equals
        ``distance_m[i, j]``.
        """
        s = self.num_stops
        if not (0 <= i < s and 0 <= j < s):
            raise ValueError(f"stop indices must lie in [0, {s - 1}], got ({i}, {j})")
        if i == j:
            return self.points_m[[i]].copy()
        centres = self._node_paths[(i, j)] if i < j else self._node_paths[(j, i)][::-1]
        pts = np.concatenate([self.points_m[[i]], centres, self.points_m[[j]]])
        keep = np.ones(len(pts), dtype=bool)
        keep[1:] = np.any(pts[1:] != pts[:-1], axis=1)
        return pts[keep]


class GridGraph:
    """Feasible raster cells -> sparse graph (8- or 16-connected lattice) -> Dijkstra distances and paths.

    ``feasible`` is ``[nx, ny]`` bool indexed ``[ix, iy]`` (x east first); cell ``[ix, iy]`` has its centre at
    ``origin_m + (ix, iy) * resolution_m``. Edge weights are Euclidean lengths in metres; see the module
    docstring for which cells an edge needs. A stop whose own cell (nearest centre) is infeasible is snapped
    to the nearest feasible centre only if that is within ``snap_m`` (default ``1.5 * resolution_m``).
    Keep one graph per (map, threshold): :meth:`shortest_paths` results are cached per stop set.
    """

    def __init__(
        self,
        feasible: np.ndarray,
        resolution_m: float,
        origin_m: tuple[float, float] = (0.0, 0.0),
        connectivity: int = 16,
        label: str = "",
        snap_m: float | None = None,
    ) -> None:
        mask = np.asarray(feasible)
        if mask.ndim != 2 or 0 in mask.shape:
            raise ValueError(f"feasible must be a non-empty 2-D [nx, ny] mask, got shape {mask.shape}")
        if mask.dtype != np.bool_:
            raise ValueError(f"feasible must be a bool mask, got dtype {mask.dtype}; pass e.g. sinr_db >= threshold")
        self.resolution_m = float(resolution_m)
        if not (math.isfinite(self.resolution_m) and self.resolution_m > 0):
            raise ValueError(f"resolution_m must be a finite number > 0, got {resolution_m!r}")
        ox, oy = (float(v) for v in origin_m)
        if not (math.isfinite(ox) and math.isfinite(oy)):
            raise ValueError(f"origin_m must be finite coordinates in metres, got {origin_m!r}")
        self.origin_m = (ox, oy)
        self.moves = lattice_moves(connectivity)
        self.connectivity = connectivity
        self.label = label or "grid graph"
        self.snap_m = 1.5 * self.resolution_m if snap_m is None else float(snap_m)
        if not self.snap_m >= 0:
            raise ValueError(f"snap_m must be >= 0 metres, got {snap_m!r}")
        self.feasible = mask.copy()
        self.feasible.setflags(write=False)
        if not mask.any():
            raise ValueError(f"{self.label}: no feasible cell; lower the SINR threshold or check the map")
        self.shape = (int(mask.shape[0]), int(mask.shape[1]))
        self.lattice: Lattice | None = None  # the same graph as moves (uamfleet.paths.bucket_dijkstra), by _build
        self.adjacency = self._build()
        ix, iy = np.nonzero(mask)
        self._feasible_nodes = ix * self.shape[1] + iy  # [F] flat node ids, ascending
        self._tree = cKDTree(self.node_xy(self._feasible_nodes))
        self._cache: dict[tuple[float, ...], StopPaths] = {}

    def __repr__(self) -> str:
        return (
            f"GridGraph({self.label!r}, shape={self.shape}, connectivity={self.connectivity}, "
            f"feasible={self._feasible_nodes.size}, edges={self.adjacency.nnz})"
        )

    def _build(self) -> sp.csr_matrix:
        nx, ny = self.shape
        pad = 2  # the longest move reaches 2 cells; padding with False keeps every shifted view in bounds
        padded = np.zeros((nx + 2 * pad, ny + 2 * pad), dtype=bool)
        padded[pad : pad + nx, pad : pad + ny] = self.feasible

        def shifted(a: int, b: int) -> np.ndarray:
            return padded[pad + a : pad + a + nx, pad + b : pad + b + ny]

        rows: list[np.ndarray] = []
        cols: list[np.ndarray] = []
        weights: list[np.ndarray] = []
        n = nx * ny
        # the same edges as moves (bit 2k: half move k forward, 2k + 1: back) for the compiled distance fields
        offsets, move_weights, bits = [], [], np.zeros(n, dtype=np.uint32)
        for k, (di, dj) in enumerate(self.moves[: len(self.moves) // 2]):
            ok = self.feasible & shifted(di, dj)
            for a, b in crossed_cells(di, dj):
                ok &= shifted(a, b)
            src = np.flatnonzero(ok)
            dst = src + di * ny + dj
            weight = self.resolution_m * math.hypot(di, dj)
            w = np.full(src.size, weight)
            rows += [src, dst]
            cols += [dst, src]
            weights += [w, w]
            offsets += [di * ny + dj, -(di * ny + dj)]
            move_weights += [weight, weight]
            bits[src] |= np.uint32(1 << (2 * k))
            bits[dst] |= np.uint32(1 << (2 * k + 1))
        # Node-id offsets are distinct only if a row holds more cells than a move spans (ny > 2 * pad); on a
        # narrower raster two moves may join the same pair of nodes, and the matrix sums such duplicates.
        self.lattice = Lattice(np.array(offsets, np.int64), np.array(move_weights), bits) if ny > 2 * pad else None
        return sp.csr_matrix((np.concatenate(weights), (np.concatenate(rows), np.concatenate(cols))), shape=(n, n))

    # -- nodes ------------------------------------------------------------------------------------------------
    def node_xy(self, nodes: Any) -> np.ndarray:
        """[..., 2] world coordinates (metres) of the cell centres of flat node ids."""
        ix, iy = np.divmod(np.asarray(nodes, dtype=np.intp), self.shape[1])
        return np.stack([self.origin_m[0] + ix * self.resolution_m, self.origin_m[1] + iy * self.resolution_m], -1)

    def _own_cell(self, point: np.ndarray) -> int | None:
        # Same rule as RadioMap.cell_index: floor(f + 0.5), a point half-way goes to the higher index.
        fx = math.floor((point[0] - self.origin_m[0]) / self.resolution_m + 0.5)
        fy = math.floor((point[1] - self.origin_m[1]) / self.resolution_m + 0.5)
        if 0 <= fx < self.shape[0] and 0 <= fy < self.shape[1]:
            return fx * self.shape[1] + fy
        return None

    def nearest_node(self, point_xy: Any) -> int:
        """Flat node id of the feasible cell centre nearest to a world point (its own cell when feasible)."""
        point = _point(point_xy)
        own = self._own_cell(point)
        if own is not None and self.feasible.flat[own]:
            return own
        _, k = self._tree.query(point)
        return int(self._feasible_nodes[k])

    def _stop_node(self, point: np.ndarray, label: str) -> int:
        node = self.nearest_node(point)
        gap_m = float(np.hypot(*(self.node_xy(node) - point)))
        own = self._own_cell(point)
        if node != own and gap_m > self.snap_m:
            raise UnreachableStopError(
                f"stop {label!r} at ({point[0]:.1f}, {point[1]:.1f}) m lies in an infeasible cell of {self.label}; "
                f"the nearest feasible cell centre is {gap_m:.1f} m away (> snap_m = {self.snap_m:g} m): move the "
                "stop, lower the SINR threshold, or raise snap_m"
            )
        return node

    def _stop_nodes(self, pts: np.ndarray, names: list[str]) -> np.ndarray:
        """[S] flat node ids of stops (:meth:`_stop_node`'s snap rule and its error, naming the stop)."""
        return np.array([self._stop_node(p, n) for p, n in zip(pts, names, strict=True)], dtype=np.intp)

    # -- queries ----------------------------------------------------------------------------------------------
    def distances_from(self, point_xy: Any) -> np.ndarray:
        """[nx, ny] lattice distance (metres) from the point's node (snap rule as for stops); inf if unreachable.

        Compiled (:func:`~uamfleet.paths.bucket_dijkstra.lattice_distances`): the same float64 numbers as
        ``csgraph.dijkstra(self.adjacency, directed=True, indices=node)``, bit for bit, 10-20 x faster; the step
        planners ask for one field per stop."""
        point = _point(point_xy)
        node = self._stop_node(point, "point")
        if self.lattice is None:
            return np.asarray(csgraph.dijkstra(self.adjacency, directed=True, indices=node)).reshape(self.shape)
        every_node = np.arange(self.shape[0] * self.shape[1], dtype=np.int64)
        return lattice_distances(self.lattice, np.array([node]), every_node).reshape(self.shape)

    def shortest_paths(self, points: Any, labels: Sequence[str] | None = None) -> StopPaths:
        """All-pairs shortest feasible paths between stops ``[S, 2]`` (e.g. start, origins, destinations).

        Raises :class:`UnreachableStopError` naming the stop when it lies in an infeasible cell farther than
        ``snap_m`` from a feasible centre, or when no feasible path joins it to stop 0. Cached per stop set.
        """
        pts, names = _checked_stops(points, labels)
        key = tuple(np.round(pts, _CACHE_DECIMALS).ravel().tolist())
        if key in self._cache:
            return self._cache[key]
        result = self._solve(pts, names)
        if len(self._cache) >= _CACHE_SIZE:
            del self._cache[next(iter(self._cache))]
        self._cache[key] = result
        return result

    def stop_distances(
        self, points: Any, labels: Sequence[str] | None = None,
        field_of: Callable[[np.ndarray], np.ndarray | None] | None = None,
    ) -> np.ndarray:  # fmt: skip
        """[S, S] the ``distance_m`` of :meth:`shortest_paths` (same numbers, bit for bit, and the same errors)
        without the paths, compiled where the graph has a :attr:`lattice`: what the step planners need.
        ``field_of`` (e.g. :meth:`DistanceFields.field`): each stop's :meth:`distances_from` field, cached
        elsewhere, read instead of new Dijkstras (row i of the table is stop i's field at the stops' nodes)."""
        pts, names = _checked_stops(points, labels)
        if self.lattice is None and field_of is None:
            return self.shortest_paths(pts, names).distance_m
        nodes = self._stop_nodes(pts, names)
        if field_of is not None:  # every stop snaps to a node (checked above), so each has a field
            between = np.stack([np.asarray(field_of(p)).reshape(-1)[nodes] for p in pts])
        else:
            assert self.lattice is not None  # checked above
            between = lattice_distances(self.lattice, nodes, nodes)  # [S, S]: row i from stop i's node
        return self._stop_table(pts, names, nodes, between)

    def _solve(self, pts: np.ndarray, names: list[str]) -> StopPaths:
        s = pts.shape[0]
        nodes = self._stop_nodes(pts, names)
        dist, pred = csgraph.dijkstra(self.adjacency, directed=True, indices=nodes, return_predecessors=True)
        distance_m = self._stop_table(pts, names, nodes, dist[:, nodes])
        node_paths: dict[tuple[int, int], np.ndarray] = {}
        for i in range(s):
            for j in range(i + 1, s):
                node_paths[(i, j)] = self.node_xy(_walk(pred[i], int(nodes[i]), int(nodes[j])))
        for arr in (pts, distance_m, nodes, *node_paths.values()):
            arr.setflags(write=False)  # results are cached and shared
        return StopPaths(points_m=pts, distance_m=distance_m, _node_paths=node_paths, nodes=nodes)

    def _stop_table(self, pts: np.ndarray, names: list[str], nodes: np.ndarray, between: np.ndarray) -> np.ndarray:
        """[S, S] stop-to-stop distances from the lattice distances ``between`` their nodes (row i: from stop i),
        plus each stop's snap to its node; UnreachableStopError for a stop that stop 0 does not reach."""
        s = pts.shape[0]
        snap_m = np.hypot(*(self.node_xy(nodes) - pts).T)  # [S]
        for i in range(1, s):
            if not np.isfinite(between[0, i]):
                raise UnreachableStopError(
                    f"stop {names[i]!r} at ({pts[i, 0]:.1f}, {pts[i, 1]:.1f}) m is walled off from stop "
                    f"{names[0]!r} in {self.label}: no feasible path joins them; lower the SINR threshold or "
                    "move the stop"
                )
        distance_m = np.zeros((s, s))
        for i in range(s):
            for j in range(i + 1, s):
                # Row i's Dijkstra serves both directions (the graph is undirected): symmetric by construction.
                distance_m[i, j] = distance_m[j, i] = snap_m[i] + between[i, j] + snap_m[j]
        return distance_m


def _checked_stops(points: Any, labels: Sequence[str] | None) -> tuple[np.ndarray, list[str]]:
    """Stops ``[S, 2]`` as float64 and their labels ("stop i" by default), or ValueError naming what is wrong."""
    pts = np.array(points, dtype=np.float64)
    if pts.ndim != 2 or pts.shape[1] != 2 or pts.shape[0] == 0:
        raise ValueError(f"points must have shape [S, 2] with S >= 1, got {pts.shape}")
    if not np.isfinite(pts).all():
        raise ValueError(f"points must be finite coordinates in metres, got {pts.tolist()}")
    s = pts.shape[0]
    names = [f"stop {i}" for i in range(s)] if labels is None else [str(x) for x in labels]
    if len(names) != s:
        raise ValueError(f"got {len(names)} labels for {s} stops; pass one label per stop")
    return pts, names


def _walk(pred: np.ndarray, source: int, target: int) -> list[int]:
    path = [target]
    while path[-1] != source:
        path.append(int(pred[path[-1]]))
    return path[::-1]


def _point(point_xy: Any) -> np.ndarray:
    p = np.asarray(point_xy, dtype=np.float64)
    if p.shape != (2,) or not np.isfinite(p).all():
        raise ValueError(f"a point must be finite (x_m, y_m), got {point_xy!r}")
    return p


def _centres(radio: RadioMap) -> np.ndarray:
    nx, ny = radio.shape
    xs = radio.origin_m[0] + np.arange(nx) * radio.resolution_m
    ys = radio.origin_m[1] + np.arange(ny) * radio.resolution_m
    return np.stack(np.meshgrid(xs, ys, indexing="ij"), axis=-1)  # [nx, ny, 2]


def _inside(radio: RadioMap, centres: np.ndarray) -> np.ndarray:
    side = cast(float, radio.side_m)  # always set by RadioMap.__post_init__
    return np.all((centres >= 0) & (centres <= side), axis=-1)


def feasible_raster(radio: RadioMap, threshold_db: float) -> np.ndarray:
    """[nx, ny] bool: raster SINR >= threshold (not-computed cells are infeasible), centre inside [0, side]^2."""
    centres = _centres(radio)
    return np.asarray(radio.feasible(centres, threshold_db) & _inside(radio, centres))


def feasible_raster_from_blocks(radio: RadioMap, block_map: BlockMap, threshold_db: float) -> np.ndarray:
    """[nx, ny] bool: the cell centre lies in [0, side]^2 and its block's mean SINR >= threshold.

    This is the environment's default "endpoint_block" rule seen at raster resolution.
    """
    if not math.isclose(block_map.side_m, cast(float, radio.side_m), rel_tol=1e-9):
        raise ValueError(
            f"block_map covers side {block_map.side_m:g} m but the radio map's side is {radio.side_m:g} m; "
            "build it with radio.block_map(block_m)"
        )
    return block_map.feasible(_centres(radio), threshold_db)
