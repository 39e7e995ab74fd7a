"""The fleet dispatchers fly through the separation shield (docs/rules.md "Separation shield"): on a drawn scene
where four taxis from the corners converge on four requests at the centre they lose separation without it, and
with it lose none and still deliver everyone."""

from __future__ import annotations

import pytest
from conftest import small_config

from uamfleet.baselines import make_policy
from uamfleet.baselines.fleet_dispatch import DISPATCHERS
from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.metrics import episode_metrics
from uamfleet.rollout import run_episode

OPEN_10 = "\n".join(["." * 10] * 10)
CORNERS = ((150.0, 150.0), (850.0, 150.0), (150.0, 850.0), (850.0, 850.0))
CENTRE_REQUESTS = (
    Request(0, (450.0, 450.0), (850.0, 850.0)),
    Request(0, (550.0, 450.0), (150.0, 850.0)),
    Request(0, (450.0, 550.0), (850.0, 150.0)),
    Request(2, (550.0, 550.0), (150.0, 150.0)),
)


@pytest.mark.parametrize("name", ["greedy", *DISPATCHERS])
def test_dispatchers_deliver_everyone_without_losing_separation_under_the_shield(name):
    metrics = {}
    for separation in ("none", "shield"):
        cfg = small_config(
            OPEN_10, starts_m=CORNERS, requests=CENTRE_REQUESTS, separation=separation, time_limit_steps=200
        )
        traj = run_episode(VectorEnv(cfg, num_envs=1, autoreset=False), make_policy(name, num_taxis=4), seed=0)
        metrics[separation] = episode_metrics(traj, cfg.radio)
    assert metrics["none"].separation_violations > 0 and metrics["none"].shield_interventions == 0
    shielded = metrics["shield"]
    assert shielded.separation_violations == 0 and shielded.shield_interventions > 0
    assert shielded.delivered == 4 and shielded.hovers <= shielded.shield_interventions


@pytest.mark.parametrize("name", ["greedy", *DISPATCHERS])
def test_dispatchers_with_the_hover_action_deliver_everyone_under_the_shield(name):
    # The same scene with the hover action: taxis idle after their drop-off hover (action 16) where they are.
    cfg = small_config(
        OPEN_10, starts_m=CORNERS, requests=CENTRE_REQUESTS, separation="shield", hover_action=True,
        time_limit_steps=200,
    )  # fmt: skip
    traj = run_episode(VectorEnv(cfg, num_envs=1, autoreset=False), make_policy(name, num_taxis=4), seed=0)
    m = episode_metrics(traj, cfg.radio)
    assert (m.separation_violations, m.delivered) == (0, 4)
    assert m.hovers >= m.hover_actions


@pytest.mark.slow
def test_the_8_taxi_episode_that_deadlocked_under_the_first_shield_delivers_everyone():
    # batch_assignment, Berlin 8 x 48, test seed 2000005 (docs/results/fleet_shield_100.csv: 46 of 48 delivered, two
    # taxis turned aside side by side every step from step 139 to the time limit). Under the yield rule and the
    # stayed-longest-first order (docs/rules.md "Separation shield") everyone is delivered, without a violation.
    from uamfleet.instances import make_fleet_instance
    from uamfleet.rollout import fly

    cfg = make_fleet_instance("berlin", 2000005, 8, 48, separation="shield")
    m = episode_metrics(fly(cfg, make_policy("batch_assignment", num_taxis=8)), cfg.radio)
    assert (m.delivered, m.separation_violations) == (48, 0)
