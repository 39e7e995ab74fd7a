"""The PettingZoo face under the engines docs/scaling.md points to: TorchRL's PettingZooWrapper and RLlib's
ParallelPettingZooEnv construct around our env and step it (optional extras: skipped where not installed)."""

from __future__ import annotations

import sys

import numpy as np
import pytest

import uamfleet


def allowed_actions(obs: dict) -> dict:
    """The first allowed heading of every agent, from its observation's action mask."""
    return {agent: int(np.flatnonzero(o["action_mask"])[0]) for agent, o in obs.items()}


def test_torchrl_pettingzoo_wrapper_steps_our_env():
    envs = pytest.importorskip("torchrl.envs")
    env = envs.PettingZooWrapper(env=uamfleet.parallel_env("berlin_p4", num_taxis=2), use_mask=False)
    env.set_seed(0)
    rollout = env.rollout(max_steps=3)  # random actions within each taxi's action mask
    (group,) = env.group_map  # both taxis in one group: one shared policy
    assert sorted(env.group_map[group]) == ["uam_0", "uam_1"]
    assert rollout[group, "action"].shape[:2] == (3, 2)


def test_rllib_parallel_pettingzoo_env_steps_our_env():
    pytest.importorskip("ray.rllib")
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv

    env = ParallelPettingZooEnv(uamfleet.parallel_env("berlin_p4", num_taxis=2))
    obs, _ = env.reset(seed=0)
    assert set(obs) == {"uam_0", "uam_1"}
    for _ in range(3):
        obs, rewards, terminated, truncated, _ = env.step(allowed_actions(obs))
        assert set(rewards) == {"uam_0", "uam_1"} and "__all__" in terminated and "__all__" in truncated


@pytest.mark.parametrize(
    ("blocked", "call", "install"),
    [
        ("ray", lambda: __import__("uamfleet.engines.rllib").engines.rllib.ppo_config("berlin_p4"),
         "pip install 'ray[rllib]'"),
        ("torchrl", lambda: __import__("uamfleet.engines.torchrl").engines.torchrl.torchrl_env("berlin_p4"),
         "pip install 'uamfleet[torchrl]'"),
        ("tensordict", lambda: __import__("uamfleet.engines.torchrl").engines.torchrl.masked_policy(None),
         "pip install 'uamfleet[torchrl]'"),
    ],
    ids=["rllib", "torchrl", "torchrl policy"],
)  # fmt: skip
def test_an_engine_that_is_not_installed_says_how_to_install_it(monkeypatch, blocked, call, install):
    monkeypatch.setitem(sys.modules, blocked, None)  # import of it fails, installed or not
    with pytest.raises(ImportError) as caught:
        call()
    message = str(caught.value)
    assert install in message and f"no module {blocked!r}" in message and "\n" not in message, message
