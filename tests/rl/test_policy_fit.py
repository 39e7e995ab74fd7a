"""A learned policy fits itself to the world it is reset in, never the world to itself: it reads the world with its
observer spec (a world built with ``observer=policy.spec``), refuses in one line a world its spec cannot read, and
flies another fleet size with the rows its spec reads there and its normaliser's set statistics pooled, exactly as
a policy built by hand for that fleet's shapes (the same weights, the statistics resized) flies a world sized to it."""

from __future__ import annotations

import copy

import numpy as np
import pytest

import uamfleet
from uamfleet.checks import ConfigError
from uamfleet.config import EnvConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance
from uamfleet.metrics import episode_metrics
from uamfleet.observe.legacy import observed_config
from uamfleet.observe.spec import ObserverSpec
from uamfleet.rl.policy import GreedyPolicy


def _built_for(policy: GreedyPolicy, cfg: EnvConfig) -> GreedyPolicy:
    """``policy``'s weights built by hand for the observation shapes of ``cfg`` (its own observer): no spec, so it
    acts with these shapes and statistics whatever it is reset in."""
    shapes = {k: tuple(v.shape or ()) for k, v in VectorEnv(cfg).single_observation_space.spaces.items()}
    shapes = {k: v for k, v in shapes.items() if k in (policy.obs_shapes or {})}
    net = copy.copy(policy.net)
    net.shapes = shapes
    normalizer = policy.normalizer.resized(shapes) if policy.normalizer is not None else None
    return GreedyPolicy(net, normalizer, policy.device, shapes, cfg.num_taxis, cfg.num_passengers, cfg)


def _actions(env: VectorEnv, policy, steps: int) -> list[np.ndarray]:  # type: ignore[no-untyped-def]
    obs, _ = env.reset(seed=0)
    policy.reset(env.sim)
    flown = []
    for _ in range(steps):
        actions = policy.act(obs)
        flown.append(actions)
        obs, _, terminated, truncated, _ = env.step(actions)
        if terminated[0] or truncated[0]:
            break
    return flown


@pytest.mark.parametrize("requests", [12, 8])  # 8: the observer pads to the 12 rows the spec reads at 2 taxis
def test_a_fleet_policy_reset_in_a_smaller_fleet_flies_as_the_policy_resized_for_it(requests: int) -> None:
    policy = uamfleet.pretrained("berlin_fleet_v1")  # 4 taxis, 24 rows (6 per taxi), no window
    instance = make_fleet_instance("berlin", 3, num_taxis=2, num_requests=requests, hover_action=False)
    assert policy.spec is not None
    sized = observed_config(instance.replace(max_passengers=12).world, policy.spec)[0]  # a world of 12 rows
    resized = _built_for(policy, sized)
    old = VectorEnv(sized, autoreset=False)
    new = VectorEnv(instance, observer=policy.spec, autoreset=False)  # the world as it is: its own time limit
    assert new.cfg.num_passengers == requests and new.single_observation_space == old.single_observation_space
    expected = _actions(old, resized, 60)
    flown = _actions(new, policy, 60)
    assert len(flown) == len(expected) == 60
    for step, (a, b) in enumerate(zip(flown, expected, strict=True)):
        np.testing.assert_array_equal(a, b, err_msg=f"step {step}")
    # it reads what the resized policy reads: the same rows, normalised with the same pooled statistics
    obs, _ = new.reset(seed=0)
    policy.reset(new.sim)
    mine, theirs = policy.network_input(obs), resized.network_input(obs)
    assert sorted(mine) == sorted(theirs) and mine["passengers"].shape == (2, 12, 12)
    for name in mine:
        np.testing.assert_array_equal(mine[name], theirs[name], err_msg=name)
    assert (policy.obs_shapes["passengers"], policy.passenger_slots, policy.num_taxis) == ((24, 12), 24, 4)  # as built
    # back in a world of its trained shape it reads its trained rows and statistics again
    trained = VectorEnv(
        make_fleet_instance("berlin", 3, num_taxis=4, num_requests=24, hover_action=False), observer=policy.spec
    )
    obs, _ = trained.reset(seed=0)
    policy.reset(trained.sim)
    fresh = uamfleet.pretrained("berlin_fleet_v1").network_input(obs)
    mine = policy.network_input(obs)
    assert mine["passengers"].shape == (4, 24, 12)
    for name in mine:
        np.testing.assert_array_equal(mine[name], fresh[name], err_msg=name)


def test_a_policy_refuses_at_reset_a_world_its_spec_cannot_read_in_one_line_naming_the_fix() -> None:
    fleet = uamfleet.pretrained("berlin_fleet_v1")  # 6 rows per taxi, no window
    crowded = make_fleet_instance("berlin", 3, num_taxis=2, num_requests=16)
    env = VectorEnv(crowded, observer=ObserverSpec(passenger_window=8), autoreset=False)
    env.reset(seed=0)
    with pytest.raises(ConfigError) as err:
        fleet.reset(env.sim)
    assert str(err.value) == (
        "the world has 16 passenger rows; this policy reads 12: give it at most 12 requests, or fly it with a "
        "passenger window."
    )
    hover = uamfleet.pretrained("berlin_fleet")  # waits with the hover action
    still = VectorEnv(make_fleet_instance("berlin", 3, num_taxis=2, num_requests=8, hover_action=False))
    still.reset(seed=0)
    with pytest.raises(
        ConfigError, match=r"hover action \(16\), which this world refuses: build it with hover_action="
    ):
        hover.reset(still.sim)


def test_rollout_flies_a_world_as_made_observed_by_the_policys_spec() -> None:
    from uamfleet.rollout import fly

    cfg = make_fleet_instance("berlin", 2_000_001, num_taxis=2, num_requests=6)  # the fleet preset's hover
    shipped = uamfleet.pretrained("berlin_fleet")  # trained on up to 8 taxis, a 24-row window
    flown = fly(cfg, shipped)  # no resize, no layout: the policy fits itself at reset
    assert shipped.spec is not None
    laid_out = fly(observed_config(cfg.world, shipped.spec)[0], _built_for(shipped, observed_config(cfg.world,
                   shipped.spec)[0]))  # fmt: skip
    assert flown.num_steps == laid_out.num_steps and flown.truncated == laid_out.truncated
    np.testing.assert_array_equal(flown.stacked("actions"), laid_out.stacked("actions"))
    assert episode_metrics(flown, cfg.radio).delivered == 6
