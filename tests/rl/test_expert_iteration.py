"""Expert iteration (uamfleet.rl.expert_iteration): the fit moves the network toward soft targets, the KL anchor
holds it, and a round whose fit does not fly shorter on validation leaves the network as it was."""

from __future__ import annotations

import copy
import csv
import math

import numpy as np
import pytest
import torch

from uamfleet.config import ConfigError
from uamfleet.rl.expert_iteration import (
    ExItOptions,
    LabelSet,
    expert_iteration,
    fine_tune,
    fit,
    instance_world,
    label_set,
    start_policy,
)
from uamfleet.rl.policy import load_policy
from uamfleet.types import HOVER_ACTION


def _states(policy, count: int = 12) -> dict[str, np.ndarray]:
    """Normalised network rows of the start policy's own first steps on a validation instance of a hover world."""
    from uamfleet.env.protocol import observer_of
    from uamfleet.env.vector_env import VectorEnv

    cfg = instance_world("berlin", 1_000_000, hover=True)
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy))
    obs, _ = env.reset(seed=0)
    policy.reset(env.sim)
    rows = []
    for _ in range(count):
        rows.append(policy.network_input(obs))
        obs, _, term, trunc, _ = env.step(policy(obs))
        if term.any() or trunc.any():
            break
    return {k: np.concatenate([r[k] for r in rows]) for k in rows[0]}


def _logp(policy, rows: dict[str, np.ndarray]) -> torch.Tensor:
    from uamfleet.rl.networks import obs_to_torch

    with torch.no_grad():
        return torch.log_softmax(policy.net.masked_logits(obs_to_torch(rows, "cpu")), -1)


@pytest.fixture(scope="module")
def start():
    return start_policy(ExItOptions())


def test_fit_raises_the_hover_target_and_the_anchor_holds_the_start(start) -> None:
    """With targets all on the hover action (16), a fit without the anchor raises p(16) on those states by orders of
    magnitude; the same fit under a very strong anchor raises it as well but keeps the distribution over the
    headings (given no hover) within 0.01 of the start's, and so the preferred heading."""
    _, policy = start
    rows = _states(policy)
    n = len(rows["action_mask"])
    target = np.zeros((n, 17), np.float32)
    target[:, HOVER_ACTION] = 1.0
    data = LabelSet(rows, target, np.ones(n, np.float32))
    before = _logp(policy, rows)
    assert before[:, HOVER_ACTION].exp().max() < 1e-5  # the converted start never hovers
    moved = copy.deepcopy(policy)
    fit(moved, policy, data, ExItOptions(epochs=20, learning_rate=1e-2, kl_anchor=0.0), np.random.default_rng(0))
    after = _logp(moved, rows)
    assert (after[:, HOVER_ACTION] - before[:, HOVER_ACTION]).min() > 2.0  # e^2: p(16) at least 7 times higher
    held = copy.deepcopy(policy)
    fit(held, policy, data, ExItOptions(epochs=20, learning_rate=1e-3, kl_anchor=1e4), np.random.default_rng(0))
    anchored = _logp(held, rows)
    # the anchor (KL from the start's heading distribution) holds which heading it prefers, never the hover
    given_no_hover = torch.log_softmax(anchored[:, :HOVER_ACTION], -1).exp()
    assert torch.allclose(given_no_hover, torch.log_softmax(before[:, :HOVER_ACTION], -1).exp(), atol=0.01)
    assert torch.equal(anchored[:, :HOVER_ACTION].argmax(-1), before[:, :HOVER_ACTION].argmax(-1))
    assert (anchored[:, HOVER_ACTION] - before[:, HOVER_ACTION]).min() > 2.0


def test_masked_targets_are_dropped(start) -> None:
    """A target wholly on actions the state masks carries no weight: the fit leaves the network bit-identical."""
    _, policy = start
    rows = _states(policy, count=60)
    mask = rows["action_mask"].reshape(len(rows["action_mask"]), -1).astype(bool)
    with_masked = np.flatnonzero(~mask.all(-1))
    assert len(with_masked), "no state of this flight masks a heading: choose another instance"
    i = int(with_masked[0])
    masked = np.flatnonzero(~mask[i])
    rows = {k: v[i : i + 1].repeat(8, 0) for k, v in rows.items()}  # that state 8 times
    n = len(rows["action_mask"])
    target = np.zeros((n, 17), np.float32)
    target[:, masked[0]] = 1.0
    moved = copy.deepcopy(policy)
    fit(moved, policy, LabelSet(rows, target, np.ones(n, np.float32)), ExItOptions(epochs=2, kl_anchor=0.0),
        np.random.default_rng(0))  # fmt: skip
    for a, b in zip(moved.net.parameters(), policy.net.parameters(), strict=True):
        assert torch.equal(a, b)


def test_bad_options_name_the_value() -> None:
    with pytest.raises(ConfigError, match="family='nowhere'"):
        ExItOptions(family="nowhere")
    with pytest.raises(ConfigError, match=r"no_such\.pt"):
        ExItOptions(init="no_such.pt")
    with pytest.raises(ValueError, match="kl_anchor"):
        ExItOptions(kl_anchor=-1.0)


@pytest.mark.slow
def test_a_rejected_round_keeps_the_start_and_progress_records_the_cost(tmp_path) -> None:
    """One round at a learning rate too small to change a flight: validation is not shorter, the round is rejected
    and best.pt holds the start's weights bit for bit; progress.csv records the labelling cost."""
    opts = ExItOptions(rounds=1, label_instances=2, label_futures=2, val_instances=2, workers=1, epochs=1,
                       learning_rate=1e-12, run_dir=tmp_path, run_name="tiny")  # fmt: skip
    expert_iteration(opts)
    with (tmp_path / "tiny" / "progress.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert [float(r["accepted"]) for r in rows] == [1.0, 0.0]
    assert float(rows[1]["label_cpu_s"]) > 0 and float(rows[1]["hedge_labels"]) > 0
    start, best = load_policy(tmp_path / "tiny" / "start.pt")[0], load_policy(tmp_path / "tiny" / "best.pt")[0]
    for a, b in zip(start.net.state_dict().values(), best.net.state_dict().values(), strict=True):
        assert torch.equal(a, b)
    assert not (tmp_path / "tiny" / "round0.pt").exists()


def test_bad_ppo_options_name_the_fix() -> None:
    with pytest.raises(ConfigError, match="ppo_after=-1"):
        ExItOptions(ppo_after=-1)
    with pytest.raises(ConfigError, match=r"ppo_after=100 is less than one PPO iteration .* = 1280 .*--ppo-after 0"):
        ExItOptions(ppo_after=100)
    with pytest.raises(ConfigError, match="'berlin_burst' has no training scenario 'berlin_burst_instances'"):
        ExItOptions(ppo_after=1280, family="berlin_burst")
    with pytest.raises(ConfigError, match="ppo_kl"):
        ExItOptions(ppo_kl=-0.1)
    with pytest.raises(ConfigError, match="ppo_learning_rate"):
        ExItOptions(ppo_learning_rate=0.0)
    ExItOptions(family="berlin_burst")  # without PPO any family labels and validates as before


ADAM_STEP_BOUND = 0.1 / math.sqrt(0.001)
"""Kingma & Ba 2015, §2.1: one Adam step moves a parameter by at most lr (1 − β1) / √(1 − β2) when 1 − β1 > √(1 − β2)
(β = 0.9, 0.999, the learner's): 3.16 lr."""


def _kl(policy, reference, rows: dict[str, np.ndarray]) -> float:
    """Mean KL(π_policy ‖ π_reference) over ``rows``, all 17 actions."""
    p, q = _logp(policy, rows), _logp(reference, rows)
    return float((p.exp() * (p - q)).sum(-1).mean())


@pytest.mark.slow
def test_ppo_after_the_fit_moves_the_network_within_the_bounds(start, tmp_path) -> None:
    """One PPO iteration (5 envs x 64 steps, 4 epochs x 8 minibatches = 32 Adam steps) on the fitted network: its
    weights change, no parameter by more than 32 Adam steps can move one (ADAM_STEP_BOUND x lr each, the first
    iteration's rate), the fitted network's own file is written, and on the start's states the KL toward the fitted
    network is positive and smaller with a strong KL term (weight 10) than without one (same seed, same rollout)."""
    source, fitted = start
    rows = _states(fitted, count=40)
    moved = {}
    for kl in (0.0, 10.0):
        opts = ExItOptions(ppo_after=320, ppo_envs=5, ppo_steps=64, ppo_kl=kl, ppo_learning_rate=1e-3)
        moved[kl] = copy.deepcopy(fitted)
        figures = fine_tune(moved[kl], source, opts, tmp_path / f"kl{kl:g}", 0)
        assert figures["ppo_agent_steps"] == 320 and figures["ppo_cpu_s"] > 0
        assert (tmp_path / f"kl{kl:g}" / "fit0.pt").is_file()
        pairs = zip(moved[kl].net.parameters(), fitted.net.parameters(), strict=True)
        change = max(float((a - b).detach().abs().max()) for a, b in pairs)
        assert 0 < change <= 32 * ADAM_STEP_BOUND * 1e-3 * (1 + 1e-6)
    free, held = _kl(moved[0.0], fitted, rows), _kl(moved[10.0], fitted, rows)
    assert 0 < held < free


@pytest.mark.slow
def test_the_loop_validates_the_fit_without_ppo_and_the_fine_tuned_fit_with_it(tmp_path, monkeypatch) -> None:
    """A tiny seeded round: with ppo_after=0 the network validated is, bit for bit, the fit of the start to the
    round's labels reproduced here from its saved labels (today's loop), and PPO never runs; with ppo_after=320 the
    validated network is that fit after PPO (other weights), written first as ppo/fit0.pt."""
    import uamfleet.rl.expert_iteration as exit_module
    from uamfleet.instances import split_seeds
    from uamfleet.rl.labels import load_labels
    from uamfleet.rl.policy import GreedyPolicy

    validated: list[dict[str, torch.Tensor]] = []
    flights = exit_module.validation_flights

    def recording(policy, *args, **kwargs):
        if isinstance(policy, GreedyPolicy):
            validated.append({k: v.clone() for k, v in policy.net.state_dict().items()})
        return flights(policy, *args, **kwargs)

    monkeypatch.setattr(exit_module, "validation_flights", recording)
    tiny = dict(rounds=1, label_instances=2, label_futures=2, val_instances=2, workers=1, epochs=1, run_dir=tmp_path)
    real_fine_tune = exit_module.fine_tune
    monkeypatch.setattr(exit_module, "fine_tune", lambda *a: pytest.fail("PPO ran with ppo_after=0"))
    opts = ExItOptions(**tiny, run_name="fit_only")
    expert_iteration(opts)
    _, policy = start_policy(opts)
    seeds = [int(s) for s in split_seeds("train", 2, 0)]  # round 0's block, as the loop draws it
    labels = load_labels(tmp_path / "fit_only" / "labels" / "0", seeds)
    refit = copy.deepcopy(policy)
    fit(refit, policy, label_set(policy, labels, opts), opts, np.random.default_rng(opts.seed))
    assert len(validated) == 2  # the start, then the round's candidate
    for name, value in refit.net.state_dict().items():
        assert torch.equal(validated[1][name], value), name
    monkeypatch.setattr(exit_module, "fine_tune", real_fine_tune)
    expert_iteration(ExItOptions(**tiny, run_name="with_ppo", ppo_after=320, ppo_envs=5, ppo_steps=64))
    assert (tmp_path / "with_ppo" / "ppo" / "fit0.pt").is_file()
    assert len(validated) == 4
    assert any(not torch.equal(validated[3][k], v) for k, v in refit.net.state_dict().items())
    with (tmp_path / "with_ppo" / "progress.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert float(rows[1]["ppo_agent_steps"]) == 320 and float(rows[1]["ppo_cpu_s"]) > 0
