"""Every kind of bad input raises an exception that names the value and the fix."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

import uamfleet
from uamfleet.config import Request
from uamfleet.env.dynamics import InvalidActionError
from uamfleet.env.generator import InfeasibleInstanceError
from uamfleet.env.vector_env import VectorEnv

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
        (np.array([[0.5]]), r"must be integer headings 0..15, got dtype float64"),
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
    from uamfleet.env.observer import ObservationShapeError, check_observation

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
    from uamfleet.config import DemandConfig

    demand = DemandConfig(num_initial=1, vertiports=((50.0, 50.0), (150.0, 350.0)))
    with pytest.raises(InfeasibleInstanceError, match=r"vertiport 1 at \(150.0, 350.0\).*below sinr_min_db"):
        VectorEnv(small_config(ISLAND, starts_m=((50.0, 50.0),), requests=None, demand=demand))
    enclosed = DemandConfig(num_initial=1, vertiports=((50.0, 50.0), (250.0, 250.0)))
    with pytest.raises(InfeasibleInstanceError, match=r"vertiport 1 at \(250.0, 250.0\) is unreachable"):
        VectorEnv(small_config(ISLAND, starts_m=None, requests=None, demand=enclosed))
