"""Property-based test (Hypothesis) of bad and odd input: any EnvConfig, requests and actions either build a
working env, whose observations stay finite and in their spaces for a few hundred random steps, or raise one of
the package's documented errors: never another exception, a hang or a NaN.

The documented errors (all ``ValueError`` subclasses whose message names the value and the fix):
``ConfigError`` for a bad field, ``InfeasibleInstanceError`` for a start or stop the radio map rules out,
``InvalidActionError`` for a bad action.
"""

from __future__ import annotations

import math
import signal
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np
from conftest import drawn_map
from gymnasium import spaces
from hypothesis import HealthCheck, event, given, settings
from hypothesis import strategies as st

from uamfleet.config import ConfigError, DemandConfig, EnvConfig, Request, RewardConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.sim.dynamics import InvalidActionError
from uamfleet.sim.generator import InfeasibleInstanceError

DOCUMENTED_ERRORS = (ConfigError, InfeasibleInstanceError, InvalidActionError)

ART = """
......
..##..
..#...
......
.#..#.
......
"""  # 600 m square, 100 m cells; '#' = -10 dB, '.' = 0 dB
RADIO = drawn_map(ART)
GOOD_CENTRES = [
    (100.0 * x + 50.0, 100.0 * (5 - y) + 50.0)
    for y, row in enumerate(ART.strip().splitlines())
    for x, ch in enumerate(row.strip())
    if ch == "."
]
STEPS = 300

# ---- strategies: sensible values per field; in half the examples one to three fields get a bad value ----

junk = st.sampled_from([math.nan, math.inf, -math.inf, "3", None, True, (1, 2), 1e300, -1e300, -1, 0, 2.5])
bad_values = st.one_of(junk, st.floats(-1e3, 1e3, allow_nan=False), st.integers(-5, 5000))

points = st.one_of(
    st.sampled_from(GOOD_CENTRES),
    st.sampled_from(GOOD_CENTRES),
    st.sampled_from(GOOD_CENTRES),
    st.tuples(st.floats(-100, 700), st.floats(-100, 700)),  # anywhere: outside, in a bad block, or fine
)
bad_points = st.sampled_from([(50.0, 50.0, 100.0), (math.nan, 50.0), ("50", "50"), (50.0,), "50,50", None])
good_requests = st.lists(st.tuples(st.integers(0, 40), points, points), min_size=1, max_size=5)
GOOD_FIELDS: dict[str, st.SearchStrategy[Any]] = {
    "sinr_min_db": st.floats(-12, 3),
    "num_taxis": st.integers(1, 4),
    "seats": st.integers(1, 3),
    "step_m": st.sampled_from([100.0, 141.42, 150.0, 250.0, 700.0]),
    "slot_s": st.floats(0.5, 10),
    "pickup_radius_m": st.one_of(st.none(), st.floats(1, 300)),
    "block_m": st.one_of(st.none(), st.sampled_from([100.0, 150.0, 200.0, 1000.0])),
    "nc_rule": st.sampled_from(["global_min", "nanmean"]),
    "feasibility": st.sampled_from(["endpoint_block", "segment_raster"]),
    "starts_m": st.one_of(st.none(), st.lists(points, min_size=1, max_size=4)),
    "requests": st.one_of(st.none(), good_requests),
    "max_passengers": st.one_of(st.none(), st.integers(5, 8)),
    "time_limit_steps": st.integers(1, 120),
    "history_len": st.integers(1, 5),
    "patch_size": st.sampled_from([1, 3, 4, 10, 64]),
    "min_separation_m": st.floats(0, 200),
    "max_block_visits": st.one_of(st.none(), st.integers(1, 20)),
}
BAD_FIELDS: dict[str, st.SearchStrategy[Any]] = {
    **{name: bad_values for name in GOOD_FIELDS},
    "nc_rule": st.sampled_from(["median", 3, None]),
    "feasibility": st.sampled_from(["anywhere", None]),
    "patch_size": st.sampled_from([0, 65, 3000, 2.5]),
    "starts_m": st.one_of(bad_values, st.lists(st.one_of(points, bad_points), min_size=0, max_size=4)),
    "requests": st.one_of(
        bad_values,
        st.lists(
            st.tuples(st.one_of(st.integers(-2, 200), bad_values), st.one_of(points, bad_points), points),
            max_size=4,
        ),
        st.lists(st.sampled_from([(0, (50.0, 50.0)), Request(0, (50.0, 50.0), (250.0, 50.0)), 7]), max_size=3),
    ),
}
GOOD_DEMAND = {
    "num_initial": st.integers(0, 4),
    "rate_per_step": st.floats(0, 0.5),
    "horizon_steps": st.integers(0, 80),
    "max_requests": st.integers(4, 6),
    "min_trip_m": st.floats(0, 800),
    "vertiports": st.one_of(st.just(()), st.lists(points, min_size=2, max_size=4, unique=True).map(tuple)),
}
GOOD_REWARD = {
    "step": st.floats(-5, 0),
    "pickup": st.floats(0, 300),
    "shaping": st.sampled_from([0.0, 0.5, 1.0]),
    "shaping_metric": st.sampled_from(["path", "euclidean"]),
}


@st.composite
def configs(draw: st.DrawFn) -> tuple[dict[str, Any], dict[str, Any], dict[str, Any]]:
    """(EnvConfig overrides, DemandConfig keywords, RewardConfig keywords): keyword dicts, built inside the test,
    because their errors are part of the contract under test."""
    fields = draw(st.fixed_dictionaries({}, optional=GOOD_FIELDS))
    demand = draw(st.fixed_dictionaries({}, optional=GOOD_DEMAND))
    reward = draw(st.fixed_dictionaries({}, optional=GOOD_REWARD))
    if draw(st.booleans()):
        for _ in range(draw(st.integers(1, 3))):
            where = draw(st.sampled_from(["env"] * 6 + ["demand", "reward"]))
            if where == "env":
                name = draw(st.sampled_from(sorted(BAD_FIELDS)))
                fields[name] = draw(BAD_FIELDS[name])
            else:
                target, names = (demand, GOOD_DEMAND) if where == "demand" else (reward, GOOD_REWARD)
                target[draw(st.sampled_from(sorted(names)))] = draw(st.one_of(bad_values, bad_points))
    return fields, demand, reward


# A rare bad action at a random step: what it is and when it comes.
bad_actions = st.one_of(
    st.none(), st.tuples(st.integers(0, STEPS - 1), st.sampled_from([3.5, math.nan, "3", True, 16, -1, [3]]))
)


@contextmanager
def time_limit(seconds: int) -> Iterator[None]:
    """Fail instead of hanging (SIGALRM: the main thread on Unix, as pytest runs)."""

    def handler(signum: int, frame: Any) -> None:
        raise TimeoutError(f"no answer within {seconds} s: a hang")

    old = signal.signal(signal.SIGALRM, handler)
    signal.alarm(seconds)
    try:
        yield
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, old)


def assert_in_space(obs: dict[str, np.ndarray], space: spaces.Dict, batch: tuple[int, int]) -> None:
    """Every taxi's observation in its Box (dtype, shape, bounds) and finite: vectorised ``space.contains``."""
    assert set(obs) == set(space.spaces)
    for key, box in space.spaces.items():
        value = obs[key]
        assert isinstance(box, spaces.Box)
        assert value.dtype == box.dtype and value.shape == batch + box.shape, (key, value.dtype, value.shape)
        assert np.all(np.isfinite(value)), key
        assert np.all((value >= box.low) & (value <= box.high)), (key, value.min(), value.max())


def build(overrides: dict[str, Any], demand: dict[str, Any], reward: dict[str, Any]) -> VectorEnv:
    cfg_fields: dict[str, Any] = {"radio": RADIO, "time_limit_steps": 60, "patch_size": 4, **overrides}
    cfg_fields["demand"] = DemandConfig(**demand)
    cfg_fields["reward"] = RewardConfig(**reward)
    starts = cfg_fields.get("starts_m")
    if "num_taxis" not in overrides and isinstance(starts, list) and starts:
        cfg_fields["num_taxis"] = len(starts)
    return VectorEnv(EnvConfig(**cfg_fields), num_envs=2)


def run(env: VectorEnv, seed: int, bad: tuple[int, Any] | None) -> None:
    rng = np.random.default_rng(seed)
    obs, _ = env.reset(seed=seed)
    batch = (env.num_envs, env.num_taxis)
    assert_in_space(obs, env.single_observation_space, batch)
    for t in range(STEPS):
        if bad is not None and t == bad[0]:
            actions: Any = np.zeros(batch, dtype=object)
            actions[...] = 0
            actions[0, 0] = bad[1]
            try:
                env.step(actions)
            except InvalidActionError as exc:
                assert "action" in str(exc)
            else:
                raise AssertionError(f"bad action {bad[1]!r} was accepted")
        # Mostly allowed moves (so that passengers get served), sometimes any heading (a blocked move).
        mask = obs["action_mask"].astype(bool)
        allowed = np.where(mask.any(-1, keepdims=True), mask, True)
        masked_pick = np.argmax(rng.random(mask.shape) * allowed, axis=-1)
        actions = np.where(rng.random(batch) < 0.9, masked_pick, rng.integers(0, 16, batch))
        obs, rewards, terminated, truncated, info = env.step(actions)
        assert_in_space(obs, env.single_observation_space, batch)
        assert not np.any(terminated & truncated)
        assert rewards.shape == batch and np.all(np.isfinite(rewards))
        assert np.all(np.isfinite(info["reward_terms"]))
        assert np.all(np.isfinite(env.global_state()))
        if "episode" in info:
            assert_in_space(info["final_obs"], env.single_observation_space, batch)
            for key, value in info["episode"].items():
                assert np.all(np.isfinite(value)), key


@settings(
    max_examples=250,
    deadline=None,
    derandomize=True,  # the same examples on every run: CI reproducible
    suppress_health_check=[HealthCheck.too_slow, HealthCheck.data_too_large],
)
@given(config=configs(), bad=bad_actions)
def test_any_config_builds_a_working_env_or_raises_a_documented_error(config, bad):
    with time_limit(30):
        try:
            env = build(*config)
        except DOCUMENTED_ERRORS as exc:
            assert str(exc), "an error without a message"
            event(type(exc).__name__)
            return
        event("built")
        run(env, seed=len(repr(config)), bad=bad)


def test_requests_on_their_own():
    # Requests built directly: the same contract as through EnvConfig.
    for item in [(0, (1.0, 2.0), (1.0, 2.0)), (-1, (1.0, 2.0), (3.0, 4.0)), (1.5, (1.0, 2.0), (3.0, 4.0))]:
        try:
            Request(*item)
        except ConfigError as exc:
            assert repr(item[0]) in str(exc) or "origin_m == destination_m" in str(exc)
        else:
            raise AssertionError(f"{item} was accepted")


def test_random_rides_go_somewhere_even_with_min_trip_zero():
    # Found by the property test: with min_trip_m=0 the origin itself counted as "far enough", and a drawn
    # request with origin == destination failed inside reset().
    env = build({"requests": None, "starts_m": None}, {"min_trip_m": 0.0, "max_requests": 6, "num_initial": 6}, {})
    for seed in range(50):
        env.reset(seed=seed)
        s = env.state
        assert np.all(np.any(s.pax_origin_m != s.pax_dest_m, axis=-1) | ~s.pax_exists)
