"""DAgger from a fleet dispatcher (uamfleet/rl/fleet_imitation.py): its labels are the dispatcher's own actions, the
fit lowers the imitation loss, and the trained checkpoint flies any fleet size with one set of weights."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import torch
import torch.nn.functional as F

from uamfleet.checks import ConfigError
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.rl.checkpoint import Checkpoint, pretrained_path
from uamfleet.rl.fleet_imitation import (
    MASKED_LOG_PROB,
    TEACHER,
    anchored_fit,
    FleetImitationArgs,
    fleet_imitate,
    fleet_policy,
    label_episode,
    make_teacher,
    parameter_groups,
    stop_labels,
)
from uamfleet.rl.heads import HOVER_START, PRIOR_FLOOR
from uamfleet.rl.hover import NEW_PARAMETERS
from uamfleet.rl.imitation import RESIDUAL_PREFIX, Dataset, fit
from uamfleet.rl.networks import obs_to_torch
from uamfleet.rl.policy import load_policy
from uamfleet.rollout import fly
from uamfleet.types import HOVER_ACTION, STOP_CLAIMED_BY_OTHER


def small_scene(taxis: int = 2, requests: int = 4, seed_index: int = 0):
    """A small drawn Berlin fleet scene under the shield with the hover action (as the fleet benchmark flies)."""
    seed = split_seeds("train", seed_index + 1)[seed_index]
    return make_fleet_instance("berlin", seed, taxis, requests, separation="shield", hover_action=True)


class Recording:
    """The dispatcher flying alone, its actions recorded: the independent account of what it does at each step."""

    def __init__(self, dispatcher) -> None:
        self.dispatcher, self.actions = dispatcher, []

    def reset(self, sim) -> None:
        self.dispatcher.reset(sim)

    def act(self, obs):
        action = self.dispatcher.act(obs)
        self.actions.append(np.asarray(action)[0].copy())
        return action


def test_labels_at_beta_one_are_the_dispatchers_own_actions_when_it_flies_alone() -> None:
    cfg = small_scene()
    alone = Recording(make_teacher(TEACHER, cfg.num_taxis))
    traj = fly(cfg, alone)
    episode = label_episode(cfg, fleet_policy("berlin_fleet", 24), make_teacher(TEACHER, 2), 1.0,
                            np.random.default_rng(0))  # fmt: skip
    expected = np.stack(alone.actions)  # [T, A]
    assert episode.teacher_actions.shape == expected.shape == (len(traj.events), 2)
    assert np.array_equal(episode.teacher_actions, expected)
    assert np.array_equal(episode.flown, expected)  # β = 1: every step the dispatcher's joint move
    assert episode.teacher_steps == episode.steps == len(expected)
    # the fitted labels are the taught subset of them, the rest counted as ruled out
    assert len(episode.labels) + episode.ruled_out == expected.size
    assert set(np.unique(episode.labels)) <= set(np.unique(expected))


def test_labels_on_the_policys_own_states_are_what_a_dispatcher_replayed_on_those_moves_does() -> None:
    # β = 0: the policy flies; replaying its joint moves in a fresh env with a fresh dispatcher watching each step
    # must give the same labels (the dispatcher's commitments depend on the states it watched, nothing else)
    cfg = small_scene(seed_index=1)
    episode = label_episode(cfg, fleet_policy("berlin_fleet", 24), make_teacher(TEACHER, 2), 0.0,
                            np.random.default_rng(0))  # fmt: skip
    moves = iter(episode.flown)
    replayed = Recording(make_teacher(TEACHER, 2))

    class Replay:
        def reset(self, sim) -> None:
            replayed.reset(sim)

        def act(self, obs):
            replayed.act(obs)
            return next(moves)[None]

    fly(cfg, Replay())
    assert np.array_equal(np.stack(replayed.actions), episode.teacher_actions)
    assert episode.teacher_steps == 0
    assert not np.array_equal(episode.flown, episode.teacher_actions)  # the policy's own states, not the teacher's


def test_the_fit_lowers_the_imitation_loss_on_a_small_fixed_dataset() -> None:
    torch.manual_seed(0)
    policy = fleet_policy("berlin_fleet", 24)
    episode = label_episode(small_scene(), policy, make_teacher(TEACHER, 2), 1.0, np.random.default_rng(0))
    data = Dataset()
    data.add(episode.obs, episode.labels, episode.corrected)

    def loss() -> float:
        with torch.no_grad():
            logits = policy.net.masked_logits(obs_to_torch(episode.obs, "cpu"))
            return float(F.cross_entropy(logits, torch.as_tensor(episode.labels)))

    before = loss()
    args = FleetImitationArgs(epochs=20, minibatch=64, learning_rate=3e-4)
    optimizer = torch.optim.Adam(policy.net.parameters(), lr=args.learning_rate)
    fit(policy.net, data, args.fit_args(), optimizer, np.random.default_rng(0))
    after = loss()
    assert np.isfinite(before) and after < 0.8 * before, (before, after)


def test_the_trained_checkpoint_flies_any_fleet_size_with_one_set_of_weights(tmp_path: Path) -> None:
    args = FleetImitationArgs(mixture=("2x4", "4x8"), rounds=1, epochs=1, run_dir=tmp_path, run_name="tiny")
    rows = fleet_imitate(args)
    assert len(rows) == 1 and rows[0]["samples"] > 0 and rows[0]["teacher_steps"] == rows[0]["steps"]
    path = tmp_path / "tiny" / "round0.pt"
    trained = torch.load(path, weights_only=True)["model"]
    shipped = Checkpoint.load(pretrained_path("berlin_fleet")).model
    assert trained.keys() == shipped.keys()
    assert any(not torch.equal(trained[k], shipped[k]) for k in trained)  # fitted
    policy = fleet_policy(str(path), 24)
    for taxis, requests in ((1, 3), (3, 6), (8, 16)):
        traj = fly(small_scene(taxis, requests, seed_index=2), policy)
        assert traj.events[0].pos_m.shape[1] == taxis
    # the same network object flew every size: nothing was resized but the shapes it checks
    assert load_policy(path)[0].net.state_dict().keys() == trained.keys()


def test_bad_options_are_refused_naming_them() -> None:
    with pytest.raises(ConfigError, match="--mixture setting '4by8'"):
        FleetImitationArgs(mixture=("4by8",))
    with pytest.raises(ConfigError, match="--beta0=2"):
        FleetImitationArgs(beta0=2.0)
    for name in ("replan", "learned:source=berlin_fleet", "no_such_dispatcher"):
        with pytest.raises(ConfigError, match=f"--teacher='{name}' is not a fleet dispatcher"):
            make_teacher(name, 2)


def test_stop_labels_fly_for_the_dispatchers_stop_and_fit_the_headings_it_ruled_out() -> None:
    # beta 1: both labellings watch the same flight; where a stop label replaces the dispatcher's heading, it must
    # head for the dispatcher's own stop (progress by the dispatcher's path fields, an independent measure), and each
    # ruled-out heading whose stop label the network gives more than e^-12 is one ruled-out label fewer
    cfg = small_scene(4, 12, seed_index=3)
    policy = fleet_policy("berlin_fleet", 24)
    changed: list[tuple[float, float, float]] = []  # (log-prob of the heading, of its stop label, progress m)

    def watch(env, obs, teacher, actions, log_probs) -> None:
        labels = stop_labels(env, obs, teacher, actions)
        pos = env.state.pos_m[0]
        for a in np.flatnonzero(labels != actions):
            ends = np.stack([pos[a], pos[a] + env.world.moves_m[labels[a]]])
            here, after = teacher.fields.remaining_m(teacher.target(a), ends)
            changed.append((log_probs[a, actions[a]], log_probs[a, labels[a]], here - after))

    heading = label_episode(cfg, policy, make_teacher(TEACHER, 4), 1.0, np.random.default_rng(0), watch=watch)
    stop = label_episode(cfg, policy, make_teacher(TEACHER, 4), 1.0, np.random.default_rng(0), labels="stop")
    assert np.array_equal(heading.teacher_actions, stop.teacher_actions)
    before, after, progress = (np.array(x) for x in zip(*changed, strict=True))
    assert len(progress) > 20 and (progress > 0).all(), progress.min()
    newly_fitted = int(((before <= PRIOR_FLOOR) & (after > PRIOR_FLOOR)).sum())
    lost = int(((before > PRIOR_FLOOR) & (after <= PRIOR_FLOOR)).sum())
    assert newly_fitted > 20
    assert stop.ruled_out == heading.ruled_out - newly_fitted + lost


def test_the_hover_at_an_open_stop_is_fitted_once_the_hover_is_open_at_every_step() -> None:
    # the shipped fleet network masks the hover wherever a stop is open: such a label can never be fitted; with the
    # hover open at every step (--hover-anytime) a fit on a tiny set of them makes it the likeliest action there
    torch.manual_seed(0)
    shipped = fleet_policy("berlin_fleet", 24)
    episode = label_episode(small_scene(), shipped, make_teacher(TEACHER, 2), 1.0, np.random.default_rng(0))
    open_stop = (
        (episode.obs["stop_heading_mask"] > 0.5).any(-1)
        & (episode.obs["stop_claims"][..., STOP_CLAIMED_BY_OTHER] < 0.5)
    ).any(-1)
    rows = {k: v[open_stop][:48] for k, v in episode.obs.items()}
    hovers = np.full(len(rows["self"]), HOVER_ACTION)
    assert len(hovers) >= 24

    def hover_log_prob(net) -> np.ndarray:
        with torch.no_grad():
            return torch.log_softmax(net.masked_logits(obs_to_torch(rows, "cpu")), -1)[:, HOVER_ACTION].numpy()

    assert (hover_log_prob(shipped.net) <= MASKED_LOG_PROB).all()
    args = FleetImitationArgs(hover_anytime=True, epochs=30, minibatch=16, fit_improbable=True)
    policy = fleet_policy("berlin_fleet", 24, hover_anytime=True)
    assert np.allclose(hover_log_prob(policy.net), HOVER_START, atol=1e-3)  # log sigmoid(-12): at the floor
    data = Dataset()
    data.add(rows, hovers, np.ones(len(hovers), bool))
    fit(
        policy.net,
        data,
        args.fit_args(),
        torch.optim.Adam(parameter_groups(policy.net, args)),
        np.random.default_rng(0),
    )
    assert (hover_log_prob(policy.net) > np.log(0.5)).mean() > 0.9


def test_a_run_with_stop_labels_and_the_hover_anytime_writes_a_checkpoint_that_loads_with_it(tmp_path: Path) -> None:
    args = FleetImitationArgs(mixture=("2x4",), rounds=1, epochs=1, labels="stop", hover_anytime=True,
                              fit_improbable=True, run_dir=tmp_path, run_name="hover")  # fmt: skip
    rows = fleet_imitate(args)
    assert rows[0]["samples"] + rows[0]["ruled_out"] == rows[0]["steps"] * 2
    policy, _ = load_policy(tmp_path / "hover" / "round0.pt")
    assert policy.net.cfg.hover_anytime and policy.net.cfg.hover_logit and policy.net.num_actions == HOVER_ACTION + 1
    shipped = Checkpoint.load(pretrained_path("berlin_fleet")).model
    assert set(policy.net.state_dict()) - set(shipped) == {NEW_PARAMETERS + "weight", NEW_PARAMETERS + "bias"}
    with pytest.raises(ConfigError, match="--labels='stops' is unknown"):
        FleetImitationArgs(labels="stops")  # type: ignore[arg-type]


def test_the_kl_anchor_holds_the_network_nearer_its_start_than_the_plain_fit() -> None:
    episode = label_episode(small_scene(), fleet_policy("berlin_fleet", 24), make_teacher(TEACHER, 2), 1.0,
                            np.random.default_rng(0), labels="stop")  # fmt: skip
    data = Dataset()
    data.add(episode.obs, episode.labels, episode.corrected)
    batch = obs_to_torch(episode.obs, "cpu")
    start = fleet_policy("berlin_fleet", 24)

    def headings(net) -> torch.Tensor:  # log-probabilities over the 16 headings, given no hover
        with torch.no_grad():
            return torch.log_softmax(net.masked_logits(batch)[:, :HOVER_ACTION], -1).clamp(min=-1e4)

    def kl_from_start(net) -> float:
        p = headings(start.net)
        return float((p.exp() * (p - headings(net))).sum(-1).mean())

    drift = {}
    for anchor in (0.0, 10.0):
        torch.manual_seed(0)
        policy = fleet_policy("berlin_fleet", 24)
        args = FleetImitationArgs(epochs=6, minibatch=64, learning_rate=1e-3, kl_anchor=anchor)
        if anchor:
            stats = anchored_fit(policy, data, args, np.random.default_rng(0))
            assert stats.keys() == {"bc_loss", "bc_agreement", "fit_kl"}
        else:
            optimizer = torch.optim.Adam(parameter_groups(policy.net, args))
            fit(policy.net, data, args.fit_args(), optimizer, np.random.default_rng(0))
        drift[anchor] = kl_from_start(policy.net)
    assert 0 < drift[10.0] < 0.5 * drift[0.0], drift


ONWARD_TEACHER = (
    "batch_assignment_value:value_price_s=100,wait=1,release=true,unassigned_price_s=1000,unassigned_guard_s=600,"
    "heading=onward"
)


def test_the_heading_residual_flies_as_before_and_learns_a_heading_the_stop_head_rules_out() -> None:
    # the onward teacher heads into a stop's pick-up radius on the side of its next stop, a heading the stop head
    # (which marks one heading per stop) rules out; converted with --heading-residual the policy first flies exactly
    # as before, then a fit at the residual's learning rate makes most such labels its likeliest heading (none were)
    torch.manual_seed(0)
    start = fleet_policy("berlin_fleet", 24)
    policy = fleet_policy("berlin_fleet", 24, heading_residual=True)
    episode = label_episode(small_scene(4, 12, seed_index=3), policy, make_teacher(ONWARD_TEACHER, 4), 1.0,
                            np.random.default_rng(0), fit_floor=MASKED_LOG_PROB)  # fmt: skip
    args = FleetImitationArgs(heading_residual=True, fit_improbable=True, epochs=40, minibatch=16)
    batch = obs_to_torch(episode.obs, "cpu")

    def log_probs(net) -> torch.Tensor:
        with torch.no_grad():
            return torch.log_softmax(net.masked_logits(batch), -1)

    before = log_probs(policy.net)
    assert torch.equal(before.argmax(-1), log_probs(start.net).argmax(-1))  # the zero residual changes no move
    labels = torch.as_tensor(episode.labels)
    ruled_out = (before[torch.arange(len(labels)), labels] <= PRIOR_FLOOR + 0.5).numpy()  # at the floor
    assert ruled_out.sum() >= 8, ruled_out.sum()
    data = Dataset()
    data.add(
        {k: v[ruled_out] for k, v in episode.obs.items()}, episode.labels[ruled_out], np.ones(ruled_out.sum(), bool)
    )
    groups = parameter_groups(policy.net, args)
    assert [g["lr"] for g in groups] == [args.learning_rate, args.residual_learning_rate]
    assert all(name.startswith(RESIDUAL_PREFIX) == any(p is q for q in groups[1]["params"])
               for name, p in policy.net.named_parameters())  # fmt: skip
    fit(policy.net, data, args.fit_args(), torch.optim.Adam(groups), np.random.default_rng(0))
    after = log_probs(policy.net).argmax(-1).numpy()[ruled_out]
    assert (before.argmax(-1).numpy()[ruled_out] != episode.labels[ruled_out]).all()
    assert (after == episode.labels[ruled_out]).mean() > 0.6  # 0.75 when written
    again = fleet_policy(str(_saved_with_residual(policy)), 24, heading_residual=True)  # a trained start: as it is
    assert all(torch.equal(v, policy.net.state_dict()[k]) for k, v in again.net.state_dict().items())


def _saved_with_residual(policy) -> Path:
    import tempfile

    from uamfleet.rl.fleet_imitation import save_fleet_checkpoint

    path = Path(tempfile.mkdtemp()) / "residual.pt"
    save_fleet_checkpoint(path, Checkpoint.load(pretrained_path("berlin_fleet")), policy.net,
                          FleetImitationArgs(heading_residual=True), {"round": 0})  # fmt: skip
    assert load_policy(path)[0].net.cfg.heading_residual
    return path
