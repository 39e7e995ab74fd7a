"""Hedge labels for expert iteration: each label keeps its promise when replayed (a finish plan flown delivers everyone
in its moves; a hedge label's candidate flown in its futures averages its mean moves), its soft target is the
candidates' softmin, the hedge's own decision is the argmin of :meth:`scores_at`, and the pool's files do not depend
on its number of workers."""

from __future__ import annotations

import copy

import numpy as np
import pytest
import torch
from conftest import small_config

from uamfleet.baselines.anticipation import DemandPrior
from uamfleet.baselines.step_planner import released_only
from uamfleet.config import Request
from uamfleet.env.protocol import observer_of
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import split_seeds
from uamfleet.rl.buffer import ObservationNormalizer
from uamfleet.rl.guided import AnticipatingGuidedSearch
from uamfleet.rl.labels import (
    FINISH,
    FUTURES_STREAM,
    HEDGE,
    LabelOptions,
    Labels,
    label_instance,
    label_instances,
    load_labels,
    soft_target,
)
from uamfleet.rl.loop_guard import LoopGuard
from uamfleet.rl.networks import MSHAActorCritic, NetConfig, observed_inputs
from uamfleet.rl.policy import GreedyPolicy
from uamfleet.sim.generator import flyable_sites, pad_passengers
from uamfleet.sim.world import World
from uamfleet.types import HOVER_ACTION, FleetState

OPEN_7 = "\n".join(["......."] * 7)
REQUESTS = (Request(0, (550.0, 150.0), (550.0, 550.0)), Request(6, (150.0, 550.0), (550.0, 350.0)))


def _world(hover: bool = True):  # type: ignore[no-untyped-def]
    cfg = small_config(OPEN_7, starts_m=((350.0, 350.0),), requests=REQUESTS, time_limit_steps=80,
                       stop_features=True, max_passengers=3)  # fmt: skip
    return cfg.replace(hover_action=hover)


def _prior(cfg) -> DemandPrior:  # type: ignore[no-untyped-def]
    return DemandPrior(min_requests=1, max_requests=3, window_steps=12, min_trip_m=200.0,
                       sites=flyable_sites(World(cfg)))  # fmt: skip


def _policy(cfg, seed: int = 3) -> GreedyPolicy:  # type: ignore[no-untyped-def]
    venv = VectorEnv(cfg, 1)
    obs, _ = venv.reset(seed=0)
    torch.manual_seed(seed)
    space = venv.single_observation_space
    inputs = observed_inputs(space.spaces, "de", "stops")
    config = NetConfig(variant="de", d_model=16, num_heads=2, action_head="stops", heading_residual=True, **inputs)
    net = MSHAActorCritic(space, config)
    with torch.no_grad():  # a residual that is not zero: the greedy flight is not simply the prior's
        for p in (net.stop_head.residual_free.weight, net.stop_head.residual_per_stop.weight):
            p.normal_(0.0, 0.5)
    shapes = {k: tuple(s.shape or ()) for k, s in space.spaces.items()}
    normalizer = ObservationNormalizer(shapes)
    normalizer.update({k: v.reshape(1, *v.shape[2:]) for k, v in obs.items()})
    return GreedyPolicy(net, normalizer, torch.device("cpu"), shapes, 1, cfg.num_passengers, cfg)


OPTS = LabelOptions(every=1, futures=3, temperature=2.0, finish_beam=8, tail=None, first_headings=3)


@pytest.fixture(scope="module")
def labelled():  # type: ignore[no-untyped-def]
    cfg = _world()
    policy = _policy(cfg)
    return cfg, policy, label_instance(policy, _prior(cfg), cfg, OPTS, np.random.default_rng(0), seed=7)


def _at_step(cfg, policy: GreedyPolicy, step: int) -> tuple[VectorEnv, dict[str, np.ndarray]]:  # type: ignore[no-untyped-def]
    """A fresh one-env world flown by the policy's greedy decoding (its loop guard reset) to ``step``."""
    env = VectorEnv(cfg, 1, autoreset=False, observer=observer_of(policy))
    obs, _ = env.reset(seed=0)
    policy.reset(env.sim)
    for _ in range(step):
        obs, *_ = env.step(policy(obs))
    assert int(env.state.t[0]) == step
    return env, obs


def _set(env: VectorEnv, state: FleetState) -> VectorEnv:
    for name in FleetState._fields:
        getattr(env.state, name)[:] = getattr(state, name)
    return env


def _flown_in_future(cfg, policy: GreedyPolicy, future: FleetState, action: int, hold: int) -> float:  # type: ignore[no-untyped-def]
    """Moves of ``action`` held ``hold`` steps, then the policy's greedy decoding (a loop guard of its own that, as
    in the hedge's batch, sees every step after the first), from ``future`` to the end; the time limit's steps more
    where someone is left."""
    env = VectorEnv(cfg, 1, autoreset=False, observer=observer_of(policy))
    env.reset(seed=0)
    _set(env, future)
    obs, moves, guard = env.observer.observe(env.state), 0.0, LoopGuard()
    for depth in range(cfg.time_limit_steps - int(future.t[0])):
        chosen = np.array([action])
        if depth:
            greedy = guard.choose(obs, policy.logits_of(policy.network_input(obs)).numpy())
            chosen = chosen if depth < hold else greedy
        obs, _, terminated, truncated, info = env.step(chosen[:, None])
        moves += float(info["events"].moved[0, 0])
        if terminated[0] or truncated[0]:
            break
    return moves + (0.0 if terminated[0] else cfg.time_limit_steps)


def test_a_finish_label_s_plan_delivers_everyone_in_its_promised_moves(labelled) -> None:  # type: ignore[no-untyped-def]
    cfg, policy, labels = labelled
    finish = np.flatnonzero(labels.source == FINISH)
    assert len(finish) >= 3 and (labels.weight[finish] == 1).all()
    for i in finish[[0, len(finish) // 2, -1]]:
        env, obs = _at_step(cfg, policy, int(labels.step[i]))
        for name, value in obs.items():  # the stored observation is the one the network read there
            np.testing.assert_array_equal(labels.obs[name][i], value[0])
        plan = labels.plan[i][labels.plan[i] >= 0]
        assert plan[0] == labels.action[i]
        moves = 0.0
        for k, heading in enumerate(plan):
            _, _, terminated, truncated, info = env.step(np.array([[heading]]))
            moves += float(info["events"].moved[0, 0])
            assert bool(terminated[0]) == (k == len(plan) - 1) and not truncated[0]  # everyone delivered at its end
        assert moves == labels.promised_moves[i]


def test_a_hedge_label_s_candidate_flown_in_its_futures_averages_its_promised_moves(labelled) -> None:  # type: ignore[no-untyped-def]
    cfg, policy, labels = labelled
    hedge = np.flatnonzero(labels.source == HEDGE)
    assert len(hedge) >= 3 and (labels.step[hedge] == np.arange(len(hedge))).all()  # every step of the window
    assert (labels.action[hedge] == HOVER_ACTION).any() and (labels.action[hedge] != HOVER_ACTION).any()
    prior = _prior(cfg)
    for i in hedge[[0, 1, len(hedge) // 2, -1]]:
        env, _ = _at_step(cfg, policy, int(labels.step[i]))
        rng = np.random.default_rng([FUTURES_STREAM, 7, int(labels.step[i])])  # the label's futures, drawn again
        known = pad_passengers(released_only(env.state), prior.max_requests)
        futures = [prior.sample(known, rng) for _ in range(OPTS.futures)]
        assert any(f is not None for f in futures)
        hold = int((labels.plan[i] >= 0).sum())
        assert hold == (OPTS.commit if labels.action[i] == HOVER_ACTION else 1)
        flown = [_flown_in_future(cfg, policy, known if f is None else f, int(labels.action[i]), hold) for f in futures]
        assert np.mean(flown) == pytest.approx(labels.promised_moves[i])


def test_soft_targets_are_the_softmin_of_the_candidates_mean_moves(labelled) -> None:  # type: ignore[no-untyped-def]
    cfg, policy, labels = labelled
    np.testing.assert_allclose(labels.target.sum(1), 1.0, rtol=1e-6)
    assert (labels.target.argmax(1) == labels.action).all()  # the argmin carries the most weight
    finish = labels.source == FINISH
    np.testing.assert_array_equal(labels.target[finish], np.eye(17, dtype=np.float32)[labels.action[finish]])
    # one label recomputed from the hedge's scores at its state, by hand
    i = int(np.flatnonzero(labels.source == HEDGE)[2])
    env, _ = _at_step(cfg, policy, 0)
    hedge = AnticipatingGuidedSearch(policy, _prior(cfg), first_headings=3, futures=1, tail=None, wait_action="hover")
    hedge.reset(env.sim)
    for _ in range(int(labels.step[i])):
        env.step(policy(env.observer.observe(env.state)))
    rng = np.random.default_rng([FUTURES_STREAM, 7, int(labels.step[i])])
    futures = hedge.futures_at(rng, OPTS.futures)
    assert futures is not None
    scores = hedge.scores_at(futures)
    assert scores.actions[-1] == HOVER_ACTION and len(set(scores.actions.tolist())) == 4
    q = np.exp(-(scores.mean_moves - scores.mean_moves.min()) / OPTS.temperature)
    expected = np.zeros(17)
    expected[scores.actions] = q / q.sum()
    np.testing.assert_allclose(labels.target[i], expected, rtol=1e-5)
    assert (labels.target[i][np.setdiff1d(np.arange(17), scores.actions)] == 0).all()
    second, best = np.sort(scores.mean_moves)[1], scores.mean_moves.min()
    assert labels.weight[i] == pytest.approx(1 - np.exp(-(second - best) / OPTS.temperature), rel=1e-5)


def test_soft_target_by_hand() -> None:
    """A repeated candidate counts once; T = 0.5: q ∝ (e^0, e^-1, e^-2) for means 9.5, 10, 10.5; gap 0.5."""
    target, action, weight = soft_target(np.array([3, 5, 3, 16]), np.array([10.0, 10.5, 10.0, 9.5]), 0.5)
    z = 1 + np.exp(-1) + np.exp(-2)
    expected = np.zeros(17)
    expected[[16, 3, 5]] = [1 / z, np.exp(-1) / z, np.exp(-2) / z]
    np.testing.assert_allclose(target, expected, rtol=1e-6)
    assert action == 16 and weight == pytest.approx(1 - np.exp(-1))


@pytest.mark.parametrize("wait_action", ["hover", "forbidden"])
def test_the_hedge_flies_the_argmin_of_scores_at(wait_action: str) -> None:
    """At each of its searches over futures, the hedge's action is the first action of least mean moves of
    ``scores_at`` over the same futures (drawn again from its generator's state before the search), held
    ``commit`` steps where it is the wait."""
    cfg = _world(hover=wait_action == "hover").replace(starts_m=((50.0, 50.0),))  # a corner: a forbidden heading
    policy = _policy(cfg, 4)
    hedge = AnticipatingGuidedSearch(policy, _prior(cfg), first_headings=3, futures=3, tail=4, commit=3,
                                     wait_action=wait_action)  # fmt: skip
    env = VectorEnv(cfg, 1, autoreset=False, observer=observer_of(policy))
    obs, _ = env.reset(seed=0)
    hedge.reset(env.sim)  # its first search, from a fresh generator of its seed
    checked = 0
    while True:
        t = int(env.state.t[0])
        rng = np.random.default_rng(hedge.seed) if t == 0 else copy.deepcopy(hedge.rng_futures)
        action = hedge(obs)
        if hedge.searched_at and hedge.searched_at[-1] == t:  # it searched over futures at this state
            futures = hedge.futures_at(rng, hedge.futures)
            assert futures is not None
            scores = hedge.scores_at(futures)
            best = int(np.argmin(scores.mean_moves))
            assert int(action[0, 0]) == scores.actions[best]
            assert len(hedge.queue) == (hedge.commit - 1 if scores.waits[best] else 0)
            np.testing.assert_array_equal(scores.mean_moves, hedge.scores[-1][1])
            checked += 1
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated[0] or truncated[0]:
            break
    assert checked >= 3


def test_label_options_and_the_pool_refuse_bad_values(tmp_path) -> None:  # type: ignore[no-untyped-def]
    for bad, match in [
        (dict(every=0), "every"),
        (dict(futures=0), "futures"),
        (dict(temperature=0.0), "temperature"),
        (dict(finish_beam=0), "finish_beam"),
        (dict(wait_action="sit"), "wait_action='sit'"),
        (dict(beta=1.5), "beta=1.5"),
        (dict(tail=-1), "tail"),
    ]:
        with pytest.raises(ValueError, match=match):
            LabelOptions(**bad)  # type: ignore[arg-type]
    with pytest.raises(FileNotFoundError, match="no checkpoint"):
        label_instances(tmp_path / "none.pt", "berlin", [1], None, LabelOptions(), 1, tmp_path)
    with pytest.raises(ValueError, match="atlantis"):
        label_instances("berlin", "atlantis", [1], None, LabelOptions(), 1, tmp_path)
    with pytest.raises(ValueError, match="workers"):
        label_instances("berlin", "berlin", [1], None, LabelOptions(), 0, tmp_path)


@pytest.mark.slow  # about a minute: three spawned processes load the shipped policy
def test_two_workers_write_the_labels_of_one(tmp_path) -> None:  # type: ignore[no-untyped-def]
    seeds = split_seeds("train", 3)
    opts = LabelOptions(every=6, futures=2, first_headings=2, finish_beam=4, tail=4)
    costs = [label_instances("berlin", "berlin", seeds, None, opts, w, tmp_path / str(w)) for w in (1, 2)]
    one, two = (load_labels(tmp_path / str(w), seeds) for w in (1, 2))
    assert one.num_labels > 0 and (one.source == HEDGE).any() and (one.source == FINISH).any()
    assert list(dict.fromkeys(one.seed.tolist())) == seeds  # in the order of the seeds
    for field in Labels._fields[1:]:
        np.testing.assert_array_equal(getattr(one, field), getattr(two, field))
    assert one.obs.keys() == two.obs.keys()
    for name in one.obs:
        np.testing.assert_array_equal(one.obs[name], two.obs[name])
    for cost in costs:
        assert (cost.instances, cost.hedge_labels, cost.finish_labels) == (
            3, int((one.source == HEDGE).sum()), int((one.source == FINISH).sum()))  # fmt: skip
        assert cost.searches == cost.hedge_labels and cost.solves >= 1 and cost.cpu_s > 0 and cost.labels_per_cpu_s > 0
    with pytest.raises(FileExistsError, match="exists"):
        label_instances("berlin", "berlin", seeds[:1], None, opts, 1, tmp_path / "1")


def test_labels_round_trip_through_their_npz_file(labelled, tmp_path) -> None:  # type: ignore[no-untyped-def]
    _, _, labels = labelled
    back = Labels.load(labels.save(tmp_path / "one.npz"))
    both = Labels.concat([labels, back])
    assert both.num_labels == 2 * labels.num_labels
    for field in Labels._fields[1:]:
        np.testing.assert_array_equal(getattr(back, field), getattr(labels, field))
        np.testing.assert_array_equal(getattr(both, field)[labels.num_labels :], getattr(labels, field))
    assert back.obs.keys() == labels.obs.keys()
    for name in labels.obs:
        np.testing.assert_array_equal(back.obs[name], labels.obs[name])
    with pytest.raises(FileNotFoundError, match="no labels file"):
        Labels.load(tmp_path / "none.npz")


def test_with_beta_one_the_expert_s_actions_are_flown() -> None:
    """``beta`` = 1 flies every label's action: after the window the first finish plan is flown to its end, so
    every later step is labelled with the next heading of that one plan (one solve held)."""
    cfg = _world()
    opts = LabelOptions(every=3, futures=2, finish_beam=8, tail=4, first_headings=2, beta=1.0)
    labels = label_instance(_policy(cfg), _prior(cfg), cfg, opts, np.random.default_rng(0), seed=7)
    finish = np.flatnonzero(labels.source == FINISH)
    plan = labels.plan[finish[0]][labels.plan[finish[0]] >= 0]
    assert len(finish) == len(plan) >= 3
    np.testing.assert_array_equal(labels.action[finish], plan)
    np.testing.assert_array_equal(labels.step[finish], labels.step[finish[0]] + np.arange(len(plan)))
