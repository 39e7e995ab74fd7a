"""Motion, masks, boarding, seats, releases and separation on small drawn maps, against hand computations."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

import uamfleet
from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.types import DELIVERED, HIDDEN, ON_BOARD, WAITING

WALL = """
.....
.....
.....
..#..
.....
"""  # the bad block is (bx, by) = (2, 1): x in [200, 300), y in [100, 200)

EAST, NORTH_EAST, NORTH, WEST, SOUTH = 0, 2, 4, 8, 12


def run(cfg, actions_seq, num_envs=1):
    env = VectorEnv(cfg, num_envs=num_envs)
    env.reset(seed=0)
    out = []
    for actions in actions_seq:
        out.append(env.step(np.asarray(actions).reshape(num_envs, cfg.num_taxis)))
    return env, out


def test_headings_move_one_step_length_counter_clockwise_from_east():
    for action, expected in [
        (EAST, (250, 150)),
        (NORTH, (150, 250)),
        (NORTH_EAST, (150 + 50 * 2**0.5, 150 + 50 * 2**0.5)),
        (1, (150 + 100 * np.cos(np.pi / 8), 150 + 100 * np.sin(np.pi / 8))),
    ]:
        env, _ = run(small_config(requests=(Request(0, (450.0, 450.0), (50.0, 450.0)),)), [[action]])
        np.testing.assert_allclose(env.state.pos_m[0, 0], expected, atol=1e-9)
        assert env.state.distance_m[0, 0] == pytest.approx(100.0)


def test_mask_marks_bad_block_and_map_edge():
    env = VectorEnv(small_config(WALL, starts_m=((150.0, 150.0),)))
    obs, _ = env.reset(seed=0)
    mask = obs["action_mask"][0, 0]
    assert mask.dtype == np.int8 and mask.shape == (16,)
    # East lands at (250, 150): the bad block. Every other heading lands inside the map on good blocks
    # except those whose endpoint falls in block (2, 1): heading 1 -> (242, 188) also in it; 15 -> (242, 112).
    expected_bad = {0, 1, 15}
    assert {k for k in range(16) if mask[k] == 0} == expected_bad
    env2 = VectorEnv(small_config(starts_m=((50.0, 50.0),), requests=(Request(0, (450.0, 450.0), (50.0, 450.0)),)))
    obs2, _ = env2.reset(seed=0)
    # From (50, 50): headings 0..4 stay inside; 5 lands at (11.7, 142.4) and 15 at (142.4, 11.7), still inside;
    # 6 reaches x = -20.7 and 14 y = -20.7, outside [0, 500]^2.
    assert [k for k in range(16) if obs2["action_mask"][0, 0, k]] == [0, 1, 2, 3, 4, 5, 15]


def test_blocked_action_stays_in_place_with_named_penalty():
    cfg = small_config(WALL)
    env, [(_, rew, _, _, info)] = run(cfg, [[EAST]])
    np.testing.assert_allclose(env.state.pos_m[0, 0], (150, 150))
    assert env.state.t[0] == 1 and env.state.distance_m[0, 0] == 0.0
    events = info["events"]
    assert events.blocked[0, 0] and not events.moved[0, 0]
    terms = dict(zip(uamfleet.REWARD_TERMS, info["reward_terms"][0, 0], strict=True))
    # step -2; same block visited a 2nd time: -0.1 * (2 - 1); blocked -50.
    assert terms == pytest.approx(
        {
            "step": -2,
            "explore": -0.1,
            "pickup": 0,
            "dropoff": 0,
            "blocked": -50,
            "shaping": 0,
            "separation": 0,
            "shield": 0,
            "hover": 0,
        }
    )
    assert rew[0, 0] == pytest.approx(-52.1)


def test_pickup_dropoff_reward_and_termination_by_hand():
    # P1 waits at (350, 150) and goes to (350, 350); the pick-up radius is one step (100 m).
    cfg = small_config()
    _, steps = run(cfg, [[EAST], [NORTH], [NORTH]])
    (_, r1, t1, _, i1), (_, r2, t2, _, i2), (_, r3, t3, tr3, i3) = steps
    # step 1: (250,150), new block (+1), 100 m from the origin -> pick-up (+200)
    assert i1["events"].picked_up[0, 0] and r1[0, 0] == pytest.approx(-2 + 1 + 200)
    # step 2: (250,250), new block; destination (350,350) is 141 m away: no drop-off
    assert not i2["events"].dropped_off[0, 0] and r2[0, 0] == pytest.approx(-2 + 1)
    # step 3: (250,350), 100 m from the destination -> drop-off (+300), all delivered -> terminated
    assert i3["events"].dropped_off[0, 0] and r3[0, 0] == pytest.approx(-2 + 1 + 300)
    assert not t1[0] and not t2[0] and t3[0] and not tr3[0]
    ep = i3["episode"]
    assert ep["length"][0] == 3 and ep["delivered"][0] == 1 and ep["return"][0, 0] == pytest.approx(497.0)
    assert ep["reward/pickup"][0, 0] == 200 and ep["reward/explore"][0, 0] == 3


def test_request_is_hidden_before_release_and_pickable_only_after_it_was_seen():
    # The taxi hovers next to the origin by flying east/west between (150,150) and (250,150); the request at
    # (250, 150) is released at step 2, so the earliest pick-up is at the end of step 3.
    cfg = small_config(requests=(Request(2, (250.0, 150.0), (450.0, 450.0)),))
    env = VectorEnv(cfg)
    obs, _ = env.reset(seed=0)
    assert obs["passenger_mask"][0, 0, 0] == 0 and not obs["passengers"][0, 0, 0].any()
    statuses, picks = [], []
    for action in [EAST, WEST, EAST, WEST]:
        obs, _, _, _, info = env.step(np.array([[action]]))
        statuses.append(int(env.state.pax_status[0, 0]))
        picks.append(bool(info["events"].picked_up[0, 0]))
        if env.state.t[0] == 2:
            assert obs["passenger_mask"][0, 0, 0] == 1 and obs["passengers"][0, 0, 0, 7] == 1  # waiting
    assert statuses == [HIDDEN, WAITING, ON_BOARD, ON_BOARD]
    assert picks == [False, False, True, False]
    assert env.state.pax_pickup_step[0, 0] == 3


def test_seats_limit_boarding_lowest_passenger_indices_first():
    reqs = tuple(Request(0, (250.0, 150.0), (450.0, 450.0)) for _ in range(3))
    env, [(_, rew, _, _, info)] = run(small_config(requests=reqs), [[EAST]])
    assert info["events"].picked_up[0].tolist() == [True, True, False]
    assert env.state.free_seats[0, 0] == 0 and rew[0, 0] == pytest.approx(-2 + 1 + 400)
    _, [(_, _, _, _, info1)] = run(small_config(requests=reqs, seats=1), [[EAST]])
    assert info1["events"].picked_up[0].tolist() == [True, False, False]


def test_fleet_tie_boards_lowest_taxi_and_full_taxi_passes_on():
    # Taxis 0 and 1 both reach (250, 250) +- 0; two passengers wait there; taxi 0 has one seat.
    reqs = (Request(0, (250.0, 250.0), (450.0, 450.0)), Request(0, (250.0, 250.0), (50.0, 450.0)))
    cfg = small_config(starts_m=((150.0, 250.0), (350.0, 250.0)), requests=reqs, seats=1)
    env, [(_, _, _, _, info)] = run(cfg, [[EAST, WEST]])
    assert env.state.pax_taxi[0].tolist() == [0, 1]
    assert info["events"].pickups[0].tolist() == [1, 1]
    # with two seats, taxi 0 takes both
    env2, _ = run(small_config(starts_m=((150.0, 250.0), (350.0, 250.0)), requests=reqs), [[EAST, WEST]])
    assert env2.state.pax_taxi[0].tolist() == [0, 0]


def test_dropoff_frees_seat_for_pickup_in_same_step():
    # P1 on board is delivered at (250,150) while P2 waits there; seats = 1.
    reqs = (Request(0, (150.0, 150.0), (250.0, 150.0)), Request(0, (250.0, 150.0), (450.0, 150.0)))
    cfg = small_config(requests=reqs, seats=1)
    env, [(_, _, _, _, i1), (_, _, _, _, i2)] = run(cfg, [[WEST], [EAST]])
    # step 1: west to (50,150): P1 (100 m away) boards; P2's origin is 200 m away
    assert i1["events"].picked_up[0].tolist() == [True, False]
    # step 2: back to (150,150): P1's destination (250,150) is 100 m away -> delivered, P2 then boards
    assert i2["events"].dropped_off[0].tolist() == [True, False]
    assert i2["events"].picked_up[0].tolist() == [False, True]
    assert env.state.pax_status[0].tolist() == [DELIVERED, ON_BOARD]


def test_truncation_at_time_limit_is_not_termination():
    cfg = small_config(time_limit_steps=2, requests=(Request(0, (450.0, 450.0), (50.0, 450.0)),))
    _, [(_, _, t1, tr1, _), (_, _, t2, tr2, info)] = run(cfg, [[EAST], [WEST]])
    assert not t1[0] and not tr1[0]
    assert not t2[0] and tr2[0] and info["_episode"][0]


def test_separation_events():
    cfg = small_config(starts_m=((150.0, 150.0), (350.0, 150.0)), min_separation_m=50.0)
    _, [(_, _, _, _, i1), (_, _, _, _, i2)] = run(cfg, [[EAST, WEST], [NORTH, NORTH]])
    # both taxis at (250,150) after step 1 (distance 0 < 50); still together after step 2
    assert i1["events"].separation_violation[0].tolist() == [True, True]
    assert i2["events"].separation_violation[0].tolist() == [True, True]
    _, [(_, _, _, _, i3)] = run(cfg, [[NORTH, NORTH]])
    assert i3["events"].separation_violation[0].tolist() == [False, False]


def test_segment_rule_blocks_crossing_a_bad_block_the_endpoint_rule_allows():
    # From (150, 250) heading east lands at (250, 250) (good) in both rules. With a bad block at (2, 2)... use
    # a 20 m raster instead: the bad strip lies between start and endpoint.
    from uamfleet.radio import RadioMap

    sinr = np.zeros((25, 25))
    sinr[10, :] = -10.0  # x = 10 + 20*10 = 210 m column of bad raster cells (origin 10 m)
    radio = RadioMap(sinr_db=sinr, resolution_m=20.0, origin_m=(10.0, 10.0), side_m=500.0, name="strip")
    base = dict(radio=radio, starts_m=((150.0, 250.0),), requests=(Request(0, (150.0, 450.0), (50.0, 450.0)),))
    # the block map at 100 m averages the bad column with 4 good ones: block mean -2 dB >= -3 -> flyable
    env_block = VectorEnv(small_config(**base, feasibility="endpoint_block"))
    env_seg = VectorEnv(small_config(**base, feasibility="segment_raster"))
    assert env_block.reset(seed=0)[0]["action_mask"][0, 0, EAST] == 1
    assert env_seg.reset(seed=0)[0]["action_mask"][0, 0, EAST] == 0
    assert env_seg.reset(seed=0)[0]["action_mask"][0, 0, WEST] == 1


def test_random_demand_is_seeded_and_feasible():
    from uamfleet.config import DemandConfig

    cfg = small_config(
        num_taxis=3,
        starts_m=None,
        requests=None,
        demand=DemandConfig(num_initial=2, rate_per_step=0.5, horizon_steps=10, max_requests=6, min_trip_m=200.0),
    )
    a, b = VectorEnv(cfg, num_envs=4), VectorEnv(cfg, num_envs=4)
    a.reset(seed=3)
    b.reset(seed=3)
    np.testing.assert_array_equal(a.state.pax_origin_m, b.state.pax_origin_m)
    np.testing.assert_array_equal(a.state.pos_m, b.state.pos_m)
    assert not np.array_equal(a.state.pax_origin_m[0], a.state.pax_origin_m[1])  # envs differ
    s = a.state
    for e in range(4):
        n = int(s.pax_exists[e].sum())
        assert 2 <= n <= 6
        assert np.all(s.pax_release[e, :2] == 0) and np.all(np.diff(s.pax_release[e, :n]) >= 0)
        trips = np.linalg.norm(s.pax_dest_m[e, :n] - s.pax_origin_m[e, :n], axis=-1)
        assert np.all(trips >= 200.0)
    assert a.world.point_feasible(s.pos_m).all()
