"""``replan_futures`` (uamfleet/baselines/anticipation.py): the count posterior against a simulation of the
instance generator's draws, sampled futures against the demand model, and the planner against ``replan`` where no
request can come any more and against an instance whose future differs (it must not read hidden rows)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

from uamfleet.baselines.anticipation import REPLAN_FUTURES_SEARCH, AnticipatingReplan, DemandPrior
from uamfleet.baselines.step_planner import StepPlannerPolicy, released_only
from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.rollout import fly
from uamfleet.sim.generator import flyable_sites
from uamfleet.sim.world import World
from uamfleet.types import HIDDEN

OPEN_7 = "\n".join(["......."] * 7)


def _prior(cfg, **kw) -> DemandPrior:  # type: ignore[no-untyped-def]
    fields = dict(min_requests=2, max_requests=6, window_steps=39, min_trip_m=200.0, sites=flyable_sites(World(cfg)))
    return DemandPrior(**{**fields, **kw})


@pytest.mark.parametrize(("known", "t"), [(2, 19), (3, 5), (1, 30)])
def test_the_count_posterior_matches_a_simulation_of_the_generator(known: int, t: int) -> None:
    """The generator's draws (uamfleet.instances.make_instance): N uniform over 2..6, the first request at step 0,
    the other N - 1 at steps uniform over 0..39; kept where exactly ``known`` are released by step t."""
    prior = _prior(small_config(OPEN_7))
    rng = np.random.default_rng(0)
    n = rng.integers(2, 7, size=400_000)
    steps = rng.integers(0, 40, size=(400_000, 5))  # the other requests' release steps (the first n - 1 are real)
    released = 1 + np.sum((steps <= t) & (np.arange(5) < (n - 1)[:, None]), axis=1)
    kept = n[released == known]
    counts, probs = prior.count_posterior(known, t)
    simulated = np.array([np.mean(kept == c) for c in counts])
    assert len(kept) > 5_000 and np.isclose(probs.sum(), 1.0)
    np.testing.assert_allclose(probs, simulated, atol=0.01)
    assert np.all(kept >= counts[0])  # no mass below the counts the posterior allows


def test_the_count_posterior_by_hand_and_at_its_ends() -> None:
    prior = _prior(small_config(OPEN_7))
    counts, probs = prior.count_posterior(2, 19)  # p = 1/2: weights (N - 1) / 2^(N - 1) for N = 2..6
    weights = np.array([1 / 2, 2 / 4, 3 / 8, 4 / 16, 5 / 32])
    assert counts.tolist() == [2, 3, 4, 5, 6]
    np.testing.assert_allclose(probs, weights / weights.sum())
    assert prior.count_posterior(3, 39)[0].tolist() == [3]  # the window is over: nothing more comes
    assert prior.count_posterior(6, 0)[0].tolist() == [6]  # the most an instance has


def test_a_sampled_future_keeps_what_is_known_and_adds_requests_the_model_can_draw() -> None:
    requests = (Request(0, (150.0, 450.0), (550.0, 450.0)), Request(3, (650.0, 50.0), (50.0, 650.0)))
    cfg = small_config(OPEN_7, requests=requests, max_passengers=6, time_limit_steps=60)
    env = VectorEnv(cfg, 1, autoreset=False)
    env.reset(seed=0)
    env.step(np.array([[0]]))
    known = released_only(env.state)
    assert known.pax_exists[0].sum() == 1  # the second request is hidden until step 3: not known
    prior = _prior(cfg, window_steps=20)
    rng = np.random.default_rng(1)
    added = 0
    for _ in range(50):
        future = prior.sample(known, rng)
        assert future is not None
        new = future.pax_exists[0] & ~known.pax_exists[0]
        for name in ("pax_exists", "pax_status", "pax_origin_m", "pax_dest_m", "pax_release"):
            assert np.array_equal(getattr(future, name)[0, :1], getattr(known, name)[0, :1])
        assert 1 + new.sum() <= 6 and np.all(future.pax_status[0, new] == HIDDEN)
        assert np.all((future.pax_release[0, new] > 1) & (future.pax_release[0, new] <= 20))
        trips = np.linalg.norm(future.pax_origin_m[0, new] - future.pax_dest_m[0, new], axis=-1)
        assert np.all(trips >= 200.0)
        for point in np.concatenate([future.pax_origin_m[0, new], future.pax_dest_m[0, new]]):
            assert np.min(np.linalg.norm(prior.sites - point, axis=-1)) == 0.0
        added += int(new.sum())
    assert added > 50  # one known at step 1 of 20: usually more to come
    env.state.t[0] = 20
    assert prior.sample(released_only(env.state), rng) is None


def test_where_no_request_can_come_it_flies_replan() -> None:
    """Both requests released at the start and the prior's most: no future to sample, so replan's plan is flown."""
    requests = (Request(0, (380.0, 560.0), (600.0, 330.0)), Request(0, (230.0, 400.0), (470.0, 420.0)))
    cfg = small_config(OPEN_7, starts_m=((110.0, 620.0),), requests=requests, time_limit_steps=40)
    ours = AnticipatingReplan(_prior(cfg, min_requests=1, max_requests=2))
    replan = StepPlannerPolicy("replan", [REPLAN_FUTURES_SEARCH])
    a, b = fly(cfg, ours), fly(cfg, replan)
    assert np.array_equal(a.stacked("moved"), b.stacked("moved"))
    assert np.array_equal(a.episode["distance_m"], b.episode["distance_m"]) and a.terminated
    assert [p[1] for p in ours.plans] == [1]  # one decision, one candidate


def test_it_never_reads_a_hidden_request() -> None:
    """Two instances that differ only in a request released at step 5: the same decision at the start, and the
    same moves until that release (the planner sees only what is released)."""
    first = Request(0, (150.0, 150.0), (550.0, 550.0))
    flights = []
    for later in (Request(5, (650.0, 50.0), (50.0, 650.0)), Request(5, (350.0, 650.0), (650.0, 250.0))):
        cfg = small_config(OPEN_7, starts_m=((350.0, 350.0),), requests=(first, later), time_limit_steps=60)
        policy = AnticipatingReplan(_prior(cfg, window_steps=10, max_requests=3), futures=2, scored=2, seed=3)
        trajectory = fly(cfg, policy)
        assert trajectory.terminated  # everyone delivered
        flights.append((trajectory.stacked("moved")[:5, 0].tolist(), policy.plans[0][:5]))
    assert flights[0] == flights[1]
    assert flights[0][1][1] > 1  # futures were sampled: the test is not replan's alone


def test_a_futures_plan_is_flown_only_until_its_future_expected_a_release() -> None:
    """One request and nothing more to come, but a prior that expects more within 6 steps: whenever a future's plan
    is chosen, it is cut at that future's next release (at most 6 steps on) and the decision is made again there,
    without a real release; past the window only replan's plan is left, and the rider is delivered."""
    cfg = small_config(OPEN_7, starts_m=((50.0, 50.0),), requests=(Request(0, (650.0, 650.0), (50.0, 650.0)),),
                       time_limit_steps=60)  # fmt: skip
    policy = AnticipatingReplan(_prior(cfg, min_requests=1, max_requests=3, window_steps=6), seed=0)
    trajectory = fly(cfg, policy)
    assert trajectory.terminated
    steps = [p[0] for p in policy.plans]
    chose_a_future = [p for p in policy.plans if p[2] > 0]
    assert chose_a_future, "no future's plan was chosen: the test would not see the cut"
    for t, _, _, _, committed, _ in chose_a_future:
        assert 1 <= committed <= 6 - t
    for (t, _, best, _, committed, _), later in zip(policy.plans, steps[1:], strict=False):
        if best > 0:
            assert later == t + committed
    assert all(p[1] == 1 for p in policy.plans if p[0] >= 6)  # after the window: replan's plan alone


def test_bad_settings_are_refused() -> None:
    with pytest.raises(ValueError, match="each must be >= 1"):
        AnticipatingReplan(_prior(small_config(OPEN_7)), futures=0)
