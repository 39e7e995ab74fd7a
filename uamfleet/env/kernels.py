"""Compiled (numba) loops over [env, taxi, passenger]: the only implementation of the motion, boarding and
observation rules. :mod:`uamfleet.env.dynamics` and :mod:`uamfleet.env.observer` document the rules and
call these; nothing else re-implements them.

Why compiled: a step is a few dozen small operations per taxi. As numpy calls each costs microseconds of
overhead, which capped a one-env step at ~1.7k steps/s; as one loop it is memory-bound and fast for any
batch size. ``cache=True`` stores the machine code next to this file, so only the first run compiles.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from uamfleet.radio._sampling import segment_min

# Feasibility rules (EnvConfig.feasibility) as integers for the kernels.
RULE_ENDPOINT_BLOCK = 0
RULE_SEGMENT_RASTER = 1

# Passenger status codes, as in uamfleet.types (numba needs them as module constants).
_HIDDEN, _WAITING, _ON_BOARD, _DELIVERED = 0, 1, 2, 3


@njit(cache=True, inline="always")
def _block_of(v: float, block_m: float, nb: int) -> int:
    b = math.floor(v / block_m)
    return min(max(b, 0), nb - 1)


@njit(cache=True)
def action_mask(
    pos: np.ndarray,  # [N, 2]
    moves: np.ndarray,  # [16, 2]
    side_m: float,
    rule: int,
    block_ok: np.ndarray,  # [nbx, nby] bool
    block_m: float,
    raster: np.ndarray,  # [nx, ny] SINR dB, NaN = not computed
    raster_origin: np.ndarray,  # [2]
    raster_res: float,
    threshold_db: float,
    out: np.ndarray,  # [N, 16] bool
) -> None:
    nbx, nby = block_ok.shape
    ox, oy = raster_origin[0], raster_origin[1]
    for i in range(pos.shape[0]):
        x, y = pos[i, 0], pos[i, 1]
        for k in range(moves.shape[0]):
            tx, ty = x + moves[k, 0], y + moves[k, 1]
            ok = 0.0 <= tx <= side_m and 0.0 <= ty <= side_m
            if ok:
                if rule == RULE_ENDPOINT_BLOCK:
                    ok = block_ok[_block_of(tx, block_m, nbx), _block_of(ty, block_m, nby)]
                else:
                    ok = segment_min(raster, ox, oy, raster_res, x, y, tx, ty) >= threshold_db
            out[i, k] = ok


@njit(cache=True)
def step(  # noqa: C901 - one loop that applies the rules in their documented order
    t: np.ndarray,  # [E] int64
    pos: np.ndarray,  # [E, A, 2]
    free_seats: np.ndarray,  # [E, A] int64
    history: np.ndarray,  # [E, A, H, 2]
    history_seats: np.ndarray,  # [E, A, H] int64
    visits: np.ndarray,  # [E, A, nbx + k, nby + k] int32
    distance: np.ndarray,  # [E, A]
    mask: np.ndarray,  # [E, A, 16] bool, updated to the new positions at the end
    pax_exists: np.ndarray,  # [E, P] bool
    pax_release: np.ndarray,  # [E, P] int64
    pax_origin: np.ndarray,  # [E, P, 2]
    pax_dest: np.ndarray,  # [E, P, 2]
    pax_status: np.ndarray,  # [E, P] int8
    pax_taxi: np.ndarray,  # [E, P] int64
    pax_pickup: np.ndarray,  # [E, P] int64
    pax_dropoff: np.ndarray,  # [E, P] int64
    actions: np.ndarray,  # [E, A] int64
    moves: np.ndarray,  # [16, 2]
    step_m: float,
    radius_m: float,
    side_m: float,
    min_separation_m: float,
    rule: int,
    block_ok: np.ndarray,  # [nbx, nby] bool
    block_m: float,
    patch_lo: int,
    raster: np.ndarray,  # [nx, ny] SINR dB, NaN = not computed
    raster_origin: np.ndarray,  # [2]
    raster_res: float,
    threshold_db: float,
) -> tuple[np.ndarray, ...]:
    """Returns (prev_pos, moved, block_visits, picked, dropped, released, pickups, dropoffs, separation,
    segment_min_sinr, all_delivered): the per-step events."""
    num_envs, num_taxis, hist_len = history.shape[0], history.shape[1], history.shape[2]
    num_pax = pax_status.shape[1]
    nbx, nby = block_ok.shape
    prev_pos = pos.copy()
    moved = np.empty((num_envs, num_taxis), np.bool_)
    block_visits = np.empty((num_envs, num_taxis), np.int32)
    picked = np.empty((num_envs, num_pax), np.bool_)
    dropped = np.empty((num_envs, num_pax), np.bool_)
    released = np.empty((num_envs, num_pax), np.bool_)
    pickups = np.empty((num_envs, num_taxis), np.int64)
    dropoffs = np.empty((num_envs, num_taxis), np.int64)
    all_delivered = np.empty(num_envs, np.bool_)
    reach = radius_m + 1e-9
    for e in range(num_envs):
        t[e] += 1
        now = t[e]
        for a in range(num_taxis):
            # 1. move (or stay, when the move is not allowed)
            for h in range(hist_len - 1, 0, -1):
                history[e, a, h, 0] = history[e, a, h - 1, 0]
                history[e, a, h, 1] = history[e, a, h - 1, 1]
                history_seats[e, a, h] = history_seats[e, a, h - 1]
            history[e, a, 0, 0] = pos[e, a, 0]
            history[e, a, 0, 1] = pos[e, a, 1]
            history_seats[e, a, 0] = free_seats[e, a]
            k = actions[e, a]
            ok = mask[e, a, k]
            moved[e, a] = ok
            if ok:
                pos[e, a, 0] += moves[k, 0]
                pos[e, a, 1] += moves[k, 1]
                distance[e, a] += step_m
            # 2. visits of the block the taxi is in now
            bx = _block_of(pos[e, a, 0], block_m, nbx) + patch_lo
            by = _block_of(pos[e, a, 1], block_m, nby) + patch_lo
            visits[e, a, bx, by] += 1
            block_visits[e, a] = visits[e, a, bx, by]
            pickups[e, a] = 0
            dropoffs[e, a] = 0
        # 3. drop-offs
        for p in range(num_pax):
            dropped[e, p] = False
            if pax_status[e, p] == _ON_BOARD:
                a = pax_taxi[e, p]
                dx = pos[e, a, 0] - pax_dest[e, p, 0]
                dy = pos[e, a, 1] - pax_dest[e, p, 1]
                if math.sqrt(dx * dx + dy * dy) <= reach:
                    pax_status[e, p] = _DELIVERED
                    pax_dropoff[e, p] = now
                    free_seats[e, a] += 1
                    dropoffs[e, a] += 1
                    dropped[e, p] = True
        # 4. pick-ups: taxis in index order take the lowest-index waiting passengers in reach. Only requests
        # released before this step are WAITING here, so every pick-up was observable beforehand.
        for p in range(num_pax):
            picked[e, p] = False
        for a in range(num_taxis):
            for p in range(num_pax):
                if free_seats[e, a] == 0:
                    break
                if pax_status[e, p] != _WAITING:
                    continue
                dx = pos[e, a, 0] - pax_origin[e, p, 0]
                dy = pos[e, a, 1] - pax_origin[e, p, 1]
                if math.sqrt(dx * dx + dy * dy) <= reach:
                    pax_status[e, p] = _ON_BOARD
                    pax_taxi[e, p] = a
                    pax_pickup[e, p] = now
                    free_seats[e, a] -= 1
                    pickups[e, a] += 1
                    picked[e, p] = True
        # 5. releases: visible from now on, pickable from the next step
        for p in range(num_pax):
            released[e, p] = False
            if pax_status[e, p] == _HIDDEN and pax_exists[e, p] and pax_release[e, p] <= now:
                pax_status[e, p] = _WAITING
                released[e, p] = True
        all_delivered[e] = True
        for p in range(num_pax):
            if pax_exists[e, p] and pax_status[e, p] != _DELIVERED:
                all_delivered[e] = False
                break
    # 6. the mask of the new positions, separation, and the SINR along the flown segments
    flat_pos = pos.reshape(num_envs * num_taxis, 2)
    action_mask(
        flat_pos, moves, side_m, rule, block_ok, block_m, raster, raster_origin, raster_res, threshold_db,
        mask.reshape(num_envs * num_taxis, moves.shape[0]),
    )  # fmt: skip
    separation_out = np.empty((num_envs, num_taxis), np.bool_)
    separation(pos, min_separation_m, separation_out)
    seg = np.empty((num_envs, num_taxis))
    for e in range(num_envs):
        for a in range(num_taxis):
            seg[e, a] = segment_min(
                raster, raster_origin[0], raster_origin[1], raster_res, prev_pos[e, a, 0], prev_pos[e, a, 1],
                pos[e, a, 0], pos[e, a, 1],
            )  # fmt: skip
    return (prev_pos, moved, block_visits, picked, dropped, released, pickups, dropoffs, separation_out, seg,
            all_delivered)  # fmt: skip


@njit(cache=True)
def observe(
    t: np.ndarray,  # [E]
    pos: np.ndarray,  # [E, A, 2]
    free_seats: np.ndarray,  # [E, A]
    history: np.ndarray,  # [E, A, H, 2]
    history_seats: np.ndarray,  # [E, A, H]
    visits: np.ndarray,  # [E, A, nbx + k, nby + k]
    mask: np.ndarray,  # [E, A, 16] bool
    pax_exists: np.ndarray,  # [E, P]
    pax_release: np.ndarray,  # [E, P]
    pax_origin: np.ndarray,  # [E, P, 2]
    pax_dest: np.ndarray,  # [E, P, 2]
    pax_status: np.ndarray,  # [E, P]
    pax_taxi: np.ndarray,  # [E, P]
    sinr_patch_source: np.ndarray,  # [nbx + k, nby + k] float32
    block_m: float,
    side_m: float,
    seats: float,
    time_limit: float,
    # outputs
    o_self: np.ndarray,  # [E, A, 4]
    o_history: np.ndarray,  # [E, A, H, 3]
    o_pax: np.ndarray,  # [E, A, P, 12]
    o_pax_mask: np.ndarray,  # [E, A, P] int8
    o_sinr: np.ndarray,  # [E, A, k, k]
    o_visit: np.ndarray,  # [E, A, k, k]
    o_others: np.ndarray,  # [E, A, max(A-1, 1), 3]
    o_others_mask: np.ndarray,  # [E, A, max(A-1, 1)] int8
    o_mask: np.ndarray,  # [E, A, 16] int8
) -> None:
    num_envs, num_taxis, hist_len = history.shape[0], history.shape[1], history.shape[2]
    num_pax = pax_status.shape[1]
    k = o_sinr.shape[2]
    nbx = sinr_patch_source.shape[0] - k
    nby = sinr_patch_source.shape[1] - k
    for e in range(num_envs):
        steps = max(t[e], 1)
        for a in range(num_taxis):
            x, y = pos[e, a, 0], pos[e, a, 1]
            o_self[e, a, 0] = x / side_m
            o_self[e, a, 1] = y / side_m
            o_self[e, a, 2] = free_seats[e, a] / seats
            o_self[e, a, 3] = min(t[e] / time_limit, 1.0)
            for h in range(hist_len):
                o_history[e, a, h, 0] = (history[e, a, h, 0] - x) / side_m
                o_history[e, a, h, 1] = (history[e, a, h, 1] - y) / side_m
                o_history[e, a, h, 2] = history_seats[e, a, h] / seats
            for p in range(num_pax):
                status = pax_status[e, p]
                if status == _HIDDEN or not pax_exists[e, p]:
                    o_pax_mask[e, a, p] = 0
                    for f in range(12):
                        o_pax[e, a, p, f] = 0.0
                    continue
                o_pax_mask[e, a, p] = 1
                odx, ody = (pax_origin[e, p, 0] - x) / side_m, (pax_origin[e, p, 1] - y) / side_m
                ddx, ddy = (pax_dest[e, p, 0] - x) / side_m, (pax_dest[e, p, 1] - y) / side_m
                tdx, tdy = ddx - odx, ddy - ody
                mine = pax_taxi[e, p] == a
                o_pax[e, a, p, 0] = odx
                o_pax[e, a, p, 1] = ody
                o_pax[e, a, p, 2] = ddx
                o_pax[e, a, p, 3] = ddy
                o_pax[e, a, p, 4] = math.sqrt(odx * odx + ody * ody)
                o_pax[e, a, p, 5] = math.sqrt(ddx * ddx + ddy * ddy)
                o_pax[e, a, p, 6] = math.sqrt(tdx * tdx + tdy * tdy)
                o_pax[e, a, p, 7] = 1.0 if status == _WAITING else 0.0
                o_pax[e, a, p, 8] = 1.0 if status == _ON_BOARD and mine else 0.0
                o_pax[e, a, p, 9] = 1.0 if status == _ON_BOARD and not mine else 0.0
                o_pax[e, a, p, 10] = 1.0 if status == _DELIVERED else 0.0
                o_pax[e, a, p, 11] = min(max((t[e] - pax_release[e, p]) / time_limit, 0.0), 1.0)
            # k x k patches: padded rows bx .. bx + k - 1 are blocks bx - patch_lo .. bx + k - patch_lo - 1
            bx = _block_of(x, block_m, nbx)
            by = _block_of(y, block_m, nby)
            for i in range(k):
                for j in range(k):
                    o_sinr[e, a, i, j] = sinr_patch_source[bx + i, by + j]
                    o_visit[e, a, i, j] = min(visits[e, a, bx + i, by + j] / steps, 1.0)
            n = 0
            for b in range(num_taxis):
                if b == a:
                    continue
                o_others[e, a, n, 0] = (pos[e, b, 0] - x) / side_m
                o_others[e, a, n, 1] = (pos[e, b, 1] - y) / side_m
                o_others[e, a, n, 2] = free_seats[e, b] / seats
                o_others_mask[e, a, n] = 1
                n += 1
            for m in range(n, o_others.shape[2]):
                o_others[e, a, m, 0] = 0.0
                o_others[e, a, m, 1] = 0.0
                o_others[e, a, m, 2] = 0.0
                o_others_mask[e, a, m] = 0
            for h in range(16):
                o_mask[e, a, h] = 1 if mask[e, a, h] else 0


@njit(cache=True)
def separation(pos: np.ndarray, min_separation_m: float, out: np.ndarray) -> None:
    """out[e, a] = another taxi of env e is closer than min_separation_m."""
    num_envs, num_taxis = pos.shape[0], pos.shape[1]
    for e in range(num_envs):
        for a in range(num_taxis):
            out[e, a] = False
        for a in range(num_taxis):
            for b in range(a + 1, num_taxis):
                dx = pos[e, a, 0] - pos[e, b, 0]
                dy = pos[e, a, 1] - pos[e, b, 1]
                if math.sqrt(dx * dx + dy * dy) < min_separation_m:
                    out[e, a] = True
                    out[e, b] = True
