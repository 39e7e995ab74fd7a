"""A search over sampled futures never reads a request before its release: on an instance whose hidden requests are
all changed (each trip reversed, each release a few steps later), the hedge and ``replan_futures`` take the same
actions, and the hedge scores its candidates the same, until the first of those requests would have been released."""

from __future__ import annotations

import numpy as np
import pytest

from uamfleet.baselines.demand_models import EstimatedDemand
from uamfleet.config import EnvConfig, Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import FAMILIES, make_instance, split_seeds
from uamfleet.env.protocol import observer_of
from uamfleet.policies import make


def _perturbed(cfg: EnvConfig, family: str = "berlin") -> tuple[EnvConfig, int]:
    """``cfg`` with every request released after step 0 reversed and released 2 steps later (at most the family's
    last release step), and the first step at which one of them is released in ``cfg``."""
    window = FAMILIES[family].window_steps(cfg.slot_s)
    assert cfg.requests is not None
    hidden = [r for r in cfg.requests if r.release_step > 0]
    changed = tuple(
        r if r.release_step == 0 else Request(min(r.release_step + 2, window), r.destination_m, r.origin_m)
        for r in cfg.requests
    )
    return cfg.replace(requests=changed), min(r.release_step for r in hidden)


def _instances(count: int, family: str = "berlin") -> list[EnvConfig]:
    """The first ``count`` validation instances of ``family`` with a request released after step 0."""
    out = []
    for seed in split_seeds("validation", 4 * count):
        cfg = make_instance(family, seed)
        assert cfg.requests is not None
        if any(r.release_step > 0 for r in cfg.requests):
            out.append(cfg)
        if len(out) == count:
            return out
    raise AssertionError("too few instances with a later release")


def _fly(policy, cfg: EnvConfig, steps: int) -> list[int]:  # type: ignore[no-untyped-def]
    """The actions of ``policy`` over the first ``steps`` steps of ``cfg`` (observed as it reads)."""
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy))
    obs, _ = env.reset(seed=0)
    policy.reset(env.sim)
    actions = []
    for _ in range(steps):
        action = policy(obs)
        actions.append(int(action[0, 0]))
        obs, _, terminated, truncated, _ = env.step(action)
        if terminated[0] or truncated[0]:
            break
    return actions


@pytest.mark.parametrize("index", range(5))
def test_the_hedge_never_reads_a_request_before_its_release(index: int) -> None:
    cfg = _instances(5)[index]
    changed, first = _perturbed(cfg)
    assert changed.requests != cfg.requests
    flown = []
    for world in (cfg, changed):
        hedge = make("hedge", futures=2, first_headings=2, samples=0, top_k=1, tail=10)
        actions = _fly(hedge, world, first)
        searches = zip(hedge.searched_at, hedge.scores, strict=True)
        flown.append((actions, [(t, scores) for t, scores in searches if t < first]))
    (actions, scores), (actions_changed, scores_changed) = flown
    assert actions == actions_changed and len(actions) == first
    assert len(scores) == len(scores_changed) >= 1  # it searched over futures before the first release
    for (t, (heads, means)), (t2, (heads2, means2)) in zip(scores, scores_changed, strict=True):
        assert t == t2
        np.testing.assert_array_equal(heads, heads2)
        np.testing.assert_array_equal(means, means2)


@pytest.mark.slow
def test_replan_futures_never_reads_a_request_before_its_release() -> None:
    for cfg in _instances(2):
        changed, first = _perturbed(cfg)
        actions = [_fly(make("replan_futures"), world, first) for world in (cfg, changed)]
        assert actions[0] == actions[1] and len(actions[0]) == first


@pytest.fixture(scope="module")
def stream_model(tmp_path_factory: pytest.TempPathFactory) -> str:
    """A demand model of ``berlin_stream`` fitted on 40 of its train episodes, as a file."""
    episodes = [make_instance("berlin_stream", seed).requests or () for seed in split_seeds("train", 40)]
    path = tmp_path_factory.mktemp("demand") / "berlin_stream.json"
    EstimatedDemand.fit(episodes, make_instance("berlin_stream", 0).slot_s).save(path)
    return str(path)


@pytest.mark.slow  # 10-35 s per model: the stream's first hidden release comes late
@pytest.mark.parametrize("model", ["family", "wrong", "fitted"])
def test_the_hedge_never_reads_a_request_before_its_release_with_any_demand_model(model: str, stream_model) -> None:
    """On the stream family (a Poisson stream with hot spots): the true law, a deliberately wrong one and a model
    fitted on train episodes; the hidden requests changed, the same actions and scores until the first release."""
    spec = stream_model if model == "fitted" else model
    for cfg in _instances(2, "berlin_stream"):
        changed, first = _perturbed(cfg, "berlin_stream")
        flown = []
        for world in (cfg, changed):
            hedge = make("hedge", futures=2, first_headings=2, samples=0, top_k=1, tail=10, demand=spec)
            actions = _fly(hedge, world, first)
            assert type(hedge.prior).__name__ == {"family": "FamilyLaw", "wrong": "FamilyLaw"}.get(
                model, "EstimatedDemand"
            )
            flown.append((actions, [(t, s) for t, s in zip(hedge.searched_at, hedge.scores, strict=True) if t < first]))
        assert flown[0][0] == flown[1][0] and len(flown[0][0]) == first
        assert len(flown[0][1]) == len(flown[1][1])
        for (t, (heads, means)), (t2, (heads2, means2)) in zip(flown[0][1], flown[1][1], strict=True):
            assert t == t2
            np.testing.assert_array_equal(heads, heads2)
            np.testing.assert_array_equal(means, means2)


def test_the_true_law_of_a_family_without_one_is_the_recorded_prior() -> None:
    """``berlin`` declares no law: its hedge samples the DemandPrior every recorded hedge row was flown with; the
    new families sample their own law."""
    from uamfleet.baselines.anticipation import DemandPrior
    from uamfleet.rl.guided import model_on_world

    assert isinstance(model_on_world(None, make_instance("berlin", 3), "hedge"), DemandPrior)
    assert isinstance(model_on_world("family", make_instance("berlin", 3), "hedge"), DemandPrior)
    law = model_on_world(None, make_instance("berlin_peak", 3), "hedge")
    assert type(law).__name__ == "FamilyLaw" and law.max_requests == FAMILIES["berlin_peak"].max_passengers
    with pytest.raises(ValueError, match="atlantis"):
        make("hedge", demand="atlantis")
