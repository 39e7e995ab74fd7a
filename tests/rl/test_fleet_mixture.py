"""Training one fleet policy on a mixture of fleet sizes and loads (issue 21, part 4): the mixture pads smaller
fleets to the largest without changing what a taxi reads, and a run fine-tunes the shipped fleet policy at other
sizes and loads under a passenger window (``TrainArgs.fleet_mixture``, ``num_requests``, ``reinit_critic``)."""

from __future__ import annotations

import dataclasses

from pathlib import Path

import numpy as np
import pytest
import torch

from uamfleet.config import ConfigError
from uamfleet.presets import make_config
from uamfleet.env.mixture import OTHER_TAXI_FIELDS, MixtureVectorEnv
from uamfleet.env.vector_env import VectorEnv
from uamfleet.rl.checkpoint import Checkpoint, pretrained_path, run_config
from uamfleet.rl.collector import observed, run_observer
from uamfleet.types import STATE_PASSENGER_FEATURES, STATE_TAXI_FEATURES
from uamfleet.rl.runs import read_progress
from uamfleet.rl.trainer import TrainArgs, load_policy, train
from uamfleet.zoo import pretrained


def _fleet(taxis: int, window: int = 8, limit: int = 12) -> object:
    return make_config(
        "berlin_fleet", num_taxis=taxis, sinr_min_db=-5.0, passenger_window=window, time_limit_steps=limit
    )


def test_a_mixture_of_fleet_sizes_pads_the_smaller_fleets_and_keeps_each_env_as_alone() -> None:
    """Two envs of one taxi and one of three: every real taxi's observation, reward and episode are those of the
    same env stepped alone; the padding (taxi columns past an env's fleet, other-taxi rows past its A - 1) is zero
    and masked, and the padding taxis' actions are ignored."""
    cfgs = [_fleet(1), _fleet(3)]
    mix = MixtureVectorEnv(cfgs, num_envs=3)
    assert mix.num_taxis == 3 and mix.mixed_sizes and mix.taxis_per_env.tolist() == [1, 1, 3]
    assert mix.taxi_mask.tolist() == [[True, False, False], [True, False, False], [True, True, True]]
    alone = [VectorEnv(cfgs[0], num_envs=2), VectorEnv(cfgs[1], num_envs=1)]
    obs, _ = mix.reset(seed=10)
    parts = [alone[0].reset(seed=10)[0], alone[1].reset(seed=12)[0]]
    rng = np.random.default_rng(0)
    episodes = 0
    for _ in range(30):
        for key in obs:
            small, big = parts[0][key], parts[1][key]
            np.testing.assert_array_equal(obs[key][2], big[0])
            rows = small.shape[2] if key in OTHER_TAXI_FIELDS else None
            np.testing.assert_array_equal(obs[key][:2, :1, :rows], small)  # the lone taxi's own rows
            assert not obs[key][:2, 1:].any()  # padding taxis: all zero
            if key in OTHER_TAXI_FIELDS:
                assert not obs[key][:2, :, rows:].any()  # padded other-taxi rows: zero, and masked
        assert not obs["others_mask"][:2].any()  # a lone taxi has no other taxi, padded or not
        actions = rng.integers(0, cfgs[0].num_actions, size=(3, 3))
        obs, rewards, terminated, truncated, info = mix.step(actions)
        ref = [alone[0].step(actions[:2, :1]), alone[1].step(actions[2:])]  # padding columns' actions dropped
        parts = [r[0] for r in ref]
        np.testing.assert_array_equal(rewards[:2, :1], ref[0][1])
        np.testing.assert_array_equal(rewards[2], ref[1][1][0])
        assert not rewards[:2, 1:].any()
        np.testing.assert_array_equal(terminated | truncated, np.concatenate([r[2] | r[3] for r in ref]))
        if "episode" in info:
            episodes += 1
            np.testing.assert_array_equal(info["episode"]["return"][:2, :1], ref[0][4]["episode"]["return"])
            assert not info["episode"]["return"][:2, 1:].any()
    assert episodes >= 2  # the 12-step episodes ended (and restarted) inside the 30 steps
    assert mix.state_space is None
    with pytest.raises(ValueError, match="global states of"):
        mix.global_state()
    with pytest.raises(ValueError, match="observation layout"):
        MixtureVectorEnv([_fleet(1), _fleet(3, window=12)], num_envs=2)


def test_padding_leaves_the_shipped_fleet_policy_s_decisions_unchanged() -> None:
    """The shipped fleet policy laid out for three taxis reads a lone taxi's padded observation (masked other-taxi
    rows) to the same logits as the policy laid out for one taxi reads it unpadded: the set encoder's masked mean
    and the pooled normaliser make padding invisible, which is what lets one network train on every size at once."""
    cfgs = [_fleet(1, window=24), _fleet(3, window=24)]
    mix = MixtureVectorEnv(cfgs, num_envs=2)
    obs, _ = mix.reset(seed=3)
    lone, _ = VectorEnv(cfgs[0], num_envs=1).reset(seed=3)
    shipped = pretrained("berlin_fleet_v1")
    windowed = shipped.reading(dataclasses.replace(shipped.spec, passenger_window=24, time_scale_steps=None))
    windowed.fit(cfgs[1].world)  # three taxis: the mixture's padded rows
    padded = windowed.logits_of(windowed.network_input({k: v[:1] for k, v in obs.items()}))[0]
    windowed.fit(cfgs[0].world)  # one taxi, unpadded
    unpadded = windowed.logits_of(windowed.network_input(lone))[0]
    torch.testing.assert_close(padded, unpadded, rtol=1e-5, atol=1e-5)


def _mixture_args(tmp_path: Path, **overrides: object) -> TrainArgs:
    """One tiny iteration per call from the shipped fleet policy (4 taxis, 24 requests, no window, MAPPO critic)
    on a mixture of 1 taxi x 6 requests and 2 taxis x 24 requests under a window of 24 (12-step episodes)."""
    base: dict[str, object] = dict(
        scenario="berlin_fleet", sinr_min_db=-5.0, init_from="berlin_fleet_v1", passenger_window=24,
        fleet_mixture=("1x6", "2x24"), num_requests=24, reinit_critic=True, centralised_critic=False,
        kl_to_init=0.5, total_timesteps=48, num_envs=2, num_steps=16, num_minibatches=2, update_epochs=1,
        eval_every=1, checkpoint_every=1, time_limit_steps=12, fill_tables=False, run_dir=tmp_path, run_name="mix",
        progress=False, tensorboard=False, threads=1, shaping=0.0, learning_rate=1e-3,
    )  # fmt: skip
    base.update(overrides)
    return TrainArgs.from_flat(base)  # type: ignore[arg-type]


def test_a_fine_tune_of_the_shipped_fleet_on_a_mixture_starts_from_its_actor_and_loads_and_resumes(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    args = _mixture_args(tmp_path)
    result = train(args)
    assert "critic re-initialised (--reinit-critic)" in capsys.readouterr().out
    rows = read_progress(tmp_path / "mix" / "progress.csv")
    assert [r["iteration"] for r in rows] == [0, 1]
    # a batch holds the real taxis only: 16 steps x (1 env x 1 taxi + 1 env x 2 taxis)
    assert result.global_step == 16 * 3
    # best.pt of iteration 0 (the start's evaluation) holds the shipped actor and torso, tensor for tensor; the
    # critic alone is new (the shipped one read a 4-taxi global state, this one each taxi's own features)
    start = Checkpoint.load(pretrained_path("berlin_fleet_v1")).model
    at_start = torch.load(tmp_path / "mix" / "best.pt", weights_only=True)["model"]
    assert at_start.keys() == start.keys()
    for name, tensor in start.items():
        if name.startswith("critic."):
            assert name == "critic.0.weight" or at_start[name].shape == tensor.shape
        else:
            torch.testing.assert_close(at_start[name], tensor, rtol=0, atol=0)
    assert at_start["critic.0.weight"].shape != start["critic.0.weight"].shape
    # the trained checkpoint moved (learning rate 1e-3), loads like any other and flies any fleet
    last = torch.load(tmp_path / "mix" / "last.pt", weights_only=True)["model"]
    assert any(not torch.equal(last[k], start[k]) for k in start if not k.startswith("critic."))
    policy, saved = load_policy(tmp_path / "mix" / "last.pt")
    assert (
        saved.env.fleet_mixture == ("1x6", "2x24") and saved.observer.passenger_window == 24 and saved.net.reinit_critic
    )
    assert policy.num_taxis == 2 and policy.passenger_window == 24 and policy.net.cfg.critic_state_dim is None
    cfg = make_config("berlin_fleet", num_taxis=3, sinr_min_db=-5.0, time_limit_steps=12)
    assert len(policy.fly(cfg).stacked("actions")) == 12
    # and it resumes from last.pt: one more iteration
    more = train(_mixture_args(tmp_path, total_timesteps=96, resume=True))
    assert more.iterations == 3 and more.global_step == 96


def test_what_cannot_start_from_the_shipped_fleet_is_refused_with_the_fix(tmp_path: Path) -> None:
    # its centralised critic cannot read another fleet's global state unless it starts afresh
    at_two = dict(fleet_mixture=(), num_taxis=2, total_timesteps=64, reinit_critic=False, centralised_critic=True)
    with pytest.raises(ConfigError, match=r"global state of 4 taxi\(s\) and 24 passenger\(s\).*--reinit-critic"):
        train(_mixture_args(tmp_path, **at_two))
    # ... and with --reinit-critic it keeps its MAPPO critic, afresh, sized for this run's state (2 taxis, 24
    # passengers: 2 x taxi features + 24 x passenger features + time + a one-hot of 2 taxis)
    result = train(_mixture_args(tmp_path, **{**at_two, "reinit_critic": True}, eval_every=0))
    policy, _ = load_policy(result.run_dir / "last.pt")
    assert policy.net.cfg.critic_state_dim == 2 * len(STATE_TAXI_FEATURES) + 24 * len(STATE_PASSENGER_FEATURES) + 1 + 2
    assert 4 * len(STATE_TAXI_FEATURES) + 24 * len(STATE_PASSENGER_FEATURES) + 1 + 4 == 237  # the start's, as logged
    # no one global state holds a mixture of sizes (a new run name: the run folder is claimed before the envs that
    # tell the sizes are built, and "mix" now holds the run above)
    with pytest.raises(ConfigError, match=r"states of different sizes.*--no-centralised-critic"):
        train(_mixture_args(tmp_path, centralised_critic=True, run_name="mix-critic"))
    # nor may --centralised-critic silently differ from the start's without --reinit-critic
    with pytest.raises(ConfigError, match=r"--centralised-critic=False differs.*--reinit-critic"):
        train(_mixture_args(tmp_path, reinit_critic=False))


def test_a_run_with_its_own_window_keeps_its_own_requests_and_time_limit() -> None:
    """From a start without a window, a run with --passenger-window reads the window and keeps its own load and
    episode length; without one it takes the start's 24 passenger slots, which 48 requests do not fit."""
    windowed = TrainArgs.from_flat(
        dict(
            scenario="berlin_fleet",
            init_from="berlin_fleet_v1",
            passenger_window=24,
            num_requests=48,
            time_limit_steps=700,
        )
    )
    cfg = observed(windowed, run_config(windowed, training=True), run_observer(windowed, run_config(windowed)))
    assert (cfg.passenger_window, cfg.num_passengers, cfg.demand.max_requests) == (24, 48, 48)
    assert cfg.time_limit_steps == 700 and cfg.observed_passengers == 24
    unwindowed = TrainArgs.from_flat(dict(scenario="berlin_fleet", init_from="berlin_fleet_v1", num_requests=48))
    own = run_config(unwindowed)
    with pytest.raises(ConfigError, match=r"the world has 48 passenger rows; this policy reads 24: give it at most"):
        observed(unwindowed, own, run_observer(unwindowed, own))


@pytest.mark.parametrize(
    ("overrides", "message"),
    [
        ({"fleet_mixture": ("2x12", "4")}, r"setting '4' is not <taxis>x<requests>"),
        ({"fleet_mixture": ("2x12", "2x12")}, r"repeats \['2x12'\]"),
        ({"fleet_mixture": ("2x12", "8x96"), "num_taxis": 4}, r"--num-taxis=4 is not the largest fleet .* \(8\)"),
        ({"fleet_mixture": ("2x12",), "scenario": "berlin_instances"}, "needs a \\*_fleet scenario"),
        ({"num_requests": 48, "scenario": "berlin_p4"}, "needs a \\*_fleet scenario"),
        ({"fleet_mixture": "2x12"}, "must be a list of settings"),
        ({"reinit_critic": True}, "--reinit-critic starts the critic of an --init-from policy afresh"),
    ],
)
def test_fleet_mixture_options_are_checked(overrides: dict[str, object], message: str) -> None:
    base: dict[str, object] = {"scenario": "berlin_fleet"}
    with pytest.raises(ConfigError, match=message):
        TrainArgs.from_flat({**base, **overrides})  # type: ignore[arg-type]
