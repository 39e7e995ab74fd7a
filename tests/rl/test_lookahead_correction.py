"""The stop head's look-ahead correction (``NetConfig.lookahead_inputs``): at zero it flies exactly as the prior;
set to prefer headings of least look-ahead, it flies one of them wherever the prior's heading is worse. The rule
term (``NetConfig.lookahead_rule``) makes the untrained head fly the least look-ahead heading."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
import torch
from gymnasium import spaces

from uamfleet.env.vector_env import VectorEnv
from uamfleet.presets import make_config
from uamfleet.rl.heads import LOOKAHEAD_GAIN, LOOKAHEAD_RULE, PRIOR_FLOOR
from uamfleet.rl.networks import MSHAActorCritic, NetConfig, obs_to_torch, observed_inputs


def _lookahead_nets() -> tuple[MSHAActorCritic, MSHAActorCritic, dict[str, torch.Tensor]]:
    venv = VectorEnv(make_config("berlin_instances", sinr_min_db=-5.0, heading_lookahead=True), num_envs=8)
    obs, _ = venv.reset(seed=5)
    rng = np.random.default_rng(0)
    for _ in range(12):
        allowed = obs["action_mask"][:, 0].astype(bool)
        obs, *_ = venv.step(np.array([[rng.choice(np.flatnonzero(a))] for a in allowed]))
    batch = obs_to_torch({k: v.reshape(8, *v.shape[2:]) for k, v in obs.items()}, "cpu")
    space = venv.single_observation_space
    inputs = observed_inputs(space.spaces, "de_msfea", "stops")
    assert inputs["lookahead_inputs"]
    torch.manual_seed(0)
    plain = NetConfig(variant="de_msfea", d_model=32, action_head="stops", **{**inputs, "lookahead_inputs": False})
    prior = MSHAActorCritic(space, plain)
    with_look = MSHAActorCritic(space, NetConfig(**{**plain.__dict__, "lookahead_inputs": True}))
    missing, unexpected = with_look.load_state_dict(prior.state_dict(), strict=False)
    assert not unexpected and missing and all(k.startswith("stop_head.residual_lookahead.") for k in missing)
    return prior, with_look, batch


def test_a_zero_lookahead_correction_flies_exactly_as_the_prior() -> None:
    prior, with_look, obs = _lookahead_nets()
    with torch.no_grad():
        p_logits, l_logits = prior.masked_logits(obs), with_look.masked_logits(obs)
        torch.testing.assert_close(with_look.prior_logits(obs), p_logits, atol=0, rtol=0)
    assert torch.equal(p_logits.argmax(-1), l_logits.argmax(-1))
    assert float(p_logits.softmax(-1).max(-1).values.min()) > 0.5  # the prior is decided: the test is not vacuous


def test_a_lookahead_correction_can_fly_the_best_lookahead_heading() -> None:
    """A correction of -1 per move of look-ahead (clipped at 1) outweighs the prior: the policy then flies a heading
    of least look-ahead, wherever the prior's heading is worse."""
    _, with_look, obs = _lookahead_nets()
    net = with_look.stop_head.residual_lookahead
    with torch.no_grad():  # tanh(20 x) ~ 1 for x >= 0.1 move: the output is -1.5 there, 0 at x = 0
        net[0].weight.fill_(20.0)
        net[0].bias.zero_()
        net[2].weight.fill_(-1.5 / net[2].weight.shape[1])
        chosen = with_look.masked_logits(obs).argmax(-1)
        prior_choice = with_look.prior_logits(obs).argmax(-1)
    look = obs["heading_lookahead"]
    allowed = obs["action_mask"] > 0.5
    best = torch.where(allowed, look, torch.inf).amin(-1)
    rows = torch.arange(len(chosen))
    assert torch.all(look[rows, chosen] <= best + 0.1)
    # a drawn look-ahead in which every allowed heading but one the prior does not choose is a move worse
    drawn = look.clone()
    for b in range(len(chosen)):
        other = next(h for h in torch.nonzero(allowed[b])[:, 0].tolist() if h != int(prior_choice[b]))
        drawn[b] = 1.0
        drawn[b, other] = 0.0
    with torch.no_grad():
        flown = with_look.masked_logits({**obs, "heading_lookahead": drawn}).argmax(-1)
    assert torch.all(drawn[rows, flown] == 0.0) and torch.all(flown != prior_choice)
    assert LOOKAHEAD_GAIN * 1.5 > -PRIOR_FLOOR  # the setting above outweighs the floor by construction


def test_the_rule_term_flies_the_least_lookahead_heading_and_leaves_near_ties_to_the_prior() -> None:
    """``NetConfig.lookahead_rule``: with zero corrections the policy flies a heading of least look-ahead (within
    the 0.12 move at which the rule outweighs the prior's whole range), and where several headings tie exactly,
    the prior's choice among them."""
    prior, with_look, obs = _lookahead_nets()
    space = spaces.Dict({k: spaces.Box(-np.inf, np.inf, shape, np.float32) for k, shape in with_look.shapes.items()})
    ruled = MSHAActorCritic(space, dataclasses.replace(with_look.cfg, lookahead_rule=LOOKAHEAD_RULE))
    ruled.load_state_dict(with_look.state_dict())
    look, allowed = obs["heading_lookahead"], obs["action_mask"] > 0.5
    rows = torch.arange(len(look))
    with torch.no_grad():
        prior_choice = prior.masked_logits(obs).argmax(-1)
        flown = ruled.masked_logits(obs).argmax(-1)
        best = torch.where(allowed, look, torch.inf).amin(-1)
        assert torch.all(look[rows, flown] <= best + 0.12)
        # every allowed heading ties: the prior decides; one other heading a fifth of a move better: it wins
        tied = torch.where(allowed, 0.5, look)
        assert torch.equal(ruled.masked_logits({**obs, "heading_lookahead": tied}).argmax(-1), prior_choice)
        drawn = tied.clone()
        for b in range(len(look)):
            other = next(h for h in torch.nonzero(allowed[b])[:, 0].tolist() if h != int(prior_choice[b]))
            drawn[b, other] = 0.3
        chosen = ruled.masked_logits({**obs, "heading_lookahead": drawn}).argmax(-1)
    assert torch.all(drawn[rows, chosen] == 0.3) and torch.all(chosen != prior_choice)


@pytest.mark.parametrize("rule, lookahead, message", [(-1.0, True, ">= 0"), (math.inf, True, "finite"),
                                                      (10.0, False, "needs lookahead_inputs=True")])  # fmt: skip
def test_a_rule_term_out_of_range_or_without_the_lookahead_is_refused(
    rule: float, lookahead: bool, message: str
) -> None:
    with pytest.raises(ValueError, match=message):
        NetConfig(variant="de_msfea", d_model=32, action_head="stops", stop_inputs=True, lookahead_inputs=lookahead,
                  lookahead_rule=rule)  # fmt: skip
