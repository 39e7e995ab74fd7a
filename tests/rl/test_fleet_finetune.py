"""Fine-tuning a claims fleet policy with the return (uamfleet/rl/fleet_finetune.py): the cost recomputed by hand
on a small drawn scene, one iteration writes a checkpoint that flies by its registry name, a zero learning rate leaves
the weights as they were, and bad options are refused in one line."""

from __future__ import annotations

import csv
import dataclasses

import numpy as np
import pytest
import torch

from uamfleet import policies
from uamfleet.checks import ConfigError
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.rl.fleet_claims import with_dispatch_claims
from uamfleet.rl.fleet_finetune import COST_SCALE, FleetFinetuneArgs, advantages, fleet_finetune, sample_episode
from uamfleet.rl.fleet_imitation import fleet_policy
from uamfleet.rollout import fly, observer_of
from uamfleet.types import WAITING


def scene(taxis: int = 2, requests: int = 6, split: str = "train"):
    """A small drawn Berlin fleet scene under the shield with the hover action (as the fleet benchmark flies)."""
    return make_fleet_instance("berlin", split_seeds(split, 1)[0], taxis, requests, separation="shield",
                               hover_action=True)  # fmt: skip


def tiny_args(tmp_path, **changes) -> FleetFinetuneArgs:
    base = FleetFinetuneArgs(init="berlin_fleet", mixture=("2x6",), iterations=1, run_dir=tmp_path, run_name="ft")
    return dataclasses.replace(base, **changes)


def test_the_cost_by_hand_on_a_small_scene(tmp_path) -> None:
    cfg = scene()
    args = tiny_args(tmp_path, wait_weight=7.0, undelivered_m=1000.0)
    policy = with_dispatch_claims(fleet_policy("berlin_fleet", 24))
    policy.loop_guard = None
    episode = sample_episode(cfg, policy, args.teacher, args, torch.Generator().manual_seed(3))
    A = cfg.num_taxis
    actions = episode.actions.reshape(-1, A)
    assert (
        len(actions) == len(episode.costs) and (episode.step.reshape(-1, A) == np.arange(len(actions))[:, None]).all()
    )
    # replay the sampled actions and recompute each step's cost from the positions and the passengers' statuses
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy))
    env.reset(seed=0)
    release = env.state.pax_release[0].copy()
    exists = env.state.pax_exists[0].copy()
    picked_at = np.full(len(exists), -1)
    by_hand = []
    for t, action in enumerate(actions):
        before = env.state.pos_m[0].copy()
        waiting = int(((env.state.pax_status[0] == WAITING) & exists).sum())
        env.step(action[None])
        flown = float(np.linalg.norm(env.state.pos_m[0] - before, axis=-1).sum())
        by_hand.append(flown + 7.0 * waiting * cfg.slot_s)
        newly = (picked_at < 0) & exists & (env.state.pax_status[0] != WAITING) & (release <= t)
        picked_at[newly] = t + 1
    delivered = episode.delivered
    by_hand[-1] += 1000.0 * (exists.sum() - delivered)
    np.testing.assert_allclose(episode.costs, by_hand, atol=1e-6)
    # the wait term summed over the episode is every passenger's wait (pick-up step - release step) x slot
    boarded = picked_at >= 0
    assert episode.wait_s == pytest.approx(float(((picked_at - release)[boarded]).sum() * cfg.slot_s))
    assert episode.distance_m == pytest.approx(float(env.state.distance_m[0].sum()))
    # the baseline: with two samples each sample's advantage is minus half the gap between their cost-to-go
    other = dataclasses.replace(episode, costs=episode.costs[:-3] + 50.0)
    adv = advantages([episode, other], gamma=1.0)
    togo_a, togo_b = np.cumsum(episode.costs[::-1])[::-1], np.cumsum(other.costs[::-1])[::-1]
    togo_b = np.concatenate([togo_b, np.zeros(3)])
    np.testing.assert_allclose(adv[0], -(togo_a - togo_b) / COST_SCALE)
    np.testing.assert_allclose(adv[1], -(togo_b - togo_a)[: len(other.costs)] / COST_SCALE)


def test_one_iteration_writes_a_checkpoint_that_flies_by_its_registry_name(tmp_path) -> None:
    rows = fleet_finetune(tiny_args(tmp_path, learning_rate=1e-3))
    assert len(rows) == 1 and rows[0]["episodes"] == 2 and rows[0]["kl_to_start"] >= 0
    with open(tmp_path / "ft" / "progress.csv", encoding="utf-8") as f:
        progress = list(csv.DictReader(f))
    assert {"mean_return", "kl_to_start"} <= set(progress[0])
    saved = torch.load(tmp_path / "ft" / "iter0.pt", weights_only=True)
    assert saved["net_config"]["dispatch_claim_inputs"] is True
    assert saved["args"]["fleet_finetune"]["learning_rate"] == 1e-3 and saved["best_eval"]["iteration"] == 0
    start = with_dispatch_claims(fleet_policy("berlin_fleet", 24)).net.state_dict()
    assert any(not torch.equal(saved["model"][k], v) for k, v in start.items())  # it learned something
    policy = policies.make_named(f"fleet_claims:source={tmp_path / 'ft' / 'iter0.pt'}")
    traj = fly(scene(split="validation"), policy)
    assert traj.terminated


def test_a_zero_learning_rate_leaves_the_weights_bit_identical(tmp_path) -> None:
    fleet_finetune(tiny_args(tmp_path, learning_rate=0.0))
    saved = torch.load(tmp_path / "ft" / "last.pt", weights_only=True)["model"]
    start = with_dispatch_claims(fleet_policy("berlin_fleet", 24)).net.state_dict()
    assert set(saved) == set(start)
    for key, value in start.items():
        assert torch.equal(saved[key], value), key


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"samples_per_episode": 1}, "--samples-per-episode=1"),
        ({"temperature": 0.0}, "--temperature=0.0"),
        ({"gamma": 1.5}, "--gamma=1.5"),
        ({"learning_rate": -1.0}, "--learning-rate=-1.0"),
        ({"mixture": ()}, "--mixture is empty"),
        ({"mixture": ("9",)}, "9"),
        ({"also_family": "atlantis"}, "--also-family='atlantis'"),
    ],
)
def test_bad_options_are_refused_in_one_line(tmp_path, changes, message) -> None:
    with pytest.raises(ConfigError) as err:
        tiny_args(tmp_path, **changes)
    text = str(err.value)
    assert message in text and "\n" not in text
    assert any(word in text for word in ("use", "give", "must", "e.g.")), text  # it says what to do
