"""The learned value inside ``batch_assignment`` (NeurADP-style): features and fit against hand computations, a
zero value that changes nothing, and the valued assignment against brute force on a small drawn scene."""

from __future__ import annotations

import itertools
import json
import math

import numpy as np
import pytest
from conftest import small_config

from uamfleet.baselines.assignment_value import (
    FEATURES,
    INCREASING,
    LinearValue,
    SiteRemoteness,
    discounted_future_pickups,
    fit_linear_value,
    load_value,
    post_state_features,
    save_value,
    value_for_dispatcher,
)
from uamfleet.baselines.batch_assignment import BatchAssignmentPolicy
from uamfleet.checks import ConfigError
from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import split_seeds
from uamfleet.policies import make_flown
from uamfleet.rollout import run_episode

OPEN_10 = "\n".join(["." * 10] * 10)
STARTS = ((150.0, 150.0), (850.0, 850.0), (150.0, 850.0))
REQUESTS = (
    Request(0, (350.0, 150.0), (750.0, 550.0)),
    Request(0, (450.0, 250.0), (850.0, 650.0)),
    Request(0, (650.0, 850.0), (150.0, 450.0)),
    Request(0, (250.0, 650.0), (550.0, 150.0)),
    Request(2, (850.0, 250.0), (250.0, 250.0)),
    Request(4, (550.0, 550.0), (150.0, 950.0)),
    Request(7, (950.0, 950.0), (450.0, 850.0)),
)


def _env(**overrides):
    cfg = small_config(OPEN_10, starts_m=STARTS, requests=REQUESTS, time_limit_steps=150, **overrides)
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    return env


def _value(weights, price_s=100.0):
    return LinearValue(np.asarray(weights, dtype=float), price_s=price_s, horizon_s=60.0, arrival_window_s=120.0)


def test_post_state_features_by_hand():
    # window 600 s; free at 300 s and at 700 s (after the window), remoteness 0.8 and 1.5
    feats = post_state_features(np.array([300.0, 700.0]), np.array([0.8, 1.5]), 600.0)
    assert FEATURES == ("bias", "open_share", "open_share_sq", "remoteness_x_open_share", "remoteness")
    np.testing.assert_allclose(feats[0], [1.0, 0.5, 0.25, 0.4, 0.8])
    np.testing.assert_allclose(feats[1], [1.0, 0.0, 0.0, 0.0, 1.5])


def test_site_remoteness_by_hand():
    sites = np.array([[0.0, 0.0], [300.0, 0.0], [0.0, 400.0]])
    remote = SiteRemoteness(sites)
    pair_mean = (300.0 + 400.0 + 500.0) / 3.0  # the mean distance between two different sites
    assert remote.scale_m == pytest.approx(pair_mean)
    np.testing.assert_allclose(remote(np.array([[0.0, 0.0]])), [(0 + 300 + 400) / 3 / pair_mean])
    np.testing.assert_allclose(remote(np.array([[300.0, 400.0]])), [(500 + 400 + 300) / 3 / pair_mean])


def test_discounted_future_pickups_counts_later_pickups_off_the_plan():
    pickups = [(3, 10.0), (4, 25.0), (5, 40.0), (6, 70.0)]  # (passenger, time s)
    # decided at 25 s with passenger 5 on the plan: 4 was picked up at the decision (not after), 5 was planned
    expected = math.exp(-(70.0 - 25.0) / 30.0)
    assert discounted_future_pickups(25.0, [5], pickups, 30.0) == pytest.approx(expected)
    assert discounted_future_pickups(0.0, [], pickups, 1e12) == pytest.approx(4.0)


def test_least_squares_fit_on_a_two_state_chain():
    # A chain A -> B -> end: from A the taxi picks up one new passenger at 10 s and one at 20 s, from B (at 10 s)
    # only the one at 20 s. With one-hot features the fit is each state's mean return, here exact.
    horizon = 10.0
    pickups = [(1, 10.0), (2, 20.0)]
    g_a = discounted_future_pickups(0.0, [], pickups, horizon)
    g_b = discounted_future_pickups(10.0, [], pickups, horizon)
    assert g_a == pytest.approx(math.exp(-1.0) + math.exp(-2.0)) and g_b == pytest.approx(math.exp(-1.0))
    feats = np.array([[1.0, 0.0], [0.0, 1.0], [1.0, 0.0]])  # A seen twice (returns g_a and g_a + 1), B once
    w = fit_linear_value(feats, np.array([g_a, g_b, g_a + 1.0]), ridge=0.0, nonnegative=())
    np.testing.assert_allclose(w, [g_a + 0.5, g_b])
    with pytest.raises(ValueError, match="finite"):
        fit_linear_value(feats, np.array([g_a, math.nan, 1.0]))


def test_the_fit_keeps_the_open_share_weights_non_negative():
    # returns fall with the open share (2 when closed, 1 when open): unconstrained, the slope is -1; kept >= 0 it
    # is 0, and the bias is the mean return 1.5
    feats = np.array([[1.0, 0.0], [1.0, 1.0], [1.0, 0.0], [1.0, 1.0]])
    returns = np.array([2.0, 1.0, 2.0, 1.0])
    np.testing.assert_allclose(fit_linear_value(feats, returns, ridge=0.0, nonnegative=()), [2.0, -1.0], atol=1e-9)
    np.testing.assert_allclose(fit_linear_value(feats, returns, ridge=0.0, nonnegative=(1,)), [1.5, 0.0], atol=1e-9)
    # so a fitted value never grows with the time the taxi is free, at any place
    rng = np.random.default_rng(0)
    x = post_state_features(rng.uniform(0, 900, 400), rng.uniform(0.5, 2.0, 400), 600.0)
    w = fit_linear_value(x, -x[:, 1] + rng.normal(0, 0.1, 400))  # data that would reward being free later
    assert (w[list(INCREASING)] >= 0).all()
    free = np.linspace(0, 900, 50)
    for far in (0.5, 1.0, 2.0):
        assert (np.diff(post_state_features(free, np.full(50, far), 600.0) @ w) <= 1e-12).all()


def _routes_every_step(policy, env):
    """Fly the episode and keep every taxi's schedule after every decision."""
    seen = []
    inner = policy.dispatch

    def dispatch(released):
        inner(released)
        seen.append([list(r) for r in policy.routes])

    policy.dispatch = dispatch
    traj = run_episode(env, policy, seed=0)
    return seen, traj


@pytest.mark.parametrize(
    "value",
    [_value(np.zeros(len(FEATURES)), price_s=500.0), _value([3.0, 2.0, 1.0, 5.0, -4.0], price_s=0.0)],
    ids=["zero-weights", "zero-price"],
)
def test_a_zero_value_decides_exactly_as_batch_assignment(value):
    plain, plain_traj = _routes_every_step(BatchAssignmentPolicy(), _env())
    valued, valued_traj = _routes_every_step(BatchAssignmentPolicy(value=value), _env())
    assert valued == plain
    np.testing.assert_array_equal(valued_traj.positions_m, plain_traj.positions_m)
    assert plain_traj.episode["delivered"] == len(REQUESTS)


def test_a_value_changes_decisions_somewhere():
    """A test that a priced value is not silently ignored: a strong pull toward ending far from the sites."""
    plain, _ = _routes_every_step(BatchAssignmentPolicy(), _env())
    valued, traj = _routes_every_step(BatchAssignmentPolicy(value=_value([0, 0, 0, 0, 50.0], 500.0)), _env())
    assert valued != plain
    assert traj.episode["delivered"] == len(REQUESTS)  # everyone is still served: the penalty dominates


@pytest.mark.parametrize(
    ("weights", "price_s"),
    [([0.3, 2.0, 1.5, 0.4, -0.7], 100.0), ([0, 0, 0, 0, -2.0], 100.0), ([0, 3.0, 0, 0, 0], 300.0)],
)
def test_the_valued_assignment_is_the_brute_force_optimum(weights, price_s):
    env = _env()
    weights = np.asarray(weights, dtype=float)
    value = _value(weights, price_s)
    policy = BatchAssignmentPolicy(value=value)
    policy.reset(env.sim)
    waiting = [p for p in range(4)]  # the four requests released at step 0
    trips, routes, free_s = policy.candidate_trips(waiting)
    policy(None)  # the first decision: the policy's own choice
    chosen_routes = [list(r) for r in policy.routes]

    # Brute force, written out from the module docstring: every choice of at most one trip per taxi serving each
    # request at most once; objective = sum of trip costs + penalty per unserved - price * sum over taxis of V of
    # the state the taxi is left in (free at the route's end at its last stop, or now where it is).
    sites = policy._remoteness.sites_m
    pair = np.linalg.norm(sites[:, None] - sites[None], axis=-1)
    scale = pair.sum() / (len(sites) * (len(sites) - 1))

    def v(free, point):
        far = np.linalg.norm(sites - point, axis=-1).mean() / scale
        open_share = min(max((value.arrival_window_s - free) / value.arrival_window_s, 0.0), 1.0)
        return float(np.dot(weights, [1, open_share, open_share**2, far * open_share, far]))

    def left_in(taxi, k):
        if k is None:
            return v(0.0, env.state.pos_m[0, taxi])
        return v(free_s[k], policy.dest_m[routes[k][-1][0]])

    options = [[None] + [k for k, t in enumerate(trips) if t[0] == a] for a in range(policy.num_taxis)]
    best = None
    for choice in itertools.product(*options):
        served = [r for k in choice if k is not None for r in trips[k][1]]
        if len(served) != len(set(served)):
            continue
        total = sum(trips[k][2] for k in choice if k is not None) + policy.penalty_s * (len(waiting) - len(served))
        total -= value.price_s * sum(left_in(a, k) for a, k in enumerate(choice))
        if best is None or total < best[0] - 1e-6:
            best = (total, choice)
    assert best is not None
    expected = [routes[k] if k is not None else [] for k in best[1]]
    assert chosen_routes == expected
    plain = BatchAssignmentPolicy()
    assert _first_routes(plain, _env()) != expected  # the value changed this decision: the test can fail


def _first_routes(policy, env):
    policy.reset(env.sim)
    policy(None)
    return [list(r) for r in policy.routes]


def test_value_files_round_trip_and_refuse_what_they_cannot_read(tmp_path):
    value = LinearValue(np.arange(len(FEATURES), dtype=float), 30.0, 200.0, 600.0, {"episodes": 3})
    path = tmp_path / "value.json"
    save_value(path, value)
    back = load_value(path)
    np.testing.assert_array_equal(back.weights, value.weights)
    assert (back.price_s, back.horizon_s, back.arrival_window_s, back.meta) == (30.0, 200.0, 600.0, {"episodes": 3})
    assert value_for_dispatcher("batch_assignment", path) is None
    assert value_for_dispatcher("batch_assignment_value:75", path, 1800.0).price_s == 75.0
    assert value_for_dispatcher("batch_assignment_value", path, 1800.0).arrival_window_s == 1800.0
    policy = make_flown("batch_assignment_value:12.5", num_taxis=2, assignment_value=path)
    assert isinstance(policy, BatchAssignmentPolicy) and policy.value.price_s == 12.5
    with pytest.raises(ValueError, match="batch_assignment_value:<price_s>"):
        value_for_dispatcher("batch_assignment_value:cheap", path)
    with pytest.raises(ValueError, match=r"price_s=-1\.0"):
        value_for_dispatcher("batch_assignment_value:-1", path)
    with pytest.raises(FileNotFoundError, match=r"train\.assignment_value"):
        load_value(tmp_path / "missing.json")
    body = json.loads(path.read_text())
    body["features"] = ["bias"]
    path.write_text(json.dumps(body))
    with pytest.raises(ValueError, match="refit"):
        load_value(path)
    with pytest.raises(ValueError, match="weights must have 5"):
        LinearValue(np.zeros(3))


def test_the_fleet_benchmark_flies_the_value_dispatcher_through_the_same_rows(tmp_path):
    from uamfleet.cli.fleet_benchmark import Args, main, run_episode_set

    path = tmp_path / "value.json"
    save_value(path, LinearValue(np.array([0.5, 1.0, 0.5, 0.5, -0.5]), 60.0, 300.0, 600.0))
    names = ("batch_assignment", "batch_assignment_value:0", "batch_assignment_value")
    rows = run_episode_set(("berlin", "2x12", 2000000, names, (), "shield", True, None, 600.0, path))
    # rows of a value file other than the shipped one are named apart from the shipped value's
    assert [r["dispatcher"] for r in rows] == ["batch_assignment", "batch_assignment_value:0@value",
                                               "batch_assignment_value@value"]  # fmt: skip
    timing = {"decision_p50_ms", "decision_max_ms", "policy_s"}
    assert {k: v for k, v in rows[1].items() if k not in timing | {"dispatcher"}} == {
        k: v for k, v in rows[0].items() if k not in timing | {"dispatcher"}
    }  # price 0: the same episode as batch_assignment
    assert rows[2]["separation_violations"] == 0 and rows[2]["service_pct"] == 100.0
    with pytest.raises(ValueError, match="unknown --dispatchers"):
        main(Args(dispatchers=("batch_assignment_values",), out_csv=tmp_path / "x.csv", out_md=tmp_path / "x.md"))
    with pytest.raises(FileNotFoundError, match="no assignment value"):
        main(Args(dispatchers=("batch_assignment_value",), assignment_value=tmp_path / "none.json",
                  out_csv=tmp_path / "x.csv", out_md=tmp_path / "x.md"))  # fmt: skip


@pytest.mark.parametrize("on_release", [False, True], ids=["every-period", "and-at-releases"])
def test_the_recorder_flies_its_options_and_records_every_batch_that_runs(on_release):
    from uamfleet.baselines.batch_assignment import RecordingAssignment

    env = _env()
    policy = RecordingAssignment(wait_weight=1.0, assign_on_release=on_release)
    traj = run_episode(env, policy, seed=0)
    assert policy.wait_weight == 1.0 and policy.assign_on_release is on_release
    steps = len(traj.decision_s)  # the steps the policy was called at: 0 ... steps - 1
    # period 3: batches at steps 0, 3, 6, ...; the requests are released at steps 0, 2, 4 and 7
    expected = {t for t in range(steps) if t % 3 == 0} | ({2, 4, 7} if on_release else set())
    slot = env.cfg.slot_s
    recorded = sorted({round(now / slot) for _, now, _, _, _ in policy.decisions})
    assert recorded == sorted(expected)
    assert len(policy.decisions) == len(expected) * len(STARTS)  # one row per taxi per batch
    assert traj.episode["delivered"] == len(REQUESTS)


def test_the_recorder_options_and_settings_are_read_in_one_place():
    from uamfleet.baselines.fleet_dispatch import DispatchOptions
    from uamfleet.cli._common import UsageError
    from uamfleet.cli.assignment_value import family_setting, parse_options

    assert parse_options("") == DispatchOptions()
    assert parse_options("+wait=1+release") == DispatchOptions(wait_weight=1.0, assign_on_release=True)
    assert parse_options("+release") == DispatchOptions(assign_on_release=True)
    with pytest.raises(UsageError, match="as after a dispatcher's name"):
        parse_options("wait=1")
    with pytest.raises(ValueError, match="unknown option"):
        parse_options("+wiat=1")
    assert family_setting("4x48", "berlin") == ("berlin", "4x48")
    assert family_setting("detroit3gpp:4x24", "berlin") == ("detroit3gpp", "4x24")
    with pytest.raises(UsageError, match="unknown family"):
        family_setting("detroit:4x24", "berlin")
    with pytest.raises(ValueError, match="--settings setting '4by24' is not <taxis>x<requests>"):
        family_setting("detroit3gpp:4by24", "berlin")


def test_the_fit_records_its_options_and_both_families_in_its_meta(tmp_path):
    from uamfleet.cli.assignment_value import Args, main

    out = tmp_path / "v.json"
    meta = main(Args(settings=("1x2", "detroit3gpp:1x2"), count=1, options="+wait=1+release", out=out))
    assert meta["options"] == {"wait_weight": 1.0, "assign_on_release": True}
    assert meta["settings"] == ["1x2", "detroit3gpp:1x2"] and meta["episodes"] == 2
    assert load_value(out).meta["options"] == meta["options"]
    steered = main(Args(settings=("2x4",), count=1, options="+wait=1+release", heading="onward", out=out,
                        overwrite=True))  # fmt: skip
    assert steered["options"] == {"wait_weight": 1.0, "assign_on_release": True, "heading": "onward"}
    with pytest.raises(ConfigError, match="--heading='sideways'"):
        main(Args(settings=("1x2",), count=1, heading="sideways", out=tmp_path / "w.json"))


def test_the_recorder_flies_the_heading_it_is_given():
    from uamfleet.cli.assignment_value import fly_recorded

    assert fly_recorded("berlin", "2x4", split_seeds("train", 1)[0], None, heading="onward").heading == "onward"


def test_a_value_file_other_than_the_shipped_one_names_its_rows():
    from pathlib import Path

    from uamfleet.baselines.assignment_value import shipped_value_path
    from uamfleet.cli.fleet_benchmark import dispatcher_row_name

    name = "batch_assignment_value:100+wait=1+release"
    assert dispatcher_row_name(name, None) == name
    assert dispatcher_row_name(name, shipped_value_path()) == name
    assert dispatcher_row_name(name, Path("scratch/refit.json")) == f"{name}@refit"
    assert dispatcher_row_name("batch_assignment+wait=1", Path("scratch/refit.json")) == "batch_assignment+wait=1"
