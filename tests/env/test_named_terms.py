"""Reward terms keyed by name (weight, value, log column); the layout constants defined once in uamfleet.types."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

import uamfleet
from uamfleet.config import Request, RewardConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.types import NUM_HEADINGS, PASSENGER_FEATURES, PAX_AGE, PAX_ORIGIN_DX, PAX_WAITING

EAST, NORTH, WEST = 0, 4, 8


def test_each_term_is_weighted_by_the_field_of_its_name():
    # Weights all different from the defaults: each column must show its own weight and nothing else.
    weights = RewardConfig(
        step=-3.0, explore=5.0, explore_repeat=-0.7, pickup=11.0, dropoff=13.0, blocked=-17.0, separation=-19.0
    )
    env = VectorEnv(small_config(reward=weights))
    env.reset(seed=0)
    # East: (250, 150), a new block (explore = +5), 100 m from P1's origin (350, 150): pick-up (+11).
    _, _, _, _, info = env.step(np.array([[EAST]]))
    terms = dict(zip(uamfleet.REWARD_TERMS, info["reward_terms"][0, 0], strict=True))
    expected = {
        "step": -3,
        "explore": 5,
        "pickup": 11,
        "dropoff": 0,
        "blocked": 0,
        "shaping": 0,
        "separation": 0,
        "shield": 0,
        "hover": 0,
    }
    assert terms == pytest.approx(expected)  # one taxi: never closer than the separation minimum to another
    # West: back to the start block, visited twice now: explore = -0.7 * (2 - 1).
    _, _, _, _, info = env.step(np.array([[WEST]]))
    assert dict(zip(uamfleet.REWARD_TERMS, info["reward_terms"][0, 0], strict=True))["explore"] == pytest.approx(-0.7)


def test_separation_term_charges_each_taxi_that_ends_a_step_too_close_to_another():
    # Three taxis on a 7x7 map of 100 m blocks; taxis 0 and 1 start 200 m apart, taxi 2 far away. Taxi 0 flies
    # east and taxi 1 west: they meet (0 m) and both pay; then both fly north and stay together (0 m); taxi 2
    # hovers east / west and never pays. 60 m minimum, so 100 m apart is no violation.
    cfg = small_config(
        "\n".join(["......."] * 7), starts_m=((150.0, 150.0), (350.0, 150.0), (650.0, 650.0)),
        requests=(Request(0, (650.0, 150.0), (650.0, 350.0)),), reward=RewardConfig(separation=-19.0),
        min_separation_m=60.0,
    )  # fmt: skip
    env = VectorEnv(cfg)
    env.reset(seed=0)
    column = uamfleet.REWARD_TERMS.index("separation")
    for actions, expected in (
        ([[EAST, WEST, WEST]], [-19.0, -19.0, 0.0]),  # 0 and 1 both at (250, 150)
        ([[NORTH, NORTH, EAST]], [-19.0, -19.0, 0.0]),  # together at (250, 250)
        ([[NORTH, EAST, WEST]], [0.0, 0.0, 0.0]),  # (250, 350) and (350, 250): 141 m apart
    ):
        _, _, _, _, info = env.step(np.array(actions))
        assert info["reward_terms"][0, :, column].tolist() == expected
        assert env.state.pos_m[0, 2].tolist() in ([550.0, 650.0], [650.0, 650.0])


def test_every_term_has_a_weight_of_its_name_and_old_weight_names_still_work():
    assert all(hasattr(RewardConfig(), name) for name in uamfleet.REWARD_TERMS)
    old = RewardConfig(first_visit=2.0, repeat_visit=-0.3)
    assert (old.explore, old.explore_repeat) == (2.0, -0.3)
    with pytest.raises(ValueError, match="explore"):
        RewardConfig(explore=3.0, first_visit=2.0)


def test_layout_constants_match_the_spaces():
    env = uamfleet.vector_env("berlin_p4")
    assert env.single_action_space.n == NUM_HEADINGS
    assert env.single_observation_space["action_mask"].shape == (NUM_HEADINGS,)
    assert env.single_observation_space["passengers"].shape[-1] == len(PASSENGER_FEATURES)
    # indices come from the names: the three requests released at step 0 are waiting, age 0 at reset
    obs, _ = env.reset(seed=0)
    rows = obs["passengers"][0, 0]
    assert rows[:3, PAX_WAITING].tolist() == [1.0, 1.0, 1.0] and rows[:3, PAX_AGE].tolist() == [0.0, 0.0, 0.0]
    # P1's origin (2220, 1400) seen from the start (2600, 1500) on the 3260 m map
    assert rows[0, PAX_ORIGIN_DX] == pytest.approx((2220 - 2600) / 3260)


def test_time_limit_must_keep_step_counts_exact_in_float32():
    with pytest.raises(ValueError, match="time_limit_steps"):
        small_config(time_limit_steps=2**24)
