"""Feasible-path distance fields on a world's raster graph, for every policy that flies to a stop.

The world is read through :class:`FlightGeometry` (a structural type that ``uamfleet.sim.world.World``
satisfies), so this layer needs nothing from the environment above it.
"""

from __future__ import annotations

import math
import weakref
from collections import OrderedDict
from typing import Protocol

import numpy as np
from numba import njit

from uamfleet.paths.grid_graph import GridGraph, feasible_raster, feasible_raster_from_blocks
from uamfleet.radio import BlockMap, RadioMap


class FeasibilityConfig(Protocol):
    @property
    def feasibility(self) -> str: ...  # "endpoint_block" or "segment_raster"

    @property
    def block_size_m(self) -> float: ...


class FlightGeometry(Protocol):
    """What the paths layer reads of a world: its map, block map, threshold, rule and one step's moves."""

    @property
    def radio(self) -> RadioMap: ...

    @property
    def blocks(self) -> BlockMap: ...

    @property
    def threshold_db(self) -> float: ...

    @property
    def moves_m(self) -> np.ndarray: ...  # [H, 2] displacement of each heading

    @property
    def cfg(self) -> FeasibilityConfig: ...


# Per radio map (weakly, so a map's graphs go with it): (threshold, rule, block size) -> graph.
_GRAPHS: weakref.WeakKeyDictionary[RadioMap, dict[tuple[float, str, float], GridGraph]] = weakref.WeakKeyDictionary()


def graph_for(world: FlightGeometry) -> GridGraph:
    """The raster graph of the cells flyable under the world's rule (cached per map, threshold, rule, block)."""
    cfg = world.cfg
    graphs = _GRAPHS.setdefault(world.radio, {})
    key = (world.threshold_db, cfg.feasibility, cfg.block_size_m)
    if key not in graphs:
        if cfg.feasibility == "endpoint_block":
            feasible = feasible_raster_from_blocks(world.radio, world.blocks, world.threshold_db)
        else:
            feasible = feasible_raster(world.radio, world.threshold_db)
        label = f"{world.radio.label} at sinr_min_db={world.threshold_db:g} dB"
        graphs[key] = GridGraph(feasible, world.radio.resolution_m, world.radio.origin_m, label=label)
    return graphs[key]


class DistanceFields:
    """Steering on feasible paths: Dijkstra distance fields to goals on the world's raster graph (cached per goal)
    and the remaining distance from candidate step endpoints, for every policy that flies to a stop.

    The fields live in one pool [slots, nx, ny] of at most ``budget_bytes`` (the least recently used goal's field
    is the first recomputed): a planner that samples futures asks for fields of many sites, and on the
    Detroit-like map's 1,114 x 1,114 raster a field is 10 MB (1 GB holds 108 of them; every Berlin site's fits)."""

    def __init__(self, world: FlightGeometry, budget_bytes: int = 2**30) -> None:
        self.world = world
        self.graph = graph_for(world)
        field_bytes = 8 * self.graph.shape[0] * self.graph.shape[1]
        self.max_slots = max(1, int(budget_bytes) // field_bytes)
        self._pool = np.empty((0, *self.graph.shape))  # grows by doubling up to max_slots
        self._slots: OrderedDict[tuple[float, float], int] = OrderedDict()  # goal -> slot, -1: unreachable
        self._free: list[int] = []
        self._evictions = 0
        self._recent: tuple[bytes, int, np.ndarray] | None = None  # the last goals' slots, while none was evicted

    def _slot(self, goal: np.ndarray) -> int:
        """The pool slot that holds the field to ``goal`` (computed on a miss); -1 when no flyable cell reaches
        it. The goal becomes the most recently used."""
        key = (float(goal[0]), float(goal[1]))
        if key in self._slots:
            self._slots.move_to_end(key)
            return self._slots[key]
        try:
            field_m = self.graph.distances_from(goal)
        except ValueError:  # the goal is out of every flyable cell's reach: head straight for it
            self._slots[key] = -1
            return -1
        if not self._free:
            used = len(self._pool)
            if used < self.max_slots:
                grown = min(self.max_slots, max(1, 2 * used))
                self._pool = np.concatenate([self._pool, np.empty((grown - used, *self.graph.shape))])
                self._free.extend(range(grown - 1, used - 1, -1))
            else:  # evict the least recently used goal that holds a slot
                old = next(k for k, v in self._slots.items() if v >= 0)
                self._free.append(self._slots.pop(old))
                self._evictions += 1
        slot = self._free.pop()
        self._pool[slot] = field_m
        self._slots[key] = slot
        return slot

    def field(self, goal: np.ndarray) -> np.ndarray | None:
        """[nx, ny] the distance field to ``goal`` (a view of the cache: read it before the next look-up), or None
        when no flyable cell reaches it."""
        slot = self._slot(goal)
        return self._pool[slot] if slot >= 0 else None

    def remaining_many(self, goals: np.ndarray, candidates: np.ndarray) -> np.ndarray:
        """[K, G] :meth:`remaining_m` of each goal [G, 2] from each candidate [K, 2], in one compiled pass over the
        pool (a step-level search asks for all its stops at every layer)."""
        goals = np.ascontiguousarray(goals, dtype=np.float64).reshape(-1, 2)
        candidates = np.ascontiguousarray(candidates, dtype=np.float64).reshape(-1, 2)
        if len(goals) > self.max_slots:  # more goals than the pool holds at once: one at a time
            return np.concatenate([self._rows(goals[g : g + 1], candidates) for g in range(len(goals))], axis=1)
        return self._rows(goals, candidates)

    def _rows(self, goals: np.ndarray, candidates: np.ndarray) -> np.ndarray:
        key = goals.tobytes()
        if self._recent is not None and self._recent[0] == key and self._recent[1] == self._evictions:
            slots = self._recent[2]  # the same goals as the last call (every layer of a search), all still held
        else:
            slots = np.array([self._slot(g) for g in goals], dtype=np.int64)
            self._recent = (key, self._evictions, slots)
        radio = self.world.radio
        out = np.empty((len(candidates), len(goals)))
        _remaining_rows(self._pool, slots, goals, candidates, float(radio.origin_m[0]), float(radio.origin_m[1]),
                        float(radio.resolution_m), out)  # fmt: skip
        return out

    def stop_distances(self, stops: np.ndarray) -> np.ndarray:
        """[S, S] :meth:`GridGraph.stop_distances` (the same numbers and errors), read off the stops' cached fields
        instead of new Dijkstras: a step-level search needs both for the same stops."""
        return self.graph.stop_distances(stops, field_of=self.field)

    def remaining_m(self, goal: np.ndarray, candidates: np.ndarray) -> np.ndarray:
        """[K] feasible-path distance from each candidate point [K, 2] to ``goal``: the goal's field at the best of
        the 4 cell centres around the point plus the straight line to that centre (a point near a block edge may
        have its nearest centre across it). A goal that no flyable cell reaches falls back to the straight-line
        distance."""
        return self.remaining_many(np.reshape(goal, (1, 2)), candidates)[:, 0]

    def heading(self, pos: np.ndarray, allowed: np.ndarray, goal: np.ndarray) -> int:
        """The allowed heading whose endpoint is nearest ``goal`` along feasible paths."""
        cost = self.remaining_m(goal, pos + self.world.moves_m)
        return int(np.argmin(np.where(allowed, cost, np.inf)))


@njit(cache=True)
def _remaining_rows(
    pool: np.ndarray, slots: np.ndarray, goals: np.ndarray, candidates: np.ndarray, ox: float, oy: float,
    res: float, out: np.ndarray,
) -> None:  # fmt: skip
    """out[k, g] = :meth:`DistanceFields.remaining_m` of goal g at candidate k: the least of field + straight line
    over the 4 cell centres around the candidate (clipped to the raster), the field being ``pool[slots[g]]``; the
    straight line where ``slots[g]`` is -1 (unreachable)."""
    nx, ny = pool.shape[1], pool.shape[2]
    for k in range(candidates.shape[0]):
        cx, cy = candidates[k, 0], candidates[k, 1]
        bx = math.floor((cx - ox) / res)  # an integer in numba
        by = math.floor((cy - oy) / res)
        for g in range(goals.shape[0]):
            slot = slots[g]
            if slot < 0:
                ex, ey = cx - goals[g, 0], cy - goals[g, 1]
                out[k, g] = math.sqrt(ex * ex + ey * ey)
                continue
            best = math.inf
            for dx in range(2):
                ix = min(max(bx + dx, 0), nx - 1)
                for dy in range(2):
                    iy = min(max(by + dy, 0), ny - 1)
                    ex, ey = cx - (ox + ix * res), cy - (oy + iy * res)
                    value = pool[slot, ix, iy] + math.sqrt(ex * ex + ey * ey)
                    if value < best:
                        best = value
            out[k, g] = best
