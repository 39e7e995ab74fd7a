"""``GreedyPolicy.trace_actor``: the actor run as TorchScript traces gives the eager logits bit for bit, follows
weight updates, and every branch the tracer froze in a shipped policy is a shape check (so a trace per set of
shapes is exact for any values)."""

from __future__ import annotations

import linecache
import warnings

import numpy as np
import pytest
import torch

from uamfleet.env.vector_env import VectorEnv
from uamfleet.rl.networks import obs_to_torch
from uamfleet.rl.policy import _Actor, load_policy
from uamfleet.zoo import PRETRAINED, pretrained_path


@pytest.mark.parametrize(("name", "envs"), [("berlin", 1), ("berlin", 3), ("berlin_fleet", 2)])
def test_traced_logits_equal_the_eager_ones_along_an_episode(name: str, envs: int) -> None:
    eager, _ = load_policy(pretrained_path(name))
    traced, _ = load_policy(pretrained_path(name))
    traced.trace_actor()
    assert eager.trained_on is not None
    venv = VectorEnv(eager.trained_on.replace(sinr_min_db=-5.0), envs)
    obs, _ = venv.reset(seed=4)
    for _ in range(40):
        inputs = eager.network_input(obs)
        a, b = eager.logits_of(inputs), traced.logits_of(inputs)
        assert torch.equal(a, b)
        obs, *_ = venv.step(a.argmax(-1).numpy().reshape(envs, -1))
    assert len(traced._traces) == 1  # one set of shapes, one trace


def test_a_trace_follows_the_networks_weights() -> None:
    policy, _ = load_policy(pretrained_path("berlin"))
    policy.trace_actor()
    assert policy.trained_on is not None
    venv = VectorEnv(policy.trained_on, 2)
    obs, _ = venv.reset(seed=1)
    inputs = policy.network_input(obs)
    before = policy.logits_of(inputs).clone()
    with torch.no_grad():
        for p in policy.net.stop_head.parameters():
            p.add_(0.05 * torch.randn_like(p))
    after = policy.logits_of(inputs)
    assert not torch.equal(before, after)
    policy.trace_actor(False)
    assert torch.equal(after, policy.logits_of(inputs))


@pytest.mark.parametrize("name", PRETRAINED)
def test_every_branch_a_trace_freezes_is_a_shape_check(name: str) -> None:
    """A branch on a tensor's values would be frozen at its traced value; the tracer warns at each frozen branch.
    Every warning must come from torch's own modules or a line of ours that compares shapes."""
    policy, _ = load_policy(pretrained_path(name))
    assert policy.trained_on is not None
    venv = VectorEnv(policy.trained_on, 2)
    obs, _ = venv.reset(seed=1)
    x = obs_to_torch(policy.network_input(obs), "cpu")
    keys = tuple(sorted(x))
    with warnings.catch_warnings(record=True) as caught, torch.inference_mode():
        warnings.simplefilter("always")
        torch.jit.trace(_Actor(policy.net, keys).eval(), tuple(x[k] for k in keys), check_trace=False)
    frozen = [w for w in caught if issubclass(w.category, torch.jit.TracerWarning)]
    for w in frozen:
        line = linecache.getline(w.filename, w.lineno)
        assert "/torch/" in w.filename or "shape" in line, f"{w.filename}:{w.lineno} freezes a value: {line.strip()}"
    assert np.isfinite(policy.logits_of(policy.network_input(obs)).numpy()).any()
