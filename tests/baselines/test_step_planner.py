"""The step-level planners: against a brute-force search of every move sequence on a tiny open map, the replayed
route against the promised one, and the lower bound against hand-computed values and the plans found."""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from conftest import brute_force_moves, small_config

from uamfleet.baselines.step_planner import (
    SearchSettings,
    StepPlannerPolicy,
    StepSearch,
    instance_lower_bound_m,
    lower_bound_m,
    remaining_tables,
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


def _rest_by_enumeration(dist: np.ndarray, seats: int, phases: list[int], at: int) -> float:
    """The least sum of ``dist`` legs from stop ``at`` through every stop still to serve (phases 0: pick-up and
    drop-off to go, 1: drop-off to go), over every order that keeps pick-up before drop-off and the seats."""
    todo = [2 * i for i, ph in enumerate(phases) if ph == 0] + [2 * i + 1 for i, ph in enumerate(phases) if ph < 2]
    best = math.inf if todo else 0.0
    for order in itertools.permutations(todo):
        on_board, served, length, here, ok = sum(ph == 1 for ph in phases), set(), 0.0, at, True
        for stop in order:
            if stop % 2 == 0:
                on_board += 1
            elif stop - 1 in todo and stop - 1 not in served:
                ok = False  # a drop-off before its pick-up
            else:
                on_board -= 1
            if not ok or on_board > seats:
                ok = False
                break
            served.add(stop)
            length, here = length + dist[here, stop], stop
        if ok:
            best = min(best, length)
    return best


@pytest.mark.parametrize("seats", [1, 2])
def test_remaining_tables_against_every_stop_order(seats: int) -> None:
    """The compiled tour DP (next_cost[c, s]: the least rest of the tour after serving s from code c) against an
    enumeration of every stop order of up to 3 passengers, legs shortened by a slack and rounded up to steps."""
    rng = np.random.default_rng(seats)
    for num_pax in (1, 2, 3):
        dist = rng.uniform(0.0, 2_000.0, (2 * num_pax, 2 * num_pax))
        slack, step = 150.0, 100.0
        legs = step * np.ceil(np.maximum(dist - slack, 0.0) / step - 1e-9)
        next_cost, after = remaining_tables(dist, seats, slack, step)
        for code in range(3**num_pax):
            phases = [int(p) for p in np.unravel_index(code, (3,) * num_pax)]
            for s in range(2 * num_pax):
                i, pick = s // 2, s % 2 == 0
                allowed = (phases[i] == 0 and pick and sum(p == 1 for p in phases) < seats) or (
                    phases[i] == 1 and not pick
                )
                if not allowed:
                    assert after[code, s] == -1 and next_cost[code, s] == math.inf
                    continue
                served = list(phases)
                served[i] += 1
                assert after[code, s] == sum(p * 3 ** (num_pax - 1 - k) for k, p in enumerate(served))
                assert next_cost[code, s] == pytest.approx(_rest_by_enumeration(legs, seats, served, s), abs=1e-9)
