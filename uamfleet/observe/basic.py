"""The always-on observation fields (compiled): each taxi's own row, its history and allowed headings, the
passenger rows, the other taxis, the SINR and visit patches (:func:`observe`), and the hover heading
(:func:`hover_headings`); docs/rules.md "Observation". :class:`uamfleet.observe.observer.Observer` is their entry
point.

The boundary is typed: a kernel takes the state whole (:class:`uamfleet.types.FleetState`) and the world's arrays
whole (:class:`uamfleet.sim.arrays.WorldArrays`), NamedTuples of arrays, which numba compiles field by field.

Why compiled: a step is a few dozen small operations per taxi. As numpy calls each costs microseconds of
overhead, which capped a one-env step at ~1.7k steps/s; as one loop it is memory-bound and fast for any
batch size. ``cache=True`` stores the machine code next to this file, so only the first run compiles.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from uamfleet.sim.arrays import WorldArrays
from uamfleet.sim.motion import block_of
from uamfleet.types import (
    DELIVERED,
    HIDDEN,
    HIST_DX,
    HIST_DY,
    HIST_FREE_SEATS,
    NUM_HEADINGS,
    NUM_PASSENGER_FEATURES,
    ON_BOARD,
    OTHER_DX,
    OTHER_DY,
    OTHER_FREE_SEATS,
    PAX_AGE,
    PAX_DELIVERED,
    PAX_DEST_DX,
    PAX_DEST_DY,
    PAX_DIST_TO_DEST,
    PAX_DIST_TO_ORIGIN,
    PAX_ON_BOARD_OTHER,
    PAX_ON_BOARD_SELF,
    PAX_ORIGIN_DX,
    PAX_ORIGIN_DY,
    PAX_TRIP_LENGTH,
    PAX_WAITING,
    SELF_FREE_SEATS,
    SELF_TIME,
    SELF_X,
    SELF_Y,
    WAITING,
    FleetState,
)

__all__ = ["hover_headings", "observe"]


@njit(cache=True)
def observe(
    s: FleetState,
    w: WorldArrays,
    # outputs, [E, A, ...] (the fields of the observation dict)
    o_self: np.ndarray,  # [E, A, len(SELF_FEATURES)]
    o_history: np.ndarray,  # [E, A, H, len(HISTORY_FEATURES)]
    o_pax: np.ndarray,  # [E, A, P, NUM_PASSENGER_FEATURES]
    o_pax_mask: np.ndarray,  # [E, A, P] int8
    o_sinr: np.ndarray,  # [E, A, k, k]
    o_visit: np.ndarray,  # [E, A, k, k]
    o_others: np.ndarray,  # [E, A, max(A-1, 1), len(OTHER_FEATURES)]
    o_others_mask: np.ndarray,  # [E, A, max(A-1, 1)] int8
    o_mask: np.ndarray,  # [E, A, NUM_HEADINGS] int8
) -> None:
    """The observation of every taxi (docs/rules.md "Observation"), written into the ``o_*`` arrays (C-contiguous:
    the patches are written through flat views of them). Each part is one pass over all envs and taxis: a call
    per taxi would pass (and reference-count) every array of the state each time, ten times the work."""
    _observe_own(s, w, o_self, o_history, o_mask)
    _observe_passengers(s, w, o_pax, o_pax_mask)
    _observe_others(s, w, o_others, o_others_mask)
    _patches(s, w, o_sinr, o_visit)


@njit(cache=True)
def _observe_own(s: FleetState, w: WorldArrays, o_self: np.ndarray, o_history: np.ndarray, o_mask: np.ndarray) -> None:
    """Each taxi's ``self`` row, its ``history`` (positions relative to where it is now) and allowed headings."""
    side_m, seats = w.side_m, w.seats
    for e in range(s.history_m.shape[0]):
        for a in range(s.history_m.shape[1]):
            x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
            o_self[e, a, SELF_X] = x / side_m
            o_self[e, a, SELF_Y] = y / side_m
            o_self[e, a, SELF_FREE_SEATS] = s.free_seats[e, a] / seats
            o_self[e, a, SELF_TIME] = min(s.t[e] / w.time_limit_steps, 1.0)
            for h in range(s.history_m.shape[2]):
                o_history[e, a, h, HIST_DX] = (s.history_m[e, a, h, 0] - x) / side_m
                o_history[e, a, h, HIST_DY] = (s.history_m[e, a, h, 1] - y) / side_m
                o_history[e, a, h, HIST_FREE_SEATS] = s.history_seats[e, a, h] / seats
            for h in range(NUM_HEADINGS):
                o_mask[e, a, h] = 1 if s.action_mask[e, a, h] else 0


@njit(cache=True)
def _observe_passengers(s: FleetState, w: WorldArrays, o_pax: np.ndarray, o_pax_mask: np.ndarray) -> None:
    """Each passenger row as each taxi sees it (zeros and mask 0 while hidden or absent)."""
    side_m, time_limit = w.side_m, w.time_limit_steps
    for e in range(s.pos_m.shape[0]):
        t = s.t[e]
        for a in range(s.pos_m.shape[1]):
            x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
            for p in range(s.pax_status.shape[1]):
                row = o_pax[e, a, p]
                status = s.pax_status[e, p]
                if status == HIDDEN or not s.pax_exists[e, p]:
                    o_pax_mask[e, a, p] = 0
                    for f in range(NUM_PASSENGER_FEATURES):
                        row[f] = 0.0
                    continue
                o_pax_mask[e, a, p] = 1
                odx, ody = (s.pax_origin_m[e, p, 0] - x) / side_m, (s.pax_origin_m[e, p, 1] - y) / side_m
                ddx, ddy = (s.pax_dest_m[e, p, 0] - x) / side_m, (s.pax_dest_m[e, p, 1] - y) / side_m
                tdx, tdy = ddx - odx, ddy - ody
                mine = s.pax_taxi[e, p] == a
                row[PAX_ORIGIN_DX] = odx
                row[PAX_ORIGIN_DY] = ody
                row[PAX_DEST_DX] = ddx
                row[PAX_DEST_DY] = ddy
                row[PAX_DIST_TO_ORIGIN] = math.sqrt(odx * odx + ody * ody)
                row[PAX_DIST_TO_DEST] = math.sqrt(ddx * ddx + ddy * ddy)
                row[PAX_TRIP_LENGTH] = math.sqrt(tdx * tdx + tdy * tdy)
                row[PAX_WAITING] = 1.0 if status == WAITING else 0.0
                row[PAX_ON_BOARD_SELF] = 1.0 if status == ON_BOARD and mine else 0.0
                row[PAX_ON_BOARD_OTHER] = 1.0 if status == ON_BOARD and not mine else 0.0
                row[PAX_DELIVERED] = 1.0 if status == DELIVERED else 0.0
                row[PAX_AGE] = min(max((t - s.pax_release[e, p]) / time_limit, 0.0), 1.0)


@njit(cache=True)
def _observe_others(s: FleetState, w: WorldArrays, o_others: np.ndarray, o_others_mask: np.ndarray) -> None:
    """The other taxis as each taxi sees them, in taxi order; the rows past them zero and masked."""
    num_taxis = s.pos_m.shape[1]
    for e in range(s.pos_m.shape[0]):
        for a in range(num_taxis):
            x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
            n = 0
            for b in range(num_taxis):
                if b == a:
                    continue
                o_others[e, a, n, OTHER_DX] = (s.pos_m[e, b, 0] - x) / w.side_m
                o_others[e, a, n, OTHER_DY] = (s.pos_m[e, b, 1] - y) / w.side_m
                o_others[e, a, n, OTHER_FREE_SEATS] = s.free_seats[e, b] / w.seats
                o_others_mask[e, a, n] = 1
                n += 1
            for m in range(n, o_others.shape[2]):
                for f in range(o_others.shape[3]):
                    o_others[e, a, m, f] = 0.0
                o_others_mask[e, a, m] = 0


@njit(cache=True)
def _patches(s: FleetState, w: WorldArrays, o_sinr: np.ndarray, o_visit: np.ndarray) -> None:
    """The k x k SINR and visit-ratio patches around each taxi's block ([E, A, k, k] each).

    Patch rows bx .. bx + k - 1 of the padded arrays are blocks bx - patch_lo .. bx + k - patch_lo - 1. Written
    with unsigned flat indices: numba then checks no negative index, and the copy runs 2x faster than with
    [e, a, i, j] indexing. ``visits / steps`` is computed in float32: both are integers below 2**24
    (``EnvConfig.time_limit_steps`` is), so it equals the float64 quotient rounded to float32 (double rounding
    is innocuous for division when 53 >= 2 * 24 + 2; Figueroa 1995).
    """
    num_envs, num_taxis = s.pos_m.shape[0], s.pos_m.shape[1]
    k = np.uint64(o_sinr.shape[2])
    src = w.sinr_patch_source
    nbx, nby = src.shape[0] - o_sinr.shape[2], src.shape[1] - o_sinr.shape[2]
    src_ny = np.uint64(src.shape[1])
    cells = np.uint64(s.visits.shape[2] * s.visits.shape[3])  # padded blocks per taxi
    src_flat, visits_flat = src.ravel(), s.visits.ravel()
    sinr_flat, visit_flat = o_sinr.ravel(), o_visit.ravel()
    one = np.float32(1.0)
    for e in range(num_envs):
        steps = np.float32(max(s.t[e], 1))
        for a in range(num_taxis):
            n = np.uint64(e * num_taxis + a)
            bx = np.uint64(block_of(s.pos_m[e, a, 0], w.block_m, nbx))
            by = np.uint64(block_of(s.pos_m[e, a, 1], w.block_m, nby))
            for i in range(k):
                cell = (bx + i) * src_ny + by  # first cell of patch row i in the padded [nbx + k, nby + k] grid
                out = (n * k + i) * k
                for j in range(k):
                    sinr_flat[out + j] = src_flat[cell + j]
                for j in range(k):
                    visit_flat[out + j] = min(np.float32(visits_flat[n * cells + cell + j]) / steps, one)


@njit(cache=True)
def hover_headings(s: FleetState, w: WorldArrays, out: np.ndarray) -> None:
    """out[e, a] (int8 [E, A, 16], one-hot): the allowed heading whose endpoint is nearest the taxi's position one
    step ago, so that two such moves in a row hover about a point (as the fleet dispatchers' idle taxis do); the
    lowest allowed heading at the first step, all zero when no move is allowed."""
    num_envs, num_taxis = s.free_seats.shape
    out[:] = 0
    for e in range(num_envs):
        for a in range(num_taxis):
            x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
            px, py = s.history_m[e, a, 0, 0], s.history_m[e, a, 0, 1]
            best, best_d = -1, math.inf
            for h in range(NUM_HEADINGS):
                if not s.action_mask[e, a, h]:
                    continue
                d = (x + w.moves_m[h, 0] - px) ** 2 + (y + w.moves_m[h, 1] - py) ** 2
                if d < best_d - 1e-9:
                    best, best_d = h, d
            if best >= 0:
                out[e, a, best] = 1
