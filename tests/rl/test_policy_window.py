"""A policy flown with a passenger window (``learned:source=...,passenger_window=K``, ``GreedyPolicy.reading``): K
passenger rows whatever the number of requests, the instance's own requests and time limit, and the normaliser's
passenger statistics pooled over rows (a row no longer stands for one request index)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import uamfleet
from uamfleet.config import ConfigError
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance
from uamfleet.policies import make
from uamfleet.rl.policy import GreedyPolicy


@pytest.fixture(scope="module")
def shipped() -> GreedyPolicy:
    return uamfleet.pretrained("berlin_fleet_v1")


def _windowed(source: str = "berlin_fleet_v1", window: int = 24) -> GreedyPolicy:
    return make("learned", source=source, passenger_window=window)


def test_a_windowed_policy_reads_k_rows_and_keeps_the_instances_requests_and_time_limit(shipped: GreedyPolicy) -> None:
    assert shipped.passenger_window is None and shipped.passenger_slots == 24
    cfg = make_fleet_instance("berlin", 0, 8, 96, hover_action=False)
    with pytest.raises(ConfigError, match="the world has 96 passenger rows; this policy reads 48"):
        shipped.fly(cfg)  # without a window: the episode's requests must fit the axis (6 rows per taxi)
    policy = _windowed()
    assert policy.spec is not None and policy.spec.passenger_window == 24 and policy.passenger_slots == 24
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=policy.spec)
    policy.reset(env.sim)
    shapes = policy.fitted()[2]
    assert shapes is not None and shapes["passengers"] == (24, 12)
    assert shapes["stop_claims"] == (24, 2) and shapes["others"] == (7, 3)
    assert env.single_observation_space["passengers"].shape == (24, 12)
    assert env.cfg.num_passengers == 96 and env.cfg.time_limit_steps == cfg.time_limit_steps  # the world as made
    assert env.cfg.requests == cfg.requests and env.cfg.num_taxis == 8
    policy.fit(make_fleet_instance("berlin", 0, 2, 12, hover_action=False).world)
    assert policy.fitted()[2]["passengers"] == (24, 12)  # it keeps its window at another fleet size


def test_the_passenger_statistics_are_pooled_over_rows_under_a_window(shipped: GreedyPolicy) -> None:
    trained = shipped.normalizer.fields["passengers"]
    assert not np.allclose(trained.mean, trained.mean[:1]), "the trained rows differ (else the test cannot fail)"
    pooled_mean = trained.mean.mean(0)
    pooled_var = (trained.var + trained.mean**2).mean(0) - pooled_mean**2
    policy = _windowed()
    for taxis in (4, 8):  # also at the trained fleet size and row count, where no resize would happen
        policy.fit(make_fleet_instance("berlin", 0, taxis, 6 * taxis, hover_action=False).world)
        normalizer = policy.fitted()[1]
        assert normalizer is not None
        stats = normalizer.fields["passengers"]
        np.testing.assert_allclose(stats.mean, np.broadcast_to(pooled_mean, (24, 12)), rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(stats.var, np.broadcast_to(pooled_var, (24, 12)), rtol=1e-5, atol=1e-9)
    assert shipped.spec is not None and shipped.reading(shipped.spec) is shipped  # the same spec: nothing changes
    shipped.fit(make_fleet_instance("berlin", 0, 4, 24, hover_action=False).world)
    assert shipped.fitted()[1] is shipped.normalizer  # its trained fleet, rows and no window: as built


def test_bad_windows_are_refused_with_the_fix(shipped: GreedyPolicy) -> None:
    with pytest.raises(ValueError, match="give one"):
        make("learned", source="berlin_fleet_v1", passenger_slots=48, passenger_window=24)
    with pytest.raises(ConfigError, match="passenger_window=1 must be an integer in \\[2, "):
        _windowed(window=1).fly(make_fleet_instance("berlin", 0, 8, 48, hover_action=False))  # 2 seats: K >= 2


def test_the_fleet_benchmark_flies_a_window_for_learned_fleets_only(capsys: pytest.CaptureFixture[str]) -> None:
    from uamfleet.cli.fleet_benchmark import cli, learned_name

    assert cli(["--settings", "8x200", "--count", "1", "--passenger-window", "24"]) == 2
    assert "--passenger-window 24 applies to learned fleets: give --checkpoints" in capsys.readouterr().err
    shipped = Path("uamfleet/data/pretrained/berlin_fleet.pt")
    assert (
        learned_name(shipped, 24) == "learned:berlin_fleet+window24" and learned_name(shipped) == "learned:berlin_fleet"
    )


def test_a_windowed_policy_names_its_window_for_an_observation_of_every_request(shipped: GreedyPolicy) -> None:
    policy = _windowed()
    policy.fit(make_fleet_instance("berlin", 0, 8, 96, hover_action=False).world)
    every_request = {k: np.zeros((1, 8, 96, *v[1:])) if k == "passengers" else np.zeros((1, 8, *v))
                     for k, v in (policy.fitted()[2] or {}).items()}  # fmt: skip
    with pytest.raises(ValueError, match=r"'passengers' \(96, 12\) \(trained on \(24, 12\)\).*passenger_window=24"):
        policy(every_request)
