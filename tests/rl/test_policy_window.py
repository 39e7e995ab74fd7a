"""A policy flown with a passenger window (``GreedyPolicy.for_fleet(n, passenger_window=K)``): K passenger rows
whatever the number of requests, the instance's own requests and time limit, and the normaliser's passenger
statistics pooled over rows (a row no longer stands for one request index)."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import uamfleet
from uamfleet.config import ConfigError
from uamfleet.instances import make_fleet_instance
from uamfleet.rl.policy import GreedyPolicy


@pytest.fixture(scope="module")
def shipped() -> GreedyPolicy:
    return uamfleet.pretrained("berlin_fleet_v1")


def test_a_windowed_policy_reads_k_rows_and_keeps_the_instances_requests_and_time_limit(shipped: GreedyPolicy) -> None:
    assert shipped.passenger_window is None and shipped.passenger_slots == 24
    cfg = make_fleet_instance("berlin", 0, 8, 96)
    with pytest.raises(ValueError, match="this policy reads 48 passenger slots"):
        shipped.for_fleet(8).layout(cfg)  # without a window: the episode's requests must fit the axis
    policy = shipped.for_fleet(8, passenger_window=24)
    assert policy.passenger_window == 24 and policy.passenger_slots == 24
    assert policy.obs_shapes is not None and policy.obs_shapes["passengers"] == (24, 12)
    assert policy.obs_shapes["stop_claims"] == (24, 2) and policy.obs_shapes["others"] == (7, 3)
    flown = policy.layout(cfg)
    assert flown.passenger_window == 24 and flown.num_passengers == 96
    assert flown.time_limit_steps == cfg.time_limit_steps and flown.requests == cfg.requests
    assert flown.stop_claims and flown.num_taxis == 8
    assert policy.for_fleet(2).passenger_window == 24  # it keeps its window at another fleet size


def test_the_passenger_statistics_are_pooled_over_rows_under_a_window(shipped: GreedyPolicy) -> None:
    trained = shipped.normalizer.fields["passengers"]
    assert not np.allclose(trained.mean, trained.mean[:1]), "the trained rows differ (else the test cannot fail)"
    pooled_mean = trained.mean.mean(0)
    pooled_var = (trained.var + trained.mean**2).mean(0) - pooled_mean**2
    for taxis in (4, 8):  # also at the trained fleet size and row count, where no resize would happen
        stats = shipped.for_fleet(taxis, passenger_window=24).normalizer.fields["passengers"]
        np.testing.assert_allclose(stats.mean, np.broadcast_to(pooled_mean, (24, 12)), rtol=1e-6, atol=1e-9)
        np.testing.assert_allclose(stats.var, np.broadcast_to(pooled_var, (24, 12)), rtol=1e-5, atol=1e-9)
    assert shipped.for_fleet(4) is shipped  # without a window nothing changes


def test_bad_windows_are_refused_with_the_fix(shipped: GreedyPolicy) -> None:
    with pytest.raises(ValueError, match="give one"):
        shipped.for_fleet(8, passenger_slots=48, passenger_window=24)
    with pytest.raises(ConfigError, match="passenger_window=1 must be an integer in \\[2, "):
        shipped.for_fleet(8, passenger_window=1)  # the taxis have 2 seats: a window must hold its riders


def test_the_fleet_benchmark_flies_a_window_for_learned_fleets_only(capsys: pytest.CaptureFixture[str]) -> None:
    from uamfleet.cli.fleet_benchmark import cli, learned_name

    assert cli(["--settings", "8x200", "--count", "1", "--passenger-window", "24"]) == 2
    assert "--passenger-window 24 applies to learned fleets: give --checkpoints" in capsys.readouterr().err
    shipped = Path("uamfleet/data/pretrained/berlin_fleet.pt")
    assert (
        learned_name(shipped, 24) == "learned:berlin_fleet+window24" and learned_name(shipped) == "learned:berlin_fleet"
    )


def test_a_windowed_policy_names_its_window_for_an_observation_of_every_request(shipped: GreedyPolicy) -> None:
    policy = shipped.for_fleet(8, passenger_window=24)
    every_request = {k: np.zeros((1, 8, 96, *v[1:])) if k == "passengers" else np.zeros((1, 8, *v))
                     for k, v in (policy.obs_shapes or {}).items()}  # fmt: skip
    with pytest.raises(ValueError, match=r"'passengers' \(96, 12\) \(trained on \(24, 12\)\).*passenger_window=24"):
        policy(every_request)
