"""Shaping and stuck-truncation recomputed by hand; the paper presets against the paper's scenario table
(as its authors coded it)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import small_config

import uamfleet
from uamfleet.config import DemandConfig, Request, RewardConfig
from uamfleet.env.vector_env import VectorEnv

EAST, NORTH, WEST = 0, 4, 8
SHAPING = uamfleet.REWARD_TERMS.index("shaping")


def test_potential_based_shaping_by_hand():
    # Phi = -(distance to the nearest actionable stop) / step_m; F = w * (gamma * Phi(s') - Phi(s)), Phi(end) = 0.
    cfg = small_config(reward=RewardConfig(shaping=2.0, shaping_gamma=0.9))
    env = VectorEnv(cfg)
    env.reset(seed=0)
    # s0: taxi (150,150), P1 waits at (350,150): Phi0 = -2. East: (250,150), P1 boards; its destination
    # (350,350) is sqrt(100^2 + 200^2) away: Phi1 = -2.2360...
    _, _, _, _, info = env.step(np.array([[EAST]]))
    phi0, phi1 = -2.0, -math.hypot(100, 200) / 100
    assert info["reward_terms"][0, 0, SHAPING] == pytest.approx(2.0 * (0.9 * phi1 - phi0))
    # North: (250,250), destination sqrt(100^2+100^2) away.
    _, _, _, _, info = env.step(np.array([[NORTH]]))
    phi2 = -math.hypot(100, 100) / 100
    assert info["reward_terms"][0, 0, SHAPING] == pytest.approx(2.0 * (0.9 * phi2 - phi1))
    # North: (250,350), delivered, terminated: Phi of the terminal state is 0.
    _, _, term, _, info = env.step(np.array([[NORTH]]))
    assert term[0]
    assert info["reward_terms"][0, 0, SHAPING] == pytest.approx(2.0 * (0.0 - phi2))


def test_shaping_off_by_default():
    env = VectorEnv(small_config())
    env.reset(seed=0)
    _, _, _, _, info = env.step(np.array([[EAST]]))
    assert info["reward_terms"][0, 0, SHAPING] == 0.0


def test_truncation_when_a_block_is_visited_too_often():
    cfg = small_config(max_block_visits=2, requests=(Request(0, (450.0, 450.0), (50.0, 450.0)),))
    env = VectorEnv(cfg)
    env.reset(seed=0)
    truncs = [bool(env.step(np.array([[a]]))[3][0]) for a in (EAST, WEST, EAST, WEST)]
    # visits of the start block (1,1): 1 at reset, 2 after step 2, 3 after step 4 -> truncated at step 4
    assert truncs == [False, False, False, True]


def test_berlin_p4_is_the_papers_instance():
    cfg = uamfleet.make_config("berlin_p4")
    assert cfg.radio.name == "berlin" and cfg.side_m == 3260.0
    assert cfg.starts_m == ((2600.0, 1500.0),) and cfg.num_taxis == 1 and cfg.seats == 2
    assert (cfg.step_m, cfg.slot_s, cfg.radius_m, cfg.block_size_m) == (100.0, 3.0, 100.0, 100.0)
    assert (cfg.patch_size, cfg.history_len, cfg.sinr_min_db) == (10, 3, -3.0)
    assert [(r.release_step, r.origin_m, r.destination_m) for r in cfg.requests] == [
        (0, (2220.0, 1400.0), (1850.0, 1100.0)),
        (0, (1450.0, 2000.0), (1270.0, 450.0)),
        (0, (650.0, 1000.0), (1700.0, 620.0)),
        (5, (1010.0, 2220.0), (400.0, 1200.0)),
    ]
    assert cfg.reward == RewardConfig(step=-2, first_visit=1, repeat_visit=-0.1, pickup=200, dropoff=300, blocked=-50)


def test_detroit_p5_is_the_papers_instance_on_the_estimate():
    cfg = uamfleet.make_config("detroit_p5")
    assert cfg.radio.is_estimate and "(estimate)" in cfg.radio.label and cfg.side_m == 11130.0
    assert cfg.starts_m == ((6290.0, 9450.0),) and cfg.step_m == 320.0 and cfg.sinr_min_db == -17.0
    assert [r.release_step for r in cfg.requests] == [0, 0, 5, 8, 15]
    assert cfg.requests[4].origin_m == (3781.0, 3438.0) and cfg.requests[4].destination_m == (7830.0, 2430.0)
    assert cfg.slot_s == pytest.approx(9.6, abs=0.05)  # 320 m at 120 km/h


def test_paper_instance_as_a_fleet_shares_the_start():
    cfg = uamfleet.make_config("berlin_p4", num_taxis=3)
    assert cfg.starts_m == ((2600.0, 1500.0),) * 3


def test_random_demand_on_vertiports():
    ports = ((450.0, 450.0), (50.0, 450.0), (450.0, 50.0))
    demand = DemandConfig(num_initial=3, rate_per_step=0.0, max_requests=3, min_trip_m=100.0, vertiports=ports)
    env = VectorEnv(small_config(requests=None, demand=demand), num_envs=5)
    env.reset(seed=4)
    stops = np.concatenate([env.state.pax_origin_m.reshape(-1, 2), env.state.pax_dest_m.reshape(-1, 2)])
    assert {tuple(p) for p in stops.tolist()} <= set(ports)
    assert np.all(np.any(env.state.pax_origin_m != env.state.pax_dest_m, axis=-1))
    assert np.all(env.state.pax_release == 0)


@pytest.mark.parametrize(("scenario", "thresholds"), [("berlin_p4", (-7, -6, -5, -4, -3)), ("detroit_p5", (-17,)),
                                                      ("detroit3gpp_p5", (-21, -20, -19, -18, -17))])  # fmt: skip
def test_paper_scenarios_build_at_the_papers_thresholds(scenario, thresholds):
    for threshold in thresholds:
        env = uamfleet.parallel_env(scenario, sinr_min_db=float(threshold))
        obs, _ = env.reset(seed=0)
        assert obs["uam_0"]["action_mask"].any()
        assert obs["uam_0"]["passenger_mask"].tolist()[:2] == [1, 1]


GAP_EAST = """
.....
.....
####.
.....
.....
"""  # a wall along y in [200, 300) with a gap at x in [400, 500)


@pytest.mark.parametrize(("metric", "steps"), [("euclidean", 2.0), ("path", 10.0), ("path_exact", 10.0)])
def test_path_potential_goes_round_the_wall(metric, steps):
    base = dict(starts_m=((50.0, 150.0),), requests=(Request(0, (50.0, 350.0), (450.0, 450.0)),))
    env = VectorEnv(small_config(GAP_EAST, reward=RewardConfig(shaping=1.0, shaping_metric=metric), **base))
    env.reset(seed=0)
    # straight line: 200 m = 2 steps. Along feasible cells (no corner cutting): east 400 m to x = 450, north 200 m
    # through the gap, west 400 m back to x = 50: 1000 m = 10 steps.
    assert env.potential is not None
    assert env.potential(env.state)[0, 0] == pytest.approx(-steps)


def test_unknown_shaping_metric():
    with pytest.raises(ValueError, match=r"shaping_metric='manhattan' is unknown"):
        RewardConfig(shaping_metric="manhattan")


def test_reward_weights_can_change_between_steps_but_not_the_shaping_metric():
    env = VectorEnv(small_config(reward=RewardConfig(shaping=2.0)))
    env.reset(seed=0)
    env.set_reward_weights(RewardConfig(shaping=1.0, step=-5.0))
    _, _, _, _, info = env.step(np.array([[EAST]]))
    assert info["reward_terms"][0, 0, 0] == -5.0
    with pytest.raises(ValueError, match="shaping on/off and shaping_metric are fixed"):
        env.set_reward_weights(RewardConfig(shaping=1.0, shaping_metric="euclidean"))
    with pytest.raises(ValueError, match="shaping on/off"):
        env.set_reward_weights(RewardConfig(shaping=0.0))
