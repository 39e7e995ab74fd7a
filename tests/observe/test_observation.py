"""Observation contents against hand computations on drawn maps."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

from uamfleet.config import Request
from uamfleet.observe.observer import PASSENGER_FEATURES
from uamfleet.env.vector_env import VectorEnv
from uamfleet.sim.world import PATCH_PAD_DB

WALL = """
.....
.....
.....
..#..
.....
"""


def test_observations_lie_in_their_spaces_with_their_dtypes():
    env = VectorEnv(small_config(WALL, num_taxis=2, starts_m=((150.0, 150.0), (350.0, 350.0))), num_envs=3)
    obs, _ = env.reset(seed=1)
    for _ in range(5):
        for e in range(3):
            for a in range(2):
                single = {k: v[e, a] for k, v in obs.items()}
                assert env.single_observation_space.contains(single), {k: v.dtype for k, v in single.items()}
        actions = np.array([[np.flatnonzero(obs["action_mask"][e, a])[0] for a in range(2)] for e in range(3)])
        obs, *_ = env.step(actions)


def test_sinr_patch_is_block_sinr_minus_threshold_centred_on_the_taxi():
    env = VectorEnv(small_config(WALL, patch_size=4))
    obs, _ = env.reset(seed=0)
    patch = obs["sinr_patch"][0, 0]
    # taxi block (1, 1); a 4x4 patch covers blocks -1..2 in x and y (index [i, j] = block (i-1, j-1)).
    expected = np.full((4, 4), 3.0, np.float32)  # 0 dB - (-3 dB)
    expected[0, :] = PATCH_PAD_DB  # x = -1: outside the map
    expected[:, 0] = PATCH_PAD_DB  # y = -1
    expected[3, 2] = -10.0 + 3.0  # block (2, 1) is the bad one
    np.testing.assert_array_equal(patch, expected)


def test_visit_patch_is_visit_ratio_of_this_taxi():
    env = VectorEnv(small_config(patch_size=4, requests=(Request(0, (450.0, 450.0), (50.0, 450.0)),)))
    env.reset(seed=0)
    for action in (0, 8, 0):  # (150,150) -> (250,150) -> (150,150) -> (250,150)
        obs, *_ = env.step(np.array([[action]]))
    visit = obs["visit_patch"][0, 0]
    # now at block (2,1); patch index [i, j] = block (i+1-... ) -> block (bx - 2 + i, by - 2 + j)
    # block (1,1) visited twice (start + step 2), block (2,1) twice (steps 1, 3): ratio 2 / 3 steps.
    assert visit[1, 2] == pytest.approx(2 / 3)  # block (1, 1)
    assert visit[2, 2] == pytest.approx(2 / 3)  # block (2, 1)
    assert visit.sum() == pytest.approx(4 / 3)


def test_passenger_table_relative_to_each_taxi():
    reqs = (Request(0, (350.0, 150.0), (350.0, 350.0)), Request(9, (50.0, 50.0), (450.0, 50.0)))
    env = VectorEnv(small_config(requests=reqs, num_taxis=2, starts_m=((150.0, 150.0), (250.0, 450.0))))
    obs, _ = env.reset(seed=0)
    table, mask = obs["passengers"][0], obs["passenger_mask"][0]
    f = {name: i for i, name in enumerate(PASSENGER_FEATURES)}
    side = 500.0
    assert mask.tolist() == [[1, 0], [1, 0]]
    assert table[0, 0, f["origin_dx"]] == pytest.approx(200 / side)
    assert table[1, 0, f["origin_dx"]] == pytest.approx(100 / side)
    assert table[1, 0, f["origin_dy"]] == pytest.approx(-300 / side)
    assert table[0, 0, f["dist_to_dest"]] == pytest.approx(np.hypot(200, 200) / side)
    assert table[0, 0, f["trip_length"]] == pytest.approx(200 / side)
    assert table[0, 0, f["waiting"]] == 1
    assert not table[:, 1].any()  # the unreleased request shows nothing at all
    obs, *_ = env.step(np.array([[0, 12]]))  # taxi 0 picks P1 up
    table = obs["passengers"][0]
    assert table[0, 0, f["on_board_self"]] == 1 and table[1, 0, f["on_board_other"]] == 1
    assert table[0, 0, f["waiting"]] == 0


def test_history_is_reset_between_episodes_and_tracks_moves():
    env = VectorEnv(
        small_config(history_len=3, time_limit_steps=2, requests=(Request(0, (450.0, 450.0), (50.0, 450.0)),))
    )
    env.reset(seed=0)
    obs, *_ = env.step(np.array([[0]]))  # to (250, 150)
    hist = obs["history"][0, 0]
    np.testing.assert_allclose(hist[:, :2], [[-0.2, 0.0], [-0.2, 0.0], [-0.2, 0.0]])
    obs, _, _, trunc, info = env.step(np.array([[4]]))  # to (250, 250); episode truncates and autoresets
    assert trunc[0]
    np.testing.assert_allclose(info["final_obs"]["history"][0, 0, :, :2], [[0.0, -0.2], [-0.2, -0.2], [-0.2, -0.2]])
    np.testing.assert_allclose(obs["history"][0, 0], [[0, 0, 1], [0, 0, 1], [0, 0, 1]])  # fresh episode


def test_others_and_global_state():
    env = VectorEnv(small_config(num_taxis=2, starts_m=((150.0, 150.0), (250.0, 450.0))))
    obs, _ = env.reset(seed=0)
    np.testing.assert_allclose(obs["others"][0, 0, 0], [0.2, 0.6, 1.0])
    np.testing.assert_allclose(obs["others"][0, 1, 0], [-0.2, -0.6, 1.0])
    assert obs["others_mask"][0].tolist() == [[1], [1]]
    state = env.global_state()
    assert state.shape == (1, env.state_space.shape[0]) and state.dtype == np.float32
    np.testing.assert_allclose(state[0, :4], [0.3, 0.3, 1.0, 0.0])
    single = VectorEnv(small_config()).reset(seed=0)[0]
    assert single["others_mask"][0, 0].tolist() == [0]
