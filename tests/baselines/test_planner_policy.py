"""Planners flown through the environment: drawn maps with hand-known answers, and the Berlin instance."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

import uamfleet
from uamfleet.baselines.planner_policy import (
    PLANNERS,
    PlannerPolicy,
    append_late,
    clairvoyant_plan,
    exact_stop_length,
    offline_plan,
    planner_env_overrides,
    service_order,
)
from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.metrics import episode_metrics
from uamfleet.rollout import run_episode

WALL_WITH_GAP = """
.........
.........
####.####
.........
.........
.........
.........
.........
.........
"""  # y = 600..700 is a wall except the block x in [400, 500)


def fly(cfg, planner):
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    policy = PlannerPolicy(planner)
    return run_episode(env, policy, seed=0), policy


def test_planner_flies_through_the_gap_and_delivers():
    # start (150, 150), passenger from (150, 350) to (150, 850): the direct line crosses the wall at y ~ 650
    cfg = small_config(WALL_WITH_GAP, requests=(Request(0, (150.0, 350.0), (150.0, 850.0)),), time_limit_steps=60)
    traj, _ = fly(cfg, "raster_opt")
    assert traj.terminated and traj.episode["delivered"] == 1
    path = traj.positions_m[0]
    assert cfg.radio.block_map(100.0).feasible(path, -3.0).all()  # never in a wall block
    crossing = path[(path[:, 1] >= 600) & (path[:, 1] < 700)]
    assert len(crossing) and np.all((crossing[:, 0] >= 400) & (crossing[:, 0] < 500))  # through the gap
    # lower bound: up to y = 600 then through the gap block and on to within 100 m of (150, 850)
    assert traj.num_steps >= 9


def test_offline_plans_append_late_requests_and_replan_reoptimises():
    # On a line: start 0; P0 100 -> 200, P1 300 -> 400 (known); P2 released late at 900 -> 0 region.
    xs = np.array([0, 100, 200, 300, 400, 900, 50], float)
    dist = np.abs(xs[:, None] - xs[None, :])
    release = np.array([0.0, 0.0, 10.0])
    plan, stops = offline_plan(dist, 10.0, release, capacity=2)
    assert stops == [(0, "pickup"), (0, "dropoff"), (1, "pickup"), (1, "dropoff")]
    assert plan.distance_m == pytest.approx(400.0)
    assert append_late([2], release) == [(2, "pickup"), (2, "dropoff")]
    opt_plan, opt_stops = clairvoyant_plan(dist, 10.0, release, capacity=2)
    assert {s for s in opt_stops} == {(p, k) for p in range(3) for k in ("pickup", "dropoff")}
    # with everything known, the completion is no later than appending P2 after the known plan
    appended = plan.finish_s + (dist[4, 5] + dist[5, 6]) / 10.0
    assert opt_plan.finish_s <= appended + 1e-9


def test_replan_replans_when_the_late_request_appears_on_berlin():
    traj, policy = fly(uamfleet.make_config("berlin_p4"), "raster_replan")
    assert len(policy.planned) == 2  # the initial plan and one re-plan when P4 was released at step 5
    assert traj.terminated and traj.episode["delivered"] == 4


@pytest.mark.parametrize("threshold", [-7.0, -3.0])
def test_berlin_planners_serve_everyone_and_opt_is_fastest(threshold):
    completion = {}
    for planner in PLANNERS:
        cfg = uamfleet.make_config("berlin_p4", **{"sinr_min_db": threshold, **planner_env_overrides(planner)})
        traj, _ = fly(cfg, planner)
        m = episode_metrics(traj, cfg.radio, threshold_db=threshold)
        assert m.pr_pct == 100.0, planner
        completion[planner] = m.completion_s
        if planner == "cptsp":  # flown with one seat: never two on board
            on_board = np.cumsum(traj.stacked("pickups") - traj.stacked("dropoffs"), axis=0)
            assert on_board.max() == 1
        if planner != "straight":  # flown under the SINR rule: every visited block is flyable
            assert cfg.radio.block_map(100.0).feasible(traj.positions_m[0], threshold).all()
    for planner in ("cptsp", "pdpcc", "raster_replan"):
        assert completion["raster_opt"] <= completion[planner], (planner, completion)


def test_exact_stop_length_and_service_order():
    dist = np.array([[0, 1, 2], [1, 0, 3], [2, 3, 0]], float)
    order = service_order(np.array([2]), np.array([5]))
    assert order == [(0, "pickup"), (0, "dropoff")]
    assert exact_stop_length(order, dist) == 1 + 3
    # at one step a drop-off happens before a pick-up, as in the env
    assert service_order(np.array([1, 3]), np.array([3, 4])) == [
        (0, "pickup"), (0, "dropoff"), (1, "pickup"), (1, "dropoff")
    ]  # fmt: skip


def test_planner_bad_input():
    with pytest.raises(ValueError, match=r"unknown planner 'dijkstra'; choose one of"):
        PlannerPolicy("dijkstra")
    with pytest.raises(ValueError, match=r"flies one taxi in one env; got num_envs=1, num_taxis=2"):
        PlannerPolicy("raster_opt").reset(VectorEnv(uamfleet.make_config("berlin_p4", num_taxis=2), 1, autoreset=False))


CORNER_ONLY = """
..##
..##
##..
##..
"""  # two open quarters touching only at the corner (200, 200)


def test_stop_reachable_only_through_a_corner_is_named_with_the_threshold():
    # The env's block rule lets a 45° step cut the corner, so the env accepts the instance; the planners' raster
    # graph never cuts corners, so it must refuse it loudly, naming the passenger and the threshold.
    from uamfleet.paths.grid_graph import UnreachableStopError

    cfg = small_config(CORNER_ONLY, starts_m=((50.0, 350.0),), requests=(Request(0, (350.0, 50.0), (250.0, 50.0)),),
                       sinr_min_db=-4.0)  # fmt: skip
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    with pytest.raises(UnreachableStopError, match=r"origin of passenger 0 \(P1\).*sinr_min_db=-4 dB"):
        PlannerPolicy("raster_opt").reset(env.sim)


def test_greedy_fleet_serves_a_random_berlin_demand():
    from uamfleet.baselines.greedy_fleet import GreedyFleetPolicy

    cfg = uamfleet.make_config("berlin_random", num_taxis=4)
    traj = run_episode(VectorEnv(cfg, num_envs=1, autoreset=False), GreedyFleetPolicy(), seed=0)
    m = episode_metrics(traj, cfg.radio)
    assert traj.terminated and m.pr_pct == 100.0
    assert cfg.radio.block_map(100.0).feasible(traj.positions_m.reshape(-1, 2), cfg.sinr_min_db).all()
    # every taxi took part
    assert np.all(traj.stacked("pickups").sum(axis=0) > 0)
