"""Every kind of bad input raises an exception that names the value and the fix."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

import uamfleet
from uamfleet.config import ConfigError, DemandConfig, Request, RewardConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.sim.dynamics import InvalidActionError
from uamfleet.sim.generator import InfeasibleInstanceError

ISLAND = """
.....
.###.
.#.#.
.###.
.....
"""  # the centre block (2, 2) is flyable but enclosed by bad blocks


def test_unknown_preset_lists_the_known_ones():
    with pytest.raises(ValueError, match=r"Unknown scenario 'berlin_p9'.*berlin_p4"):
        uamfleet.parallel_env("berlin_p9")


def test_unknown_keyword_lists_the_valid_ones():
    with pytest.raises(TypeError, match=r"Unknown config keyword\(s\) \['sinr_db'\].*sinr_min_db"):
        uamfleet.parallel_env("berlin_p4", sinr_db=-3)


@pytest.mark.parametrize(
    ("overrides", "pattern"),
    [
        (
            dict(starts_m=((600.0, 100.0),)),
            r"start of taxi 0 at \(600.0, 100.0\) lies outside the map \[0, 500\]",
        ),
        (
            dict(requests=(Request(0, (-5.0, 100.0), (50.0, 50.0)),)),
            r"origin of passenger 0 \(P1\) at \(-5.0, 100.0\) lies outside",
        ),
        (
            dict(requests=(Request(0, (150.0, 350.0), (450.0, 50.0)),)),
            r"origin of passenger 0 \(P1\).*SINR -10.00 dB, below sinr_min_db=-3.0",
        ),
        (
            dict(requests=(Request(0, (50.0, 50.0), (250.0, 250.0)),)),
            r"destination of passenger 0 \(P1\).*unreachable from the start",
        ),
        (dict(starts_m=((250.0, 250.0),)), r"start of taxi 0 at \(250.0, 250.0\) has no allowed move"),
    ],
)
def test_infeasible_instances(overrides, pattern):
    base = dict(starts_m=((50.0, 50.0),), requests=(Request(0, (450.0, 50.0), (450.0, 450.0)),))
    base.update(overrides)
    with pytest.raises(InfeasibleInstanceError, match=pattern):
        VectorEnv(small_config(ISLAND, **base))


def test_threshold_that_disconnects_a_paper_stop():
    # At +5 dB most of Berlin is below the threshold: some stop of P4 is cut off or in a bad block.
    with pytest.raises(InfeasibleInstanceError, match=r"sinr_min_db=5.0"):
        uamfleet.parallel_env("berlin_p4", sinr_min_db=5.0)


@pytest.mark.parametrize(
    ("overrides", "pattern"),
    [
        (dict(seats=0), r"seats=0 must be an integer >= 1"),
        (dict(step_m=0.0), r"step_m=0.0 must be a positive number"),
        (dict(step_m=-100.0), r"step_m=-100.0 must be a positive number"),
        (dict(num_taxis=0, starts_m=None), r"num_taxis=0"),
        (dict(feasibility="anywhere"), r"feasibility='anywhere' is unknown"),
        (
            dict(starts_m=((50.0, 50.0), (50.0, 50.0)), num_taxis=3),
            r"starts_m has 2 positions but num_taxis=3",
        ),
        (
            dict(requests=((0, (1.0, 2.0)),)),
            r"must be a Request or \(release_step, origin_xy, destination_xy\)",
        ),
    ],
)
def test_bad_config_values(overrides, pattern):
    with pytest.raises(ValueError, match=pattern):
        small_config(**overrides)


def test_negative_release_step():
    with pytest.raises(ValueError, match=r"release_step=-1 must be an integer >= 0"):
        Request(-1, (0.0, 0.0), (1.0, 1.0))


@pytest.mark.parametrize(
    ("actions", "pattern"),
    [
        (np.array([[16]]), r"action 16 of env 0, taxi 0 is outside 0..15"),
        (np.array([[-1]]), r"action -1 of env 0, taxi 0 is outside 0..15"),
        (np.array([0, 1]), r"actions have shape \(2,\), expected \(num_envs, num_taxis\) = \(1, 1\)"),
        (np.array([[0.5]]), r"action 0.5 of env 0, taxi 0 is not a whole number"),
        (np.array([[np.nan]]), r"action nan of env 0, taxi 0 is not a whole number"),
        (np.array([[True]]), r"must be integer headings 0..15, got dtype bool"),
        (np.array([["3"]]), r"must be integer headings 0..15, got dtype <U1"),
        ([[1], [1, 2]], r"are not an array of shape \(num_envs, num_taxis\) = \(1, 1\)"),
    ],
)
def test_bad_actions(actions, pattern):
    env = VectorEnv(small_config())
    env.reset(seed=0)
    with pytest.raises(InvalidActionError, match=pattern):
        env.step(actions)


def test_pettingzoo_bad_action_and_missing_agent():
    env = uamfleet.parallel_env("berlin_p4", num_taxis=2)
    env.reset(seed=0)
    with pytest.raises(InvalidActionError, match="action 99 of env 0, taxi 1"):
        env.step({"uam_0": 0, "uam_1": 99})
    with pytest.raises(ValueError, match=r"missing \['uam_1'\]"):
        env.step({"uam_0": 0})


def test_step_before_reset():
    with pytest.raises(RuntimeError, match="before reset"):
        VectorEnv(small_config()).step(np.array([[0]]))


def test_observation_of_wrong_shape_is_named():
    from uamfleet.observe.observer import ObservationShapeError, check_observation

    env = VectorEnv(small_config(), num_envs=2)
    obs, _ = env.reset(seed=0)
    check_observation(obs, env.single_observation_space, batch_dims=2)  # the env's own observations pass
    other = VectorEnv(small_config(patch_size=6), num_envs=2).reset(seed=0)[0]
    with pytest.raises(
        ObservationShapeError, match=r"'sinr_patch' has shape \(2, 1, 6, 6\), expected \('\*', '\*', 4, 4\)"
    ):
        check_observation(other, env.single_observation_space, batch_dims=2)
    with pytest.raises(ObservationShapeError, match=r"lacks field\(s\) \['action_mask'\]"):
        check_observation({k: v for k, v in obs.items() if k != "action_mask"}, env.single_observation_space, 2)
    single = {k: v[0, 0] for k, v in obs.items()}
    check_observation(single, env.single_observation_space)
    with pytest.raises(ObservationShapeError, match=r"'action_mask' has shape \(2, 1, 16\), expected \(16,\)"):
        check_observation(obs, env.single_observation_space)  # batched obs where one taxi's was expected


def test_vertiport_in_a_bad_block():
    demand = DemandConfig(num_initial=1, vertiports=((50.0, 50.0), (150.0, 350.0)))
    with pytest.raises(InfeasibleInstanceError, match=r"vertiport 1 at \(150.0, 350.0\).*below sinr_min_db"):
        VectorEnv(small_config(ISLAND, starts_m=((50.0, 50.0),), requests=None, demand=demand))
    enclosed = DemandConfig(num_initial=1, vertiports=((50.0, 50.0), (250.0, 250.0)))
    with pytest.raises(InfeasibleInstanceError, match=r"vertiport 1 at \(250.0, 250.0\) is unreachable"):
        VectorEnv(small_config(ISLAND, starts_m=None, requests=None, demand=enclosed))


# ---- issue 14: values that were accepted silently, or failed with a traceback instead of a message --------


@pytest.mark.parametrize(
    ("overrides", "pattern"),
    [
        (dict(time_limit_steps=float("nan")), r"time_limit_steps=nan must be a whole number in \[1, 16777215\]"),
        (
            dict(time_limit_steps=1.5),
            r"time_limit_steps=1.5 must be a whole number in \[1, 16777215\].*; it is never rounded",
        ),
        (dict(time_limit_steps=True), r"time_limit_steps=True is a bool, not a number"),
        (dict(min_separation_m=float("nan")), r"min_separation_m=nan must be a finite number"),
        (dict(min_separation_m=-1.0), r"min_separation_m=-1.0 must be >= 0"),
        (dict(patch_size=3000), r"patch_size=3000 is too large: at most 64 \(blocks per side"),
        (dict(history_len=2.5), r"history_len=2.5 must be a whole number in \[1, 256\]"),
        (dict(history_len=0), r"history_len=0 must be an integer in \[1, 256\]"),
        (
            dict(sinr_min_db="-3"),
            r"sinr_min_db='-3' is a str, not a number; pass an int or float, e.g. sinr_min_db=-3.0",
        ),
        (dict(sinr_min_db=float("inf")), r"sinr_min_db=inf must be a finite number"),
        (dict(seats="2"), r"seats='2' is a str, not a number; pass an integer >= 1, e.g. seats=2"),
        (dict(num_taxis=1.5, starts_m=None), r"num_taxis=1.5 must be a whole number in \[1, 1024\]"),
        (dict(num_taxis=5000, starts_m=None), r"num_taxis=5000 is too large: at most 1024"),
        (dict(step_m=float("nan")), r"step_m=nan must be a finite number"),
        (dict(block_m=5.0), r"SINR blocks of 5 m .* finer than the radio map's 100 m raster.*block_m >= 100"),
        (dict(block_m=1e300), r"SINR blocks of 1e\+300 m .* larger than the whole 500 m map; use block_m <= 500"),
        (dict(seats=1e300), r"seats=1e\+300 is too large: at most 2147483647"),
        (dict(time_limit_steps=2**40), r"time_limit_steps=1099511627776 is too large"),
        (dict(pickup_radius_m="50"), r"pickup_radius_m \(None: step_m\)='50' is a str"),
        (dict(max_block_visits=0.5), r"max_block_visits \(or None: never\)=0.5 must be a whole number"),
        (dict(max_passengers=2.5), r"max_passengers \(or None\)=2.5 must be a whole number"),
        (dict(nc_rule="mean"), r"nc_rule='mean' is unknown"),
        (dict(demand=dict(max_requests=3)), r"demand=\{'max_requests': 3\} must be a DemandConfig"),
        (dict(reward=None), r"reward=None must be a RewardConfig"),
        (
            dict(starts_m=((150.0, 150.0, 100.0),)),
            r"starts_m\[0\]=\(150.0, 150.0, 100.0\) must be a finite \(x, y\) pair",
        ),
        (dict(starts_m=((150.0, float("nan")),)), r"starts_m\[0\]=\(150.0, nan\) must be a finite \(x, y\) pair"),
        (dict(starts_m="150,150"), r"starts_m='150,150' must be a sequence"),
        (dict(requests=[(0, (350.0, 150.0), (350.0, 150.0))]), r"origin_m == destination_m == \(350.0, 150.0\)"),
        (
            dict(requests=[(50, (350.0, 150.0), (350.0, 350.0))]),
            r"request 0 \(P1\) has release_step=50, not before time_limit_steps=50: .*raise time_limit_steps",
        ),
        (dict(requests=[(2.5, (350.0, 150.0), (350.0, 350.0))]), r"release_step=2.5 must be a whole number >= 0"),
        (dict(requests=[(0, (350.0, 150.0, 100.0), (350.0, 350.0))]), r"Request origin_m=\(350.0, 150.0, 100.0\)"),
        (dict(requests=[(0, "350,150", (350.0, 350.0))]), r"Request origin_m='350,150' must be a finite \(x, y\)"),
        (dict(requests=5), r"requests=5 must be a sequence"),
    ],
)
def test_config_values_once_accepted_or_a_traceback(overrides, pattern):
    with pytest.raises(ConfigError, match=pattern):
        small_config(**overrides)


@pytest.mark.parametrize(
    ("make", "pattern"),
    [
        (lambda: DemandConfig(max_requests=2.5), r"DemandConfig.max_requests=2.5 must be a whole number"),
        (lambda: DemandConfig(max_requests=5000), r"DemandConfig.max_requests=5000 is too large: at most 1024"),
        (lambda: DemandConfig(num_initial=9, max_requests=8), r"DemandConfig.num_initial=9 is too large: at most 8"),
        (lambda: DemandConfig(rate_per_step=float("nan")), r"DemandConfig.rate_per_step=nan must be a finite"),
        (lambda: DemandConfig(horizon_steps=-1), r"DemandConfig.horizon_steps=-1 must be an integer >= 0"),
        (lambda: DemandConfig(min_trip_m="500"), r"DemandConfig.min_trip_m='500' is a str"),
        (lambda: DemandConfig(vertiports=((0.0, 0.0), (0.0, 0.0))), r"lists a site twice"),
        (lambda: DemandConfig(vertiports=((0.0, 0.0), (1.0, 2.0, 3.0))), r"vertiports\[1\]=\(1.0, 2.0, 3.0\)"),
        (lambda: RewardConfig(pickup="200"), r"RewardConfig.pickup='200' is a str, not a number"),
        (lambda: RewardConfig(step=float("nan")), r"RewardConfig.step=nan must be a finite number"),
        (lambda: Request(True, (0.0, 0.0), (1.0, 1.0)), r"release_step=True is a bool"),
    ],
)
def test_demand_reward_and_request_values(make, pattern):
    with pytest.raises(ConfigError, match=pattern):
        make()


def test_whole_floats_are_taken_as_integers_and_numbers_as_floats():
    cfg = small_config(time_limit_steps=50.0, history_len=np.int64(2), sinr_min_db=np.float32(-3), step_m=100)
    assert (cfg.time_limit_steps, cfg.history_len) == (50, 2)
    assert type(cfg.time_limit_steps) is int and type(cfg.history_len) is int
    assert type(cfg.sinr_min_db) is float and type(cfg.step_m) is float
    assert Request(np.int64(3), (np.float32(1.5), 2), (3, 4)) == Request(3, (1.5, 2.0), (3.0, 4.0))


def test_preset_fleet_size_is_checked_before_use():
    with pytest.raises(ConfigError, match=r"num_taxis=2.5 must be a whole number"):
        uamfleet.parallel_env("berlin_p4", num_taxis=2.5)
    with pytest.raises(ConfigError, match=r"starts_m\[0\]=\(2600, 1500, 100\).*altitude_m"):
        uamfleet.parallel_env("berlin_p4", starts_m=((2600, 1500, 100),))


@pytest.mark.parametrize(
    ("action", "pattern"),
    [
        (3.5, r"action 3.5 of env 0, taxi 1 \(uam_1\) is not a whole number.*never rounded"),
        (float("nan"), r"action nan of env 0, taxi 1 \(uam_1\) is not a whole number"),
        ("3", r"the action of env 0, taxi 1 \(uam_1\) is '3' \(str\); give an integer heading 0..15"),
        (True, r"the action of env 0, taxi 1 \(uam_1\) is True \(bool\)"),
        (np.bool_(False), r"the action of env 0, taxi 1 \(uam_1\) is np.False_ \(bool"),
        (np.array([3]), r"the action of env 0, taxi 1 \(uam_1\) is an array of shape \(1,\).*one scalar"),
        (None, r"the action of env 0, taxi 1 \(uam_1\) is None"),
        (-1, r"action -1 of env 0, taxi 1 \(uam_1\) is outside 0..15"),
    ],
)
def test_pettingzoo_actions_are_never_truncated(action, pattern):
    env = uamfleet.parallel_env("berlin_p4", num_taxis=2)
    env.reset(seed=0)
    with pytest.raises(InvalidActionError, match=pattern):
        env.step({"uam_0": 0, "uam_1": action})


def test_pettingzoo_accepts_integer_scalars_of_any_kind():
    # The same move whether the heading is an int, a NumPy integer, a 0-d array or a whole float.
    positions = []
    for action in (4, np.int64(4), np.int8(4), np.array(4), 4.0, np.float32(4.0)):
        env = uamfleet.parallel_env("berlin_p4")
        env.reset(seed=0)
        env.step({"uam_0": action})
        positions.append(env.core.state.pos_m[0, 0].tolist())
    assert positions == [[2600.0, 1600.0]] * len(positions)  # heading 4 = 90°: one 100 m step north


def test_random_demand_needs_two_flyable_sites():
    one_block = """
.####
#####
#####
#####
#####
"""
    with pytest.raises(InfeasibleInstanceError, match=r"random starts and random stops need 2 flyable block"):
        VectorEnv(small_config(one_block, starts_m=None, requests=None))
