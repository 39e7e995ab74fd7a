"""GAE against hand computations, the PPO loss, normalisers, and the trainer: determinism, checkpoints, resume."""

from __future__ import annotations

import multiprocessing

import numpy as np
import pytest
import torch

from uamfleet.rl.buffer import RunningMeanStd, compute_gae
from uamfleet.rl.ppo import ppo_loss


def gae(terminated, truncated):
    return compute_gae(
        rewards=np.array([[1.0], [2.0], [3.0]]),
        values=np.array([[0.5], [1.0], [1.5]]),
        terminated=np.array(terminated, bool)[:, None],
        truncated=np.array(truncated, bool)[:, None],
        final_values=np.array([[0.0], [4.0], [0.0]]),
        next_value=np.array([2.0]),
        gamma=0.9,
        lam=0.8,
    )


def test_gae_bootstraps_a_truncation_from_the_final_value():
    adv, ret = gae([0, 0, 0], [0, 1, 0])
    # t=2: 3 + 0.9*2.0 - 1.5 = 3.3; t=1 (truncated): 2 + 0.9*4.0 - 1.0 = 4.6, nothing flows back across the end;
    # t=0: 1 + 0.9*1.0 - 0.5 = 1.4, plus 0.9*0.8*4.6
    np.testing.assert_allclose(adv[:, 0], [1.4 + 0.72 * 4.6, 4.6, 3.3])
    np.testing.assert_allclose(ret[:, 0], [1.4 + 0.72 * 4.6 + 0.5, 5.6, 4.8])


def test_gae_does_not_bootstrap_a_termination():
    adv, _ = gae([0, 1, 0], [0, 0, 0])
    np.testing.assert_allclose(adv[:, 0], [1.4 + 0.72 * 1.0, 2.0 - 1.0, 3.3])


def test_gae_without_episode_ends_equals_discounted_td_sum():
    rng = np.random.default_rng(0)
    r, v, nv = rng.normal(size=(5, 3)), rng.normal(size=(5, 3)), rng.normal(size=3)
    zeros = np.zeros((5, 3), bool)
    adv, _ = compute_gae(r, v, zeros, zeros, np.zeros((5, 3)), nv, 0.97, 0.9)
    nxt = np.concatenate([v[1:], nv[None]])
    deltas = r + 0.97 * nxt - v
    expected = [sum((0.97 * 0.9) ** (k - t) * deltas[k] for k in range(t, 5)) for t in range(5)]
    np.testing.assert_allclose(adv, np.array(expected))


def test_running_mean_std_matches_numpy():
    data = np.random.default_rng(1).normal(3.0, 2.0, size=(1000, 2))
    rms = RunningMeanStd((2,))
    for chunk in np.split(data, 10):
        rms.update(chunk)
    np.testing.assert_allclose(rms.mean, data.mean(0), rtol=1e-3)
    np.testing.assert_allclose(rms.var, data.var(0), rtol=1e-3)


def test_ppo_loss_clips_the_ratio():
    old = torch.zeros(4)
    new = torch.log(torch.tensor([1.5, 1.5, 0.5, 0.5]))  # ratios 1.5, 1.5, 0.5, 0.5
    adv = torch.tensor([1.0, -1.0, 1.0, -1.0])
    zeros = torch.zeros(4)
    _, info = ppo_loss(new, old, zeros, zeros, zeros, adv, zeros, 0.2, 0.5, 0.0, norm_adv=False)
    # per sample max(-A r, -A clip(r)): A=1,r=1.5 -> -1.2; A=-1,r=1.5 -> 1.5; A=1,r=0.5 -> -0.5; A=-1,r=0.5 -> 0.8
    assert info.policy_loss == pytest.approx((-1.2 + 1.5 - 0.5 + 0.8) / 4)
    assert info.clipfrac == 1.0


# ---- the trainer ----------------------------------------------------------------------------------------------

from conftest import small_config  # noqa: E402

from uamfleet.config import ConfigError, Request  # noqa: E402
from uamfleet.rl.trainer import TrainArgs, load_policy, make_env_config, train  # noqa: E402
from uamfleet.rollout import fly  # noqa: E402


def tiny_args(tmp_path, **overrides) -> TrainArgs:
    base = dict(
        total_timesteps=2 * 64 * 4, num_envs=4, num_steps=64, num_minibatches=2, update_epochs=2, eval_every=1,
        checkpoint_every=1, run_dir=tmp_path, run_name="tiny", progress=False, tensorboard=False, threads=1,
        time_limit_steps=30, eval_time_limit_steps=30, d_model=16, num_heads=2,
    )  # fmt: skip
    base.update(overrides)
    return TrainArgs.from_flat(base)


ONE_PASSENGER = small_config(requests=(Request(0, (350.0, 150.0), (350.0, 350.0)),), time_limit_steps=30)


def test_two_short_cpu_runs_with_one_seed_give_identical_losses(tmp_path):
    # On the CPU explicitly: CUDA kernels may reduce in another order run to run (seen on an H200: 1e-9 apart).
    a = train(tiny_args(tmp_path / "a", seed=3, device="cpu"), env_config=ONE_PASSENGER)
    b = train(tiny_args(tmp_path / "b", seed=3, device="cpu"), env_config=ONE_PASSENGER)
    assert a.losses and a.losses == b.losses
    c = train(tiny_args(tmp_path / "c", seed=4), env_config=ONE_PASSENGER)
    assert c.losses != a.losses


def test_env_workers_train_the_same_run_as_the_envs_in_process(tmp_path):
    # The envs stepped by two worker processes (uamfleet.env.workers) are the same envs: the same losses, bit for bit.
    here = train(tiny_args(tmp_path / "here", seed=3, device="cpu"), env_config=ONE_PASSENGER)
    workers = train(tiny_args(tmp_path / "workers", seed=3, device="cpu", env_workers=2), env_config=ONE_PASSENGER)
    assert here.losses and here.losses == workers.losses
    assert not [p for p in multiprocessing.active_children() if p.name.startswith("uamfleet-env-worker")]  # none left
    with pytest.raises(ConfigError, match=r"--env-workers=5 exceeds this rank's 4 envs"):
        train(tiny_args(tmp_path / "five", env_workers=5), env_config=ONE_PASSENGER)


def test_checkpoint_resume_continues_the_run(tmp_path):
    args = tiny_args(tmp_path, total_timesteps=4 * 64 * 4)
    first = train(tiny_args(tmp_path, total_timesteps=2 * 64 * 4), env_config=ONE_PASSENGER)
    assert (tmp_path / "tiny" / "last.pt").exists() and (tmp_path / "tiny" / "progress.csv").exists()
    assert first.iterations == 2
    resumed = train(TrainArgs.from_flat({**args.flat(), "resume": True}), env_config=ONE_PASSENGER)
    assert resumed.global_step == 4 * 64 * 4 and resumed.iterations == 4  # 2 before + 2 after, in one CSV
    policy, saved = load_policy(tmp_path / "tiny" / "last.pt", env_config=ONE_PASSENGER)
    assert saved.ppo.seed == args.ppo.seed
    obs = {k: v for k, v in __import__("uamfleet").VectorEnv(ONE_PASSENGER).reset(seed=0)[0].items()}
    assert policy(obs).shape == (1, 1)


def test_resume_without_checkpoint_names_the_path(tmp_path):
    with pytest.raises(FileNotFoundError, match=r"no checkpoint at .*last.pt"):
        train(tiny_args(tmp_path, resume=True), env_config=ONE_PASSENGER)


@pytest.mark.slow
def test_must_learn_one_passenger_optimal_route(tmp_path):
    # Optimal: east (pick-up within 100 m), north, north (drop-off): 3 steps, TD 300 m, return 199 - 1 + 299 = 497.
    result = train(
        tiny_args(tmp_path, total_timesteps=60_000, num_envs=8, num_steps=64, eval_every=5, shaping=0.0,
                  d_model=32, num_heads=2, learning_rate=1e-3, update_epochs=4, num_minibatches=4),
        env_config=ONE_PASSENGER,
    )  # fmt: skip
    assert result.best_eval["pr_pct"] == 100.0
    assert result.best_eval["td_m"] == 300.0


def test_shaping_discount_is_the_trainers_unless_given():
    default = make_env_config("berlin_p4", TrainArgs.from_flat(dict(gamma=0.9, shaping=50.0)))
    assert default.reward.shaping_gamma == 0.9 and default.reward.shaping == 50.0
    assert (
        make_env_config("berlin_p4", TrainArgs.from_flat(dict(gamma=0.9, shaping_gamma=1.0))).reward.shaping_gamma
        == 1.0
    )


def test_a_run_with_a_passenger_window_reads_k_rows_and_flies_any_number_of_requests(tmp_path):
    """--passenger-window K: the network trains on K passenger rows, and its checkpoint flies an instance with more
    requests than it ever saw (the window keeps each taxi's rows at K)."""
    three = tuple(Request(0, (350.0, 150.0 + 100.0 * i), (150.0, 350.0)) for i in range(3))
    cfg = small_config(requests=three, time_limit_steps=30)
    options = tiny_args(tmp_path, passenger_window=2, total_timesteps=64 * 4)
    result = train(options, env_config=cfg)
    # the config it evaluated on: the given one with the run's options (make_env_config), the window among them
    trained_on = make_env_config(cfg, options, training=False)
    assert trained_on.passenger_window == 2 and trained_on.observed_passengers == 2
    policy, args = load_policy(result.run_dir / "last.pt", env_config=trained_on)
    assert args.observer.passenger_window == 2 and policy.obs_shapes is not None
    assert policy.obs_shapes["passengers"][0] == 2 and policy.passenger_window == 2
    five = tuple(Request(2 * i, (350.0, 150.0), (150.0, 350.0 - 50.0 * i)) for i in range(5))
    more = make_env_config(small_config(requests=five, time_limit_steps=30), options, training=False)
    assert more.num_passengers == 5 and more.observed_passengers == 2
    flown = fly(more, policy)  # five requests through two rows: the episode runs to its end without a shape error
    assert flown.terminated or flown.truncated
