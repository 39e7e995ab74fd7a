"""Guided search at decision time: never longer than the greedy decoding it starts from on drawn instances whose
requests are all known at the start, plans again at a release, and refuses a fleet."""

from __future__ import annotations

import numpy as np
import pytest
import torch
from conftest import small_config

from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.metrics import episode_metrics
from uamfleet.rl.buffer import ObservationNormalizer
from uamfleet.rl.guided import GuidedSearchPolicy
from uamfleet.rl.networks import MSHAActorCritic, NetConfig, observed_inputs
from uamfleet.rl.trainer import GreedyPolicy

WALLED_7 = "\n".join(["......."] * 3 + ["..###.."] + ["......."] * 3)


def _policy(cfg, seed: int) -> GreedyPolicy:
    venv = VectorEnv(cfg, 1)
    obs, _ = venv.reset(seed=0)
    torch.manual_seed(seed)
    net = MSHAActorCritic(
        venv.single_observation_space,
        NetConfig(
            variant="de",
            d_model=16,
            num_heads=2,
            action_head="stops",
            heading_residual=True,
            **observed_inputs(venv.single_observation_space.spaces, "de", "stops"),
        ),
    )
    with torch.no_grad():  # a residual that is not zero: the greedy flight is not simply the prior's
        for p in (net.stop_head.residual_free.weight, net.stop_head.residual_per_stop.weight):
            p.normal_(0.0, 0.5)
    shapes = {k: tuple(s.shape or ()) for k, s in venv.single_observation_space.spaces.items()}
    normalizer = ObservationNormalizer(shapes)
    normalizer.update({k: v.reshape(1, *v.shape[2:]) for k, v in obs.items()})
    return GreedyPolicy(net, normalizer, torch.device("cpu"), shapes, 1, cfg.num_passengers, cfg)


INSTANCES = [
    ((150.0, 150.0), (Request(0, (550.0, 550.0), (150.0, 650.0)), Request(0, (350.0, 150.0), (650.0, 350.0)))),
    ((650.0, 650.0), (Request(0, (150.0, 150.0), (350.0, 550.0)), Request(0, (550.0, 150.0), (150.0, 450.0)))),
    ((350.0, 50.0), (Request(0, (350.0, 650.0), (50.0, 350.0)),)),
]


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(("start", "requests"), INSTANCES)
def test_guided_search_never_flies_longer_than_greedy_decoding(start, requests, seed) -> None:
    cfg = small_config(WALLED_7, starts_m=(start,), requests=requests, time_limit_steps=60, stop_features=True,
                       max_passengers=3)  # fmt: skip
    greedy = _policy(cfg, seed)
    g = episode_metrics(greedy.fly(cfg), cfg.radio)
    guided = GuidedSearchPolicy(greedy, top_k=3, samples=6, seed=seed)
    s = episode_metrics(guided.fly(cfg), cfg.radio)
    assert s.pr_pct >= g.pr_pct
    if g.pr_pct == 100.0:
        assert s.td_m <= g.td_m
    assert len(guided.plans) == 1  # everything known at the start: one search


def test_guided_search_plans_again_at_a_release() -> None:
    requests = (Request(0, (550.0, 550.0), (150.0, 650.0)), Request(5, (350.0, 150.0), (650.0, 350.0)))
    cfg = small_config(WALLED_7, starts_m=((150.0, 150.0),), requests=requests, time_limit_steps=80,
                       stop_features=True, max_passengers=3)  # fmt: skip
    guided = GuidedSearchPolicy(_policy(cfg, 0), top_k=2, samples=4)
    traj = guided.fly(cfg)
    assert [p[0] for p in guided.plans][:2] == [0, 5]
    assert np.isfinite(episode_metrics(traj, cfg.radio).td_m)


def test_guided_search_checks_its_arguments() -> None:
    with pytest.raises(ValueError, match="top_k"):
        GuidedSearchPolicy(None, top_k=0)  # type: ignore[arg-type]


@pytest.mark.parametrize(("start", "requests"), INSTANCES)
def test_with_the_search_as_a_candidate_it_is_never_longer_than_either(start, requests) -> None:
    """expert_beam: replan's plan over the known requests competes with the policy's flights, so on an instance
    known at the start the flight is never longer than the greedy decoding or the search alone."""
    from uamfleet.baselines.step_planner import SearchSettings, StepSearch

    cfg = small_config(WALLED_7, starts_m=(start,), requests=requests, time_limit_steps=60, stop_features=True,
                       max_passengers=3)  # fmt: skip
    greedy = _policy(cfg, 0)
    g = episode_metrics(greedy.fly(cfg), cfg.radio)
    env = VectorEnv(cfg, 1, autoreset=False)
    env.reset(seed=0)
    alone = StepSearch(cfg).solve(env.state, [SearchSettings(beam=32, rank_slack=0.5)])
    assert alone is not None
    hybrid = GuidedSearchPolicy(greedy, top_k=2, samples=2, expert_beam=32)
    h = episode_metrics(hybrid.fly(cfg), cfg.radio)
    assert h.pr_pct == 100.0 and h.td_m <= alone.moves * cfg.step_m
    if g.pr_pct == 100.0:
        assert h.td_m <= g.td_m
    assert len(hybrid.search_won) == 1
