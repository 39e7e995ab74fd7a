"""``NetConfig.hover_anytime`` and :func:`uamfleet.rl.hover.with_hover_anytime`: the shipped single-taxi policy with
the hover action (16) open at every step, on its own flights over Berlin validation instances in hover worlds."""

from __future__ import annotations

import copy
import dataclasses
from pathlib import Path

import numpy as np
import pytest
import torch

import uamfleet
from uamfleet.checks import ConfigError
from uamfleet.instances import make_instance, split_seeds
from uamfleet.rl.checkpoint import Checkpoint, pretrained_path
from uamfleet.rl.heads import HOVER_START
from uamfleet.rl.hover import hover_checkpoint, with_hover_anytime
from uamfleet.rl.networks import NetConfig, obs_to_torch
from uamfleet.rl.policy import GreedyPolicy, load_policy
from uamfleet.types import HOVER_ACTION, NUM_HEADINGS

SEEDS = split_seeds("validation", 5)


def _recording(policy: GreedyPolicy) -> tuple[list[dict[str, np.ndarray]], list[torch.Tensor]]:
    """Record the network inputs and the logits of every decision ``policy`` takes from now on."""
    inputs: list[dict[str, np.ndarray]] = []
    logits: list[torch.Tensor] = []
    decide = policy.logits_of

    def recorded(x: dict[str, np.ndarray]) -> torch.Tensor:
        inputs.append({k: v.copy() for k, v in x.items()})
        logits.append(decide(x).clone())
        return logits[-1]

    policy.logits_of = recorded  # type: ignore[method-assign]
    return inputs, logits


@pytest.fixture(scope="module")
def flights() -> dict[str, object]:
    """The shipped ``berlin`` policy and its conversion flown on 5 validation instances in hover worlds: their
    actions, and the converted policy's inputs and logits at every step."""
    shipped = uamfleet.pretrained("berlin")
    converted = with_hover_anytime(uamfleet.pretrained("berlin"))
    shipped_logits = _recording(shipped)[1]
    converted_in, converted_logits = _recording(converted)
    actions: dict[str, list[np.ndarray]] = {"shipped": [], "converted": []}
    for seed in SEEDS:
        cfg = make_instance("berlin", seed).replace(hover_action=True)
        actions["shipped"].append(shipped.fly(cfg, seed=0).stacked("actions"))
        actions["converted"].append(converted.fly(cfg, seed=0).stacked("actions"))
    del converted.logits_of  # the recording wrapper: the tests below call the policy's own method
    return {
        "converted": converted, "actions": actions,
        "inputs": {k: np.concatenate([x[k] for x in converted_in]) for k in converted_in[0]},
        "logits": torch.cat(converted_logits), "shipped_logits": torch.cat(shipped_logits),
    }  # fmt: skip


def test_the_option_is_off_by_default_and_refuses_what_it_cannot_be() -> None:
    assert NetConfig().hover_anytime is False
    assert uamfleet.pretrained("berlin").net.cfg.hover_anytime is False
    assert uamfleet.pretrained("berlin").net.num_actions == NUM_HEADINGS
    with pytest.raises(ValueError, match=r"hover_anytime=True .* needs action_head='stops'"):
        NetConfig(hover_anytime=True)


def test_with_the_fleets_hover_logit_the_two_hovers_add_up_and_it_flies_as_shipped() -> None:
    """The shipped fleet policy (``hover_logit``: action 16 open only where no stop is) converted: every action keeps
    its probability times 1 - p and the hover gains p = sigmoid(HOVER_START), step by step on the same states."""
    from uamfleet.instances import make_fleet_instance
    from uamfleet.rl.fleet_imitation import fleet_policy

    shipped, converted = fleet_policy("berlin_fleet", 24), fleet_policy("berlin_fleet", 24, hover_anytime=True)
    assert shipped.net.cfg.hover_logit and converted.net.cfg.hover_logit and converted.net.cfg.hover_anytime
    shipped_logits, converted_logits = _recording(shipped)[1], _recording(converted)[1]
    cfg = make_fleet_instance("berlin", SEEDS[0], 4, 24, separation="shield", hover_action=True)
    flown = shipped.fly(cfg, seed=0).stacked("actions")
    assert np.array_equal(flown, converted.fly(cfg, seed=0).stacked("actions"))
    old = torch.softmax(torch.cat(shipped_logits).double(), dim=-1).numpy()  # [T * 4, 17]
    new = torch.softmax(torch.cat(converted_logits).double(), dim=-1).numpy()
    p = 1.0 / (1.0 + np.exp(-HOVER_START))  # 6.1e-6: the new hover's probability before any training
    np.testing.assert_allclose(new[:, :NUM_HEADINGS], old[:, :NUM_HEADINGS] * (1 - p), rtol=1e-4, atol=1e-9)
    np.testing.assert_allclose(new[:, HOVER_ACTION], old[:, HOVER_ACTION] * (1 - p) + p, rtol=1e-4, atol=1e-9)
    closed = old[:, HOVER_ACTION] < 1e-30  # a stop open: the shipped hover closed, the new one at p
    assert closed.any() and (~closed).any(), "both kinds of state were flown"
    assert (flown == HOVER_ACTION).any(), "the shipped hover (no stop open) was flown, and still is"


def test_the_converted_policy_flies_as_shipped_and_hovers_with_probability_below_1e_5(flights) -> None:
    actions = flights["actions"]
    for seed, shipped, converted in zip(SEEDS, actions["shipped"], actions["converted"], strict=True):
        assert shipped.shape == converted.shape and (shipped == converted).all(), f"validation seed {seed}"
    converted: GreedyPolicy = flights["converted"]
    assert converted.spec is not None and converted.spec.hover and converted.net.num_actions == NUM_HEADINGS + 1
    probs = torch.softmax(flights["logits"].double(), dim=-1).numpy()  # [T, 17] every step of the 5 flights
    assert len(probs) == sum(len(a) for a in actions["converted"]) and len(probs) > 200
    assert probs[:, HOVER_ACTION].max() < 1e-5
    assert probs[:, HOVER_ACTION].min() > 1e-6, "the hover is open at every step, not closed"
    # each heading keeps the shipped policy's probability times 1 - p(16), step by step on the same states
    shipped = torch.softmax(flights["shipped_logits"].double(), dim=-1).numpy()  # [T, 16]
    expected = shipped * (1.0 - probs[:, HOVER_ACTION : HOVER_ACTION + 1])
    np.testing.assert_allclose(probs[:, :NUM_HEADINGS], expected, rtol=1e-4, atol=1e-7)
    open_stop = (flights["inputs"]["stop_heading_mask"] > 0.5).any(axis=(-2, -1))  # [T] a stop to fly to
    assert open_stop.mean() > 0.5, "most steps have an open stop (where the fleet's hover logit is closed)"


def test_a_cross_entropy_step_toward_hover_at_an_open_stop_raises_its_probability(flights) -> None:
    inputs = flights["inputs"]
    row = int(np.flatnonzero((inputs["stop_heading_mask"] > 0.5).any(axis=(-2, -1)))[7])  # a state with an open stop
    obs = obs_to_torch({k: v[row : row + 1] for k, v in inputs.items()}, "cpu")
    net = copy.deepcopy(flights["converted"].net)
    features = net.torso.encode(obs)[0].detach()  # [1, F] what the hover logit reads
    before = torch.log_softmax(net.masked_logits(obs), dim=-1)[0, HOVER_ACTION].detach()
    lr = 0.01
    optimizer = torch.optim.SGD(net.parameters(), lr=lr)
    loss = torch.nn.functional.cross_entropy(net.masked_logits(obs), torch.tensor([HOVER_ACTION]))
    loss.backward()
    optimizer.step()
    after = torch.log_softmax(net.masked_logits(obs), dim=-1)[0, HOVER_ACTION].detach()
    assert after > before + 0.3  # p(16) up by a third
    # by hand: the loss is -log sigmoid(z), z = b + w . f with w = 0, so only b and w move, z by lr (1 - p)(1 + |f|^2)
    p = before.exp()
    z = HOVER_START + lr * (1 - p) * (1 + (features.double() ** 2).sum())
    np.testing.assert_allclose(float(after), float(torch.nn.functional.logsigmoid(z)), rtol=1e-4)


def test_a_saved_conversion_loads_back_with_its_option_and_bit_identical_logits(flights, tmp_path: Path) -> None:
    converted = with_hover_anytime(uamfleet.pretrained("berlin"))
    with torch.no_grad():  # as after training: the new parameters are no longer their initial values
        converted.net.stop_head.anytime_hover.weight.normal_(0.0, 0.05, generator=torch.Generator().manual_seed(0))
        converted.net.stop_head.anytime_hover.bias.fill_(1.0)
    path = tmp_path / "hover.pt"
    hover_checkpoint(Checkpoint.load(pretrained_path("berlin")), converted).save(path)
    raw = torch.load(path, weights_only=True)
    assert raw["net_config"]["hover_anytime"] is True and raw["observer"]["hover"] is True
    loaded, _ = load_policy(path)
    assert loaded.net.cfg.hover_anytime and loaded.spec is not None and loaded.spec.hover
    inputs = flights["inputs"]
    assert torch.equal(loaded.logits_of(inputs), converted.logits_of(inputs))
    assert (loaded.logits_of(inputs).argmax(-1) == HOVER_ACTION).any(), "the trained hover logit came back"
    traced = copy.copy(loaded).trace_actor()  # the deployed actor reads the option as the eager one does
    assert torch.equal(traced.logits_of(inputs), loaded.logits_of(inputs))


def test_the_option_on_a_spec_without_the_hover_action_is_refused_in_one_line(tmp_path: Path) -> None:
    converted = with_hover_anytime(uamfleet.pretrained("berlin"))
    assert converted.spec is not None
    no_hover = dataclasses.replace(converted.spec, hover=False)
    with pytest.raises(ConfigError, match=r"hover_anytime.* hover=False: give it .*hover=True") as err:
        GreedyPolicy(converted.net, converted.normalizer, converted.device, converted.obs_shapes, spec=no_hover)
    assert "\n" not in str(err.value)
    ckpt = hover_checkpoint(Checkpoint.load(pretrained_path("berlin")), converted)
    ckpt.observer = {**(ckpt.observer or {}), "hover": False}  # a file whose spec lacks the hover its network takes
    ckpt.save(tmp_path / "no_hover.pt")
    with pytest.raises(ConfigError, match="hover=False") as err:
        load_policy(tmp_path / "no_hover.pt")
    assert "\n" not in str(err.value)
    with pytest.raises(ConfigError, match="hover_action=True"):  # a world without the hover action
        converted.fly(make_instance("berlin", SEEDS[0]))


def test_the_hedge_and_guided_search_fly_a_policy_that_hovers_at_any_step() -> None:
    """Guided search samples its flights from all 17 actions of a hover_anytime policy (the hover included), and the
    hedge over it flies an instance to the end, everyone delivered."""
    from uamfleet.rl.guided import AnticipatingGuidedSearch, GuidedSearchPolicy
    from uamfleet.metrics import episode_metrics
    from uamfleet.rl.hover import with_hover_anytime
    from uamfleet.rollout import fly

    policy = with_hover_anytime(uamfleet.pretrained("berlin"))
    cfg = make_instance("berlin", 1_000_000).replace(hover_action=True)
    for search in (
        GuidedSearchPolicy(policy, top_k=2, samples=2),
        AnticipatingGuidedSearch(policy, None, futures=2, samples=2, wait_action="hover"),
    ):
        m = episode_metrics(fly(cfg, search), cfg.radio, threshold_db=cfg.sinr_min_db)
        assert m.pr_pct == 100.0
