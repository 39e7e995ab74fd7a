"""The ``heading_lookahead`` field (uamfleet/observe/lookahead.py) against the env's own step: each heading flown in a
copy of the env over the requests known so far, costed as the move plus the shortest tour the copy then observes."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit

from uamfleet.baselines.step_planner import released_only
from uamfleet.config import ConfigError
from uamfleet.observe import lookahead
from uamfleet.observe.moves import StopRows
from uamfleet.env.vector_env import VectorEnv
from uamfleet.paths.distance_table import TableArrays
from uamfleet.presets import make_config
from uamfleet.sim.arrays import WorldArrays
from uamfleet.sim.world import row_stop
from uamfleet.types import LOOKAHEAD_CLIP, NUM_HEADINGS, STOP_PATH_TO_STOP, STOP_TOUR_VIA_STOP, FleetState


def _expected_lookahead(env: VectorEnv, e: int, scratch: VectorEnv) -> tuple[np.ndarray, bool]:
    """[16] each heading's move + shortest tour after it, minus the best, in moves, by stepping a copy of env e; and
    whether some heading's move serves a stop."""
    root = released_only(env.state)
    for target, source in zip(scratch.state, root, strict=True):
        target[:] = source[e : e + 1]
    obs, _, terminated, truncated, info = scratch.step(np.arange(NUM_HEADINGS)[:, None])
    assert not truncated.any(), "the test's flight must end before the time limit"
    cost = env.cfg.step_m * info["events"].moved[:, 0] + _observed_tour_m(obs, terminated, env.cfg.side_m)
    served = bool(info["events"].picked_up.any() or info["events"].dropped_off.any())
    return _excess_moves(cost, env.state.action_mask[e, 0].astype(bool), env.cfg.step_m), served


def _observed_tour_m(obs: dict[str, np.ndarray], ended: np.ndarray, side: float) -> np.ndarray:
    """[N] the shortest tour each env of a copy observes after its flight (metres; 0 once its episode ended or no
    stop is left)."""
    paths = obs["stop_paths"][:, 0]
    offered = paths[..., STOP_PATH_TO_STOP] > 0
    tour = np.where(offered, paths[..., STOP_TOUR_VIA_STOP], np.inf).min(-1) * side
    return np.where(offered.any(-1) & ~ended, tour, 0.0)


def _excess_moves(cost: np.ndarray, allowed: np.ndarray, step: float) -> np.ndarray:
    """[16] the field's value from each heading's cost: above the least allowed one, in moves, clipped; the clip
    where a heading is not allowed or costs inf."""
    allowed = allowed & np.isfinite(cost)
    out = np.full(NUM_HEADINGS, LOOKAHEAD_CLIP)
    out[allowed] = np.minimum((cost[allowed] - cost[allowed].min()) / step, LOOKAHEAD_CLIP)
    return out


def test_lookahead_is_the_move_plus_the_tour_the_step_leaves() -> None:
    cfg = make_config("berlin_instances", sinr_min_db=-4.0, heading_lookahead=True)
    env = VectorEnv(cfg, num_envs=4)
    scratch = VectorEnv(cfg, num_envs=NUM_HEADINGS, autoreset=True)
    scratch.reset(seed=0)
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(1)
    checked = served_by_a_move = 0
    for _ in range(30):
        for e in range(env.num_envs):
            if not obs["stop_heading_mask"][e, 0].any():
                assert not obs["heading_lookahead"][e, 0].any(), "no stop: all zero"
                continue
            expected, served = _expected_lookahead(env, e, scratch)
            np.testing.assert_allclose(obs["heading_lookahead"][e, 0], expected, atol=2e-3)
            checked += 1
            served_by_a_move += served
        # fly the best look-ahead heading mostly (so that stops get served), sometimes a random allowed one
        allowed = obs["action_mask"][:, 0].astype(bool)
        best = np.where(allowed, obs["heading_lookahead"][:, 0], np.inf).argmin(-1)
        random = np.array([rng.choice(np.flatnonzero(a)) for a in allowed])
        actions = np.where(rng.random(env.num_envs) < 0.8, best, random)
        obs, *_ = env.step(actions[:, None])
    assert checked > 80 and served_by_a_move > 3  # the branch that serves stops at the move's end is exercised


def _expected_two_move_lookahead(env: VectorEnv, e: int, scratch: VectorEnv) -> np.ndarray:
    """[16] depth 2: each heading's move, then the best second move allowed from its end, then the shortest tour the
    copy observes (the move alone where it serves every known stop), minus the best heading's, in moves: every
    pair of headings flown in a 256-env copy of env e over the requests known so far."""
    root = released_only(env.state)
    for target, source in zip(scratch.state, root, strict=True):
        target[:] = np.repeat(source[e : e + 1], NUM_HEADINGS**2, axis=0)
    first, second = np.repeat(np.arange(NUM_HEADINGS), NUM_HEADINGS), np.tile(np.arange(NUM_HEADINGS), NUM_HEADINGS)
    obs1, _, done1, _, info1 = scratch.step(first[:, None])
    second_allowed = obs1["action_mask"][np.arange(first.size), 0, second] > 0
    obs2, _, done2, truncated, info2 = scratch.step(second[:, None])
    assert not truncated.any(), "the test's flight must end before the time limit"
    step = env.cfg.step_m
    tour = _observed_tour_m(obs2, done2, env.cfg.side_m)
    moved1, moved2 = info1["events"].moved[:, 0], info2["events"].moved[:, 0]
    cost = np.where(second_allowed, (moved1 + moved2) * step + tour, np.inf)
    cost = np.where(done1, moved1 * step, cost).reshape(NUM_HEADINGS, NUM_HEADINGS).min(1)
    return _excess_moves(cost, env.state.action_mask[e, 0].astype(bool), step)


@pytest.mark.parametrize("feasibility", ["endpoint_block", "segment_raster"])
def test_depth_two_is_the_best_pair_of_moves_and_the_tour_they_leave(feasibility: str) -> None:
    """``lookahead_depth=2`` against the env's own step: every pair of headings flown in a copy of the env."""
    cfg = make_config(
        "berlin_instances", sinr_min_db=-4.0, heading_lookahead=True, lookahead_depth=2, feasibility=feasibility
    )
    env = VectorEnv(cfg, num_envs=3)
    scratch = VectorEnv(cfg, num_envs=NUM_HEADINGS**2, autoreset=True)
    scratch.reset(seed=0)
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(1)
    checked = differs_from_depth_one = 0
    single = VectorEnv(cfg.replace(lookahead_depth=1), num_envs=3)
    for _ in range(20):
        for e in range(env.num_envs):
            if not obs["stop_heading_mask"][e, 0].any():
                continue
            expected = _expected_two_move_lookahead(env, e, scratch)
            np.testing.assert_allclose(obs["heading_lookahead"][e, 0], expected, atol=2e-3)
            checked += 1
            for target, source in zip(single.state, env.state, strict=True):
                target[:] = source
            depth_one = single.observer.observe(single.state)["heading_lookahead"][e, 0]
            differs_from_depth_one += not np.allclose(depth_one, expected, atol=2e-3)
        allowed = obs["action_mask"][:, 0].astype(bool)
        best = np.where(allowed, obs["heading_lookahead"][:, 0], np.inf).argmin(-1)
        random = np.array([rng.choice(np.flatnonzero(a)) for a in allowed])
        obs, *_ = env.step(np.where(rng.random(env.num_envs) < 0.8, best, random)[:, None])
    assert checked > 40 and differs_from_depth_one > 5  # depth 2 is another field than depth 1


def test_the_depth_is_one_or_two() -> None:
    with pytest.raises(ConfigError, match="lookahead_depth=3 must be 1"):
        make_config("berlin_instances", heading_lookahead=True, lookahead_depth=3)


def test_lookahead_needs_the_stop_features() -> None:
    with pytest.raises(ConfigError, match="heading_lookahead=True needs stop_features=True"):
        make_config("berlin_p4", heading_lookahead=True)


@njit
def _costs_both_ways(s: FleetState, w: WorldArrays, t: TableArrays, fast: np.ndarray, plain: np.ndarray) -> np.ndarray:
    """fast[e, a] = :func:`lookahead._heading_costs` (bounded look-ups, shared served sets), plain[e, a] = the same
    costs without any shortcut: every heading tested for serving, its tours computed afresh, every offered stop
    looked up. Returns counts [3]: headings that reused another heading's served set, taxis where no move can serve
    (the serving test skipped), look-ups a bound can skip."""
    num_envs, num_taxis = s.free_seats.shape
    num_pax = s.pax_status.shape[1]
    pts = np.empty((2 * num_pax, 2))
    scratch = lookahead._new_scratch(num_pax)
    rests, undo = np.empty(2 * num_pax), np.empty(num_pax, np.int64)
    counts = np.zeros(3, np.int64)
    for e in range(num_envs):
        for p in range(num_pax):
            pts[2 * p], pts[2 * p + 1] = s.pax_origin_m[e, p], s.pax_dest_m[e, p]
        for a in range(num_taxis):
            fast[e, a] = np.nan
            plain[e, a] = np.nan
            if lookahead._heading_costs(s, w, t, e, a, pts, scratch, fast[e, a]) != 1:
                continue
            x, y = s.pos_m[e, a, 0], s.pos_m[e, a, 1]
            rows = StopRows(s.pax_exists[e], s.pax_status[e], s.pax_taxi[e], s.free_seats[e], s.stop_tour_m[e, a])
            sets, any_served = 0, False
            for h in range(NUM_HEADINGS):
                plain[e, a, h] = math.inf
                if not s.action_mask[e, a, h]:
                    continue
                qx, qy = x + w.moves_m[h, 0], y + w.moves_m[h, 1]
                if lookahead._serve_at(rows, a, pts, qx, qy, w.radius_m + 1e-9, undo):
                    any_served = True
                    sets += 1
                    found = lookahead._rests_after_serving(s, e, a, pts, t, rests)
                    tour = lookahead._tour_from(rows, a, qx, qy, pts, rests, t) if found == 1 else math.nan
                    lookahead._unserve(rows, a, undo)
                else:
                    tour = lookahead._tour_from(rows, a, qx, qy, pts, s.stop_tour_m[e, a], t)
                    counts[2] += _beaten_by_bound(s, e, a, qx, qy, pts, tour)
                plain[e, a, h] = w.step_m + tour
            counts[0] += sets - _distinct_sets(s, w, rows, pts, e, a, undo)
            counts[1] += not any_served and not lookahead._stop_within(
                rows, a, x, y, pts, w.radius_m + 1e-9 + lookahead._longest_move(w.moves_m) + lookahead.SURE_M
            )
    return counts


@njit
def _beaten_by_bound(s: FleetState, e: int, a: int, qx: float, qy: float, pts: np.ndarray, tour: float) -> int:
    """How many offered stops' straight line from (qx, qy) plus their rest is at least the tour (look-ups a bound
    can skip)."""
    count = 0
    for p in range(s.pax_status.shape[1]):
        point = row_stop(s, e, a, p) if s.pax_exists[e, p] else -1
        if point >= 0 and math.hypot(qx - pts[point, 0], qy - pts[point, 1]) + s.stop_tour_m[e, a, point] > tour:
            count += 1
    return count


@njit
def _distinct_sets(
    s: FleetState, w: WorldArrays, rows: StopRows, pts: np.ndarray, e: int, a: int, undo: np.ndarray
) -> int:
    seen = np.empty((NUM_HEADINGS, undo.size), np.int64)
    count = 0
    for h in range(NUM_HEADINGS):
        qx, qy = s.pos_m[e, a, 0] + w.moves_m[h, 0], s.pos_m[e, a, 1] + w.moves_m[h, 1]
        if s.action_mask[e, a, h] and lookahead._serve_at(rows, a, pts, qx, qy, w.radius_m + 1e-9, undo):
            lookahead._unserve(rows, a, undo)
            if lookahead._matching_set(undo, seen, count) < 0:
                seen[count] = undo
                count += 1
    return count


@pytest.mark.parametrize(("scenario", "num_taxis"), [("berlin_instances", 1), ("berlin_random", 1),
                                                     ("berlin_random", 4)])  # fmt: skip
def test_the_shortcuts_change_no_cost(scenario: str, num_taxis: int) -> None:
    """The look-ahead's bounded look-ups and shared served sets give every heading's cost bit for bit as computing
    each afresh does, on scenes drawn from rollouts that serve stops (and the shortcuts are exercised)."""
    cfg = make_config(scenario, num_taxis=num_taxis, stop_features=True, heading_lookahead=True)
    env = VectorEnv(cfg, num_envs=8)
    obs, _ = env.reset(seed=11)
    rng = np.random.default_rng(2)
    fast, plain = np.empty((8, num_taxis, NUM_HEADINGS)), np.empty((8, num_taxis, NUM_HEADINGS))
    table = env.observer.table
    assert table is not None
    counts = np.zeros(3, np.int64)
    for _ in range(60):
        state = env.state.copy()  # the state heading_lookahead saw, its kept tours up to date
        counts += _costs_both_ways(state, env.world.arrays, table.arrays, fast, plain)
        assert np.array_equal(fast, plain, equal_nan=True)
        allowed = obs["action_mask"] > 0
        best = np.where(allowed, obs["heading_lookahead"], np.inf).argmin(-1)
        random = np.where(allowed, rng.random(allowed.shape), -1.0).argmax(-1)
        obs, *_ = env.step(np.where(rng.random(best.shape) < 0.8, best, random))
    shared, skipped_serving, skippable = counts
    assert shared > 0 and skipped_serving > 0 and skippable > 0, counts
