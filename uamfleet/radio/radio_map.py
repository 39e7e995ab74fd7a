"""Radio maps: an expected-SINR raster in an explicit world frame, and its block averages.

Frame: metres from the raster's first data point (min east, min north), x east, y north; arrays are indexed
``[ix, iy]`` (x first). The operating area is
the square ``[0, side_m]^2``. A raster value is the SINR at a cell *centre*; a point belongs to the cell whose
centre is nearest, with ties (a point exactly half-way) going to the higher index.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, cast

import numpy as np

from uamfleet.checks import check_size
from uamfleet.radio._sampling import segment_min_batch

NC_RULES: tuple[str, ...] = ("global_min", "nanmean")


def _finite(value: float, what: str) -> float:
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{what} must be a finite number, got {value!r}")
    return value


def _pair(value: Any, what: str) -> tuple[float, float]:
    try:
        a, b = value
    except (TypeError, ValueError):
        raise ValueError(f"{what} must be a pair (x_m, y_m), got {value!r}") from None
    return (_finite(a, what), _finite(b, what))


def _as_points(points: Any, what: str = "points") -> np.ndarray:
    arr = np.asarray(points, dtype=np.float64)
    if arr.ndim == 0 or arr.shape[-1] != 2:
        raise ValueError(f"{what} must have shape [..., 2] (x_m, y_m), got shape {arr.shape}")
    return arr


def _threshold(threshold_db: float) -> float:
    threshold_db = float(threshold_db)
    if math.isnan(threshold_db):
        raise ValueError("threshold_db is NaN; pass a threshold in dB such as -3.0")
    return threshold_db


def check_map_size(
    what: str, shape: tuple[int, ...], resolution_m: float, side_m: float | None, origin_m: tuple[float, float]
) -> None:
    """Refuse a map whose raster, area or origin is over the size limits (:data:`uamfleet.checks.SIZE_LIMITS`,
    docs/inputs.md "Size limits of maps"), before anything of that size is allocated: the raster's cells
    (``map_cells``), its span, ``side_m`` and the origin's distance from world (0, 0) (``scene_extent_m``), and the
    cells of a grid of ``resolution_m`` over the operating square ``[0, side_m]^2`` (``map_cells``), the finest
    block map and path graph the map allows. ``what`` names the map in the message; the numbers must be finite and
    positive (checked by the caller)."""
    cells = math.prod(int(n) for n in shape)
    check_size("map_cells", cells, f"{what} (a {' x '.join(str(int(n)) for n in shape)} raster)", 8)
    span = max(int(n) - 1 for n in shape) * resolution_m if shape else 0.0
    check_size("scene_extent_m", span, f"{what} (its raster of {resolution_m:g} m cells spans {span:g} m)")
    if side_m is None:
        side_m = min(int(n) - 1 for n in shape) * resolution_m if shape else 0.0
    check_size("scene_extent_m", side_m, f"{what} (side_m={side_m:g})")
    far = max(abs(origin_m[0]), abs(origin_m[1]))
    check_size("scene_extent_m", far, f"{what} (origin_m=({origin_m[0]:g}, {origin_m[1]:g}) lies {far:g} m out)")
    n = math.ceil(side_m / resolution_m - 1e-9) + 1
    check_size(
        "map_cells",
        float(n) * n,
        f"{what} (side_m={side_m:g} at resolution_m={resolution_m:g}: block maps and path graphs of {n:,} x {n:,} "
        "cells)",
        8,
    )


def _read_only(arr: np.ndarray) -> np.ndarray:
    arr.setflags(write=False)
    return arr


@dataclass(frozen=True)
class BaseStation:
    """A ground base station (GBS) in the world frame."""

    x_m: float
    y_m: float
    height_m: float
    power_dbm: float = 40.0
    frequency_mhz: float = 2000.0
    loading: float = 1.0  # probability that the GBS reuses the band (paper Eq. 6, l_m)
    name: str = ""

    def __post_init__(self) -> None:
        for attr in ("x_m", "y_m", "height_m", "power_dbm", "frequency_mhz", "loading"):
            object.__setattr__(self, attr, _finite(getattr(self, attr), f"BaseStation.{attr}"))
        if self.frequency_mhz <= 0:
            raise ValueError(f"BaseStation.frequency_mhz must be > 0, got {self.frequency_mhz}")
        if not 0.0 <= self.loading <= 1.0:
            raise ValueError(f"BaseStation.loading must lie in [0, 1] (a probability), got {self.loading}")


def base_station_tuple(base_stations: Any, if_empty: str = "pass at least one BaseStation") -> tuple[BaseStation, ...]:
    """``base_stations`` as a non-empty tuple of :class:`BaseStation`; a ValueError naming the fix otherwise."""
    stations = tuple(base_stations)
    if not stations:
        raise ValueError(f"base_stations is empty; {if_empty}")
    for bs in stations:
        if not isinstance(bs, BaseStation):
            raise ValueError(f"base_stations must hold BaseStation objects, got {type(bs).__name__}")
    return stations


@dataclass(frozen=True, eq=False)
class BlockMap:
    """Block-mean SINR over ``[0, side_m]^2``; block ``(bx, by)`` covers ``[bx*block_m, (bx+1)*block_m)``
    (the last block per axis is cut at ``side_m``)."""

    sinr_db: np.ndarray  # [nbx, nby] block means in dB, NaN = no computed point in the block
    block_m: float
    side_m: float

    def __post_init__(self) -> None:
        arr = np.array(self.sinr_db, dtype=np.float64)
        if arr.ndim != 2 or 0 in arr.shape:
            raise ValueError(f"BlockMap.sinr_db must be a non-empty 2-D array [nbx, nby], got shape {arr.shape}")
        object.__setattr__(self, "sinr_db", _read_only(arr))
        block_m = _finite(self.block_m, "block_m")
        side_m = _finite(self.side_m, "side_m")
        if block_m <= 0 or side_m <= 0:
            raise ValueError(f"block_m and side_m must be > 0, got block_m={block_m}, side_m={side_m}")
        object.__setattr__(self, "block_m", block_m)
        object.__setattr__(self, "side_m", side_m)

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.sinr_db.setflags(write=False)

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.sinr_db.shape[0]), int(self.sinr_db.shape[1]))

    def __repr__(self) -> str:
        return f"BlockMap(shape={self.shape}, block_m={self.block_m:g}, side_m={self.side_m:g})"

    def block_index(self, points: Any) -> tuple[np.ndarray, np.ndarray]:
        """``floor(coordinate / block_m)`` clipped to ``[0, nb - 1]`` (``x == side_m``: the last block)."""
        pts = _as_points(points)
        nbx, nby = self.shape
        with np.errstate(invalid="ignore"):
            fx = np.nan_to_num(np.floor(pts[..., 0] / self.block_m), nan=0.0, posinf=nbx, neginf=0.0)
            fy = np.nan_to_num(np.floor(pts[..., 1] / self.block_m), nan=0.0, posinf=nby, neginf=0.0)
        bx = np.clip(fx, 0, nbx - 1).astype(np.intp)
        by = np.clip(fy, 0, nby - 1).astype(np.intp)
        return bx, by

    def inside(self, points: Any) -> np.ndarray:
        """bool [...]: the point lies in the closed operating square ``[0, side_m]^2``."""
        pts = _as_points(points)
        x, y = pts[..., 0], pts[..., 1]
        return (x >= 0) & (x <= self.side_m) & (y >= 0) & (y <= self.side_m)

    def sinr_at(self, points: Any) -> np.ndarray:
        """Block SINR [...] in dB; NaN outside ``[0, side_m]^2`` (never the clipped edge block)."""
        bx, by = self.block_index(points)
        return np.where(self.inside(points), self.sinr_db[bx, by], np.nan)

    def feasible(self, points: Any, threshold_db: float) -> np.ndarray:
        """bool [...]: inside ``[0, side_m]^2`` and block SINR >= threshold (NaN blocks are infeasible)."""
        return self.sinr_at(points) >= _threshold(threshold_db)


def _checked_raster(sinr_db: Any, what: str) -> np.ndarray:
    """A private float64 copy of ``sinr_db``: a non-empty 2-D array without ±inf, within the map-cell size limit."""
    declared = np.shape(sinr_db) if isinstance(sinr_db, np.ndarray) else None
    if declared is not None and len(declared) == 2:  # before the private copy below
        check_size("map_cells", math.prod(declared), f"{what} (a {declared[0]} x {declared[1]} raster)", 8)
    arr = np.array(sinr_db, dtype=np.float64)  # a private copy: the caller's array stays theirs
    if arr.ndim != 2 or 0 in arr.shape:
        raise ValueError(f"RadioMap.sinr_db must be a non-empty 2-D array [nx, ny], got shape {arr.shape}")
    if np.isinf(arr).any():
        raise ValueError("RadioMap.sinr_db contains ±inf; use finite dB values, or NaN for not-computed cells")
    return arr


def _checked_side(side_m: float | None, shape: tuple[int, ...], res: float) -> float:
    """The side of the operating square: ``side_m``, or inferred from the raster's ``shape`` when None; > 0."""
    if side_m is None:
        side = min(n - 1 for n in shape) * res
        if side <= 0:
            raise ValueError(
                f"cannot infer side_m from a raster of shape {shape} (needs >= 2 points per axis); "
                "pass side_m explicitly"
            )
    else:
        side = _finite(side_m, "side_m")
        if side <= 0:
            raise ValueError(f"side_m must be > 0, got {side}")
    return side


def _checked_stations(base_stations: Any) -> tuple[BaseStation, ...]:
    """``base_stations`` as a tuple of :class:`BaseStation` objects."""
    stations = tuple(base_stations)
    for bs in stations:
        if not isinstance(bs, BaseStation):
            raise ValueError(f"base_stations must hold BaseStation objects, got {type(bs).__name__}")
    return stations


@dataclass(frozen=True, eq=False)
class RadioMap:
    """Expected SINR (dB) at flight altitude on a regular raster of cell centres.

    ``sinr_db[ix, iy]`` is the value at world point ``origin_m + (ix, iy) * resolution_m``; NaN marks cells
    the planner did not compute (WinProp "N.C."), treated as outage everywhere. Immutable: the array is
    read-only and derived tables (block maps, heading tables) are cached on the instance.
    """

    sinr_db: np.ndarray  # [nx, ny] dB at cell centres, NaN = not computed
    resolution_m: float
    origin_m: tuple[float, float] = (0.0, 0.0)  # world coordinates of the centre of cell [0, 0]
    side_m: float | None = None  # None -> min((n - 1) * resolution_m) over both axes
    name: str = ""
    is_estimate: bool = False
    altitude_m: float = 100.0
    base_stations: tuple[BaseStation, ...] = ()
    utm_origin_m: tuple[float, float] | None = None  # UTM (E, N) of world (0, 0), when known
    source: str = ""
    _cache: dict[tuple[Any, ...], Any] = field(default_factory=dict, init=False, repr=False, compare=False)

    def __post_init__(self) -> None:
        what = f"radio map {self.name!r}" if self.name else "RadioMap"
        arr = _checked_raster(self.sinr_db, what)
        object.__setattr__(self, "sinr_db", _read_only(arr))
        res = _finite(self.resolution_m, "resolution_m")
        if res <= 0:
            raise ValueError(f"resolution_m must be > 0, got {res}")
        object.__setattr__(self, "resolution_m", res)
        object.__setattr__(self, "origin_m", _pair(self.origin_m, "origin_m"))
        side = _checked_side(self.side_m, arr.shape, res)
        check_map_size(what, arr.shape, res, side, self.origin_m)
        object.__setattr__(self, "side_m", side)
        object.__setattr__(self, "altitude_m", _finite(self.altitude_m, "altitude_m"))
        if self.utm_origin_m is not None:
            object.__setattr__(self, "utm_origin_m", _pair(self.utm_origin_m, "utm_origin_m"))
        object.__setattr__(self, "base_stations", _checked_stations(self.base_stations))
        object.__setattr__(self, "is_estimate", bool(self.is_estimate))

    # -- pickling (envs in subprocesses): drop the caches, keep the array read-only -------------------------
    def __getstate__(self) -> dict[str, Any]:
        return {**self.__dict__, "_cache": {}}

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        self.sinr_db.setflags(write=False)

    # -- description ---------------------------------------------------------------------------------------
    @property
    def _side(self) -> float:
        # side_m is always set by __post_init__; it is typed Optional only for the constructor.
        return cast(float, self.side_m)

    @property
    def shape(self) -> tuple[int, int]:
        return (int(self.sinr_db.shape[0]), int(self.sinr_db.shape[1]))

    @property
    def label(self) -> str:
        return self.name + (" (estimate)" if self.is_estimate else "")

    def __repr__(self) -> str:
        return (
            f"RadioMap({self.label!r}, shape={self.shape}, resolution_m={self.resolution_m:g}, "
            f"side_m={self.side_m:g}, origin_m={self.origin_m}, altitude_m={self.altitude_m:g}, "
            f"base_stations={len(self.base_stations)}, is_estimate={self.is_estimate})"
        )

    # -- point queries ---------------------------------------------------------------------------------------
    def cell_index(self, points: Any) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Nearest cell centre of each point ``[..., 2]``.

        Returns ``(ix, iy, inside)``; ``inside`` is False for points outside the raster (further than half
        a cell beyond the outer centres) or non-finite. ``ix, iy`` are clipped into the raster so they can
        always index ``sinr_db``; use ``inside`` to tell whether they are meaningful.
        """
        pts = _as_points(points)
        nx, ny = self.shape
        ox, oy = self.origin_m
        with np.errstate(invalid="ignore"):
            # floor(f + 0.5): a point exactly between two centres goes to the higher index (np.rint would
            # round half to even, which makes the owner of a boundary depend on the parity of the index).
            fx = np.floor((pts[..., 0] - ox) / self.resolution_m + 0.5)
            fy = np.floor((pts[..., 1] - oy) / self.resolution_m + 0.5)
            inside = (fx >= 0) & (fx < nx) & (fy >= 0) & (fy < ny)
        ix = np.where(inside, fx, 0).astype(np.intp)
        iy = np.where(inside, fy, 0).astype(np.intp)
        return ix, iy, inside

    def sinr_at(self, points: Any) -> np.ndarray:
        """SINR [...] in dB of the nearest cell; NaN outside the raster or where not computed."""
        ix, iy, inside = self.cell_index(points)
        return np.where(inside, self.sinr_db[ix, iy], np.nan)

    def feasible(self, points: Any, threshold_db: float) -> np.ndarray:
        """bool [...]: ``sinr_at(points) >= threshold_db``; NaN (outside / not computed) is infeasible."""
        return self.sinr_at(points) >= _threshold(threshold_db)

    # -- segment queries -------------------------------------------------------------------------------------
    def _num_samples(self, length_m: np.ndarray) -> np.ndarray:
        # Samples spaced <= resolution_m, both endpoints included. The 1e-9 slack keeps a segment whose length
        # is a whole number of cells up to round-off (e.g. 100 * hypot(cos, sin)) at exactly that many gaps,
        # so that heading_segment_min_sinr and segment_min_sinr agree sample for sample.
        gaps = np.ceil(length_m / self.resolution_m - 1e-9)
        return np.maximum(gaps, 1).astype(np.intp) + 1

    def segment_min_sinr(self, p0: Any, p1: Any) -> np.ndarray:
        """Minimum SINR [...] (dB) along straight segments ``p0 -> p1`` (each ``[..., 2]``, broadcast).

        Samples are spaced evenly, at most ``resolution_m`` apart, both endpoints included, each read from its
        nearest cell. Returns ``-inf`` where any sample is outside the raster or not computed.
        """
        a, b = np.broadcast_arrays(_as_points(p0, "p0"), _as_points(p1, "p1"))
        if not (np.isfinite(a).all() and np.isfinite(b).all()):
            raise ValueError("segment endpoints p0, p1 must be finite coordinates in metres")
        flat_a = np.ascontiguousarray(a.reshape(-1, 2), dtype=np.float64)
        flat_b = np.ascontiguousarray(b.reshape(-1, 2), dtype=np.float64)
        ox, oy = self.origin_m
        out = segment_min_batch(self.sinr_db, ox, oy, self.resolution_m, flat_a, flat_b)
        return out.reshape(a.shape[:-1])

    def segment_feasible(self, p0: Any, p1: Any, threshold_db: float) -> np.ndarray:
        """bool [...]: every sample along the segment has SINR >= threshold_db (see segment_min_sinr)."""
        return self.segment_min_sinr(p0, p1) >= _threshold(threshold_db)

    def heading_segment_min_sinr(self, step_m: float, num_headings: int = 16) -> np.ndarray:
        """``[num_headings, nx, ny]``: min SINR along the segment that starts at each cell centre and goes
        ``step_m`` along heading k (angle ``2*pi*k/num_headings`` counter-clockwise from east).

        Same sampling as :meth:`segment_min_sinr` (``-inf`` if any sample is outside the raster or not
        computed). For a point that is not a cell centre this is an approximation within half a cell; use
        ``segment_min_sinr`` for exact positions. Cached per (step_m, num_headings); the result is
        read-only.
        """
        step_m = _finite(step_m, "step_m")
        if step_m <= 0:
            raise ValueError(f"step_m must be > 0, got {step_m}")
        if int(num_headings) != num_headings or num_headings < 1:
            raise ValueError(f"num_headings must be a positive integer, got {num_headings!r}")
        if num_headings > 360:
            raise ValueError(f"num_headings={num_headings!r} is too large: at most 360 (the env flies 16)")
        nx, ny = self.shape
        pad = math.ceil(step_m / self.resolution_m) + 1  # the raster is padded by the longest shift of a sample
        what = f"the heading table of {self.label or 'a radio map'!r} (step_m={step_m:g}: a raster padded by {pad:,})"
        check_size("map_cells", float(nx + 2 * pad) * (ny + 2 * pad), what, 8)
        key = ("heading", step_m, int(num_headings))
        if key not in self._cache:
            self._cache[key] = _read_only(self._heading_table(step_m, int(num_headings)))
        return self._cache[key]

    def _heading_table(self, step_m: float, num_headings: int) -> np.ndarray:
        nx, ny = self.shape
        res = self.resolution_m
        n = int(self._num_samples(np.array(step_m)))
        t = np.minimum(np.arange(n) / (n - 1), 1.0)
        # A sample at centre + t*d lies in cell (ix + di, iy + dj) with di = floor(t*dx/res + 0.5): the shift
        # is the same for every start cell, so each heading is a min over a few shifted copies of the raster.
        shifts: list[set[tuple[int, int]]] = []
        for k in range(num_headings):
            theta = 2.0 * math.pi * k / num_headings
            dx, dy = step_m * math.cos(theta), step_m * math.sin(theta)
            shifts.append({(math.floor(tk * dx / res + 0.5), math.floor(tk * dy / res + 0.5)) for tk in t})
        pad = max(max(abs(di), abs(dj)) for s in shifts for di, dj in s)
        padded = np.full((nx + 2 * pad, ny + 2 * pad), -np.inf)
        padded[pad : pad + nx, pad : pad + ny] = np.where(np.isnan(self.sinr_db), -np.inf, self.sinr_db)
        out = np.empty((num_headings, nx, ny))
        for k, s in enumerate(shifts):
            out[k] = np.inf
            for di, dj in s:
                np.minimum(out[k], padded[pad + di : pad + di + nx, pad + dj : pad + dj + ny], out=out[k])
        return out

    # -- block averages --------------------------------------------------------------------------------------
    def block_map(self, block_m: float, nc_rule: str = "global_min") -> BlockMap:
        """Mean of the dB values of the raster points whose centres fall in each block of side ``block_m``.

        Blocks tile ``[0, side_m]^2``: ``nb = ceil(side_m / block_m)`` per axis, the last one cut at side_m;
        raster points with a coordinate < 0 or >= side_m are left out. ``nc_rule``: ``"global_min"`` replaces
        not-computed cells by the raster's global minimum first (the original code's rule); ``"nanmean"``
        ignores them. A block with no usable point is NaN. Cached per (block_m, nc_rule).
        """
        if nc_rule not in NC_RULES:
            raise ValueError(f"unknown nc_rule {nc_rule!r}; choose one of {', '.join(map(repr, NC_RULES))}")
        block_m = _finite(block_m, "block_m")
        if block_m <= 0:
            raise ValueError(f"block_m must be > 0, got {block_m}")
        nb = math.ceil(self._side / block_m - 1e-9)
        what = f"the block map of {self.label or 'a radio map'!r} ({nb:,} x {nb:,} blocks of {block_m:g} m)"
        check_size("map_cells", float(nb) * nb, what, 8)
        key = ("block", block_m, nc_rule)
        if key not in self._cache:
            self._cache[key] = self._block_map(block_m, nc_rule)
        return self._cache[key]

    def _block_axis(self, axis: int, block_m: float) -> tuple[np.ndarray, np.ndarray]:
        # The raster is separable: a cell's block index per axis depends only on its index along that axis.
        centres = self.origin_m[axis] + np.arange(self.shape[axis]) * self.resolution_m
        valid = (centres >= 0) & (centres < self._side)
        return np.floor(centres / block_m).astype(np.intp), valid

    def _block_map(self, block_m: float, nc_rule: str) -> BlockMap:
        nb = math.ceil(self._side / block_m - 1e-9)
        bx, vx = self._block_axis(0, block_m)
        by, vy = self._block_axis(1, block_m)
        values = self.sinr_db
        computed = ~np.isnan(values)
        if nc_rule == "global_min" and computed.any():
            values = np.where(computed, values, values[computed].min())
            computed = np.ones_like(computed)
        use = vx[:, None] & vy[None, :] & computed
        flat = (bx[:, None] * nb + by[None, :])[use]
        sums = np.bincount(flat, weights=values[use], minlength=nb * nb)
        counts = np.bincount(flat, minlength=nb * nb)
        with np.errstate(invalid="ignore", divide="ignore"):
            means = np.where(counts > 0, sums / counts, np.nan)
        return BlockMap(means.reshape(nb, nb), block_m, self._side)
