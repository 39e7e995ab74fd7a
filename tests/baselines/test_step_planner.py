"""The step-level planners: against a brute-force search of every move sequence on a tiny open map, the replayed
route against the promised one, and the lower bound against hand-computed values and the plans found."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import brute_force_moves, small_config

from uamfleet.baselines.step_planner import (
    SearchSettings,
    StepPlannerPolicy,
    StepSearch,
    instance_lower_bound_m,
    lower_bound_m,
)
from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.metrics import episode_metrics
from uamfleet.rollout import fly

OPEN_7 = "\n".join(["......."] * 7)


TINY = [
    ((150.0, 150.0), (Request(0, (420.0, 180.0), (520.0, 430.0)),)),
    ((110.0, 620.0), (Request(0, (380.0, 560.0), (600.0, 330.0)), Request(0, (230.0, 400.0), (470.0, 420.0)))),
    ((650.0, 80.0), (Request(0, (400.0, 280.0), (190.0, 440.0)), Request(0, (500.0, 300.0), (180.0, 400.0)))),
]  # optima 4, 5 and 5 moves (two passengers share the taxi in the last two)


@pytest.mark.parametrize(("start", "requests"), TINY)
def test_step_search_matches_brute_force_on_a_tiny_map(start, requests):
    cfg = small_config(OPEN_7, starts_m=(start,), requests=requests, time_limit_steps=40)
    optimum = brute_force_moves(start, requests, cfg.side_m, cfg.step_m, cfg.radius_m, cfg.seats, max_moves=6)
    assert optimum is not None and optimum >= 3  # the instances are not trivial
    env = VectorEnv(cfg, 1, autoreset=False)
    env.reset(seed=0)
    plan = StepSearch(cfg).solve(env.state, [SearchSettings(beam=256, rank_slack=0.0)])
    assert plan is not None and plan.moves == optimum
    assert instance_lower_bound_m(cfg) <= optimum * cfg.step_m


@pytest.mark.parametrize(("start", "requests"), TINY[1:])
def test_best_known_replayed_scores_the_td_it_promised(start, requests):
    cfg = small_config(OPEN_7, starts_m=(start,), requests=requests, time_limit_steps=40)
    policy = StepPlannerPolicy("best_known", [SearchSettings(beam=64, rank_slack=1.0)])
    traj = fly(cfg, policy)
    m = episode_metrics(traj, cfg.radio)
    assert m.pr_pct == 100.0
    assert m.td_m == policy.plans[0].moves * cfg.step_m
    assert m.completion_s == policy.plans[0].steps * cfg.slot_s
    assert policy.lower_bound_m <= m.td_m


def test_replan_resolves_when_a_request_is_released_and_delivers_everyone():
    requests = (Request(0, (380.0, 560.0), (600.0, 130.0)), Request(6, (230.0, 300.0), (470.0, 420.0)))
    cfg = small_config(OPEN_7, starts_m=((110.0, 620.0),), requests=requests, time_limit_steps=60)
    policy = StepPlannerPolicy("replan")
    traj = fly(cfg, policy)
    assert traj.terminated and traj.episode["delivered"] == 2
    assert len(policy.plans) == 2  # one plan at the start (P1 only), one when P2 appears at step 6
    assert policy.plans[0].moves > 0 and policy.plans[1].steps > 0


def test_best_known_waits_for_a_late_release_rather_than_failing():
    # the only passenger appears at step 8 next to the start: the plan must wait (or loop) and then serve it
    requests = (Request(8, (250.0, 150.0), (550.0, 150.0)),)
    cfg = small_config(OPEN_7, starts_m=((150.0, 150.0),), requests=requests, time_limit_steps=40)
    policy = StepPlannerPolicy("best_known", [SearchSettings(beam=64)])
    traj = fly(cfg, policy)
    assert traj.terminated
    assert traj.stacked("picked_up")[:, 0].argmax() + 1 >= 9  # pickable only after the release step


def test_lower_bound_by_hand():
    # one passenger: 1000 m to the origin disc (less 100 m), then 500 m between the discs (less 2 x 100 m)
    assert lower_bound_m(np.zeros(2), np.array([[1000.0, 0.0], [1000.0, 500.0]]), 2, 100.0, 100.0) == 1200.0
    # rounded up to whole steps: 950 - 100 + 0 (the destination disc overlaps the origin disc) -> 850 -> 900
    assert lower_bound_m(np.zeros(2), np.array([[950.0, 0.0], [950.0, 150.0]]), 2, 100.0, 100.0) == 900.0
    # two passengers on a line, one seat: 0 -> P0 (1000 -> 2000) -> P1 (2000 -> 3000): 900 + 800 + 0 + 800
    stops = np.array([[1000.0, 0.0], [2000.0, 0.0], [2000.0, 0.0], [3000.0, 0.0]])
    assert lower_bound_m(np.zeros(2), stops, 1, 100.0, 100.0) == 2500.0
    # each leg is whole steps: 1050 - 100 -> 1000, then 350 - 200 -> 200 (the sum rounded once would be 1100)
    assert lower_bound_m(np.zeros(2), np.array([[1050.0, 0.0], [1050.0, 350.0]]), 2, 100.0, 100.0) == 1200.0


@pytest.mark.slow
def test_lower_bound_below_best_known_on_berlin_test_instances():
    from uamfleet.instances import make_instance, split_seeds

    for seed in split_seeds("test", 2):
        cfg = make_instance("berlin", seed)
        policy = StepPlannerPolicy("best_known", [SearchSettings(beam=128, rank_slack=1.0)])
        m = episode_metrics(fly(cfg, policy), cfg.radio)
        assert m.pr_pct == 100.0 and policy.lower_bound_m <= m.td_m
