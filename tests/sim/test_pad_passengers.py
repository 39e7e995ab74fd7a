"""A state on a longer passenger axis (``sim.generator.pad_passengers``): what the hedge samples its futures into, so
that it flies a world as made, whatever its passenger rows."""

from __future__ import annotations

import numpy as np
import pytest

import uamfleet
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_instance
from uamfleet.policies import make
from uamfleet.sim.generator import pad_passengers
from uamfleet.types import FleetState


def _state_after(cfg: uamfleet.EnvConfig, steps: int) -> FleetState:
    env = VectorEnv(cfg.replace(stop_features=True), num_envs=2, autoreset=False)
    env.reset(seed=0)
    for _ in range(steps):
        env.step(np.zeros((2, 1), np.int64))
    return env.state


def test_padded_rows_are_empty_and_the_known_rows_and_taxis_are_copied() -> None:
    state = _state_after(make_instance("berlin", 3), 5)
    P = state.pax_exists.shape[1]
    padded = pad_passengers(state, P + 3)
    assert padded.pax_exists.shape == (2, P + 3) and not padded.pax_exists[:, P:].any()
    for name in ("pax_exists", "pax_release", "pax_origin_m", "pax_dest_m", "pax_status", "pax_taxi"):
        np.testing.assert_array_equal(getattr(padded, name)[:, :P], getattr(state, name), err_msg=name)
    assert (padded.pax_taxi[:, P:] == -1).all() and (padded.pax_pickup_step[:, P:] == -1).all()
    assert (padded.pax_status[:, P:] == 0).all() and (padded.pax_release[:, P:] == 0).all()
    assert padded.stop_pair_m.shape == (2, 2 * P + 6, 2 * P + 6)
    np.testing.assert_array_equal(padded.stop_pair_m[:, : 2 * P, : 2 * P], state.stop_pair_m)
    assert np.isnan(padded.stop_pair_m[:, 2 * P :]).all() and np.isnan(padded.stop_pair_m[:, :, 2 * P :]).all()
    assert (padded.stop_tour_key == -1).all() and padded.stop_tour_m.shape[2] == 2 * P + 6  # tours recomputed
    for name in ("t", "pos_m", "free_seats", "history_m", "visits", "distance_m", "action_mask"):
        np.testing.assert_array_equal(getattr(padded, name), getattr(state, name), err_msg=name)
    padded.pos_m[:] = 0.0
    assert state.pos_m.any(), "a copy: the state is untouched"
    with pytest.raises(ValueError, match=f"rows={P - 1} is fewer than the state's {P} passenger rows"):
        pad_passengers(state, P - 1)


def test_the_hedge_flies_a_world_as_made_as_it_flew_one_sized_to_its_demand_model() -> None:
    """Berlin test instance 2000000 has 4 requests; the family's demand model samples up to 6. The hedge pads its
    own futures: flown on the instance as made it takes the moves it takes on the instance sized to 6 rows."""
    cfg = make_instance("berlin", 2_000_000)
    assert cfg.num_passengers == 4
    flights = []
    for world in (cfg, cfg.replace(max_passengers=6)):
        hedge = make("hedge", futures=2, first_headings=2, samples=0, top_k=1, tail=10)
        flights.append(uamfleet.rollout.fly(world, hedge, seed=0).stacked("actions"))
    np.testing.assert_array_equal(flights[0], flights[1])
    assert len(flights[0]) > 20
