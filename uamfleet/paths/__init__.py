"""Shortest SINR-feasible paths on a radio map: the raster graph and distance fields.

This layer sits between ``radio`` and ``env``: the environment's path shaping, the planners and the
dispatchers all use it, and it imports nothing above ``radio``.
"""

from uamfleet.paths.distance_fields import DistanceFields, graph_for
from uamfleet.paths.distance_table import DistanceTable, table_for
from uamfleet.paths.grid_graph import (
    GridGraph,
    StopPaths,
    UnreachableStopError,
    feasible_raster,
    feasible_raster_from_blocks,
)

__all__ = [
    "DistanceFields",
    "DistanceTable",
    "GridGraph",
    "StopPaths",
    "UnreachableStopError",
    "feasible_raster",
    "feasible_raster_from_blocks",
    "graph_for",
    "table_for",
]
