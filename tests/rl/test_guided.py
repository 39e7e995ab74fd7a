"""Guided search at decision time: never longer than the greedy decoding it starts from on drawn instances whose
requests are all known at the start, plans again at a release, and refuses a fleet."""

from __future__ import annotations

import itertools

import numpy as np
import pytest
import torch
from conftest import small_config

from uamfleet.checks import ConfigError
from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.metrics import episode_metrics
from uamfleet.rl.buffer import ObservationNormalizer
from uamfleet.rl.guided import GuidedSearchPolicy
from uamfleet.rl.networks import MSHAActorCritic, NetConfig, observed_inputs
from uamfleet.rl.trainer import GreedyPolicy
from uamfleet.types import ON_BOARD

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


@pytest.mark.parametrize("seed", [0, 1, 2])
@pytest.mark.parametrize(("start", "requests"), INSTANCES)
def test_guarded_rollouts_fly_the_policys_own_decoding(start, requests, seed) -> None:
    """One candidate, the greedy one, with guard_rollouts: the search's plan is the policy's own flight, loop guard
    included, step for step (known at the start: one search, flown to the end)."""
    cfg = small_config(WALLED_7, starts_m=(start,), requests=requests, time_limit_steps=60, stop_features=True,
                       max_passengers=3)  # fmt: skip
    greedy = _policy(cfg, seed)
    own = [e.actions.tolist() for e in greedy.fly(cfg).events]
    guided = GuidedSearchPolicy(greedy, top_k=1, samples=0, guard_rollouts=True)
    flown = [e.actions.tolist() for e in guided.fly(cfg).events]
    if guided.plans[0][2] >= 0:  # the greedy flight delivered everyone: it is the plan
        assert flown == own


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


OPEN_7 = "\n".join(["......."] * 7)


def _open_search(policy_seed: int, top_k: int):
    """Horizon-1 guided search after its first search on an open 7 x 7 map: a taxi at (150, 150) and one request
    from (550, 150) to (550, 550); (config, search, env)."""
    requests = (Request(0, (550.0, 150.0), (550.0, 550.0)),)
    cfg = small_config(OPEN_7, starts_m=((150.0, 150.0),), requests=requests, time_limit_steps=40,
                       stop_features=True, max_passengers=3)  # fmt: skip
    guided = GuidedSearchPolicy(_policy(cfg, policy_seed), top_k=top_k, samples=0, horizon=1)
    env = VectorEnv(cfg, 1)
    env.reset(seed=0)
    guided.reset(env.sim)
    return cfg, guided, env


def test_tour_bound_of_a_cut_candidate_is_the_tour_by_hand() -> None:
    """On an open map the tour left is the straight legs: taxi -> origin -> destination, in moves of 100 m."""
    _, guided, env = _open_search(0, top_k=2)
    for target, source in zip(guided.scratch.state, env.state, strict=True):
        target[:] = source  # the scratch rows back at the root (the search at reset flew them)
    obs = guided.scratch.observer.observe(guided.scratch.state)
    np.testing.assert_allclose(guided._tour_moves(obs), [4.0 + 4.0, 4.0 + 4.0], atol=1e-4)


@pytest.mark.parametrize(("start", "requests"), INSTANCES)
def test_a_horizon_past_the_time_limit_searches_as_without_one(start, requests) -> None:
    cfg = small_config(WALLED_7, starts_m=(start,), requests=requests, time_limit_steps=60, stop_features=True,
                       max_passengers=3)  # fmt: skip
    full = GuidedSearchPolicy(_policy(cfg, 1), top_k=3, samples=6, seed=1)
    cut = GuidedSearchPolicy(_policy(cfg, 1), top_k=3, samples=6, seed=1, horizon=60)
    a, b = full.fly(cfg), cut.fly(cfg)
    assert [e.actions.tolist() for e in a.events] == [e.actions.tolist() for e in b.events]
    assert [p[:3] for p in full.plans] == [p[:3] for p in cut.plans]


@pytest.mark.parametrize(("start", "requests"), INSTANCES)
def test_a_short_horizon_searches_again_each_time_its_plan_is_flown(start, requests) -> None:
    cfg = small_config(WALLED_7, starts_m=(start,), requests=requests, time_limit_steps=60, stop_features=True,
                       max_passengers=3)  # fmt: skip
    guided = GuidedSearchPolicy(_policy(cfg, 0), top_k=3, samples=6, horizon=3)
    traj = guided.fly(cfg)
    starts = [p[0] for p in guided.plans]
    assert starts[:2] == [0, 3] and all(b - a == 3 for a, b in itertools.pairwise(starts))
    assert len(traj.events) > starts[-1]


def test_a_cut_candidate_is_ranked_by_moves_plus_its_tour_bound() -> None:
    """Horizon 1 on an open map: every first heading costs one move, so the heading chosen is the one whose tour
    left is shortest: toward the origin (east), not away from it."""
    cfg, guided, env = _open_search(2, top_k=16)
    assert len(guided.queue) == 1
    by_hand = {}  # heading -> 1 move + straight legs from its end: to the origin (unless within reach) and on
    for heading in np.flatnonzero(env.observer.observe(env.state)["action_mask"][0, 0]):
        probe = VectorEnv(cfg, 1)
        probe.reset(seed=0)
        probe.step(np.array([[heading]]))
        q = probe.state.pos_m[0, 0]
        picked = probe.state.pax_status[0, 0] == ON_BOARD
        leg = 0.0 if picked else np.hypot(*(q - (550.0, 150.0))) + 400.0
        by_hand[int(heading)] = 1.0 + (np.hypot(*(q - (550.0, 550.0))) if picked else leg) / 100.0
    least = min(by_hand.values())
    assert by_hand[guided.queue[0]] == pytest.approx(least, abs=1e-6)
    assert guided.plans[0][2] == round(least)


# ---- AnticipatingGuidedSearch: the rollout algorithm over futures drawn from the demand model ----


def _prior(cfg, **kw):  # type: ignore[no-untyped-def]
    from uamfleet.baselines.anticipation import DemandPrior
    from uamfleet.sim.generator import flyable_sites
    from uamfleet.sim.world import World

    fields = dict(min_requests=1, max_requests=3, window_steps=20, min_trip_m=200.0, sites=flyable_sites(World(cfg)))
    return DemandPrior(**{**fields, **kw})  # type: ignore[arg-type]


def _hedge_config(requests, art: str = OPEN_7, start=(150.0, 150.0)):  # type: ignore[no-untyped-def]
    return small_config(art, starts_m=(start,), requests=requests, time_limit_steps=80, stop_features=True,
                        max_passengers=3)  # fmt: skip


def _probe(cfg, state):  # type: ignore[no-untyped-def]
    """A one-env core of ``cfg`` set to ``state`` (a future drawn for the hedge, or the known requests)."""
    from uamfleet.types import FleetState

    probe = VectorEnv(cfg, 1, autoreset=False)
    probe.reset(seed=0)
    for name in FleetState._fields:
        getattr(probe.state, name)[:] = getattr(state, name)
    return probe


def _greedy_moves(policy, env: VectorEnv) -> float:  # type: ignore[no-untyped-def]
    """Moves of the policy's greedy decoding (a loop guard of its own) from the env's state until it ends; the time
    limit adds its steps where someone is left undelivered."""
    from uamfleet.rl.loop_guard import LoopGuard

    obs, moves, guard = env.observer.observe(env.state), 0.0, LoopGuard()
    while True:
        action = guard.choose(obs, policy.logits_of(policy.network_input(obs)).numpy())
        obs, _, terminated, truncated, info = env.step(action[:, None])
        moves += float(info["events"].moved[0, 0])
        if terminated[0] or truncated[0]:
            return moves + (0.0 if terminated[0] else env.cfg.time_limit_steps)


def test_where_nothing_can_come_the_hedge_is_guided_search() -> None:
    """Both requests released at the start and the demand model's most: no future to draw, so it flies guided
    search's flight, with its one search."""
    from uamfleet.rl.guided import AnticipatingGuidedSearch

    cfg = _hedge_config(INSTANCES[0][1], WALLED_7)
    guided = GuidedSearchPolicy(_policy(cfg, 1), top_k=3, samples=6, seed=1, guard_rollouts=True)
    hedge = AnticipatingGuidedSearch(_policy(cfg, 1), _prior(cfg, max_requests=2), top_k=3, samples=6, seed=1)
    a, b = guided.fly(cfg), hedge.fly(cfg)
    assert [e.actions.tolist() for e in a.events] == [e.actions.tolist() for e in b.events]
    assert hedge.scores == [] and len(hedge.plans) == len(guided.plans) == 1


def test_each_first_heading_is_scored_by_the_policy_flown_in_every_future() -> None:
    """The first search's mean moves, recomputed one future and one env at a time: the same futures (drawn again
    from the same seed), each first heading and then the policy's greedy flight to the end (tail None)."""
    from uamfleet.baselines.step_planner import released_only
    from uamfleet.rl.guided import AnticipatingGuidedSearch

    cfg = _hedge_config((Request(0, (550.0, 150.0), (550.0, 550.0)),), start=(50.0, 50.0))  # a corner: it may wait
    prior = _prior(cfg)
    policy = _policy(cfg, 3)
    hedge = AnticipatingGuidedSearch(policy, prior, first_headings=3, futures=4, tail=None, seed=5)
    env = VectorEnv(cfg, 1, autoreset=False)
    env.reset(seed=0)
    hedge.reset(env.sim)
    first, means = hedge.scores[0]
    rng = np.random.default_rng(5)
    known = released_only(env.state)
    futures = [prior.sample(known, rng) for _ in range(4)]
    assert any(f is not None for f in futures)  # a request may still come: something to hedge for
    blocked = np.flatnonzero(~env.state.action_mask[0, 0])
    assert len(blocked) and len(first) == 4  # headings off the map are forbidden: waiting is the fourth candidate
    holds = [1, 1, 1, hedge.commit]
    for heading, hold, mean in zip(first, holds, means, strict=False):
        moves = []
        for future in futures:
            probe = _probe(env.cfg, known if future is None else future)
            flown = 0.0
            for _ in range(hold):
                _, _, terminated, _, info = probe.step(np.array([[heading]]))
                flown += float(info["events"].moved[0, 0])
                if terminated[0]:
                    break
            moves.append(flown if terminated[0] else flown + _greedy_moves(policy, probe))
        assert mean == pytest.approx(np.mean(moves))
    logits = policy.logits_of(policy.network_input(env.observer.observe(env.state)))[0]
    assert first[0] == int(logits.argmax())  # the policy's own heading first: it wins ties
    best = int(np.argmin(means))
    assert hedge.queue == [int(first[best])] * holds[best]


def test_the_hover_wait_is_a_candidate_at_any_step_scored_by_the_policy_flown_after_it() -> None:
    """``wait_action="hover"`` in a world with the hover action, from the middle of an open map (no heading is
    forbidden, so the "forbidden" wait has no candidate there): action 16 held ``commit`` steps, then the policy,
    scored by hand one future at a time like every first heading; without the hover action in the world, refused."""
    from uamfleet.baselines.step_planner import released_only
    from uamfleet.rl.guided import AnticipatingGuidedSearch
    from uamfleet.types import HOVER_ACTION

    cfg = _hedge_config((Request(0, (550.0, 150.0), (550.0, 550.0)),), start=(350.0, 350.0)).replace(hover_action=True)
    prior, policy = _prior(cfg), _policy(cfg, 3)
    forbidden = AnticipatingGuidedSearch(policy, prior, first_headings=3, futures=4, tail=None, seed=5)
    hover = AnticipatingGuidedSearch(policy, prior, first_headings=3, futures=4, tail=None, seed=5, wait_action="hover")
    env = VectorEnv(cfg, 1, autoreset=False)
    env.reset(seed=0)
    assert env.state.action_mask[0, 0, :16].all()  # nothing forbidden in the middle of the open map
    forbidden.reset(env.sim)
    hover.reset(env.sim)
    assert len(forbidden.scores[0][0]) == 3  # no wait candidate without a forbidden heading
    first, means = hover.scores[0]
    assert len(first) == 4 and first[3] == HOVER_ACTION and (first[:3] == forbidden.scores[0][0]).all()
    np.testing.assert_array_equal(means[:3], forbidden.scores[0][1])  # the same futures for the headings
    rng = np.random.default_rng(5)
    known = released_only(env.state)
    futures = [prior.sample(known, rng) for _ in range(4)]
    moves = []
    for future in futures:
        probe = _probe(env.cfg, known if future is None else future)
        for _ in range(hover.commit):  # the hover flies nothing
            _, _, terminated, _, info = probe.step(np.array([[HOVER_ACTION]]))
            assert float(info["events"].moved[0, 0]) == 0.0 and not terminated[0]
        moves.append(_greedy_moves(policy, probe))
    assert means[3] == pytest.approx(np.mean(moves))
    still = VectorEnv(cfg.replace(hover_action=False), 1, autoreset=False)
    still.reset(seed=0)
    with pytest.raises(ValueError, match="wait_action='hover' waits with the hover action"):
        AnticipatingGuidedSearch(policy, prior, wait_action="hover").reset(still.sim)
    with pytest.raises(ValueError, match="wait_action='sit' is unknown"):
        AnticipatingGuidedSearch(policy, prior, wait_action="sit")


def test_the_hedge_reads_no_hidden_request() -> None:
    """Two instances that differ only in a request released at step 8: the same flight and the same searches
    until then; a search every `commit` steps in the window, and one at the release."""
    from uamfleet.rl.guided import AnticipatingGuidedSearch

    first = Request(0, (550.0, 150.0), (550.0, 550.0))
    flights, searches = [], []
    for later in (Request(8, (150.0, 650.0), (650.0, 650.0)), Request(8, (650.0, 350.0), (150.0, 350.0))):
        cfg = _hedge_config((first, later))
        hedge = AnticipatingGuidedSearch(_policy(cfg, 0), _prior(cfg), first_headings=3, futures=3, commit=3)
        traj = hedge.fly(cfg)
        flights.append([e.actions.tolist() for e in traj.events][:8])
        searches.append([(p[0], p[2]) for p in hedge.plans if p[0] < 8])
    assert flights[0] == flights[1] and searches[0] == searches[1]
    assert [t for t, _ in searches[0]] == [0, 3, 6]
    assert 8 in [p[0] for p in hedge.plans]


def test_the_hedge_checks_its_arguments_and_the_passenger_rows() -> None:
    from uamfleet.rl.guided import AnticipatingGuidedSearch

    cfg = _hedge_config((Request(0, (550.0, 150.0), (550.0, 550.0)),))
    with pytest.raises(ValueError, match="first_headings"):
        AnticipatingGuidedSearch(_policy(cfg, 0), _prior(cfg), first_headings=0)
    with pytest.raises(ValueError, match="unknown"):
        AnticipatingGuidedSearch(_policy(cfg, 0), "atlantis")
    hedge = AnticipatingGuidedSearch(_policy(cfg, 0), _prior(cfg, max_requests=6))
    with pytest.raises(ValueError, match="max_passengers >= 6"):
        hedge.fly(cfg)


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("top_k", 17, r"^top_k=17 is too large: at most 16 "),
        ("top_k", 2.5, r"^top_k=2\.5 must be a whole number in \[1, 16\]"),
        ("top_k", "8", r"^top_k='8' is a str, not a number"),
        ("samples", 10**6, r"^samples=1000000 is too large: at most 1024 "),
        ("samples", -1, r"^samples=-1 must be an integer in \[0, 1024\]"),
        ("temperature", float("inf"), r"^temperature=inf must be a finite number"),
        ("temperature", float("nan"), r"^temperature=nan must be a finite number"),
        ("expert_beam", 10**9, r"^expert_beam=1000000000 is too large: at most 4096 "),
        ("horizon", 0, r"^horizon=0 must be an integer in \[1, 16777215\] or None"),
        ("horizon", 1.5, r"^horizon=1\.5 must be a whole number"),
        ("seed", -1, r"^seed=-1 must be an integer"),
        ("guard_rollouts", "no", r"^guard_rollouts='no' must be True or False"),
    ],
)
def test_guided_search_checks_each_option_in_the_api(option, value, message) -> None:
    with pytest.raises(ConfigError, match=message):
        GuidedSearchPolicy(None, **{option: value})  # type: ignore[arg-type]


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("futures", 10**6, r"^futures=1000000 is too large: at most 256 "),  # hung before: 17 x 10^6 scratch envs
        ("futures", 0, r"^futures=0 must be an integer in \[1, 256\]"),
        ("first_headings", 17, r"^first_headings=17 is too large: at most 16 "),
        ("first_headings", True, r"^first_headings=True is a bool, not a number"),
        ("commit", 2**40, r"^commit=1099511627776 is too large: at most 16777215 "),
        ("commit", 0.5, r"^commit=0\.5 must be a whole number"),
        ("tail", -1, r"^tail=-1 must be an integer in \[0, 16777215\] or None"),
        ("tail", float("nan"), r"^tail=nan must be a whole number"),
        ("wait", 1, r"^wait=1 must be True or False"),
        ("samples", 2048, r"^samples=2048 is too large: at most 1024 "),
        ("seed", 2**64, r"^seed=18446744073709551616 is too large"),
    ],
)
def test_the_hedge_checks_each_option_in_the_api(option, value, message) -> None:
    from uamfleet.rl.guided import AnticipatingGuidedSearch

    with pytest.raises(ConfigError, match=message):
        AnticipatingGuidedSearch(None, "berlin", **{option: value})  # type: ignore[arg-type]
    with pytest.raises(
        ValueError, match=r"^demand=3 is no demand model; pass a family's name, 'family', 'wrong', a fitted model"
    ):
        AnticipatingGuidedSearch(None, 3)  # type: ignore[arg-type]


def test_the_search_caps_are_the_command_line_s() -> None:
    from uamfleet.cli import benchmark
    from uamfleet.rl import guided

    assert benchmark.MAX_FUTURES is guided.MAX_FUTURES and benchmark.MAX_SAMPLES is guided.MAX_SAMPLES
    assert benchmark.MAX_EXPERT_BEAM is guided.MAX_EXPERT_BEAM and benchmark.MAX_STEPS is guided.MAX_STEPS


@pytest.mark.parametrize("wait_action", ["forbidden", "hover"])
def test_a_traced_base_is_traced_at_reset_and_flies_as_the_eager_one(wait_action: str) -> None:
    """Every batch shape a search feeds the traced actor is traced at reset (so no search pays for a trace), and
    the hedge over the traced base flies the eager one's flight, search for search."""
    import copy

    from uamfleet.rl.guided import AnticipatingGuidedSearch

    first = Request(0, (550.0, 150.0), (550.0, 550.0))
    cfg = _hedge_config((first, Request(8, (150.0, 650.0), (650.0, 650.0)))).replace(hover_action=True)
    eager = _policy(cfg, 0)
    traced = copy.copy(eager).trace_actor()  # a shallow copy: the same weights, its own traces
    made_at_reset: list[int] = []
    flights = []
    for base in (eager, traced):
        hedge = AnticipatingGuidedSearch(base, _prior(cfg), first_headings=3, futures=3, commit=3,
                                         wait_action=wait_action)  # fmt: skip
        env = VectorEnv(cfg, 1, autoreset=False)
        obs, _ = env.reset(seed=0)
        hedge.reset(env.sim)
        made_at_reset.append(len(base._traces))
        actions, done = [], False
        while not done:
            action = hedge.act(obs)
            actions.append(action.tolist())
            obs, _, terminated, truncated, _ = env.step(action)
            done = bool(terminated[0] or truncated[0])
        flights.append((actions, [(p[0], p[1], p[2]) for p in hedge.plans]))
    assert flights[0] == flights[1] and len(flights[0][1]) >= 3  # several searches, the same ones
    expected = 3 if wait_action == "hover" else 4  # scratch, root, futures: (3 + 1) x 3 (and 3 x 3 for forbidden)
    assert made_at_reset == [0, expected] and len(traced._traces) == expected  # none made during the flight


def test_a_second_reset_makes_no_trace_and_runs_no_forward() -> None:
    """Tracing at reset runs the actor only at a batch shape whose trace is missing: a second episode's reset
    neither makes a trace nor runs a forward pass."""
    import copy

    from uamfleet.rl.guided import AnticipatingGuidedSearch

    first = Request(0, (550.0, 150.0), (550.0, 550.0))
    cfg = _hedge_config((first, Request(8, (150.0, 650.0), (650.0, 650.0)))).replace(hover_action=True)
    traced = copy.copy(_policy(cfg, 0)).trace_actor()
    hedge = AnticipatingGuidedSearch(traced, _prior(cfg), first_headings=3, futures=3, commit=3, wait_action="hover")
    env = VectorEnv(cfg, 1, autoreset=False)
    env.reset(seed=0)
    hedge.reset(env.sim)
    made = dict(traced._traces)
    forwards: list[int] = []
    forward = traced._logits  # every forward pass, through logits_of or trace_for, runs it
    traced._logits = lambda x: forwards.append(1) or forward(x)  # type: ignore[method-assign]
    env.reset(seed=1)
    hedge._trace_search_shapes()
    assert forwards == [] and traced._traces == made
    traced.trace_actor()  # traces dropped: the next reset makes them again
    hedge._trace_search_shapes()
    assert len(forwards) == len(made) and set(traced._traces) == set(made)
