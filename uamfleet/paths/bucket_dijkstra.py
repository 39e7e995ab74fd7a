"""Single-source shortest paths on a raster graph, compiled: the distance table's rows in milliseconds.

``scipy.sparse.csgraph.dijkstra`` spends ~35 ms per source on Berlin's 330 x 330 raster (a Fibonacci heap and
a full [sources, nodes] float64 result); a table needs one run per block centre (1,089 on Berlin, ~38 s). Here the
priority queue is a ring of buckets of width ``w_min`` (the lightest edge; Dinitz's rule): a node whose distance
lies in the bucket being emptied can no longer improve, since every edge into it from a node of the same or a
later bucket adds at least ``w_min``. So the nodes of a bucket are settled in any order, with no heap, and only
the distances to the wanted targets are kept.

The result is the same float64 number scipy returns, bit for bit: both compute the unique fixed point of
``d(v) = min over edges (u, v) of fl(d(u) + w(u, v))``, ``d(source) = 0`` (weights > 0, rounding monotone: take the
smallest distance where two fixed points differ; its predecessor's distances agree, so its own do), whatever
the order of the relaxations.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np
import scipy.sparse as sp
from numba import njit


class Lattice(NamedTuple):
    """A raster graph as moves: node v's neighbours are ``v + offsets[m]`` for the bits m set in ``moves[v]``,
    each at ``weights[m]`` (:func:`lattice_of`)."""

    offsets: np.ndarray  # [M] int64 node-id offsets
    weights: np.ndarray  # [M] float64 edge weight of each
    moves: np.ndarray  # [N] uint32 bit set of the offsets node v has an edge along


def lattice_of(adjacency: sp.spmatrix) -> Lattice:
    """The graph ``adjacency`` (CSR or any sparse matrix, weights > 0) as a :class:`Lattice`: its distinct node-id
    offsets ``v - u`` (at most 32; a :class:`~uamfleet.paths.GridGraph` has 8 or 16), each of one weight. Reading a
    bit set per node instead of a CSR row is what makes :func:`lattice_distances` fast. ValueError for a graph
    with more offsets or with edges along one offset that weigh differently."""
    csr = sp.csr_matrix(adjacency)
    rows = np.repeat(np.arange(csr.shape[0], dtype=np.int64), np.diff(csr.indptr))
    offsets, which = np.unique(csr.indices.astype(np.int64) - rows, return_inverse=True)
    which = which.ravel()
    if offsets.size > 32:
        raise ValueError(f"a lattice graph has at most 32 distinct moves (node-id offsets), this one {offsets.size}")
    weights = np.zeros(offsets.size)
    weights[which] = csr.data
    if csr.nnz and not (np.all(csr.data == weights[which]) and np.isfinite(weights).all() and weights.min() > 0.0):
        raise ValueError("a lattice graph needs one finite weight > 0 per move; edges along one move differ here")
    moves = np.zeros(csr.shape[0], dtype=np.uint32)
    np.bitwise_or.at(moves, rows, np.left_shift(np.uint32(1), which.astype(np.uint32)))
    return Lattice(offsets, weights, moves)


def lattice_distances(lattice: Lattice, sources: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """[len(sources), len(targets)] float64 shortest-path distances on ``lattice`` from each source node to each
    target node; ``inf`` where no path joins them. Equal, bit for bit, to
    ``csgraph.dijkstra(adjacency, directed=True, indices=sources)[:, targets]`` (module docstring)."""
    sources = np.asarray(sources, dtype=np.int64).reshape(-1)
    targets = np.asarray(targets, dtype=np.int64).reshape(-1)
    out = np.empty((sources.size, targets.size))
    if lattice.offsets.size == 0:  # no edges: each source reaches itself only
        out[:] = np.where(sources[:, None] == targets[None, :], 0.0, np.inf)
        return out
    done, capacity = 0, lattice.moves.size
    while done < sources.size:  # a bucket overflowed (never seen on the packaged maps): redo that row, roomier
        done = _bucket_rows(lattice.offsets, lattice.weights, lattice.moves, sources, targets, capacity, done, out)
        capacity *= 2
    return out


@njit(cache=True)
def _bucket_rows(
    offsets: np.ndarray, weights: np.ndarray, moves: np.ndarray, sources: np.ndarray, targets: np.ndarray,
    capacity: int, first: int, out: np.ndarray,
) -> int:  # fmt: skip
    """out[r] = distances from sources[r] to ``targets`` (see :func:`lattice_distances`) for r from ``first`` on,
    with room for ``capacity`` nodes in a bucket; returns the row where a bucket overflowed, else len(sources).

    A label-correcting loop in bucket order: a popped node is expanded unless it was already expanded with its
    current distance, so the result is the fixed point even where float rounding put a node one bucket off."""
    n = moves.size
    num_moves = offsets.size
    w_min, w_max = weights.min(), weights.max()
    per_bucket = 1.0 / w_min
    ring = 1  # a power of two above the most buckets one relaxation can jump ahead (w_max / w_min, rounded up)
    while ring < int(w_max * per_bucket) + 3:
        ring *= 2
    queue = np.empty((ring, capacity), np.int32)  # node ids < 2**31
    count = np.zeros(ring, np.int64)
    dist = np.empty(n)
    expanded = np.empty(n)  # the distance each node was last expanded with (-1: never)
    for r in range(first, sources.size):
        dist[:] = math.inf
        expanded[:] = -1.0
        count[:] = 0
        dist[sources[r]] = 0.0
        queue[0, 0] = sources[r]
        count[0] = 1
        pending, bucket = 1, 0
        while pending > 0:
            slot = bucket & (ring - 1)
            i = 0
            while i < count[slot]:  # a relaxation may land in this very bucket (rounding): it is expanded too
                u = queue[slot, i]
                i += 1
                du = dist[u]
                if du == expanded[u]:
                    continue
                expanded[u] = du
                bits = moves[u]
                for m in range(num_moves):
                    if not (bits >> m) & 1:
                        continue
                    v = u + offsets[m]
                    dv = du + weights[m]
                    if dv < dist[v]:
                        dist[v] = dv
                        target = int(dv * per_bucket) & (ring - 1)
                        if count[target] == capacity:
                            return r
                        queue[target, count[target]] = v
                        count[target] += 1
                        pending += 1
            pending -= count[slot]
            count[slot] = 0
            bucket += 1
        for j in range(targets.size):
            out[r, j] = dist[targets[j]]
    return sources.size
