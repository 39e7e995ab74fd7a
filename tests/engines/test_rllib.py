"""RLlib end to end: the flat masked env, and one PPO iteration of the shared policy on 2 taxis."""

from __future__ import annotations

import numpy as np
import pytest

import uamfleet
from tests.engines.required import require
from uamfleet.engines.rllib import POLICY_ID, FlatMaskedParallelEnv, flat_masked_env, ppo_config


def test_flat_env_concatenates_every_field_but_the_mask_in_the_space_order():
    # needs no engine: the adapter is plain PettingZoo
    inner = uamfleet.parallel_env("berlin_random", num_taxis=2)
    raw, _ = inner.reset(seed=3)
    env = FlatMaskedParallelEnv(uamfleet.parallel_env("berlin_random", num_taxis=2))
    flat, _ = env.reset(seed=3)
    names = [k for k in inner.observation_space("uam_0").spaces if k != "action_mask"]
    assert env.fields == names
    for agent in ("uam_0", "uam_1"):
        expected = np.concatenate([np.ravel(raw[agent][k]).astype(np.float32) for k in names])
        np.testing.assert_array_equal(flat[agent]["observations"], expected)
        np.testing.assert_array_equal(flat[agent]["action_mask"], raw[agent]["action_mask"].astype(np.float32))
        assert env.observation_space(agent).contains(flat[agent])
    first = {a: int(np.flatnonzero(o["action_mask"])[0]) for a, o in flat.items()}
    obs, rewards, *_ = env.step(first)
    assert set(obs) == set(rewards) == {"uam_0", "uam_1"}
    assert env.observation_space("uam_0")["observations"].shape == flat["uam_0"]["observations"].shape


@pytest.fixture(scope="module")
def ray_session():
    ray = require("ray")
    require("ray.rllib")
    ray.init(num_cpus=1, include_dashboard=False, log_to_driver=False, ignore_reinit_error=True)
    yield ray
    ray.shutdown()


def test_one_ppo_iteration_trains_the_shared_masked_policy(ray_session):
    torch = require("torch")
    config = (
        ppo_config("berlin_random", num_taxis=2)
        .env_runners(num_env_runners=0, rollout_fragment_length=32)
        .training(train_batch_size_per_learner=64, minibatch_size=32, num_epochs=1)
        .debugging(seed=0)
    )
    algo = config.build_algo()
    try:
        module = algo.get_module(POLICY_ID)
        before = [p.detach().clone() for p in module.parameters()]
        result = algo.train()
        after = list(module.parameters())
        # both taxis' samples trained the one shared policy: its weights moved, and it is the only policy
        assert set(algo.config.policies) == {POLICY_ID}
        assert any(not torch.equal(b, a) for b, a in zip(before, after, strict=True))
        assert result["env_runners"]["num_env_steps_sampled_lifetime"] >= 64
        # the module masks: sampled actions are always allowed headings, even where most are not
        env = flat_masked_env("berlin_random", num_taxis=2)
        obs, _ = env.reset(seed=1)
        mask = np.zeros((2, 16), np.float32)
        mask[0, [3]] = 1.0  # taxi 0 may only fly heading 3, taxi 1 headings 5 and 9
        mask[1, [5, 9]] = 1.0
        batch = {
            "obs": {
                "observations": torch.as_tensor(np.stack([obs[a]["observations"] for a in ("uam_0", "uam_1")])),
                "action_mask": torch.as_tensor(mask),
            }
        }
        logits = module.forward_exploration(batch)["action_dist_inputs"]
        dist = torch.distributions.Categorical(logits=logits)
        samples = dist.sample((200,)).numpy()  # [200, 2]
        assert set(samples[:, 0]) == {3}
        assert set(samples[:, 1]) <= {5, 9}
    finally:
        algo.stop()
