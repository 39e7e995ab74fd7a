"""The fleet search at decision time (``fleet_search(BASE)``, :mod:`uamfleet.baselines.fleet_search`): it never
reads a request before its release, every move it returns passes the separation shield, and its choice is the
candidate a brute-force rollout (fresh episodes flown from configs of the same futures) scores best."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

from uamfleet.baselines.fleet_search import FleetDemand, FleetSearch, known_state, shield_passed
from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.metrics import episode_metrics
from uamfleet.policies import make, make_named
from uamfleet.rollout import fly, run_episode
from uamfleet.sim.core import Simulator
from uamfleet.types import HIDDEN

BASE = "batch_assignment_value:100+wait=1+release+price=1000+guard=600"
OPEN_10 = "\n".join(["." * 10] * 10)
CORNERS = ((150.0, 150.0), (850.0, 150.0), (150.0, 850.0), (850.0, 850.0))
CENTRE_REQUESTS = (  # four taxis from the corners converge on the centre: the dispatchers need the shield here
    Request(0, (450.0, 450.0), (850.0, 850.0)),
    Request(0, (550.0, 450.0), (150.0, 850.0)),
    Request(0, (450.0, 550.0), (850.0, 150.0)),
    Request(2, (550.0, 550.0), (150.0, 150.0)),
)


def fleet_case(taxis: int = 2, requests: int = 8):
    seed = split_seeds("validation", 1)[0]
    return make_fleet_instance("berlin", seed, taxis, requests, separation="shield", hover_action=True)


def search(**options):
    return FleetSearch(make_named(BASE), **options)


def flown_actions(cfg, policy, steps: int) -> list[np.ndarray]:
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    obs, _ = env.reset(seed=0)
    policy.reset(env.sim)
    out = []
    for _ in range(steps):
        actions = policy.act(obs)
        out.append(actions.copy())
        obs, *_ = env.step(actions)
    return out


def test_the_decisions_are_the_same_whatever_the_unreleased_requests_are():
    cfg = fleet_case()
    cut = 12  # fly up to this step: every request released later is replaced by another trip
    later = [i for i, r in enumerate(cfg.requests) if r.release_step > cut]
    assert later, "the case must hold requests released after the cut"
    sites = [r.origin_m for r in cfg.requests] + [r.destination_m for r in cfg.requests]
    other = list(cfg.requests)
    for i in later:  # another trip between the instance's sites, released at another step after the cut
        r = cfg.requests[i]
        other[i] = Request(r.release_step + 3, sites[(3 * i + 1) % len(sites)], sites[(5 * i + 2) % len(sites)])
    assert other != list(cfg.requests)
    first, second = search(every=3), search(every=3)
    actions = flown_actions(cfg, first, cut)
    assert [a.tolist() for a in actions] == [a.tolist() for a in flown_actions(cfg.replace(requests=tuple(other)),
                                                                              second, cut)]  # fmt: skip
    assert [(d.t, d.mean_costs, d.chosen) for d in first.decisions] == [
        (d.t, d.mean_costs, d.chosen) for d in second.decisions
    ]
    assert len(first.decisions) == 4  # steps 0, 3, 6, 9


def test_the_known_state_holds_nothing_of_a_hidden_request():
    cfg = fleet_case()
    sim = Simulator(cfg, 1, autoreset=False)
    sim.reset(seed=0)
    hidden = sim.state.pax_status[0] == HIDDEN
    assert hidden.any() and (sim.state.pax_origin_m[0, hidden] != 0).any()
    known = known_state(sim.state)
    assert not known.pax_exists[0, hidden].any()
    assert (known.pax_origin_m[0, hidden] == 0).all() and (known.pax_dest_m[0, hidden] == 0).all()
    assert (known.pax_release[0, hidden] == 0).all()
    # the futures add the missing requests after now, from the model
    demand = FleetDemand.of_fleet(cfg, np.array(sorted({r.origin_m for r in cfg.requests})), 600.0)
    future = demand.sample(known, np.random.default_rng(0))
    assert future.pax_exists[0].sum() == 8 == demand.requests
    assert (future.pax_release[0, hidden] > 0).all() and (future.pax_status[0, hidden] == HIDDEN).all()


def test_every_move_it_returns_passes_the_shield():
    # The corner scene: the dispatcher alone needs the shield to turn or hold its taxis (a test that can fail)...
    cfg = small_config(OPEN_10, starts_m=CORNERS, requests=CENTRE_REQUESTS, separation="shield", hover_action=True,
                       time_limit_steps=200, scenario="berlin_fleet4x4_seed0")  # fmt: skip
    alone = run_episode(VectorEnv(cfg, num_envs=1, autoreset=False), make_named(BASE), seed=0)
    assert episode_metrics(alone, cfg.radio).shield_interventions > 0
    # ... the search asks only for moves the shield flies as asked, and still delivers everyone apart
    traj = run_episode(VectorEnv(cfg, num_envs=1, autoreset=False), search(every=2), seed=0)
    m = episode_metrics(traj, cfg.radio)
    assert sum(int(e.shield_intervened.sum()) for e in traj.events) == 0
    assert (m.shield_interventions, m.separation_violations, m.delivered) == (0, 0, 4)


def test_shield_passed_actions_are_flown_as_asked_on_random_moves():
    # Random joint moves at every state of a dispatcher's episode in the corner scene: the shield intervenes on
    # many of them as they are, and on none once passed (stepped by the env's own step on a copy of the state).
    cfg = small_config(OPEN_10, starts_m=CORNERS, requests=CENTRE_REQUESTS, separation="shield", hover_action=True,
                       time_limit_steps=200)  # fmt: skip
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    obs, _ = env.reset(seed=0)
    policy = make("batch_assignment")
    policy.reset(env.sim)
    probe = Simulator(cfg, 1, autoreset=False)
    probe.reset(seed=0)
    rng = np.random.default_rng(1)
    raw = passed = 0
    for _ in range(30):
        for _ in range(8):
            random = rng.integers(0, cfg.num_actions, size=(1, 4))
            for asked, count in ((random, "raw"), (shield_passed(env.sim, random), "passed")):
                for name, value in zip(type(env.state)._fields, env.state, strict=True):
                    getattr(probe.state, name)[:] = value
                probe.needs_reset = False
                _, _, _, info = probe.advance(asked)
                hits = int(info["events"].shield_intervened.sum())
                raw, passed = (raw + hits, passed) if count == "raw" else (raw, passed + hits)
        obs, _, terminated, truncated, _ = env.step(policy.act(obs))
        if terminated[0] or truncated[0]:
            break
    assert raw > 0 and passed == 0


def brute_force_cost(cfg, future, weight: float) -> float:
    """The rollout cost written out independently: the future as a config of its own, flown from its start by a
    fresh dispatcher of wait weight ``weight``; distance from the moves flown, waits from the pick-up events."""
    rows = np.flatnonzero(future.pax_exists[0])
    requests = tuple(Request(int(future.pax_release[0, p]), tuple(future.pax_origin_m[0, p]),
                             tuple(future.pax_dest_m[0, p])) for p in rows)  # fmt: skip
    flown = cfg.replace(requests=requests)
    dispatcher = make_named(BASE)
    dispatcher.wait_weight = weight
    traj = fly(flown, dispatcher)
    moves = sum(int(e.moved[0].sum()) for e in traj.events)
    picked = np.array([e.picked_up[0] for e in traj.events])[:, rows]  # [T, N]
    pickup_step = np.where(picked.any(0), np.argmax(picked, axis=0) + 1, traj.num_steps)
    waited = float((pickup_step - future.pax_release[0, rows]).sum())
    return moves * cfg.step_m / (cfg.step_m / cfg.slot_s) + waited * cfg.slot_s


def test_its_choice_is_the_best_candidate_of_a_brute_force_rollout():
    cfg = fleet_case(2, 6)
    policy = search(waits=(0.0, 6.0), futures=2, horizon=None, every=1000)
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    policy.reset(env.sim)
    decision = policy.decide()  # at step 0, to the end of every future
    rng = np.random.default_rng([policy.seed, 0])
    futures = [policy.demand.sample(known_state(env.state), rng) for _ in range(2)]
    brute = np.array([[brute_force_cost(cfg, f, w) for f in futures] for w in policy.wait_weights]).mean(axis=1)
    np.testing.assert_allclose(decision.mean_costs, brute, rtol=1e-9)
    assert decision.chosen == int(np.argmin(brute))
    assert policy.base.wait_weight == policy.wait_weights[decision.chosen]


@pytest.mark.parametrize(
    ("options", "needle"),
    [({"futures": 0}, "futures"), ({"every": 0}, "every"), ({"waits": (-1.0,)}, "waits"), ({"horizon": 0}, "horizon")],
)
def test_bad_options_are_refused_naming_them(options, needle):
    with pytest.raises(ValueError, match=needle):
        search(**options)


def test_a_world_of_no_fleet_service_is_refused_in_one_line():
    cfg = small_config(OPEN_10, starts_m=CORNERS, requests=CENTRE_REQUESTS)
    with pytest.raises(ValueError, match="fleet_search"):
        search().reset(Simulator(cfg, 1, autoreset=False))


def test_its_default_base_is_the_chosen_dispatcher():
    from uamfleet.policies import parse
    from uamfleet.policies.search import CHOSEN_DISPATCHER

    assert parse(BASE) == CHOSEN_DISPATCHER
    built = make("fleet_search")
    assert isinstance(built, FleetSearch) and built.base.wait_weight == 1.0 and built.base.value is not None


def test_the_fleet_benchmark_flies_it_over_a_dispatcher_and_refuses_it_over_another_base():
    from uamfleet.cli.fleet_benchmark import Args, _check_names, dispatcher

    built = dispatcher(f"fleet_search:futures=2,waits=0({BASE})", 4, None, 300.0)
    assert isinstance(built, FleetSearch) and (built.futures, built.wait_weights) == (2, (1.0, 0.0))
    assert built.arrival_window_s == 300.0 and built.base.value.arrival_window_s == 300.0  # the service's window
    _check_names(Args(count=1, settings=("4x8",), dispatchers=(f"fleet_search({BASE})",)))
    with pytest.raises(ValueError, match="unknown --dispatchers"):
        _check_names(Args(count=1, settings=("4x8",), dispatchers=("fleet_search(learned)",)))
