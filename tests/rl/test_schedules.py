"""The trainer's schedules (learning rate, shaping weight) on the two clocks, and the validation curve's flights.

Every expected value is written out by hand from the documented shapes: with ``--schedule-clock steps`` the
learning rate is ``lr0 (1 - i / n)`` at iteration i of n and the shaping weight decays linearly to 0 over the last
``--shaping-anneal-frac`` of the run; with ``first_delivery`` both hold their start values until the iteration after
the first greedy evaluation that delivered everyone, then follow the same shapes over the iterations left."""

from __future__ import annotations

import csv
import dataclasses
from pathlib import Path

import pytest
from conftest import small_config

from uamfleet import instances
from uamfleet.config import ConfigError, Request
from uamfleet.instances import fly_instances, split_seeds
from uamfleet.rl import trainer
from uamfleet.rl.learner import schedule
from uamfleet.rl.trainer import TrainArgs, load_policy, train

ONE_PASSENGER = small_config(requests=(Request(0, (350.0, 150.0), (350.0, 350.0)),), time_limit_steps=30)


def tiny_args(tmp_path: Path, **overrides: object) -> TrainArgs:
    """A run of 8 iterations of 2 envs x 8 steps (one taxi) on ``ONE_PASSENGER``."""
    base = dict(
        total_timesteps=8 * 2 * 8, num_envs=2, num_steps=8, num_minibatches=1, update_epochs=1, eval_every=1,
        checkpoint_every=1, run_dir=tmp_path, run_name="tiny", progress=False, tensorboard=False, threads=1,
        time_limit_steps=30, eval_time_limit_steps=30, d_model=16, num_heads=2, learning_rate=1e-3, shaping=40.0,
        shaping_anneal_frac=0.5, device="cpu",
    )  # fmt: skip
    base.update(overrides)
    return TrainArgs.from_flat(base)


def progress(run: Path) -> list[dict[str, str]]:
    with (run / "progress.csv").open(encoding="utf-8") as f:
        return list(csv.DictReader(f))


def test_the_steps_clock_decays_over_the_whole_run():
    args = tiny_args(Path("unused"))
    # n = 10, lr0 = 1e-3, shaping 40 annealed over the last half: iterations 5 ... 9 at 40 (1 - (i - 5) / 5)
    expected = {0: (1e-3, 40.0), 3: (7e-4, 40.0), 5: (5e-4, 40.0), 6: (4e-4, 32.0), 9: (1e-4, 8.0)}
    for i, (lr, weight) in expected.items():
        assert schedule(args, 10, i) == pytest.approx((lr, weight)), i
        assert schedule(args, 10, i, clock_start=4) == pytest.approx((lr, weight)), i  # the steps clock ignores it
    flat = tiny_args(Path("unused"), anneal_lr=False, shaping_anneal_frac=0.0)
    assert schedule(flat, 10, 7) == (1e-3, 40.0)


def test_the_first_delivery_clock_holds_the_start_values_until_everyone_is_delivered():
    args = tiny_args(Path("unused"), schedule_clock="first_delivery")
    for i in (0, 4, 9):
        assert schedule(args, 10, i, clock_start=None) == (1e-3, 40.0)
    # delivered after iteration 3 (clock_start 4): 6 iterations left, lr0 (1 - (i - 4) / 6), the shaping anneal over
    # their last half (iterations 7, 8, 9): 40 (1 - (i - 7) / 3)
    expected = {4: (1e-3, 40.0), 5: (1e-3 * 5 / 6, 40.0), 7: (5e-4, 40.0), 8: (1e-3 / 3, 40.0 * 2 / 3),
                9: (1e-3 / 6, 40.0 / 3)}  # fmt: skip
    for i, (lr, weight) in expected.items():
        assert schedule(args, 10, i, clock_start=4) == pytest.approx((lr, weight)), i
    steps = tiny_args(Path("unused"))
    for i in range(10):  # delivered by the start's own evaluation (a fine-tuning run): the steps schedule
        assert schedule(args, 10, i, clock_start=0) == schedule(steps, 10, i)


def fake_evaluations(delivered_from: int):
    """A stand-in for the greedy evaluation: the row of iteration k (1-based, as progress.csv counts) delivers
    everyone from ``delivered_from`` on, half before; it is never a new best."""

    def evaluate(run, learner, counters, row, last=False):
        row["eval/pr_pct"] = 100.0 if row["iteration"] >= delivered_from else 50.0
        row["eval/td_m"] = 1000.0
        return False

    return evaluate


def test_a_run_on_the_first_delivery_clock_starts_its_schedules_at_the_first_delivering_evaluation(tmp_path):
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(trainer, "evaluate_greedy", fake_evaluations(delivered_from=3))
        train(tiny_args(tmp_path, schedule_clock="first_delivery"), env_config=ONE_PASSENGER)
    rows = progress(tmp_path / "tiny")
    # rows 1-3 (iterations 0-2) at the start values; row 3 delivered, so the clock starts at iteration 3: 5 left,
    # lr 1e-3 (1 - (i - 3) / 5); shaping annealed over the last 2.5 of them: 40 (1 - (i - 5.5) / 2.5), capped at 40
    lr = [1e-3, 1e-3, 1e-3, 1e-3, 8e-4, 6e-4, 4e-4, 2e-4]
    shaping = [40.0] * 6 + [40.0 * 0.8, 40.0 * 0.4]
    assert [float(r["charts/learning_rate"]) for r in rows] == pytest.approx(lr)
    assert [float(r["charts/shaping_weight"]) for r in rows] == pytest.approx(shaping)


def test_a_resumed_run_finds_its_clock_in_its_progress_log(tmp_path):
    """Four iterations, then resumed to eight: the clock started at row 2 (its evaluation delivered), read back from
    progress.csv, so iterations 4-7 follow the schedule of an 8-iteration run that delivered there."""
    with pytest.MonkeyPatch.context() as patch:
        patch.setattr(trainer, "evaluate_greedy", fake_evaluations(delivered_from=2))
        train(tiny_args(tmp_path, schedule_clock="first_delivery", total_timesteps=4 * 2 * 8), env_config=ONE_PASSENGER)
        args = tiny_args(tmp_path, schedule_clock="first_delivery", resume=True)
        train(args, env_config=ONE_PASSENGER)
    rows = progress(tmp_path / "tiny")
    assert len(rows) == 8
    # clock start 2, 6 iterations left: lr 1e-3 (1 - (i - 2) / 6) for iterations 4 ... 7
    assert [float(r["charts/learning_rate"]) for r in rows[4:]] == pytest.approx([1e-3 * k / 6 for k in (4, 3, 2, 1)])


def test_the_first_delivery_clock_needs_evaluations():
    with pytest.raises(ConfigError, match=r"--schedule-clock first_delivery .* --eval-every 0 .* --eval-every >= 1"):
        tiny_args(Path("unused"), schedule_clock="first_delivery", eval_every=0)
    with pytest.raises(ConfigError, match=r"--schedule-clock='hourly' is unknown"):
        tiny_args(Path("unused"), schedule_clock="hourly")


def test_the_curve_flies_the_validation_instances_after_each_evaluation(tmp_path):
    """A P4 run (4 passenger rows) with --curve-instances 3: each evaluation row carries val_td_m / val_pr_pct,
    the mean distance and delivered share of the policy flown on validation instances 1000000-1000002 (up to 6
    requests each), where it reads its 4 nearest requests; flown again here from last.pt by hand. The instances are
    built once per run. The training itself is the run without the curve, to the bit."""
    common = dict(scenario="berlin_p4", sinr_min_db=-3.0, total_timesteps=2 * 2 * 8, time_limit_steps=200,
                  eval_time_limit_steps=200, shaping=50.0)  # fmt: skip
    built = []

    def instance(family: str, seed: int, like: object) -> object:
        built.append(seed)
        return make_instance(family, seed, like)

    with pytest.MonkeyPatch.context() as patch:
        make_instance = instances.instance_for_policy
        patch.setattr(instances, "instance_for_policy", instance)
        train(tiny_args(tmp_path / "curve", curve_instances=3, curve_family="berlin", **common))
    assert built == [1_000_000, 1_000_001, 1_000_002]  # built for the first evaluation, reused by the second
    train(tiny_args(tmp_path / "plain", **common))
    rows, plain = progress(tmp_path / "curve" / "tiny"), progress(tmp_path / "plain" / "tiny")
    assert len(rows) == 2 and all(r["val_td_m"] and r["val_pr_pct"] for r in rows)
    assert "val_td_m" not in plain[0] and "val_pr_pct" not in plain[0]
    for name in ("eval/td_m", "eval/pr_pct", "losses/policy_loss", "losses/value_loss", "charts/learning_rate"):
        assert [r[name] for r in rows] == [r[name] for r in plain], name
    policy, _ = load_policy(tmp_path / "curve" / "tiny" / "last.pt")
    assert policy.spec is not None and policy.trained_on is not None
    window = policy.reading(dataclasses.replace(policy.spec, passenger_window=4, slots_per_taxi=None))
    served, distance = fly_instances(window, "berlin", split_seeds("validation", 3), policy.trained_on.replace(
        max_passengers=6))  # fmt: skip
    assert float(rows[-1]["val_td_m"]) == pytest.approx(distance.mean())
    assert float(rows[-1]["val_pr_pct"]) == pytest.approx(100 * served.mean())


def test_the_curve_is_flown_at_every_nth_evaluation_and_at_the_last(tmp_path):
    """--curve-every 2 on a run of 5 iterations evaluated after each: the validation panel is flown where the row's
    iteration is a multiple of 2 (2 and 4) and at the last (5), never at 1 or 3; the training and its own
    evaluations are those of the run that flies the panel every time, to the bit."""
    common = dict(scenario="berlin_p4", sinr_min_db=-3.0, total_timesteps=5 * 2 * 8, time_limit_steps=60,
                  eval_time_limit_steps=60, curve_instances=2, curve_family="berlin")  # fmt: skip
    train(tiny_args(tmp_path / "every2", curve_every=2, **common))
    train(tiny_args(tmp_path / "every1", **common))
    rows, every = progress(tmp_path / "every2" / "tiny"), progress(tmp_path / "every1" / "tiny")
    assert [int(r["iteration"]) for r in rows] == [1, 2, 3, 4, 5]
    assert [int(r["iteration"]) for r in rows if r["val_td_m"]] == [2, 4, 5]
    for r, e in zip(rows, every, strict=True):
        assert r["eval/td_m"] == e["eval/td_m"] and r["losses/policy_loss"] == e["losses/policy_loss"]
        if r["val_td_m"]:
            assert (r["val_td_m"], r["val_pr_pct"]) == (e["val_td_m"], e["val_pr_pct"])
    with pytest.raises(ConfigError, match=r"--curve-every=0 must be an integer >= 1"):
        tiny_args(Path("unused"), curve_every=0)


def test_the_curve_needs_a_family():
    with pytest.raises(ConfigError, match=r"scenario 'berlin_p4' belongs to no instance family; .*--curve-family"):
        tiny_args(Path("unused"), scenario="berlin_p4", curve_instances=3)
    with pytest.raises(ConfigError, match=r"--curve-family='paris' is unknown"):
        tiny_args(Path("unused"), curve_family="paris", curve_instances=3)
    with pytest.raises(ConfigError, match=r"--curve-instances=10001 exceeds the 10,000 seeds"):
        tiny_args(Path("unused"), scenario="berlin_instances", curve_instances=10_001)
