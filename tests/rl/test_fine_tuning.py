"""Fine-tuning a trained policy with PPO (``TrainArgs.init_from``, ``TrainArgs.kl_to_init``; issue 20, parts 1 and 4).

The run starts from the policy's weights and observation statistics, on its observation layout, evaluates the start
before it trains (so best.pt is never worse than the start on the evaluation), and its checkpoints load like any
other. The KL term is checked against a hand computation."""

from __future__ import annotations

import math

import pytest
import torch

from uamfleet.config import ConfigError
from uamfleet.metrics import episode_metrics
from uamfleet.presets import make_config
from uamfleet.rl.checkpoint import Checkpoint, check_net_config
from uamfleet.rl.heads import NOT_THIS
from uamfleet.rl.ppo import categorical_kl
from uamfleet.rl.runs import read_progress
from uamfleet.rl.trainer import TrainArgs, load_policy, train
from uamfleet.zoo import pretrained


def test_categorical_kl_is_the_hand_computed_divergence_and_ignores_masked_actions():
    p = torch.tensor([[math.log(0.5), math.log(0.25), math.log(0.25), NOT_THIS]])
    q = torch.tensor([[math.log(0.25), math.log(0.25), math.log(0.5), NOT_THIS]])
    # 0.5 ln(0.5 / 0.25) + 0.25 ln(1) + 0.25 ln(0.25 / 0.5) = 0.25 ln 2; the masked action adds nothing
    assert categorical_kl(p, q).item() == pytest.approx(0.25 * math.log(2.0), rel=1e-6)
    assert categorical_kl(p, p).item() == pytest.approx(0.0, abs=1e-7)
    # logits are log-weights: a constant shift changes neither distribution
    assert categorical_kl(p + 3.0, q - 1.0).item() == pytest.approx(0.25 * math.log(2.0), rel=1e-6)


def fine_tune_args(tmp_path, **overrides) -> TrainArgs:
    """One tiny iteration on Berlin P4 at -3 dB from the shipped generalist; the network flags given here are those
    of a scratch run and must be replaced by the start's."""
    base = dict(
        scenario="berlin_p4", sinr_min_db=-3.0, init_from="berlin", total_timesteps=64, num_envs=2, num_steps=32,
        num_minibatches=2, update_epochs=1, eval_every=1, checkpoint_every=1, run_dir=tmp_path, run_name="ft",
        progress=False, tensorboard=False, threads=1, d_model=16, num_heads=2, learning_rate=1e-12, shaping=0.0,
    )  # fmt: skip
    base.update(overrides)
    return TrainArgs.from_flat(base)


def test_a_run_from_the_generalist_evaluates_the_start_first_and_its_checkpoints_load(tmp_path):
    result = train(fine_tune_args(tmp_path, kl_to_init=0.5))
    rows = read_progress(tmp_path / "ft" / "progress.csv")
    assert [r["iteration"] for r in rows] == [0, 1]
    # the start's evaluation is the shipped policy flown on P4 by its own public path (uamfleet.pretrained().fly)
    cfg = make_config("berlin_p4", sinr_min_db=-3.0)
    shipped = episode_metrics(pretrained("berlin").fly(cfg), cfg.radio)
    assert rows[0]["eval/td_m"] == shipped.td_m and rows[0]["eval/pr_pct"] == shipped.pr_pct == 100.0
    # with a learning rate of 1e-12 the policy has not moved: the KL to the start is 0 and the first evaluation,
    # flown again, is not a new best (ties keep the start)
    assert rows[1]["losses/kl_to_init"] == pytest.approx(0.0, abs=1e-9)
    assert rows[1]["eval/td_m"] == shipped.td_m and result.best_step == 0
    # the checkpoints state the network they hold (the start's), and load without the config they trained on
    saved = Checkpoint.load(tmp_path / "ft" / "best.pt")
    start = Checkpoint.load(__import__("uamfleet").zoo.pretrained_path("berlin"))
    # (as networks: a field added to NetConfig since the start was saved is stored with its default)
    assert check_net_config(saved.net_config, "best.pt") == check_net_config(start.net_config, "berlin")
    assert saved.args["d_model"] == 32 and saved.args["action_head"] == "stops"
    policy, args = load_policy(tmp_path / "ft" / "best.pt")
    assert args.net.init_from == "berlin"
    assert episode_metrics(policy.fly(cfg), cfg.radio).td_m == shipped.td_m
    # and the run resumes from its last.pt (its spec is checked against the same layout)
    more = train(fine_tune_args(tmp_path, kl_to_init=0.5, total_timesteps=128, resume=True))
    assert more.iterations == 3 and more.global_step == 128


def test_the_start_must_be_named_and_must_not_live_in_the_run_folder(tmp_path):
    with pytest.raises(ConfigError, match=r"--kl-to-init=0\.1 pulls the policy toward the one it starts from"):
        TrainArgs.from_flat(dict(kl_to_init=0.1))
    with pytest.raises(FileNotFoundError, match=r"'no/such\.pt' is neither a shipped policy"):
        train(fine_tune_args(tmp_path, init_from="no/such.pt"))
    train(fine_tune_args(tmp_path))
    inside = str(tmp_path / "ft" / "best.pt")
    with pytest.raises(ConfigError, match="lies inside this run's own folder"):
        train(fine_tune_args(tmp_path, init_from=inside, overwrite=True))
    with pytest.raises(ConfigError, match="--centralised-critic=True differs"):
        train(fine_tune_args(tmp_path, run_name="other", centralised_critic=True))
