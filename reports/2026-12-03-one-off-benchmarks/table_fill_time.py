"""Time to fill a distance table (every row; what a fresh machine pays per map and threshold), by the compiled
bucket Dijkstra (``DistanceTable.fill``) and, with ``--scipy``, by the Dijkstra it replaced
(``scipy.sparse.csgraph.dijkstra``, 32 sources a call, as before issue 24), with a bit-for-bit comparison of the
two tables. The disk cache is not used. Thread CPU time and wall clock; run on one core:

    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 taskset -c 0 .venv/bin/python reports/2026-12-03-one-off-benchmarks/table_fill_time.py --scipy
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np
import tyro
from scipy.sparse import csgraph

import uamfleet
from uamfleet.paths.distance_table import DistanceTable, table_graph


@dataclass
class Args:
    scenario: str = "berlin_instances"
    thresholds: tuple[float, ...] = (-7.0, -6.0, -5.0, -4.0, -3.0)
    scipy: bool = False
    """also fill each table with scipy's Dijkstra and compare the entries"""


def scipy_table(table: DistanceTable) -> np.ndarray:
    """The entries as the table computed them before issue 24 (scipy, 32 sources a call)."""
    out = np.full(table.distance_m.shape, np.inf, np.float32)
    cols = np.flatnonzero(table.nodes >= 0)
    for lo in range(0, cols.size, 32):
        chunk = cols[lo : lo + 32]
        lattice = csgraph.dijkstra(table.graph.adjacency, directed=True, indices=table.nodes[chunk])
        out[np.ix_(chunk, cols)] = table.gap_m[chunk, None] + lattice[:, table.nodes[cols]] + table.gap_m[None, cols]
    return out


def main(args: Args) -> None:
    import os

    os.environ["UAMFLEET_CACHE"] = "off"
    print(f"distance table fill, {args.scenario}: seconds of thread CPU time (wall clock)")
    print(f"{'threshold':>9} {'graph nodes':>11} {'blocks':>7} {'compiled':>16} {'scipy':>16} {'identical':>9}")
    for threshold in args.thresholds:
        env = uamfleet.vector_env(args.scenario, num_envs=1, sinr_min_db=threshold)
        graph = table_graph(env.world)
        table = DistanceTable(graph, float(env.world.blocks.block_m), env.world.blocks.shape)
        cpu, wall = time.thread_time(), time.perf_counter()
        table.fill()
        ours = f"{time.thread_time() - cpu:.2f} ({time.perf_counter() - wall:.2f})"
        theirs, same = "", ""
        if args.scipy:
            cpu, wall = time.thread_time(), time.perf_counter()
            reference = scipy_table(table)
            theirs = f"{time.thread_time() - cpu:.2f} ({time.perf_counter() - wall:.2f})"
            same = "yes" if np.array_equal(reference, table.distance_m) else "NO"
        nodes = int(graph.feasible.sum())
        print(f"{threshold:>9g} {nodes:>11,} {table.filled.size:>7,} {ours:>16} {theirs:>16} {same:>9}", flush=True)


if __name__ == "__main__":
    main(tyro.cli(Args))
