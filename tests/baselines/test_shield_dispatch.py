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
