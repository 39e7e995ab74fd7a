"""Metrics on hand-built trajectories (events written by hand, no simulator involved)."""

from __future__ import annotations


import numpy as np
import pytest

from uamfleet.metrics import episode_metrics, path_samples
from uamfleet.radio import RadioMap
from uamfleet.rollout import Trajectory
from uamfleet.types import StepEvents


def make_events(positions, picked, dropped, pax_taxi, num_pax, separation=None):
    """StepEvents for one env from per-step taxi positions [T+1][A] and {step: [passengers]} pick/drop dicts."""
    positions = np.asarray(positions, float)  # [T + 1, A, 2]
    num_steps, num_taxis = positions.shape[0] - 1, positions.shape[1]
    events = []
    for t in range(1, num_steps + 1):
        moved = np.linalg.norm(positions[t] - positions[t - 1], axis=-1) > 0
        p_up = np.zeros(num_pax, bool)
        p_up[picked.get(t, [])] = True
        d_off = np.zeros(num_pax, bool)
        d_off[dropped.get(t, [])] = True
        pickups = np.array([sum(1 for p in picked.get(t, []) if pax_taxi[p] == a) for a in range(num_taxis)])
        dropoffs = np.array([sum(1 for p in dropped.get(t, []) if pax_taxi[p] == a) for a in range(num_taxis)])
        sep = np.zeros(num_taxis, bool) if separation is None else np.asarray(separation[t - 1])
        events.append(
            StepEvents(
                prev_pos_m=positions[t - 1][None],
                pos_m=positions[t][None],
                actions=np.zeros((1, num_taxis), int),
                moved=moved[None],
                blocked=~moved[None],
                first_visit=np.zeros((1, num_taxis), bool),
                block_visits=np.ones((1, num_taxis), np.int32),
                picked_up=p_up[None],
                dropped_off=d_off[None],
                released=np.zeros((1, num_pax), bool),
                pickups=pickups[None],
                dropoffs=dropoffs[None],
                separation_violation=sep[None],
                segment_min_sinr_db=np.zeros((1, num_taxis)),
                all_delivered=np.array([False]),
                t=np.array([t]),
                heading_flown=np.where(moved, 0, -1)[None],
                shield_intervened=np.zeros((1, num_taxis), bool),
                hovered=np.zeros((1, num_taxis), bool),
            )
        )
    return events


def trajectory(positions, picked, dropped, pax_taxi, release, origins, dests, separation=None, slot_s=3.0):
    num_pax = len(release)
    return Trajectory(
        scenario="hand",
        radio_name="hand",
        sinr_min_db=-3.0,
        step_m=100.0,
        slot_s=slot_s,
        seats=2,
        start_pos_m=np.asarray(positions[0], float),
        pax_exists=np.ones(num_pax, bool),
        release_step=np.asarray(release),
        origin_m=np.asarray(origins, float),
        destination_m=np.asarray(dests, float),
        events=make_events(positions, picked, dropped, pax_taxi, num_pax, separation),
        decision_s=[0.001] * (len(positions) - 1),
    )


def flat_map(value_db=0.0, bad_x_range=None):
    """10 m raster over [0, 1000]^2 at ``value_db``; cells with x in bad_x_range at -10 dB."""
    sinr = np.full((101, 101), value_db)
    if bad_x_range is not None:
        xs = np.arange(101) * 10.0
        sinr[(xs >= bad_x_range[0]) & (xs <= bad_x_range[1])] = -10.0
    return RadioMap(sinr_db=sinr, resolution_m=10.0, side_m=1000.0)


def test_single_taxi_td_att_awt_elr_pr_by_hand():
    # One taxi flies east along y = 0 from x = 0, 100 m per step, for 6 steps (slot 3 s).
    # P0 requested at step 0, picked up at step 2, dropped at step 4; P1 requested at step 1, picked at 3, dropped
    # at 6. A seventh step after the last drop-off must not count.
    positions = [[[100.0 * t, 0.0]] for t in range(8)]
    traj = trajectory(positions, {2: [0], 3: [1]}, {4: [0], 6: [1]}, {0: 0, 1: 0}, release=[0, 1],
                      origins=[[200, 0], [300, 0]], dests=[[400, 0], [600, 0]])  # fmt: skip
    m = episode_metrics(traj, flat_map())
    assert m.td_m == 600.0  # 6 steps until the last drop-off
    assert m.completion_s == 18.0
    assert m.att_s == pytest.approx(((4 - 0) + (6 - 1)) / 2 * 3.0)
    assert m.awt_s == pytest.approx(((2 - 0) + (3 - 1)) / 2 * 3.0)
    # on board during steps 1..6: 0, 0, 1, 2, 1, 1 (a pick-up counts from the next step on) -> 2 of 6 empty
    assert m.elr_pct == pytest.approx(100 * 2 / 6)
    assert m.occupancy == pytest.approx((0 + 0 + 1 + 2 + 1 + 1) / 6 / 2)
    assert m.pr_pct == 100.0 and m.delivered == 2
    assert m.connectivity_pct == 100.0 and m.min_sinr_db == 0.0
    # detour: in-vehicle (4-2)*3 = 6 s over direct 200 m / (100 m / 3 s) = 6 s -> 1; P1: 9 s / 9 s -> 1
    assert m.detour_ratio == pytest.approx(1.0)
    assert m.wait_p50_s == pytest.approx(6.0) and m.decision_ms_mean == pytest.approx(1.0)


def test_undelivered_passenger_lowers_pr_and_spans_the_whole_episode():
    positions = [[[100.0 * t, 0.0]] for t in range(5)]
    traj = trajectory(positions, {1: [0]}, {2: [0]}, {0: 0, 1: 0}, release=[0, 0],
                      origins=[[100, 0], [900, 900]], dests=[[200, 0], [0, 900]])  # fmt: skip
    m = episode_metrics(traj, flat_map())
    assert m.pr_pct == 50.0 and m.td_m == 400.0 and m.att_s == pytest.approx(6.0)
    assert m.detour_ratio == pytest.approx(1.0)  # P0: 1 step in the taxi for a 100 m trip


def test_connectivity_counts_samples_every_10_m_with_nc_as_outage():
    # Path x: 0 -> 500 along y = 500. Cells with x in [200, 240] are at -10 dB: 5 of the 51 samples.
    positions = [[[100.0 * t, 500.0]] for t in range(6)]
    radio = flat_map(bad_x_range=(200, 240))
    traj = trajectory(positions, {}, {}, {}, release=[], origins=np.zeros((0, 2)), dests=np.zeros((0, 2)))
    m = episode_metrics(traj, radio)
    assert len(path_samples(np.array([p[0] for p in positions]), 10.0)) == 51
    assert m.connectivity_pct == pytest.approx(100 * 46 / 51)
    assert m.min_sinr_db == -10.0
    # A not-computed cell is an outage too.
    sinr = radio.sinr_db.copy()
    sinr[45, 50] = np.nan  # x = 450, y = 500
    m2 = episode_metrics(traj, RadioMap(sinr_db=sinr, resolution_m=10.0, side_m=1000.0))
    assert m2.connectivity_pct == pytest.approx(100 * 45 / 51) and m2.min_sinr_db == -np.inf


def test_fleet_metrics_wait_percentiles_and_separation():
    # Two taxis; taxi 0 serves P0 (wait 1 step), taxi 1 serves P1 (wait 3 steps); they are too close at step 1.
    positions = [[[0, 0], [0, 50]], [[100, 0], [100, 30]], [[200, 0], [200, 300]], [[300, 0], [300, 300]],
                 [[400, 0], [400, 300]]]  # fmt: skip
    traj = trajectory(positions, {1: [0], 3: [1]}, {3: [0], 4: [1]}, {0: 0, 1: 1}, release=[0, 0],
                      origins=[[100, 0], [300, 300]], dests=[[300, 0], [400, 300]],
                      separation=[[True, True], [False, False], [False, False], [False, False]])  # fmt: skip
    m = episode_metrics(traj, flat_map())
    assert m.td_m == 800.0  # both taxis, 4 steps each
    assert m.wait_p50_s == pytest.approx((1 + 3) / 2 * 3.0)
    assert m.wait_p95_s == pytest.approx((1 + 0.95 * 2) * 3.0)
    assert m.separation_violations == 2
    # taxi 0 on board steps 2..3, taxi 1 step 4: 3 of 8 taxi-steps occupied
    assert m.elr_pct == pytest.approx(100 * 5 / 8)
