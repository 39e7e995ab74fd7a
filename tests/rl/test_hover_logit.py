"""``NetConfig.hover_logit``: the stop head's hover component as the logit of the hover action (16) instead of mass
on the hover heading, on observations drawn from the shipped fleet policy's own flight (4 taxis, 48 requests,
window 24, shield, hover action)."""

from __future__ import annotations

import copy
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

import uamfleet
from uamfleet.config import ConfigError
from uamfleet.instances import make_fleet_instance
from uamfleet.policies import make
from uamfleet.rl.checkpoint import Checkpoint
from uamfleet.rl.networks import NetConfig, obs_to_torch
from uamfleet.rl.policy import GreedyPolicy, load_policy
from uamfleet.types import HOVER_ACTION, NUM_HEADINGS, STOP_CLAIMED_BY_OTHER

CLOSED = -1e3  # a log-probability below this is a closed component / masked action (NOT_THIS is -1e4)


def _switched(policy: GreedyPolicy) -> GreedyPolicy:
    """``policy`` with hover_logit on and the same weights (the option adds no parameter)."""
    switched = copy.deepcopy(policy.fitted()[0])  # the shapes as flown, its own modules
    switched.cfg = dataclasses.replace(switched.cfg, hover_logit=True)
    assert switched.stop_head is not None
    switched.stop_head.hover_logit = True
    assert policy.spec is not None
    fitted = copy.copy(policy)  # its normaliser fitted to the flight's world, the network's hover in its spec
    fitted.net, fitted.normalizer, fitted.obs_shapes = switched, policy.fitted()[1], policy.fitted()[2]
    fitted.spec = dataclasses.replace(policy.spec, hover=True)
    fitted._fitted, fitted._fits = None, {}
    return fitted


@pytest.fixture(scope="module")
def flown() -> tuple[GreedyPolicy, dict[str, np.ndarray]]:
    """The shipped fleet policy at 4 taxis with window 24, and the network inputs of 40 steps of its own flight."""
    policy = make("learned", source="berlin_fleet_v1", passenger_window=24)
    cfg = make_fleet_instance("berlin", 0, 4, 48, separation="shield", hover_action=True)
    env = uamfleet.VectorEnv(cfg, num_envs=1, observer=policy.spec)
    obs, _ = env.reset(seed=0)
    policy.reset(env.sim)
    rows = []
    for _ in range(40):
        rows.append(policy.network_input(obs))
        obs = env.step(policy(obs))[0]
    return policy, {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}


def _logp(policy: GreedyPolicy, inputs: dict[str, np.ndarray]) -> torch.Tensor:
    return torch.log_softmax(policy.logits_of(inputs).double(), dim=-1)


def test_the_option_is_off_by_default_and_needs_the_hover_component() -> None:
    assert NetConfig().hover_logit is False
    assert uamfleet.pretrained("berlin_fleet_v1").net.cfg.hover_logit is False
    with pytest.raises(ValueError, match=r"hover_logit=True .* needs stop_hover=True"):
        NetConfig(action_head="stops", stop_inputs=True, hover_logit=True)


def test_the_stop_components_keep_their_headings_and_the_hover_moves_to_action_16(flown) -> None:
    policy, inputs = flown
    before, after = _logp(policy, inputs), _logp(_switched(policy), inputs)  # [B, 16], [B, 17]
    assert before.shape[1] == NUM_HEADINGS and after.shape[1] == NUM_HEADINGS + 1
    hover_at = inputs["hover_heading_mask"] > 0.5  # [B, 16] one-hot, or none before the first move
    open_stop = (inputs["stop_heading_mask"] > 0.5).any(-1) & ~(inputs["stop_claims"][..., STOP_CLAIMED_BY_OTHER] > 0.5)
    idle = ~open_stop.any(-1) & hover_at.any(-1)  # rows where the hover component is open in both
    assert 10 <= idle.sum() < len(idle), "the drawn flight has idle and busy rows (else the test cannot fail)"
    # every heading but the hover heading keeps its probability: the stop and free components are unchanged
    others = ~hover_at & (before.numpy() > CLOSED)
    np.testing.assert_allclose(after[:, :NUM_HEADINGS].numpy()[others], before.numpy()[others], atol=1e-5)
    # the hover heading loses exactly the hover component's mass, which action 16 gets
    p_before, p_after = before.exp().numpy(), after.exp().numpy()
    moved = p_before[hover_at] - p_after[:, :NUM_HEADINGS][hover_at]  # one value per row with a hover heading
    np.testing.assert_allclose(moved, p_after[hover_at.any(-1), HOVER_ACTION], atol=1e-5)
    assert moved[idle[hover_at.any(-1)]].min() > 0.01, "the hover component carries mass on idle rows"
    assert (p_after[open_stop.any(-1), HOVER_ACTION] < 1e-6).all(), "a taxi with a stop to fly to never hovers"


def test_an_untrained_switch_keeps_every_stop_headings_probability_ratio(flown) -> None:
    policy, inputs = flown
    before, after = _logp(policy, inputs).numpy(), _logp(_switched(policy), inputs).numpy()
    hover_at = inputs["hover_heading_mask"] > 0.5
    for row in range(len(before)):
        kept = np.flatnonzero(~hover_at[row] & (before[row] > CLOSED))  # the headings the stop components fly
        if len(kept) < 2:
            continue
        ratio = before[row, kept] - before[row, kept[0]]  # log-ratios to the first such heading
        np.testing.assert_allclose(after[row, kept] - after[row, kept[0]], ratio, atol=1e-5)


def test_where_the_hover_component_dominates_the_greedy_policy_hovers(flown) -> None:
    policy, inputs = flown
    switched = _switched(policy)
    before, after = _logp(policy, inputs).numpy(), _logp(switched, inputs).numpy()
    hover_at = inputs["hover_heading_mask"] > 0.5
    hover_weight = np.exp(after[:, HOVER_ACTION])
    dominated = after[:, HOVER_ACTION] > after[:, :NUM_HEADINGS].max(-1)  # more mass than any one heading
    assert dominated.sum() >= 5, "the drawn flight has rows where the shipped policy hovers"
    choice = switched.logits_of(inputs).argmax(-1).numpy()
    assert (choice[dominated] == HOVER_ACTION).all()
    # ... where the policy without the option flew the hover heading, the 100 m move back
    assert (before[dominated].argmax(-1) == hover_at[dominated].argmax(-1)).all()
    assert (choice[hover_weight < 0.01] < NUM_HEADINGS).all(), "a taxi whose hover has no mass flies"


def test_the_greedy_policy_flies_action_16_through_the_loop_guard_at_another_fleet_size(flown) -> None:
    policy = flown[0]
    switched = _switched(policy)
    cfg = make_fleet_instance("berlin", 1, 8, 96, separation="shield", hover_action=True)
    traj = switched.fly(cfg, seed=1)  # the same weights at another fleet size keep the option
    fitted = switched.fitted()[0]
    assert fitted.cfg.hover_logit and fitted.num_actions == NUM_HEADINGS + 1
    assert switched.fitted()[2]["others"] == (7, 3)  # fitted to 8 taxis
    actions = traj.stacked("actions")
    assert (actions == HOVER_ACTION).any() and actions.max() <= HOVER_ACTION
    with pytest.raises(ConfigError, match="hover_action=True"):
        switched.fly(make_fleet_instance("berlin", 1, 8, 96, separation="shield", hover_action=False))


def test_action_16_is_never_masked_and_ppo_reads_17_actions(flown) -> None:
    policy, inputs = flown
    obs = obs_to_torch(inputs, "cpu")
    switched = _switched(policy).net
    blocked = dict(obs, action_mask=torch.zeros_like(obs["action_mask"]))  # no heading allowed (the shield's world)
    logits = switched.masked_logits(blocked)
    assert (logits[:, HOVER_ACTION] > torch.finfo(logits.dtype).min).all()
    state = torch.zeros(len(logits), switched.cfg.critic_state_dim or 0)  # the shipped critic is centralised
    dist, _ = switched.policy_and_value(obs, state)
    assert dist.probs.shape == (len(inputs["self"]), NUM_HEADINGS + 1)
    _, logprob, _, _ = switched.get_action_and_value(obs, torch.full((len(logits),), HOVER_ACTION), state)
    np.testing.assert_allclose(logprob.exp().detach(), dist.probs[:, HOVER_ACTION].detach(), rtol=1e-5, atol=1e-7)
    sampled = switched.get_action_and_value(obs, state=state)[0]
    assert sampled.max() <= HOVER_ACTION


def test_a_checkpoint_records_the_option_and_loads_with_it(tmp_path: Path) -> None:
    from uamfleet.zoo import pretrained_path

    ckpt = Checkpoint.load(pretrained_path("berlin_fleet_v1"), map_location="cpu")
    ckpt.net_config = {**ckpt.net_config, "hover_logit": True}
    path = tmp_path / "switched.pt"
    ckpt.save(path)
    policy, _ = load_policy(path)
    assert policy.net.cfg.hover_logit and policy.net.num_actions == NUM_HEADINGS + 1


def test_training_refuses_the_option_without_the_hover_action() -> None:
    from uamfleet.rl.learner import _check_hover_logit

    cfg = uamfleet.pretrained("berlin_fleet_v1").net.cfg
    on = dataclasses.replace(cfg, hover_logit=True)
    with pytest.raises(ConfigError, match="drop --hover-logit"):
        _check_hover_logit(on, make_fleet_instance("berlin", 0, 4, 48, hover_action=False))
    _check_hover_logit(on, make_fleet_instance("berlin", 0, 4, 48, hover_action=True))
    anytime = dataclasses.replace(uamfleet.pretrained("berlin").net.cfg, hover_anytime=True)
    with pytest.raises(ConfigError, match="hover_anytime"):
        _check_hover_logit(anytime, make_fleet_instance("berlin", 0, 4, 48, hover_action=False))
    _check_hover_logit(anytime, make_fleet_instance("berlin", 0, 4, 48, hover_action=True))


def test_a_fine_tune_with_the_option_trains_17_logits_and_its_checkpoint_records_it(tmp_path: Path) -> None:
    """One tiny PPO iteration from the shipped fleet with --hover-logit: 17-way sampling, update and evaluation."""
    from uamfleet.rl.runs import read_progress
    from uamfleet.rl.trainer import TrainArgs, train

    args = TrainArgs.from_flat(dict(
        scenario="berlin_fleet", init_from="berlin_fleet_v1", hover_logit=True, passenger_window=24, num_taxis=4,
        num_requests=24, reinit_critic=True, centralised_critic=False, total_timesteps=256, num_envs=2, num_steps=32,
        num_minibatches=2, update_epochs=1, eval_every=1, eval_instances=1, checkpoint_every=1, run_dir=tmp_path,
        run_name="hover", progress=False, tensorboard=False, threads=1, shaping=0.0, time_limit_steps=200,
    ))  # fmt: skip
    train(args)
    rows = read_progress(tmp_path / "hover" / "progress.csv")
    assert rows[-1]["iteration"] == 1 and rows[0]["eval/pr_pct"] == 100.0
    policy, saved = load_policy(tmp_path / "hover" / "last.pt")
    assert saved.net.hover_logit and policy.net.cfg.hover_logit and policy.net.num_actions == NUM_HEADINGS + 1
