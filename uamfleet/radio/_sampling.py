"""Compiled sampling of a raster along straight segments: the one implementation used by
:meth:`RadioMap.segment_min_sinr` and by the environment kernels (moves, SINR events)."""

from __future__ import annotations

import math

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def cell_of(v: float, origin: float, res: float, n: int) -> int:
    """Nearest cell along one axis, -1 outside (a point half-way between centres goes to the higher index)."""
    c = math.floor((v - origin) / res + 0.5)
    if c < 0 or c >= n:
        return -1
    return c


@njit(cache=True)
def segment_min(
    raster: np.ndarray, ox: float, oy: float, res: float, x0: float, y0: float, x1: float, y1: float
) -> float:
    """Min of ``raster`` over samples spaced evenly at most ``res`` apart along (x0, y0) -> (x1, y1), both ends
    included, each read from its nearest cell; -inf when a sample is outside the raster or not computed (NaN).
    The 1e-9 slack keeps a segment whose length is a whole number of cells up to round-off at that many gaps."""
    nx, ny = raster.shape
    length = math.sqrt((x1 - x0) ** 2 + (y1 - y0) ** 2)
    gaps = max(math.ceil(length / res - 1e-9), 1)
    best = np.inf
    for j in range(gaps + 1):
        t = j / gaps
        ix = cell_of((1.0 - t) * x0 + t * x1, ox, res, nx)
        iy = cell_of((1.0 - t) * y0 + t * y1, oy, res, ny)
        if ix < 0 or iy < 0:
            return -np.inf
        v = raster[ix, iy]
        if math.isnan(v):
            return -np.inf
        best = min(best, v)
    return best


@njit(cache=True)
def segment_min_batch(
    raster: np.ndarray, ox: float, oy: float, res: float, p0: np.ndarray, p1: np.ndarray
) -> np.ndarray:
    """[N] :func:`segment_min` of each segment p0[i] -> p1[i] (each [N, 2])."""
    out = np.empty(p0.shape[0])
    for i in range(p0.shape[0]):
        out[i] = segment_min(raster, ox, oy, res, p0[i, 0], p0[i, 1], p1[i, 0], p1[i, 1])
    return out
