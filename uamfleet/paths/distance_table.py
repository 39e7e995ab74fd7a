"""A table of feasible-path distances between block centres, looked up inside compiled kernels.

:class:`~uamfleet.paths.DistanceFields` runs one Dijkstra per goal, in Python, and evaluates it in Python. That is
fine for a fixed instance (a dozen stops, fields cached) but not for random demand, where every episode brings
new stops: the shaping potential then took ~99 % of a step (issue 12). The table moves the graph work out of
the step and the lookup into numba:

- **Nodes**: one per block of the world's block grid (``block_m``, the step by default), at the block centre
  ``((bx + 0.5) * block_m, (by + 0.5) * block_m)``, flat index ``bx * nby + by``. Its graph node is the raster
  cell nearest the centre or, when that cell is not flyable, the nearest flyable cell within the graph's
  ``snap_m`` (the gap counts as a straight piece); a block with none has no paths. Where the map's side is no
  whole number of blocks, the outer centres lie off the map: theirs is looked up from the centre moved onto the
  map's edge.
- **Entries**: ``distance_m[i, j]`` = gap_i + lattice distance on the raster graph of
  :func:`~uamfleet.paths.graph_for` (16-connected, 10 m cells on the packaged maps; on a raster much finer than
  the blocks, a coarser one: :func:`table_graph`) + gap_j, float32; ``inf`` where no feasible path joins them.
  Row i is one Dijkstra from node i (:func:`~uamfleet.paths.bucket_dijkstra.lattice_distances`, compiled: the
  same float64 numbers as ``scipy.sparse.csgraph.dijkstra``, ~10 x faster).
- **Rows on demand**: a row is computed the first time a stop needs it (:meth:`DistanceTable.ensure`, called
  when an instance is written), so a fixed instance costs a few Dijkstras and random demand fills the table
  over its first episodes (Berlin, 33 x 33 blocks: 1,089 rows, 4.7 MB, ~2.5 s in all on one core;
  :meth:`DistanceTable.fill` computes every row at once). Entries never change once computed, so the same
  state always gets the same distance, whenever its rows were filled. Tables are cached per (map, threshold,
  rule, block size), like the graphs.
- **On disk**: a table completed by :meth:`DistanceTable.fill` is saved under :func:`cache_dir`
  (``$UAMFLEET_CACHE``, default ``~/.cache/uamfleet``; ``UAMFLEET_CACHE=off`` disables it), named by a hash of
  everything its entries depend on (the key: the graph's flyable cells, i.e. the map's content at this threshold
  and rule, its resolution and origin, the blocks, :data:`CACHE_FORMAT`); a later process with the same table
  loads it whole instead of running its Dijkstras again (training on random demand at five thresholds otherwise
  spends its first minutes filling tables). A cache file is an input like any other: it holds its key and a
  SHA-256 of its entries, and a loaded table must be plausible (:meth:`DistanceTable.implausible`: finite exactly
  between connected blocks, symmetric, the diagonal twice the centre's gap, never shorter than the straight
  line); a file failing any check is deleted with a warning and the rows are computed again.
- **Lookup** (:func:`table_distance`, compiled): from a point a to a stop b, the entries ``distance_m[j, i]``
  between the 4 block centres j around b (their rows) and the 4 around a, interpolated bilinearly in both
  points (16 entries), and at least ``|a - b|``. Bilinear interpolation is exact where the distance varies
  linearly (open ground, goal not too near), where a "best corner + straight piece" rule is up to ~50 m off.
  Corner pairs without a path are left out and the other weights renormalised; when no pair is joined, the
  lookup returns ``inf`` (unreachable). A row not computed yet reads NaN, and the lookup returns NaN, so a
  kernel can report it and its caller fill the rows and ask again.

It approximates :meth:`DistanceFields.remaining_m` (a 10 m field from the goal), ``tests/paths`` measure the
difference (docs/rules.md "Rewards").
"""

from __future__ import annotations

import hashlib
import io
import math
import os
import warnings
import weakref
import zipfile
from pathlib import Path
from typing import NamedTuple

import numpy as np
from numba import njit
from scipy.sparse import csgraph

from uamfleet.io import write_bytes_atomic
from uamfleet.paths.bucket_dijkstra import Lattice, lattice_distances, lattice_of
from uamfleet.paths.distance_fields import FlightGeometry, graph_for
from uamfleet.paths.grid_graph import GridGraph, feasible_raster
from uamfleet.radio import RadioMap

_CHUNK = 256  # Dijkstra sources per compiled call: [chunk, blocks] float64 rows (~2 MB on Berlin)
CACHE_FORMAT = 3  # raise when the entries' definition or the file changes: older files then no longer match
# 2: an .npz holding the key and a SHA-256 of the entries beside them (1: a bare .npy, trusted as it was)


def cache_dir() -> Path | None:
    """Where filled tables are kept: ``$UAMFLEET_CACHE`` (``off`` or empty: nowhere), else ``~/.cache/uamfleet``."""
    value = os.environ.get("UAMFLEET_CACHE")
    if value is not None:
        return None if value.strip().lower() in ("", "off", "0", "none") else Path(value)
    return Path.home() / ".cache" / "uamfleet"


class TableArrays(NamedTuple):
    """What the compiled lookups read of a :class:`DistanceTable`, passed to them whole (as
    :class:`~uamfleet.sim.arrays.WorldArrays` carries the world's arrays)."""

    distance_m: np.ndarray  # [nbx * nby, nbx * nby] float32, row j = distances to block centre j; NaN: not computed
    block_m: float
    nbx: int
    nby: int


class DistanceTable:
    """Feasible-path distances between the block centres of a ``shape`` grid of ``block_m`` blocks on
    ``graph`` (see the module docstring). Rows are computed on demand; read entries through :meth:`distance`
    or, in a kernel, :func:`table_distance` after :meth:`ensure`."""

    def __init__(self, graph: GridGraph, block_m: float, shape: tuple[int, int]) -> None:
        if not (math.isfinite(block_m) and block_m > 0):
            raise ValueError(f"block_m must be a finite number > 0 metres, got {block_m!r}")
        nbx, nby = (int(v) for v in shape)
        if nbx < 1 or nby < 1:
            raise ValueError(f"shape must be (nbx, nby) with both >= 1 blocks, got {shape!r}")
        self.graph = graph
        self.block_m = float(block_m)
        self.shape = (nbx, nby)
        self.label = graph.label
        bx, by = np.meshgrid(np.arange(nbx), np.arange(nby), indexing="ij")
        centres = np.stack([(bx.ravel() + 0.5) * block_m, (by.ravel() + 0.5) * block_m], axis=-1)  # [N, 2]
        self.nodes = np.full(len(centres), -1, dtype=np.intp)  # graph node of each block centre, -1: none
        self.gap_m = np.zeros(len(centres))  # straight piece from the centre to its node
        # The map's extent: a side that is no whole number of blocks (San Francisco's 920 m) leaves the last row and
        # column of centres off the map. Such a centre takes the node nearest to it moved onto the map, allowed
        # ``snap_m`` beyond that move: else a stop in the partial strip reads as unreachable where it is not.
        low = np.asarray(graph.origin_m) - graph.resolution_m / 2
        high = low + np.asarray(graph.shape) * graph.resolution_m
        for i, c in enumerate(centres):
            on_map = np.clip(c, low, high)
            node = graph.nearest_node(on_map)
            gap = float(np.hypot(*(graph.node_xy(node) - c)))
            if gap <= graph.snap_m + float(np.hypot(*(c - on_map))):
                self.nodes[i], self.gap_m[i] = node, gap
        # NaN marks rows not computed yet; the lookup refuses to read one.
        self.distance_m = np.full((len(centres), len(centres)), np.nan, dtype=np.float32)
        self.filled = np.zeros(len(centres), dtype=bool)
        # one object for the table's life (rows are written in place): the kernels' pre-typed entries know it
        self.arrays = TableArrays(self.distance_m, self.block_m, nbx, nby)
        self._lattice: Lattice | None = None  # the graph as moves, made on the first rows computed
        self._load_cached()

    @property
    def cache_key(self) -> str:
        """Hash of everything the entries depend on (the file name of the table on disk)."""
        g = self.graph
        digest = hashlib.sha1(np.packbits(g.feasible).tobytes())
        digest.update(repr((CACHE_FORMAT, g.shape, g.resolution_m, g.origin_m, g.connectivity, g.snap_m,
                            self.block_m, self.shape)).encode())  # fmt: skip
        return digest.hexdigest()

    def _cache_file(self) -> Path | None:
        folder = cache_dir()
        return None if folder is None else folder / f"table{CACHE_FORMAT}-{self.cache_key}.npz"

    def _load_cached(self) -> None:
        """Use the cached table when its key, checksum and entries all check out; else delete it and warn (the
        rows are then computed on demand, and :meth:`fill` writes a good file)."""
        path = self._cache_file()
        if path is None or not path.is_file():
            return
        try:
            with np.load(path, allow_pickle=False) as saved:
                key, checksum, table = str(saved["key"]), str(saved["sha256"]), saved["distance_m"]
        except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile) as err:  # truncated, not an npz, ...
            return self._reject(path, f"it cannot be read ({type(err).__name__}: {err})")
        if key != self.cache_key:
            return self._reject(path, f"it holds the key {key[:12]}..., not this table's {self.cache_key[:12]}...")
        if table.shape != self.distance_m.shape or table.dtype != np.float32:
            return self._reject(path, f"it holds a {table.dtype} table of shape {table.shape}")
        if hashlib.sha256(table.tobytes()).hexdigest() != checksum:
            return self._reject(path, "its entries do not match their SHA-256 checksum")
        why = self.implausible(table)
        if why:
            return self._reject(path, why)
        self.distance_m[:] = table
        self.filled[:] = True

    def _reject(self, path: Path, why: str) -> None:
        warnings.warn(
            f"the cached distance table {path} is not used: {why}; it is deleted and its rows are computed again.",
            RuntimeWarning,
            stacklevel=3,
        )
        path.unlink(missing_ok=True)

    def implausible(self, table: np.ndarray) -> str:
        """Why ``table`` (a complete ``distance_m``) cannot be this table's, or "" when it can: every entry is a
        number; finite exactly where the two blocks' nodes are connected in the graph; symmetric (the graph's
        edges are undirected); the diagonal is twice the block centre's gap to its node; no entry is shorter than
        the straight line between the two centres."""
        if np.isnan(table).any():
            return f"{int(np.isnan(table).sum())} entries are NaN (rows never computed)"
        labels = csgraph.connected_components(self.graph.adjacency, directed=False)[1]
        component = np.where(self.nodes >= 0, labels[np.maximum(self.nodes, 0)], -1)
        joined = (component[:, None] == component[None, :]) & (component[:, None] >= 0)
        finite = np.isfinite(table)
        if (finite != joined).any():
            wrong = int((finite != joined).sum())
            return f"{wrong} entries are finite where the blocks are not connected, or infinite where they are"
        if not np.allclose(table[finite], table.T[finite], rtol=1e-5, atol=1e-3):
            return "it is not symmetric"
        node = self.nodes >= 0
        if not np.allclose(np.diag(table)[node], 2.0 * self.gap_m[node], rtol=1e-5, atol=1e-3):
            return "its diagonal is not twice each block centre's gap to its node"
        nbx, nby = self.shape
        bx, by = np.divmod(np.arange(nbx * nby), nby)
        straight = self.block_m * np.hypot(bx[:, None] - bx[None, :], by[:, None] - by[None, :])
        if (table[finite] < straight[finite] * (1.0 - 1e-5) - 1e-3).any():
            return "some entries are shorter than the straight line between their block centres"
        return ""

    def __repr__(self) -> str:
        return (
            f"DistanceTable({self.label!r}, blocks={self.shape}, block_m={self.block_m:g}, "
            f"rows filled={int(self.filled.sum())}/{self.filled.size}, {self.distance_m.nbytes} B)"
        )

    def ensure(self, stops: np.ndarray) -> None:
        """Compute the rows that lookups towards ``stops`` ([..., 2] metres) read, if not done yet."""
        pts = np.ascontiguousarray(np.asarray(stops, dtype=np.float64).reshape(-1, 2))
        rows = np.empty((pts.shape[0], 4), dtype=np.int64)
        corner_rows(pts, self.arrays, rows)
        rows = np.unique(rows[rows >= 0])
        self._compute(rows[~self.filled[rows]])

    def fill(self) -> DistanceTable:
        """Compute every row now (e.g. before timing steps or training on random demand) and save the table to
        the disk cache (module docstring); returns self."""
        missing = np.flatnonzero(~self.filled)
        self._compute(missing)
        path = self._cache_file()
        if path is not None and (missing.size or not path.is_file()):
            buffer = io.BytesIO()
            checksum = hashlib.sha256(self.distance_m.tobytes()).hexdigest()
            np.savez(buffer, distance_m=self.distance_m, key=np.array(self.cache_key), sha256=np.array(checksum))
            try:
                write_bytes_atomic(path, buffer.getvalue())
            except OSError:
                pass  # a read-only home: the table is still complete in memory
        return self

    def _compute(self, rows: np.ndarray) -> None:
        if rows.size == 0:
            return
        cols = np.flatnonzero(self.nodes >= 0)
        self.distance_m[rows] = np.inf
        todo = rows[self.nodes[rows] >= 0]
        if self._lattice is None:  # the graph's own, built with it (lattice_of reads it back from the matrix)
            self._lattice = self.graph.lattice if self.graph.lattice is not None else lattice_of(self.graph.adjacency)
        for lo in range(0, todo.size, _CHUNK):
            chunk = todo[lo : lo + _CHUNK]
            lattice = lattice_distances(self._lattice, self.nodes[chunk], self.nodes[cols])
            d = self.gap_m[chunk, None] + lattice + self.gap_m[None, cols]
            self.distance_m[np.ix_(chunk, cols)] = d
        self.filled[rows] = True

    def distance(self, points: np.ndarray, stops: np.ndarray) -> np.ndarray:
        """[...] looked-up feasible-path distance (metres) from ``points`` to ``stops`` ([..., 2], broadcast);
        ``inf`` where no path joins them (module docstring)."""
        a, b = np.broadcast_arrays(np.asarray(points, np.float64), np.asarray(stops, np.float64))
        self.ensure(b)
        flat_a, flat_b = np.ascontiguousarray(a.reshape(-1, 2)), np.ascontiguousarray(b.reshape(-1, 2))
        out = np.empty(flat_a.shape[0])
        for i in range(out.size):
            out[i] = table_distance(self.arrays, flat_a[i, 0], flat_a[i, 1], flat_b[i, 0], flat_b[i, 1])
        return out.reshape(a.shape[:-1])


# Per radio map (weakly, so a map's tables go with it): (threshold, rule, block size) -> table.
_TABLES: weakref.WeakKeyDictionary[RadioMap, dict[tuple[float, str, float], DistanceTable]] = (
    weakref.WeakKeyDictionary()
)


def table_for(world: FlightGeometry) -> DistanceTable:
    """The distance table of the world's map, threshold, rule and block size (cached; rows filled on demand)."""
    cfg = world.cfg
    tables = _TABLES.setdefault(world.radio, {})
    key = (world.threshold_db, cfg.feasibility, float(world.blocks.block_m))
    if key not in tables:
        tables[key] = DistanceTable(table_graph(world), float(world.blocks.block_m), world.blocks.shape)
    return tables[key]


MAX_CELLS_PER_BLOCK = 12
"""Above this many raster cells per block side, the table is computed on a coarser raster (see :func:`table_graph`)."""
COARSE_CELLS_PER_BLOCK = 9


def table_graph(world: FlightGeometry) -> GridGraph:
    """The raster graph the table's rows are computed on.

    The world's own graph (:func:`graph_for`, the one ``path_exact`` uses) when a block side holds at most
    :data:`MAX_CELLS_PER_BLOCK` raster cells (Berlin: 10). On a finer raster (Detroit 3GPP: 10 m cells, 320 m
    blocks, 1.2 M nodes, ~0.3 s per Dijkstra) a graph of :data:`COARSE_CELLS_PER_BLOCK` cells per block side
    (odd, so a block centre is a cell centre; 99 k nodes on Detroit), each cell inside one block: flyable under
    ``endpoint_block`` when its block is, under ``segment_raster`` when every raster cell centred in it is.
    """
    res, block_m = float(world.radio.resolution_m), float(world.blocks.block_m)
    if block_m / res <= MAX_CELLS_PER_BLOCK:
        return graph_for(world)
    cell = block_m / COARSE_CELLS_PER_BLOCK
    side = float(world.blocks.side_m)
    n = math.ceil(side / cell - 1e-9)
    axis = (np.arange(n) + 0.5) * cell
    centres = np.stack(np.meshgrid(axis, axis, indexing="ij"), axis=-1)  # [n, n, 2]
    inside = np.all(centres <= side, axis=-1)
    if world.cfg.feasibility == "endpoint_block":
        feasible = inside & world.blocks.feasible(centres, world.threshold_db)
    else:
        fine = feasible_raster(world.radio, world.threshold_db)  # [nx, ny]
        ox, oy = world.radio.origin_m
        kx = np.floor((ox + np.arange(fine.shape[0]) * res) / cell).astype(np.intp)
        ky = np.floor((oy + np.arange(fine.shape[1]) * res) / cell).astype(np.intp)
        kx2, ky2 = np.meshgrid(kx, ky, indexing="ij")
        ok = (kx2 >= 0) & (kx2 < n) & (ky2 >= 0) & (ky2 < n)
        ids = (kx2 * n + ky2)[ok]
        count = np.bincount(ids, minlength=n * n)
        count_ok = np.bincount(ids, weights=fine[ok], minlength=n * n)
        feasible = inside & ((count > 0) & (count_ok == count)).reshape(n, n)
    label = f"{world.radio.label} at sinr_min_db={world.threshold_db:g} dB, {cell:.3g} m cells"
    return GridGraph(feasible, cell, origin_m=(cell / 2, cell / 2), label=label)


@njit(cache=True, inline="always")
def _axis(v: float, block_m: float, nb: int) -> tuple[int, float]:
    """Lower corner (block centre index) around coordinate v and the weight of the upper one, clamped to the
    grid (a point beyond the outer centres takes the outer centre's value)."""
    if nb == 1:
        return 0, 0.0
    f = v / block_m - 0.5
    i = min(max(math.floor(f), 0), nb - 2)
    return i, min(max(f - i, 0.0), 1.0)


@njit(cache=True)
def corner_rows(points: np.ndarray, t: TableArrays, out: np.ndarray) -> None:
    """out[k] = the table rows (block centres) a lookup towards points[k] reads; -1 fills the rest of the 4."""
    corners = new_corners(1)
    for k in range(points.shape[0]):
        prepare_corners(t, points[k, 0], points[k, 1], corners, 0)
        out[k] = -1
        out[k, : corners.used[0]] = corners.cells[0, : corners.used[0]]


@njit(cache=True)
def table_distance(t: TableArrays, ax: float, ay: float, bx: float, by: float) -> float:
    """Distance (metres) from point a to stop b in a :class:`DistanceTable` (its :class:`TableArrays`): bilinear
    in both points over the corner pairs that are joined (weights renormalised), at least ``|a - b|``; ``inf``
    when no pair is joined; NaN when a row of b's corners is not computed yet (:meth:`DistanceTable.ensure`)."""
    table, block_m, nbx, nby = t.distance_m, t.block_m, t.nbx, t.nby
    iax, tax = _axis(ax, block_m, nbx)
    iay, tay = _axis(ay, block_m, nby)
    ibx, tbx = _axis(bx, block_m, nbx)
    iby, tby = _axis(by, block_m, nby)
    total = 0.0
    weight = 0.0
    for cb in range(4):
        wb = (tbx if cb & 1 else 1.0 - tbx) * (tby if cb & 2 else 1.0 - tby)
        if wb == 0.0:
            continue
        row = table[(ibx + (cb & 1)) * nby + iby + (cb >> 1)]
        for ca in range(4):
            wa = (tax if ca & 1 else 1.0 - tax) * (tay if ca & 2 else 1.0 - tay)
            if wa == 0.0:
                continue
            d = row[(iax + (ca & 1)) * nby + iay + (ca >> 1)]
            if math.isnan(d):
                return math.nan  # a row not computed yet: the caller ensures it and asks again
            if d < math.inf:
                total += wa * wb * d
                weight += wa * wb
    return _interpolated(total, weight, ax, ay, bx, by)


@njit(cache=True, inline="always")
def _interpolated(total: float, weight: float, ax: float, ay: float, bx: float, by: float) -> float:
    """The lookup's value from its weighted sum over the joined corner pairs: inf when none is joined, never below
    the straight line from a to b."""
    if weight == 0.0:
        return math.inf
    dx, dy = ax - bx, ay - by
    return max(total / weight, math.sqrt(dx * dx + dy * dy))


class Corners(NamedTuple):
    """Points prepared for many lookups (:func:`prepare_corners`, :func:`corner_distance`): slot k holds the block
    centres a lookup from or to point k reads, with their bilinear weights, in the order :func:`table_distance`
    reads them and without the zero-weight ones."""

    cells: np.ndarray  # [K, 4] int64 flat block-centre indices
    weights: np.ndarray  # [K, 4] float64
    used: np.ndarray  # [K] int64 how many of the 4 are used


@njit(cache=True)
def new_corners(slots: int) -> Corners:
    """Room for ``slots`` prepared points."""
    return Corners(np.empty((slots, 4), np.int64), np.empty((slots, 4)), np.zeros(slots, np.int64))


@njit(cache=True, inline="always")
def prepare_corners(t: TableArrays, x: float, y: float, c: Corners, k: int) -> None:
    """Prepare point (x, y) in slot k of ``c`` (what :func:`table_distance` computes of it on every call)."""
    ix, tx = _axis(x, t.block_m, t.nbx)
    iy, ty = _axis(y, t.block_m, t.nby)
    n = 0
    for corner in range(4):
        w = (tx if corner & 1 else 1.0 - tx) * (ty if corner & 2 else 1.0 - ty)
        if w == 0.0:
            continue
        c.cells[k, n], c.weights[k, n] = (ix + (corner & 1)) * t.nby + iy + (corner >> 1), w
        n += 1
    c.used[k] = n


@njit(cache=True, inline="always")
def corner_distance(
    t: TableArrays, a: Corners, i: int, b: Corners, j: int, ax: float, ay: float, bx: float, by: float
) -> float:
    """:func:`table_distance` from point a = (ax, ay), prepared in slot i of ``a``, to stop b = (bx, by), prepared
    in slot j of ``b``: the same number from the same float operations, a few times faster where each point is
    looked up often (a taxi's move ends towards each of its stops)."""
    table = t.distance_m
    total = 0.0
    weight = 0.0
    for cb in range(b.used[j]):
        row = b.cells[j, cb]  # a 2-D read below, not a row view: a view costs a reference count per call
        wb = b.weights[j, cb]
        for ca in range(a.used[i]):
            d = table[row, a.cells[i, ca]]
            if math.isnan(d):
                return math.nan  # a row not computed yet: the caller ensures it and asks again
            if d < math.inf:
                wa = a.weights[i, ca]
                total += wa * wb * d
                weight += wa * wb
    return _interpolated(total, weight, ax, ay, bx, by)


class MissingTableRow(RuntimeError):
    """A compiled observation kernel read a row of this table that its component's ``prepare`` did not compute:
    a bug (every existing stop's rows are filled before the kernels run), never a branch to retry."""

    def __init__(self, kernel: str) -> None:
        super().__init__(
            f"{kernel} read a distance-table row that the stop features' prepare() did not compute: a bug in "
            "uamfleet.observe (every existing stop's rows are filled before the kernels run)."
        )
