"""TorchRL end to end: one collector batch of the shared masked policy on 2 taxis."""

from __future__ import annotations

import numpy as np

from tests.engines.required import require
from uamfleet.engines.torchrl import GROUP, masked_policy, observation_fields, torchrl_env


def test_one_collector_batch_of_the_masked_policy_draws_only_allowed_headings():
    torch = require("torch")
    require("torchrl")
    from torchrl.collectors import Collector

    env = torchrl_env("berlin_random", num_taxis=2)
    policy = masked_policy(env, seed=0)
    assert observation_fields(env) and "action_mask" not in observation_fields(env)
    collector = Collector(
        lambda: torchrl_env("berlin_random", num_taxis=2), policy, frames_per_batch=64, total_frames=64
    )
    try:
        (batch,) = list(collector)
    finally:
        collector.shutdown()
    actions = batch[GROUP, "action"]
    mask = batch[GROUP, "action_mask"]
    assert actions.shape == (64, 2)  # frames x taxis: one group, the policy's agent axis
    allowed = torch.gather(mask, -1, actions.unsqueeze(-1)).squeeze(-1)
    assert bool(allowed.all()), "a masked heading was drawn"
    assert not bool(mask.all()), "every heading was allowed: the batch cannot show the mask at work"
    # the log-probabilities are those of a distribution over the allowed headings only
    assert torch.isfinite(batch[GROUP, "sample_log_prob"]).all()


def test_the_policy_is_shared_and_masks_a_single_allowed_heading():
    torch = require("torch")
    require("torchrl")
    env = torchrl_env("berlin_random", num_taxis=2)
    policy = masked_policy(env, seed=0)
    td = env.reset()
    mask = torch.zeros(2, 16, dtype=torch.bool)
    mask[0, 3] = True  # taxi 0 may fly only heading 3; taxi 1 only heading 11
    mask[1, 11] = True
    td[GROUP, "action_mask"] = mask
    for _ in range(20):
        out = policy(td.clone())
        np.testing.assert_array_equal(out[GROUP, "action"].numpy(), [3, 11])
    # one set of weights: the same observation gives both taxis the same logits
    same = td.clone()
    for name in observation_fields(env):
        same[GROUP, "observation", name] = (
            same[GROUP, "observation", name][:1].expand_as(same[GROUP, "observation", name]).clone()
        )
    logits = policy.module[0](same)[GROUP, "logits"]
    torch.testing.assert_close(logits[0], logits[1])
