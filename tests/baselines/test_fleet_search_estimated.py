"""The fleet search with a demand model estimated from the requests released so far (``fleet_search:demand=
estimated``, :class:`uamfleet.baselines.fleet_search.EstimatedFleetDemand`): it reads no unreleased request, it
recovers a fleet service's release rate from drawn episodes, and the search flying it still returns only moves the
shield passes."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config
from test_fleet_search import BASE, CENTRE_REQUESTS, CORNERS, OPEN_10, fleet_case, flown_actions

from uamfleet.baselines.fleet_search import EstimatedFleetDemand, FleetSearch, known_state
from uamfleet.config import Request, fleet_window_steps
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.metrics import episode_metrics
from uamfleet.policies import make_named
from uamfleet.rollout import run_episode
from uamfleet.sim.core import Simulator
from uamfleet.types import HIDDEN, WAITING


def at_step(cfg, t: int):
    """The state of ``cfg``'s one-env core with its clock at ``t`` and exactly the requests released by then
    showing (the others hidden), as a flight to ``t`` would leave the passengers' statuses."""
    sim = Simulator(cfg, 1, autoreset=False)
    sim.reset(seed=0)
    s = sim.state
    s.t[0] = t
    exists = s.pax_exists[0]
    s.pax_status[0] = np.where(exists & (s.pax_release[0] <= t), WAITING, HIDDEN)
    return s


def test_the_estimated_model_reads_no_unreleased_request():
    cfg = fleet_case(2, 8)
    t = 40
    later = [i for i, r in enumerate(cfg.requests) if r.release_step > t]
    assert later and len(later) < len(cfg.requests), "the case must hold requests on both sides of t"
    other = list(cfg.requests)
    for i in later:  # each unreleased request moved elsewhere and released at another step
        r = cfg.requests[i]
        other[i] = Request(r.release_step + 7, r.destination_m, other[(i + 1) % len(other)].origin_m)
    model = EstimatedFleetDemand(fleet_window_steps(cfg.slot_s), np.array([r.origin_m for r in cfg.requests]))
    one = model.sample(known_state(at_step(cfg, t)), np.random.default_rng(3))
    two = model.sample(known_state(at_step(cfg.replace(requests=tuple(other)), t)), np.random.default_rng(3))
    assert one.pax_exists[0].sum() > known_state(at_step(cfg, t)).pax_exists[0].sum()  # it drew requests to come
    for name in ("pax_exists", "pax_release", "pax_origin_m", "pax_dest_m"):
        np.testing.assert_array_equal(getattr(one, name), getattr(two, name))
    # and the search flying it decides alike whatever the unreleased requests are (every search to step 12)
    first = FleetSearch(make_named(BASE), every=3, demand="estimated")
    second = FleetSearch(make_named(BASE), every=3, demand="estimated")
    cut = 12
    actions = flown_actions(cfg, first, cut)
    moved = [r if r.release_step <= cut else Request(r.release_step + 2, r.destination_m, r.origin_m)
             for r in cfg.requests]  # fmt: skip
    assert [a.tolist() for a in actions] == [a.tolist() for a in flown_actions(cfg.replace(requests=tuple(moved)),
                                                                              second, cut)]  # fmt: skip
    assert [d.mean_costs for d in first.decisions] == [d.mean_costs for d in second.decisions]


def test_it_recovers_the_release_rate_of_drawn_fleet_episodes():
    # Berlin 4 x 48 validation episodes: 48 requests released uniformly over the 600 s window (200 steps of 3 s),
    # 0.24 per step. Half-way, a count of about Binomial(48, 1/2) is seen: each estimate's spread is about 14 %,
    # the mean of 8 episodes' about 5 %; 15 % is three of those.
    seeds = split_seeds("validation", 8)
    window = fleet_window_steps(3.0)
    t = window // 2
    rates = []
    for seed in seeds:
        cfg = make_fleet_instance("berlin", seed, 4, 48)
        model = EstimatedFleetDemand(window, np.array([r.origin_m for r in cfg.requests]))
        rates.append(model.rate_per_step(known_state(at_step(cfg, t))))
    true_rate = 48 / window
    assert abs(np.mean(rates) / true_rate - 1) < 0.15, (np.mean(rates), true_rate)
    # the count it draws over the rest of the window: the released ones plus the rest, about 48 on average
    cfg = make_fleet_instance("berlin", seeds[0], 4, 48, max_passengers=96)
    known = known_state(at_step(cfg, t))
    model = EstimatedFleetDemand(window, np.array([r.origin_m for r in cfg.requests]))
    rng = np.random.default_rng(0)
    counts = [int(model.sample(known, rng).pax_exists[0].sum()) for _ in range(200)]
    expected = known.pax_exists[0].sum() + model.rate_per_step(known) * (window - 1 - t)
    assert abs(np.mean(counts) - expected) < 1.5, (np.mean(counts), expected)


def test_its_futures_release_after_now_within_the_window_on_the_sites():
    cfg = fleet_case(2, 8)
    sites = np.array(sorted({r.origin_m for r in cfg.requests} | {r.destination_m for r in cfg.requests}))
    window = fleet_window_steps(cfg.slot_s)
    model = EstimatedFleetDemand(window, sites)
    known = known_state(at_step(cfg, 30))
    rng = np.random.default_rng(5)
    for _ in range(20):
        future = model.sample(known, rng)
        new = future.pax_exists[0] & ~known.pax_exists[0]
        assert ((future.pax_release[0, new] > 30) & (future.pax_release[0, new] < window)).all()
        for p in np.flatnonzero(new):
            assert any(np.allclose(future.pax_origin_m[0, p], s) for s in sites)
            assert not np.allclose(future.pax_origin_m[0, p], future.pax_dest_m[0, p])
    after = known_state(at_step(cfg, window))  # the window is over: nothing more comes
    assert model.sample(after, rng).pax_exists[0].sum() == after.pax_exists[0].sum()


def test_the_search_with_the_estimated_model_returns_only_shield_passed_moves():
    cfg = small_config(OPEN_10, starts_m=CORNERS, requests=CENTRE_REQUESTS, separation="shield", hover_action=True,
                       time_limit_steps=200, scenario="berlin_fleet4x4_seed0")  # fmt: skip
    alone = run_episode(VectorEnv(cfg, num_envs=1, autoreset=False), make_named(BASE), seed=0)
    assert episode_metrics(alone, cfg.radio).shield_interventions > 0  # the scene needs the shield
    policy = FleetSearch(make_named(BASE), every=2, demand="estimated", end_wait=1.0, arrival_window_s=30.0)
    traj = run_episode(VectorEnv(cfg, num_envs=1, autoreset=False), policy, seed=0)
    m = episode_metrics(traj, cfg.radio)
    assert sum(int(e.shield_intervened.sum()) for e in traj.events) == 0
    assert (m.shield_interventions, m.separation_violations, m.delivered) == (0, 0, 4)
    assert policy.decisions


@pytest.mark.parametrize(
    ("options", "needle"),
    [({"demand": "oracle"}, "demand"), ({"end_wait": -1.0}, "end_wait"), ({"cpu_budget_s": 0.0}, "cpu_budget_s")],
)
def test_bad_options_are_refused_naming_them(options, needle):
    with pytest.raises(ValueError, match=needle):
        FleetSearch(make_named(BASE), **options)


def test_a_cpu_budget_cuts_the_futures_and_the_name_reaches_the_options():
    cfg = fleet_case(2, 8)
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    policy = make_named(f"fleet_search:demand=estimated,futures=6,end_wait=0.5,cpu_budget_s=1e-6({BASE})")
    assert (policy.demand_model, policy.futures, policy.end_wait, policy.cpu_budget_s) == ("estimated", 6, 0.5, 1e-6)
    policy.reset(env.sim)
    decision = policy.decide()  # the budget is spent by the first future: the others are not flown
    unbudgeted = FleetSearch(make_named(BASE), futures=1, demand="estimated", end_wait=0.5)
    unbudgeted.reset(env.sim)
    assert decision.mean_costs == unbudgeted.decide().mean_costs
