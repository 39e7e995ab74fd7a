"""The faces take an observer (:class:`uamfleet.observe.spec.ObserverSpec`): without one they observe what the
config's observer fields say, exactly as before; with one, the observer reads its fields from the spec, and a spec
that cannot read the world is refused in one line."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

import uamfleet
from uamfleet.config import ConfigError, EnvConfig, Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.observe.legacy import split_env_config
from uamfleet.observe.observer import Observer
from uamfleet.observe.spec import LookaheadSpec, ObserverSpec, StopsSpec, observation_layout
from uamfleet.types import PAX_AGE, SELF_TIME

OPEN_7 = "\n".join(["......."] * 7)
REQUESTS = (
    Request(0, (250.0, 250.0), (550.0, 450.0)),
    Request(0, (450.0, 150.0), (150.0, 550.0)),
    Request(3, (650.0, 650.0), (50.0, 50.0)),
)


def config(**overrides: object) -> EnvConfig:
    base: dict[str, object] = {"starts_m": None, "num_taxis": 2, "requests": REQUESTS, "seats": 1, "patch_size": 3}
    base.update(overrides)
    return small_config(OPEN_7, **base)


def fly(env: VectorEnv, steps: int = 6) -> list[dict[str, np.ndarray]]:
    obs, _ = env.reset(seed=3)
    seen = [obs]
    rng = np.random.default_rng(0)
    for _ in range(steps):
        actions = rng.integers(0, 16, size=(env.num_envs, env.num_taxis))
        obs, *_ = env.step(actions)
        seen.append(obs)
    return seen


CASES = [
    {},
    {"stop_features": True, "stop_claims": True, "hover_action": True},
    {"stop_features": True, "stop_rivals": True, "heading_lookahead": True, "lookahead_depth": 2},
    {"stop_features": True, "passenger_window": 2, "history_len": 2},
]


@pytest.mark.parametrize("overrides", CASES)
def test_the_world_with_the_split_observer_observes_what_the_config_observes(overrides: dict) -> None:
    cfg = config(**overrides)
    world, spec = split_env_config(cfg)
    old, new = VectorEnv(cfg, num_envs=2), VectorEnv(world, num_envs=2, observer=spec)
    assert new.spec == spec == old.spec and list(new.layout) == list(observation_layout(cfg))
    for a, b in zip(fly(old), fly(new), strict=True):
        assert list(a) == list(b)
        for name in a:
            np.testing.assert_array_equal(a[name], b[name], err_msg=name)


def test_a_bare_world_is_observed_by_the_documented_default() -> None:
    env = VectorEnv(config(stop_features=True).world)
    assert env.spec == ObserverSpec() and "stop_paths" not in env.layout
    assert env.layout["history"].shape[0] == 3 and env.layout["sinr_patch"].shape == (10, 10)


def test_the_observer_reads_its_fields_from_the_spec_not_the_config() -> None:
    cfg = config()  # no stop fields, history 3, patch 3
    spec = ObserverSpec(history_len=2, patch_size=5, stops=StopsSpec(claims=True), lookahead=LookaheadSpec(depth=2))
    env = VectorEnv(cfg, observer=spec)
    obs, _ = env.reset(seed=1)
    assert obs["history"].shape[2] == 2 and obs["sinr_patch"].shape[2:] == (5, 5)
    assert {"stop_paths", "stop_claims", "hover_heading_mask", "heading_lookahead"} <= set(obs)
    assert env.observer.depth == 2 and env.cfg.lookahead_depth == 2


def test_the_time_features_divide_by_the_specs_time_scale() -> None:
    cfg = config(time_limit_steps=50)
    env = VectorEnv(cfg.world, observer=ObserverSpec(patch_size=3, slots_per_taxi=1.5, time_scale_steps=200))
    env.reset(seed=0)
    for _ in range(5):
        obs, *_ = env.step(np.zeros((1, 2), np.int64))
    t = int(env.state.t[0])
    assert t == 5
    np.testing.assert_allclose(obs["self"][0, :, SELF_TIME], t / 200, rtol=1e-6)  # the world's limit would give t/50
    released = obs["passenger_mask"][0, 0] == 1
    assert released.all()  # requests 0 and 1 at step 0, request 2 at step 3: ages t, t, t - 3
    np.testing.assert_allclose(obs["passengers"][0, 0, :, PAX_AGE], [5 / 200, 5 / 200, 2 / 200], rtol=1e-6)
    assert env.state.t.dtype.kind in "iu" and cfg.time_limit_steps == env.cfg.time_limit_steps == 50


@pytest.mark.parametrize(
    ("cfg", "spec", "line"),
    [
        (config(), ObserverSpec(hover=True), "which this world refuses: build it with hover_action=True."),
        (config(), ObserverSpec(fleet_rows=3), "fly it with 4 taxis."),
        (config(), ObserverSpec(slots_per_taxi=1.0), "the world has 3 passenger rows; this policy reads 2"),
        (config(seats=2), ObserverSpec(passenger_window=1), "passenger_window=1 must be an integer in [2, 1024]"),
    ],
)
def test_a_face_refuses_an_observer_that_cannot_read_its_world_in_one_line(cfg: EnvConfig, spec: ObserverSpec,
                                                                            line: str) -> None:  # fmt: skip
    with pytest.raises(ConfigError) as err:
        VectorEnv(cfg, observer=spec)
    assert line in str(err.value) and "\n" not in str(err.value)


def test_an_observer_that_reads_more_passenger_rows_than_the_world_has_pads_them_masked_and_zero() -> None:
    own = VectorEnv(config(), observer=ObserverSpec(patch_size=3))  # the world's 3 rows
    padded = VectorEnv(config(), observer=ObserverSpec(patch_size=3, slots_per_taxi=2.0))  # 4 rows for 2 taxis
    assert padded.single_observation_space["passengers"].shape[0] == 4 and padded.cfg.num_passengers == 3
    for a, b in zip(fly(own), fly(padded), strict=True):
        np.testing.assert_array_equal(b["passengers"][:, :, :3], a["passengers"])
        np.testing.assert_array_equal(b["passenger_mask"][:, :, :3], a["passenger_mask"])
        assert not b["passengers"][:, :, 3].any() and not b["passenger_mask"][:, :, 3].any()
        assert all(np.array_equal(a[k], b[k]) for k in a if k not in ("passengers", "passenger_mask"))


def test_an_observer_refuses_a_simulator_that_keeps_less_than_it_reads() -> None:
    env = VectorEnv(config())
    with pytest.raises(ConfigError, match="history_len=3, patch_size=3 and stop_features=False"):
        Observer(env.world, ObserverSpec(patch_size=3, stops=StopsSpec()))


def test_the_pettingzoo_face_takes_an_observer_and_defaults_to_the_scenarios() -> None:
    fleet = uamfleet.parallel_env("berlin_fleet", num_taxis=2)
    assert fleet.spec.stops == StopsSpec(claims=True) and fleet.spec.hover
    assert "stop_claims" in fleet.observation_space("uam_0").spaces
    plain = uamfleet.parallel_env("berlin_fleet", num_taxis=2, observer=ObserverSpec(slots_per_taxi=6.0))
    assert "stop_paths" not in plain.observation_space("uam_1").spaces
    obs, _ = plain.reset(seed=0)
    assert set(obs["uam_0"]) == set(plain.observation_space("uam_0").spaces)
    with pytest.raises(ConfigError, match="hover action"):
        uamfleet.parallel_env("berlin_p4", observer=ObserverSpec(hover=True))


def test_a_bare_world_given_to_either_face_is_observed_by_the_default() -> None:
    world = uamfleet.make_config("berlin_instances").world
    assert uamfleet.parallel_env(world).spec == ObserverSpec() == uamfleet.vector_env(world).spec
    assert uamfleet.parallel_env("berlin_instances").spec.stops == StopsSpec()
    assert uamfleet.vector_env(world, observer=ObserverSpec(stops=StopsSpec())).spec.stops == StopsSpec()
