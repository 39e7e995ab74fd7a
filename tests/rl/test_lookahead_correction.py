"""The stop head's look-ahead correction (``NetConfig.lookahead_inputs``): at zero it flies exactly as the prior;
set to prefer headings of least look-ahead, it flies one of them wherever the prior's heading is worse."""

from __future__ import annotations

import numpy as np
import torch

from uamfleet.config import make_config
from uamfleet.env.vector_env import VectorEnv
from uamfleet.rl.networks import LOOKAHEAD_GAIN, PRIOR_FLOOR, MSHAActorCritic, NetConfig, obs_to_torch, observed_inputs


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
