"""The motion kernels (numba): the action mask, the separation shield, separation, and the one batched step
(``step``: the rules of docs/rules.md "Motion" and "Release and pick-up" in order, each in a named part); the
observation kernels are :mod:`uamfleet.observe`'s. :mod:`uamfleet.sim.dynamics` is the entry point.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from uamfleet.radio._sampling import segment_min
from uamfleet.sim.arrays import RULE_ENDPOINT_BLOCK, WorldArrays
from uamfleet.types import DELIVERED, HIDDEN, HOVER_ACTION, NUM_HEADINGS, ON_BOARD, WAITING, FleetState, StepEvents


@njit(cache=True, inline="always")
def block_of(v: float, block_m: float, nb: int) -> int:
    """The index of the block holding coordinate v, clamped to the grid of nb blocks."""
    b = math.floor(v / block_m)
    return min(max(b, 0), nb - 1)


@njit(cache=True)
def action_mask(pos: np.ndarray, w: WorldArrays, out: np.ndarray) -> None:
    """out[i, k] = heading k is allowed from pos[i] ([N, 2]): docs/rules.md "Feasibility rules"."""
    block_ok = w.block_ok
    nbx, nby = block_ok.shape
    ox, oy = w.raster_origin[0], w.raster_origin[1]
    for i in range(pos.shape[0]):
        x, y = pos[i, 0], pos[i, 1]
        for k in range(NUM_HEADINGS):
            tx, ty = x + w.moves_m[k, 0], y + w.moves_m[k, 1]
            ok = 0.0 <= tx <= w.side_m and 0.0 <= ty <= w.side_m
            if ok:
                if w.rule == RULE_ENDPOINT_BLOCK:
                    ok = block_ok[block_of(tx, w.block_m, nbx), block_of(ty, w.block_m, nby)]
                else:
                    ok = segment_min(w.raster, ox, oy, w.raster_res, x, y, tx, ty) >= w.threshold_db
            out[i, k] = ok


CLEAR, CONFLICT, YIELD = 0, 1, 2
"""What :func:`_conflict` finds for a move: clear of everyone; in conflict; in conflict with a taxi the shield has
already turned aside (the move then yields: the taxi hovers, docs/rules.md "Separation shield" rule 4)."""


@njit(cache=True)
def _conflict(a: int, x: float, y: float, ends: np.ndarray, resolved: np.ndarray, turned: np.ndarray,
              pos: np.ndarray, min_separation_m: float, apart: bool) -> int:  # fmt: skip
    """Whether taxi a's move from pos[a] to (x, y) keeps its separation from every other taxi b, which flies from
    pos[b] to ends[b] once resolved, else is taken to stay at pos[b]: the end is at least ``min_separation_m`` from
    b's end (the same distance and comparison as :func:`separation`, so an accepted end is never a violation), and,
    when the two start at least that far apart, they stay so throughout the slot (closest approach of two
    straight flights at constant speed; two taxis never swap places through each other). With ``apart``, a pair
    that starts the slot closer than ``min_separation_m`` is also clear when the move takes the two apart
    (:func:`_separating`), wherever it ends. Returns :data:`CLEAR`, :data:`CONFLICT`, or :data:`YIELD` when one of
    the taxis in conflict is resolved and was turned aside."""
    ax, ay = pos[a, 0], pos[a, 1]
    found = CLEAR
    for b in range(pos.shape[0]):
        if b == a:
            continue
        bx, by = pos[b, 0], pos[b, 1]
        ex, ey = (ends[b, 0], ends[b, 1]) if resolved[b] else (bx, by)
        dx, dy = x - ex, y - ey
        close = math.sqrt(dx * dx + dy * dy) < min_separation_m
        sx, sy = ax - bx, ay - by  # b -> a at the start of the slot; + t * (vx, vy) at time t in [0, 1]
        if not close and math.sqrt(sx * sx + sy * sy) >= min_separation_m:  # else only the end must be clear
            vx, vy = (x - ax) - (ex - bx), (y - ay) - (ey - by)
            vv = vx * vx + vy * vy
            t = min(max(-(sx * vx + sy * vy) / vv, 0.0), 1.0) if vv > 0.0 else 0.0
            cx, cy = sx + t * vx, sy + t * vy
            close = math.sqrt(cx * cx + cy * cy) < min_separation_m
        elif close and apart and math.sqrt(sx * sx + sy * sy) < min_separation_m:
            close = not _separating(sx, sy, (x - ax) - (ex - bx), (y - ay) - (ey - by), min_separation_m)
        if close:
            if resolved[b] and turned[b]:
                return YIELD
            found = CONFLICT
    return found


@njit(cache=True, inline="always")
def _separating(sx: float, sy: float, vx: float, vy: float, min_separation_m: float) -> bool:
    """Two taxis s = (sx, sy) apart at the start of the slot (b -> a), a moving by v = (vx, vy) relative to b,
    move apart: their distance never shrinks during the slot (s . v >= 0; |s + t v| then grows with t) and grows
    by the end (v is not zero). The tolerances only absorb rounding: two taxis flying one heading side by side
    (v zero up to rounding) do not separate, a move at right angles to s (s . v zero up to rounding) does."""
    vv = vx * vx + vy * vy
    tiny = 1e-6 * min_separation_m
    return vv > tiny * tiny and sx * vx + sy * vy >= -1e-9 * math.sqrt((sx * sx + sy * sy) * vv)


@njit(cache=True)
def passes_within(start: np.ndarray, end: np.ndarray, point: np.ndarray, min_separation_m: float) -> bool:
    """The shield's own conflict test (:func:`_conflict`) of one straight move ``start`` -> ``end`` against a taxi
    staying at ``point``: the end closer than ``min_separation_m``, or, when the move starts at least that far
    away, its closest approach. For planners that keep out of the shield's way (``fleet_steering.make_way``)."""
    pos, ends = np.empty((2, 2)), np.empty((2, 2))
    pos[0], pos[1], ends[1] = start, point, point
    none = np.zeros(2, np.bool_)
    return _conflict(0, end[0], end[1], ends, none, none, pos, min_separation_m, False) != CLEAR


@njit(cache=True)
def passes_within_each(starts: np.ndarray, ends: np.ndarray, points: np.ndarray, min_separation_m: float) -> np.ndarray:
    """[I, B] bool: :func:`passes_within` of each move ``starts[b]`` -> ``ends[b]`` [B, 2] against each taxi staying
    at ``points[i]`` [I, 2], in one compiled pass (every idle taxi against every busy one's move, each step)."""
    out = np.zeros((points.shape[0], starts.shape[0]), np.bool_)
    for i in range(points.shape[0]):
        for b in range(starts.shape[0]):
            out[i, b] = passes_within(starts[b], ends[b], points[i], min_separation_m)
    return out


@njit(cache=True)
def stayed_steps(pos: np.ndarray, history: np.ndarray) -> np.ndarray:
    """[A] int64: the steps each taxi has stayed where it is (history rows, most recent first, equal to its
    position), at most the history's length: the shield's first priority."""
    out = np.zeros(pos.shape[0], np.int64)
    for a in range(pos.shape[0]):
        for h in range(history.shape[1]):
            if history[a, h, 0] != pos[a, 0] or history[a, h, 1] != pos[a, 1]:
                break
            out[a] += 1
    return out


@njit(cache=True)
def shield_headings(
    pos: np.ndarray,  # [A, 2] positions before the step
    free_seats: np.ndarray,  # [A]
    stayed: np.ndarray,  # [A] int64, steps each taxi has stayed in place (stayed_steps)
    allowed: np.ndarray,  # [A, NUM_HEADINGS] bool, the action mask
    requested: np.ndarray,  # [A] int64, validated actions (HOVER_ACTION: the taxi stays)
    w: WorldArrays,
    flown: np.ndarray,  # [A] int64 out: the heading flown, -1: the taxi stays where it is
) -> None:
    """The separation shield of one env (docs/rules.md "Separation shield"): the heading each taxi flies.

    Taxis are resolved one at a time: the one that has stayed in place longest first (a taxi held back goes first
    next time), then fewest free seats (most riders; the detour falls on the emptier taxi, whose delay holds up
    nobody on board), then by index. A requested heading that is not allowed stays a blocked move (the taxi
    stays), a requested hover (:data:`HOVER_ACTION`) a hover. An allowed one is kept when it is clear
    (:func:`_conflict`) of the moves already fixed and of the current positions of the taxis still to resolve.
    Else, when it conflicts with a taxi the shield turned aside, the taxi yields: it hovers and leaves the way
    free (two taxis turned aside side by side would shadow each other step after step). Else it flies the nearest
    allowed heading in angle that is clear (22.5° counter-clockwise, then clockwise, then 45°, ...), else hovers.
    Staying is clear whenever the current positions are separated: each earlier taxi's move was checked against
    this taxi staying where it is, and each later one is checked against what this one does.

    Then, once every taxi is resolved, a taxi that stays (a requested hover, a blocked move, a yield, no clear
    heading) and would end the slot closer than ``min_separation_m`` to another is moved apart when it can be
    (:func:`_move_apart`, checked against every other taxi's final move): staying keeps the conflict, and a pair
    in conflict whose every move ends within the separation (``min_separation_m`` above ``step_m``) would
    otherwise never part. With every pair separated at the start of the slot no taxi ends one in conflict, so the
    headings are those of the rules above alone.
    """
    num_taxis = pos.shape[0]
    ends = pos.copy()
    resolved = np.zeros(num_taxis, np.bool_)
    turned = np.zeros(num_taxis, np.bool_)
    half = NUM_HEADINGS // 2
    order = np.argsort(free_seats - stayed * (np.int64(1) << 32), kind="mergesort")  # stable: ties in index order
    for a in order:
        k = requested[a]
        flown[a] = -1
        if k != HOVER_ACTION and allowed[a, k]:
            for turn in range(2 * half):  # offsets 0, +1, -1, +2, -2, ..., +half
                d = (turn + 1) // 2 if turn % 2 else -(turn // 2)
                h = (k + d) % NUM_HEADINGS
                if not allowed[a, h]:
                    continue
                x, y = pos[a, 0] + w.moves_m[h, 0], pos[a, 1] + w.moves_m[h, 1]
                found = _conflict(a, x, y, ends, resolved, turned, pos, w.min_separation_m, False)
                if found == YIELD and d == 0:
                    break
                if found == CLEAR:
                    flown[a] = h
                    turned[a] = d != 0
                    ends[a, 0], ends[a, 1] = x, y
                    break
        resolved[a] = True
    for a in order:  # rule 7: a taxi that would stay in conflict moves apart, checked against every final move
        if flown[a] < 0 and _stays_in_conflict(a, pos, ends, w.min_separation_m):
            k = requested[a]
            h = _move_apart(a, k if k < NUM_HEADINGS else 0, ends, resolved, turned, pos, allowed, w)
            if h >= 0:
                flown[a] = h
                ends[a, 0], ends[a, 1] = pos[a, 0] + w.moves_m[h, 0], pos[a, 1] + w.moves_m[h, 1]


@njit(cache=True)
def _stays_in_conflict(a: int, pos: np.ndarray, ends: np.ndarray, min_separation_m: float) -> bool:
    """Taxi a, staying at pos[a], ends the slot closer than ``min_separation_m`` to another taxi's end."""
    for b in range(pos.shape[0]):
        if b != a:
            dx, dy = pos[a, 0] - ends[b, 0], pos[a, 1] - ends[b, 1]
            if math.sqrt(dx * dx + dy * dy) < min_separation_m:
                return True
    return False


@njit(cache=True)
def _move_apart(a: int, first: int, ends: np.ndarray, resolved: np.ndarray, turned: np.ndarray, pos: np.ndarray,
                allowed: np.ndarray, w: WorldArrays) -> int:  # fmt: skip
    """The heading that moves taxi a, about to stay in conflict, apart (docs/rules.md "Separation shield" rule 7):
    of the allowed headings clear of every other taxi when moves that take a pair in conflict apart count as
    clear (:func:`_conflict` with ``apart``), the one whose end is farthest from the nearest end of the taxis a
    starts the slot closer than ``min_separation_m`` to (ties, to a micrometre: nearest in angle to ``first``,
    counter-clockwise first); -1 when there is none."""
    sep = w.min_separation_m
    half = NUM_HEADINGS // 2
    best, best_gap = -1, -1.0
    for turn in range(2 * half):  # offsets 0, +1, -1, +2, -2, ..., +half, as in shield_headings
        d = (turn + 1) // 2 if turn % 2 else -(turn // 2)
        h = (first + d) % NUM_HEADINGS
        if not allowed[a, h]:
            continue
        x, y = pos[a, 0] + w.moves_m[h, 0], pos[a, 1] + w.moves_m[h, 1]
        if _conflict(a, x, y, ends, resolved, turned, pos, sep, True) != CLEAR:
            continue
        gap = math.inf
        for b in range(pos.shape[0]):
            sx, sy = pos[a, 0] - pos[b, 0], pos[a, 1] - pos[b, 1]
            if b != a and math.sqrt(sx * sx + sy * sy) < sep:
                dx, dy = x - ends[b, 0], y - ends[b, 1]
                gap = min(gap, math.sqrt(dx * dx + dy * dy))
        if gap > best_gap + 1e-6:  # ties within a micrometre (rounding of the moves) go to the first in angle
            best, best_gap = h, gap
    return best


@njit(cache=True)
def step(s: FleetState, w: WorldArrays, actions: np.ndarray, shield: bool) -> StepEvents:
    """Advance every env of ``s`` by one slot, in place, in the order of docs/rules.md "Motion" and "Release
    and pick-up"; ``actions`` [E, A] int64 must be validated. ``shield``: resolve conflicts first
    (:func:`shield_headings`). Returns the step's events, in arrays of their own (``actions`` is the argument)."""
    events = new_events(s, actions)
    step_into(s, w, actions, shield, events)
    return events


@njit(cache=True)
def new_events(s: FleetState, actions: np.ndarray) -> StepEvents:
    """Arrays for the events of a step of ``s`` (their values unset; ``actions`` is the ``actions`` field)."""
    num_envs, num_taxis, num_pax = s.pos_m.shape[0], s.pos_m.shape[1], s.pax_status.shape[1]
    ea, ep = (num_envs, num_taxis), (num_envs, num_pax)
    return StepEvents(
        np.empty(s.pos_m.shape), np.empty(s.pos_m.shape), actions, np.empty(ea, np.bool_), np.empty(ea, np.bool_),
        np.empty(ea, np.bool_), np.empty(ea, np.int32), np.empty(ep, np.bool_), np.empty(ep, np.bool_),
        np.empty(ep, np.bool_), np.empty(ea, np.int64), np.empty(ea, np.int64), np.empty(ea, np.bool_),
        np.empty(ea), np.empty(num_envs, np.bool_), np.empty(num_envs, np.int64), np.empty(ea, np.int64),
        np.empty(ea, np.bool_), np.empty(ea, np.bool_),
    )  # fmt: skip


@njit(cache=True)
def step_into(s: FleetState, w: WorldArrays, actions: np.ndarray, shield: bool, events: StepEvents) -> None:
    """:func:`step` writing the step's events into ``events``' arrays (every field but ``actions``, which it
    leaves as it is), allocating nothing: for a caller that reads the events before the next step (the
    PettingZoo face), where boxing fresh arrays for Python would cost more than the step itself."""
    num_envs, num_taxis = s.history_m.shape[0], s.history_m.shape[1]
    pos = s.pos_m
    prev_pos = events.prev_pos_m
    prev_pos[:] = pos
    moved, blocked, flown = events.moved, events.blocked, events.heading_flown  # flown: -1 = stayed
    intervened, hovered = events.shield_intervened, events.hovered
    first_visit, block_visits = events.first_visit, events.block_visits
    picked, dropped, released = events.picked_up, events.dropped_off, events.released
    pickups, dropoffs, all_delivered = events.pickups, events.dropoffs, events.all_delivered
    intervened[:] = False
    hovered[:] = False
    pickups[:] = 0
    dropoffs[:] = 0
    reach = w.radius_m + 1e-9
    for e in range(num_envs):
        s.t[e] += 1
        now = s.t[e]
        # 0. the headings flown (the shield may change or hold them)
        _headings_flown(s, w, actions, shield, e, flown, intervened, hovered)
        for a in range(num_taxis):
            # 1. move (or stay, when the move is not allowed or the shield holds the taxi); 2. the block visit
            moved[e, a] = flown[e, a] >= 0
            blocked[e, a] = not _allowed(s, e, a, actions[e, a])
            count = _fly(s, w, e, a, flown[e, a])
            block_visits[e, a] = count
            first_visit[e, a] = count == 1
        _drop_offs(s, e, now, reach, dropped, dropoffs)  # 3.
        _pick_ups(s, e, now, reach, picked, pickups)  # 4.
        _release(s, e, now, released)  # 5.
        all_delivered[e] = _all_delivered(s, e)
    # 6. the mask of the new positions, separation, and the SINR along the flown segments
    action_mask(pos.reshape(num_envs * num_taxis, 2), w, s.action_mask.reshape(num_envs * num_taxis, NUM_HEADINGS))
    separation(pos, w.min_separation_m, events.separation_violation)
    _segment_sinr(w, prev_pos, pos, events.segment_min_sinr_db)
    events.pos_m[:] = pos
    events.t[:] = s.t


@njit(cache=True)
def _headings_flown(
    s: FleetState, w: WorldArrays, actions: np.ndarray, shield: bool, e: int, flown: np.ndarray,
    intervened: np.ndarray, hovered: np.ndarray,
) -> None:  # fmt: skip
    """Env e's heading flown per taxi (-1: stays): the requested one if it is an allowed move; with the shield,
    the one it resolves, and whether it changed what the taxi would have done without it (intervened: another
    heading or a hover instead of an allowed move, or a move apart instead of a hover or a blocked move). Hovered:
    the taxi stayed on a hover: it asked for one (:data:`HOVER_ACTION`; the shield changes it only to move a taxi
    in conflict apart) or the shield held an allowed move."""
    num_taxis = flown.shape[1]
    for a in range(num_taxis):
        k = actions[e, a]
        flown[e, a] = k if k != HOVER_ACTION and s.action_mask[e, a, k] else -1
        hovered[e, a] = k == HOVER_ACTION
    if shield:
        stayed = stayed_steps(s.pos_m[e], s.history_m[e])
        shield_headings(s.pos_m[e], s.free_seats[e], stayed, s.action_mask[e], actions[e], w, flown[e])
        for a in range(num_taxis):
            k = actions[e, a]
            move = k != HOVER_ACTION and s.action_mask[e, a, k]  # an allowed move asked for
            intervened[e, a] = flown[e, a] != (k if move else -1)
            hovered[e, a] = flown[e, a] < 0 and (k == HOVER_ACTION or move)


@njit(cache=True, inline="always")
def _allowed(s: FleetState, e: int, a: int, k: int) -> bool:
    """Action k of taxi (e, a) is allowed: a hover always, a heading when its move is in the mask."""
    return k == HOVER_ACTION or s.action_mask[e, a, k]


@njit(cache=True)
def _fly(s: FleetState, w: WorldArrays, e: int, a: int, k: int) -> int:
    """Taxi (e, a): its history shifts (the position and free seats before the move become row 0), it flies
    heading k (-1: stays), and the visit count of the block it is in now grows by one; returns that count."""
    hist_len = s.history_m.shape[2]
    nbx, nby = w.block_ok.shape
    pos = s.pos_m
    hist, hist_seats = s.history_m[e, a], s.history_seats[e, a]
    for h in range(hist_len - 1, 0, -1):
        hist[h, 0] = hist[h - 1, 0]
        hist[h, 1] = hist[h - 1, 1]
        hist_seats[h] = hist_seats[h - 1]
    hist[0, 0] = pos[e, a, 0]
    hist[0, 1] = pos[e, a, 1]
    hist_seats[0] = s.free_seats[e, a]
    if k >= 0:
        pos[e, a, 0] += w.moves_m[k, 0]
        pos[e, a, 1] += w.moves_m[k, 1]
        s.distance_m[e, a] += w.step_m
    bx = block_of(pos[e, a, 0], w.block_m, nbx) + w.patch_lo
    by = block_of(pos[e, a, 1], w.block_m, nby) + w.patch_lo
    s.visits[e, a, bx, by] += 1
    return s.visits[e, a, bx, by]


@njit(cache=True)
def _drop_offs(s: FleetState, e: int, now: int, reach: float, dropped: np.ndarray, dropoffs: np.ndarray) -> None:
    """3. Passengers on board whose destination is within reach of their taxi are delivered."""
    pos = s.pos_m
    for p in range(s.pax_status.shape[1]):
        dropped[e, p] = False
        if s.pax_status[e, p] == ON_BOARD:
            a = s.pax_taxi[e, p]
            dx = pos[e, a, 0] - s.pax_dest_m[e, p, 0]
            dy = pos[e, a, 1] - s.pax_dest_m[e, p, 1]
            if math.sqrt(dx * dx + dy * dy) <= reach:
                s.pax_status[e, p] = DELIVERED
                s.pax_dropoff_step[e, p] = now
                s.free_seats[e, a] += 1
                dropoffs[e, a] += 1
                dropped[e, p] = True


@njit(cache=True)
def _pick_ups(s: FleetState, e: int, now: int, reach: float, picked: np.ndarray, pickups: np.ndarray) -> None:
    """4. Taxis in index order take the lowest-index waiting passengers in reach. Only requests released before
    this step are WAITING here, so every pick-up was observable beforehand."""
    pos, free_seats = s.pos_m, s.free_seats
    num_pax = s.pax_status.shape[1]
    for p in range(num_pax):
        picked[e, p] = False
    for a in range(pos.shape[1]):
        for p in range(num_pax):
            if free_seats[e, a] == 0:
                break
            if s.pax_status[e, p] != WAITING:
                continue
            dx = pos[e, a, 0] - s.pax_origin_m[e, p, 0]
            dy = pos[e, a, 1] - s.pax_origin_m[e, p, 1]
            if math.sqrt(dx * dx + dy * dy) <= reach:
                s.pax_status[e, p] = ON_BOARD
                s.pax_taxi[e, p] = a
                s.pax_pickup_step[e, p] = now
                free_seats[e, a] -= 1
                pickups[e, a] += 1
                picked[e, p] = True


@njit(cache=True)
def _release(s: FleetState, e: int, now: int, released: np.ndarray) -> None:
    """5. Requests whose release step has come are visible from now on, pickable from the next step."""
    for p in range(s.pax_status.shape[1]):
        released[e, p] = False
        if s.pax_status[e, p] == HIDDEN and s.pax_exists[e, p] and s.pax_release[e, p] <= now:
            s.pax_status[e, p] = WAITING
            released[e, p] = True


@njit(cache=True)
def _all_delivered(s: FleetState, e: int) -> bool:
    for p in range(s.pax_status.shape[1]):
        if s.pax_exists[e, p] and s.pax_status[e, p] != DELIVERED:
            return False
    return True


@njit(cache=True)
def _segment_sinr(w: WorldArrays, prev_pos: np.ndarray, pos: np.ndarray, seg: np.ndarray) -> None:
    """seg[e, a] = the lowest raster SINR (dB) along each taxi's segment of this step."""
    num_envs, num_taxis = pos.shape[0], pos.shape[1]
    ox, oy = w.raster_origin[0], w.raster_origin[1]
    for e in range(num_envs):
        for a in range(num_taxis):
            seg[e, a] = segment_min(
                w.raster, ox, oy, w.raster_res, prev_pos[e, a, 0], prev_pos[e, a, 1], pos[e, a, 0], pos[e, a, 1]
            )


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
