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
from uamfleet.zoo import pretrained, pretrained_path


@pytest.fixture(scope="module")
def fleet_policy():
    return pretrained("berlin_fleet_v1")


@pytest.mark.parametrize("size", [0, -1, 2.5, True, "4", 10**6])
def test_for_fleet_names_the_fleet_size(fleet_policy, size):
    with pytest.raises(ConfigError, match=rf"^num_taxis={size!r} .*1024") as err:
        fleet_policy.for_fleet(size)
    assert "max_requests" not in str(err.value)  # the old message blamed the demand


def test_a_resized_policy_on_another_fleet_names_both_sizes(fleet_policy):
    eight = fleet_policy.for_fleet(8)
    with pytest.raises(ValueError, match=r"2 taxi\(s\); this policy is laid out for 8 \(its weights were trained "
                       r"with 4\).*for_fleet\(2\)"):  # fmt: skip
        eight.layout(uamfleet.make_config("berlin_fleet", num_taxis=2))


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
            planner.layout(uamfleet.make_config("berlin_p4", sinr_min_db=inside))
    with pytest.warns(UserWarning, match=r"sinr_min_db=-8 dB lies outside .* \(-7 \.\.\. -3 dB\)"):
        planner.layout(uamfleet.make_config("berlin_p4", sinr_min_db=-8.0))
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # once per policy: a sweep does not repeat it
        planner.layout(uamfleet.make_config("berlin_p4", sinr_min_db=-2.0))
    with pytest.warns(UserWarning, match=r"sinr_min_db=-2 dB"):  # a fresh policy warns again
        pretrained("berlin").layout(uamfleet.make_config("berlin_p4", sinr_min_db=-2.0))


def test_a_fleet_sized_policy_keeps_the_threshold_range(fleet_policy):
    trained = trained_thresholds("berlin_fleet_v1")
    assert fleet_policy.for_fleet(2).thresholds_db == fleet_policy.thresholds_db == trained


def test_minibatches_that_do_not_divide_the_batch_are_refused_before_a_run_starts(tmp_path: Path):
    # 2 envs x 8 steps x 1 taxi = 16 agent-steps: 3 minibatches would be 5 + 5 + 5 + a silent fourth of 1
    args = TrainArgs.from_flat(dict(
        scenario="berlin_p4", num_envs=2, num_steps=8, num_minibatches=3, total_timesteps=16, run_dir=tmp_path,
        run_name="mb", eval_every=0, threads=1,
    ))  # fmt: skip
    with pytest.raises(ConfigError, match=r"--num-minibatches=3 does not divide the batch of 16 .* e\.g\. 2"):
        train(args)
    assert not (tmp_path / "mb").exists()
