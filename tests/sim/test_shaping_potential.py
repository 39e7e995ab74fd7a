"""The shaping potential's kernel against the numpy reference, and unreachable stops by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import small_config

import uamfleet
from uamfleet.config import DemandConfig, Request, RewardConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.paths import table_for
from uamfleet.sim import reward

WALLED = """
.....
.....
#####
.....
.....
"""  # a full wall y in [200, 300): two components

HOLES = """
......
.#....
.#..#.
....#.
.##...
......
"""


def _random_states(env: VectorEnv, steps: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    for _ in range(steps):
        mask = obs["action_mask"]
        obs, *_ = env.step(np.argmax(rng.random(mask.shape) * np.where(mask.any(-1, keepdims=True), mask, 1), -1))
        yield env.state


@pytest.mark.parametrize("metric", ["euclidean", "path"])
def test_kernel_equals_the_reference_on_random_states(metric):
    demand = DemandConfig(num_initial=3, rate_per_step=0.3, horizon_steps=20, max_requests=6, min_trip_m=100.0)
    cfg = small_config(HOLES, starts_m=None, requests=None, num_taxis=3, demand=demand, time_limit_steps=25,
                       reward=RewardConfig(shaping=1.0, shaping_metric=metric))  # fmt: skip
    env = VectorEnv(cfg, num_envs=6)
    potential = env.potential
    assert potential is not None
    if metric == "euclidean":
        distance_to = reward.euclidean
    else:
        table = table_for(env.world)
        distance_to = lambda goal, points: table.distance(points, goal)  # noqa: E731
    seen_nonzero = 0
    for state in _random_states(env, 60):
        phi = potential(state)
        # the same function of the same distances: bit for bit
        np.testing.assert_array_equal(phi, reward.potential_reference(state, 100.0, distance_to))
        seen_nonzero += int(np.count_nonzero(phi))
    assert seen_nonzero > 100


def test_path_table_is_close_to_path_exact_on_berlin():
    env = uamfleet.vector_env("berlin_p4", num_envs=4, reward=RewardConfig(shaping=1.0, shaping_metric="path"))
    exact = reward.Potential(env.world, "path_exact")
    assert env.potential is not None
    diffs = [env.potential(s) - exact(s) for s in _random_states(env, 40)]
    # the lookup's error on Berlin (tests/paths/test_distance_table.py): well under a step
    assert np.abs(diffs).max() <= 0.8


@pytest.mark.parametrize("metric", ["path", "path_exact"])
def test_unreachable_stops_do_not_attract(metric):
    # Taxi 0 below the wall, taxi 1 above it; request A waits above (200 m straight from taxi 0), B below.
    # Taxi 0 ignores A (no feasible path) and heads for B; taxi 1 ignores B. 16-connected lattice (100 m cells):
    # (50, 150) -> (450, 50) is a knight move (2, -1) and two east: (2 + sqrt 5) cells; so is (450, 450) -> (50, 350).
    cfg = small_config(WALLED, starts_m=((50.0, 150.0), (450.0, 450.0)),
                       requests=(Request(0, (50.0, 350.0), (150.0, 450.0)), Request(0, (450.0, 50.0), (150.0, 50.0))),
                       reward=RewardConfig(shaping=1.0, shaping_metric=metric))  # fmt: skip
    env = VectorEnv(cfg)
    env.reset(seed=0)
    assert env.potential is not None
    np.testing.assert_allclose(env.potential(env.state), [[-(2 + math.sqrt(5))] * 2], rtol=1e-6)
    # Only the unreachable stop left: potential 0, as for a taxi with nothing to do.
    env.state.pax_status[0, 1] = uamfleet.types.DELIVERED
    np.testing.assert_allclose(env.potential(env.state), [[0.0, -(2 + math.sqrt(5))]], rtol=1e-6)
