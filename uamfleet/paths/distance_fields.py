"""Feasible-path distance fields on a world's raster graph, for every policy that flies to a stop.

The world is read through :class:`FlightGeometry` (a structural type that ``uamfleet.env.world.World``
satisfies), so this layer needs nothing from the environment above it.
"""

from __future__ import annotations

import weakref
from typing import Protocol

import numpy as np

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
    and the remaining distance from candidate step endpoints, for every policy that flies to a stop."""

    def __init__(self, world: FlightGeometry) -> None:
        self.world = world
        self.graph = graph_for(world)
        self._fields: dict[tuple[float, float], np.ndarray | None] = {}

    def remaining_m(self, goal: np.ndarray, candidates: np.ndarray) -> np.ndarray:
        """[K] feasible-path distance from each candidate point [K, 2] to ``goal``. A point near a block edge may
        have its nearest cell centre across it, so the best of the 4 surrounding centres is used. A goal that no
        flyable cell reaches falls back to the straight-line distance."""
        key = (float(goal[0]), float(goal[1]))
        if key not in self._fields:
            try:
                self._fields[key] = self.graph.distances_from(goal)
            except ValueError:  # the goal is out of every flyable cell's reach: head straight for it
                self._fields[key] = None
        field_m = self._fields[key]
        if field_m is None:
            return np.linalg.norm(candidates - goal, axis=-1)
        radio = self.world.radio
        res, (ox, oy) = radio.resolution_m, radio.origin_m
        fx = (candidates[:, 0] - ox) / res
        fy = (candidates[:, 1] - oy) / res
        best = np.full(len(candidates), np.inf)
        nx, ny = field_m.shape
        for dx in (0, 1):
            for dy in (0, 1):
                ix = np.clip(np.floor(fx).astype(int) + dx, 0, nx - 1)
                iy = np.clip(np.floor(fy).astype(int) + dy, 0, ny - 1)
                centre = np.stack([ox + ix * res, oy + iy * res], axis=-1)
                best = np.minimum(best, field_m[ix, iy] + np.linalg.norm(candidates - centre, axis=-1))
        return best

    def heading(self, pos: np.ndarray, allowed: np.ndarray, goal: np.ndarray) -> int:
        """The allowed heading whose endpoint is nearest ``goal`` along feasible paths."""
        cost = self.remaining_m(goal, pos + self.world.moves_m)
        return int(np.argmin(np.where(allowed, cost, np.inf)))
