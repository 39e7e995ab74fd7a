"""The search warm start of a PPO run from scratch (``--warm-start-rounds``, uamfleet.rl.warm_start).

Expectations come from outside the warm start: the tour of ``replan`` (the planner the labels come from) flown by
the rollout core, the trainer's own KL column, and the files a run writes."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import pytest
import torch
from conftest import small_config

from uamfleet.baselines.step_planner import SearchSettings, StepPlannerPolicy
from uamfleet.config import ConfigError, Request
from uamfleet.metrics import episode_metrics
from uamfleet.rl import warm_start
from uamfleet.rl.trainer import TrainArgs, load_policy, train
from tests.rl import test_schedules as schedules
from uamfleet.rollout import fly

TWO_PASSENGERS = small_config(
    requests=(Request(0, (350.0, 150.0), (350.0, 350.0)), Request(0, (150.0, 350.0), (250.0, 450.0))),
    time_limit_steps=40,
)


def tiny_args(tmp_path: Path, **overrides: object) -> TrainArgs:
    """test_schedules' tiny run with iterations of 4 envs x 16 steps, a two-round warm start and the KL term."""
    warm = dict(
        total_timesteps=2 * 4 * 16, num_envs=4, num_steps=16, num_minibatches=2, time_limit_steps=40,
        eval_time_limit_steps=40, learning_rate=3e-4, warm_start_rounds=2, kl_to_init=0.05, run_name="warm",
    )  # fmt: skip
    return schedules.tiny_args(tmp_path, **{**warm, **overrides})


def progress(run: Path) -> list[dict[str, str]]:
    with (run / "progress.csv").open(encoding="utf-8") as f:
        return list(csv.DictReader(f))


@pytest.mark.slow
def test_a_warm_started_network_flies_the_search_tour(tmp_path):
    """From random weights, two rounds of labels make the greedy network fly ``replan``'s own distance on a
    two-passenger world: iteration 0 of progress.csv is the warm start's evaluation, before any PPO update."""
    search = [SearchSettings(beam=warm_start.EXPERT_BEAM, rank_slack=0.5)]  # the expert's settings
    replan = episode_metrics(fly(TWO_PASSENGERS, StepPlannerPolicy("replan", search)), TWO_PASSENGERS.radio)
    assert replan.pr_pct == 100.0
    result = train(tiny_args(tmp_path, total_timesteps=4 * 16), env_config=TWO_PASSENGERS)
    start = progress(result.run_dir)[0]
    assert start["iteration"] == "0" and float(start["warm/labels"]) > 0 and float(start["warm/solves"]) > 0
    assert float(start["eval/pr_pct"]) == 100.0
    assert float(start["eval/td_m"]) == pytest.approx(replan.td_m)


def test_the_warm_start_is_the_kl_reference_and_a_resumed_run_reads_it_back(tmp_path, monkeypatch):
    """A run of one iteration, resumed to two: the reference saved at the warm start is the network of iteration 0
    (best.pt, written by that evaluation before PPO), the KL column is logged after every update, and the resumed
    run neither warm-starts again nor leaves the statistics the labels were fitted on."""
    args = tiny_args(tmp_path, total_timesteps=4 * 16, warm_start_rounds=1)
    train(args, env_config=TWO_PASSENGERS)
    folder = tmp_path / "warm"
    reference = torch.load(folder / warm_start.REFERENCE_FILE, weights_only=True)
    rows = progress(folder)
    if float(rows[1]["eval/td_m"]) >= float(rows[0]["eval/td_m"]):  # best.pt is still the warm start's
        best = torch.load(folder / "best.pt", weights_only=True)["model"]
        assert all(torch.equal(reference[k], best[k]) for k in reference)
    before = torch.load(folder / "last.pt", weights_only=True)["obs_normalizer"]

    def no_second_warm_start(*a, **k):
        raise AssertionError("a resumed run warm-starts again")

    monkeypatch.setattr(warm_start, "search_warm_start", no_second_warm_start)
    train(dataclasses.replace(args).with_options(total_timesteps=2 * 4 * 16, resume=True), env_config=TWO_PASSENGERS)
    rows = progress(folder)
    assert [r["iteration"] for r in rows] == ["0", "1", "2"]
    assert all(float(r["losses/kl_to_init"]) >= 0 and r["losses/kl_to_init"] != "" for r in rows[1:])
    after = torch.load(folder / "last.pt", weights_only=True)["obs_normalizer"]
    for name, stats in before.items():
        assert all(torch.equal(torch.as_tensor(stats[k]), torch.as_tensor(after[name][k])) for k in stats), name
    policy, _ = load_policy(folder / "last.pt")  # a warm-started run's checkpoint loads like any other
    assert policy.fly(TWO_PASSENGERS) is not None


def test_warm_start_refusals(tmp_path):
    with pytest.raises(ConfigError, match="--warm-start-rounds=2 warm-starts a network from scratch"):
        tiny_args(tmp_path, init_from="berlin")
    with pytest.raises(ConfigError, match=r"--kl-to-init=0\.05 pulls the policy toward the one it starts from"):
        tiny_args(tmp_path, warm_start_rounds=0)
    with pytest.raises(ConfigError, match="--warm-start-rounds=-1"):
        tiny_args(tmp_path, warm_start_rounds=-1)
    two_taxis = small_config(starts_m=((150.0, 150.0), (250.0, 150.0)), time_limit_steps=40)
    with pytest.raises(ConfigError, match="labels one taxi per env in one process; this run has 2 taxi"):
        train(tiny_args(tmp_path, run_name="two"), env_config=two_taxis)
