"""Issue 22, part 3 leftovers: a fleet size of 0 names the fleet size, a pretrained policy flown outside the
thresholds it trained on warns once, a minibatch count that does not divide the batch is refused."""

from __future__ import annotations

import warnings
from pathlib import Path

import pytest
import torch

import uamfleet
from uamfleet.config import ConfigError
from uamfleet.rl.trainer import TrainArgs, train
from uamfleet.policies import make
from uamfleet.policies.learned import LearnedOptions
from uamfleet.zoo import pretrained, pretrained_path


@pytest.fixture(scope="module")
def fleet_policy():
    return pretrained("berlin_fleet_v1")


@pytest.mark.parametrize("size", [0, -1, 2.5, True, "4", 10**6])
def test_the_learned_options_name_the_fleet_size(size):
    with pytest.raises(ConfigError, match=rf"^taxis={size!r} .*1024") as err:
        LearnedOptions(source="berlin_fleet_v1", taxis=size, passenger_slots=24)
    assert "max_requests" not in str(err.value)  # the old message blamed the demand


def trained_thresholds(name: str) -> tuple[float, float]:
    """The lowest and highest threshold in the shipped checkpoint's own training arguments (read here directly)."""
    args = torch.load(pretrained_path(name), weights_only=True)["args"]
    assert args["thresholds"], "the shipped generalist trains on a mixture of thresholds"
    return min(args["thresholds"]), max(args["thresholds"])


def test_pretrained_warns_once_outside_its_training_thresholds():
    planner = pretrained("berlin")
    assert planner.thresholds_db == trained_thresholds("berlin") == (-7.0, -3.0)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # inside the range: silent
        for inside in (-7.0, -5.0, -3.0):
            planner.fit(uamfleet.make_config("berlin_p4", sinr_min_db=inside).world)
    with pytest.warns(UserWarning, match=r"sinr_min_db=-8 dB lies outside .* \(-7 \.\.\. -3 dB\)"):
        planner.fit(uamfleet.make_config("berlin_p4", sinr_min_db=-8.0).world)
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per policy: a sweep does not repeat it
        planner.fit(uamfleet.make_config("berlin_p4", sinr_min_db=-2.0).world)
    with pytest.warns(UserWarning, match=r"sinr_min_db=-2 dB"):  # a fresh policy warns again
        pretrained("berlin").fly(uamfleet.make_config("berlin_p4", sinr_min_db=-2.0))


def test_a_fleet_sized_policy_keeps_the_threshold_range(fleet_policy):
    trained = trained_thresholds("berlin_fleet_v1")
    windowed = make("learned", source="berlin_fleet_v1", passenger_window=24)
    assert windowed is not fleet_policy and windowed.thresholds_db == fleet_policy.thresholds_db == trained


def test_minibatches_that_do_not_divide_the_batch_are_refused_before_a_run_starts(tmp_path: Path):
    # 2 envs x 8 steps x 1 taxi = 16 agent-steps: 3 minibatches would be 5 + 5 + 5 + a silent fourth of 1
    args = TrainArgs.from_flat(dict(
        scenario="berlin_p4", num_envs=2, num_steps=8, num_minibatches=3, total_timesteps=16, run_dir=tmp_path,
        run_name="mb", eval_every=0, threads=1,
    ))  # fmt: skip
    with pytest.raises(ConfigError, match=r"--num-minibatches=3 does not divide the batch of 16 .* e\.g\. 2"):
        train(args)
    assert not (tmp_path / "mb").exists()
