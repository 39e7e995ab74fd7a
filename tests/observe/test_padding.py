"""An observer that reads more passenger rows than its world has pads them (masked, zero), so a policy flies a
world of fewer requests without the world being resized: every field it reads is byte for byte what a world
sized to the policy gives (plan risk 2, ``reports/2026-12-03-one-shape-plan/README.md`` section 7)."""

from __future__ import annotations

import numpy as np

import uamfleet
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance
from uamfleet.observe.spec import ObserverSpec


def test_berlin_on_a_four_request_instance_reads_the_same_padded_as_in_a_world_of_six_rows() -> None:
    policy = uamfleet.pretrained("berlin")
    spec = policy.spec
    assert isinstance(spec, ObserverSpec) and spec.slots_per_taxi == 6.0  # it reads 6 rows (stops, look-ahead)
    sized = uamfleet.make_config("berlin_p4", max_passengers=6, time_limit_steps=600)
    own = uamfleet.make_config("berlin_p4", time_limit_steps=600)
    assert (sized.num_passengers, own.num_passengers) == (6, 4)
    big, small = VectorEnv(sized, observer=spec, autoreset=False), VectorEnv(own, observer=spec, autoreset=False)
    assert small.single_observation_space == big.single_observation_space
    obs_big, _ = big.reset(seed=0)
    obs_small, _ = small.reset(seed=0)
    policy.reset(big.sim)
    steps = 0
    while True:
        assert sorted(obs_small) == sorted(obs_big)
        for name in obs_big:
            assert obs_small[name].dtype == obs_big[name].dtype, name
            assert obs_small[name].tobytes() == obs_big[name].tobytes(), f"{name} differs at step {steps}"
        assert not obs_small["passenger_mask"][..., 4:].any() and not obs_small["passengers"][..., 4:, :].any()
        actions = policy.act(obs_big)
        obs_big, r_big, term_big, trunc_big, _ = big.step(actions)
        obs_small, r_small, term_small, trunc_small, _ = small.step(actions)
        np.testing.assert_array_equal(r_small, r_big)
        steps += 1
        if term_big[0] or trunc_big[0]:
            assert (term_small[0], trunc_small[0]) == (term_big[0], trunc_big[0])
            break
    assert steps > 10 and bool(big.state.pax_exists[0].sum()) and int(big.state.pax_exists[0].sum()) == 4


def test_a_fleet_policy_reads_rivals_and_claims_padded_as_in_a_world_of_its_rows() -> None:
    policy = uamfleet.pretrained("berlin_fleet_v1")  # 6 rows per taxi: 12 at 2 taxis; stop rivals and claims
    own = make_fleet_instance("berlin", 5, num_taxis=2, num_requests=8)
    sized = make_fleet_instance("berlin", 5, num_taxis=2, num_requests=8, max_passengers=12)
    big = VectorEnv(sized, observer=policy.spec, autoreset=False)
    small = VectorEnv(own, observer=policy.spec, autoreset=False)
    assert (sized.num_passengers, own.num_passengers) == (12, 8)
    assert "stop_claims" in small.single_observation_space.spaces
    obs_big, _ = big.reset(seed=0)
    obs_small, _ = small.reset(seed=0)
    policy.reset(big.sim)
    for step in range(40):
        for name in obs_big:
            assert obs_small[name].tobytes() == obs_big[name].tobytes(), f"{name} differs at step {step}"
        actions = policy.act(obs_big)
        obs_big, *_ = big.step(actions)
        obs_small, *_ = small.step(actions)
