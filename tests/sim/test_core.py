"""The simulator without an observer (uamfleet/sim/core.py): it flies the episodes the vector env flies, ends
episodes as its ``autoreset`` says, its global state is the one written out by hand, and a step that keeps its
events in its own arrays (``events=False``) flies the same steps. That it imports no observation code is
tests/test_layers.py's rule (``uamfleet.sim`` sits below ``uamfleet.env``)."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config

from uamfleet.config import Request
from uamfleet.env.vector_env import VectorEnv
from uamfleet.sim.core import Simulator


def _two_taxis(**overrides):
    starts = ((150.0, 150.0), (350.0, 350.0))
    requests = (Request(0, (350.0, 150.0), (350.0, 350.0)), Request(2, (150.0, 350.0), (450.0, 50.0)))
    return small_config(starts_m=starts, requests=requests, time_limit_steps=7, **overrides)


def test_the_simulator_flies_what_the_vector_env_flies_without_observing() -> None:
    cfg = _two_taxis()
    sim, env = Simulator(cfg, num_envs=3), VectorEnv(cfg, num_envs=3)
    state = sim.reset(seed=5)
    env.reset(seed=5)
    assert state is sim.state
    rng = np.random.default_rng(0)
    ended = 0
    for _ in range(20):
        mask = sim.state.action_mask
        np.testing.assert_array_equal(mask, env.state.action_mask)
        actions = np.argmax(rng.random(mask.shape) * np.where(mask.any(-1, keepdims=True), mask, 1), -1)
        rewards, terminated, truncated, info = sim.step(actions)
        _, env_rewards, env_terminated, env_truncated, env_info = env.step(actions)
        np.testing.assert_array_equal(rewards, env_rewards)
        np.testing.assert_array_equal(terminated, env_terminated)
        np.testing.assert_array_equal(truncated, env_truncated)
        assert set(info) == set(env_info) - {"final_obs"}
        if "_episode" in info:
            ended += 1
            for key, value in info["episode"].items():
                np.testing.assert_array_equal(value, env_info["episode"][key], err_msg=key)
        for name, value in sim.state._asdict().items():
            np.testing.assert_array_equal(value, getattr(env.state, name), err_msg=name)
        np.testing.assert_array_equal(sim.global_state(), env.global_state())
    assert ended >= 2  # the time limit of 7 steps ended episodes that were drawn anew


def test_advance_leaves_the_finished_state_and_end_episodes_draws_the_next_one() -> None:
    sim = Simulator(_two_taxis(), num_envs=2)
    sim.reset(seed=0)
    stay = np.zeros((2, 2), np.int64)
    for _ in range(6):
        *_, info = sim.advance(stay)
        assert "_episode" not in info
    _, terminated, truncated, info = sim.advance(stay)
    np.testing.assert_array_equal(truncated, [True, True])
    np.testing.assert_array_equal(sim.state.t, [7, 7])  # not drawn anew yet
    np.testing.assert_array_equal(info["episode"]["length"], [7, 7])
    np.testing.assert_array_equal(sim.end_episodes(truncated | terminated), [0, 1])
    np.testing.assert_array_equal(sim.state.t, [0, 0])
    assert not sim.episode_terms.any()


def test_without_autoreset_a_finished_episode_needs_a_reset() -> None:
    sim = Simulator(_two_taxis(), num_envs=1, autoreset=False)
    with pytest.raises(RuntimeError, match="before reset"):
        sim.step(np.zeros((1, 2), np.int64))
    sim.reset(seed=0)
    for _ in range(7):
        sim.step(np.zeros((1, 2), np.int64))
    assert sim.needs_reset and sim.state.t[0] == 7
    with pytest.raises(RuntimeError, match="before reset"):
        sim.step(np.zeros((1, 2), np.int64))
    sim.reset(seed=0)
    assert sim.state.t[0] == 0


def test_the_global_state_by_hand() -> None:
    sim = Simulator(_two_taxis(), num_envs=1)
    sim.reset(seed=0)
    side, limit = 500.0, 7.0
    taxis = [150 / side, 150 / side, 1.0, 0.0, 350 / side, 350 / side, 1.0, 0.5]  # x, y, free seats / 2, a / A
    first = [350 / side, 150 / side, 350 / side, 350 / side, 1, 0, 0, 0.0, 0 / limit]  # waiting, no carrier
    hidden = [0.0] * 9  # released at step 2
    expected = np.array([taxis + first + hidden + [0.0]], np.float32)
    assert sim.state_size == expected.shape[1] and sim.state_space.shape == (expected.shape[1],)
    np.testing.assert_allclose(sim.global_state(), expected, rtol=1e-6)


def test_a_step_without_events_flies_the_same_steps_and_keeps_nothing_it_returns() -> None:
    # Four taxis crowded on an open map (the shield turns and holds moves), hovers, riders picked up and dropped
    # off, episodes ended by the time limit: the events arrays the simulator reuses are rewritten in full every step.
    open_map = "\n".join(["." * 10] * 10)
    starts = ((150.0, 150.0), (190.0, 150.0), (150.0, 190.0), (450.0, 450.0))
    requests = tuple(Request(t, (250.0 + 100 * t, 150.0), (150.0, 450.0 - 100 * t)) for t in range(3))
    cfg = small_config(
        open_map, starts_m=starts, requests=requests, separation="shield", hover_action=True, time_limit_steps=9
    )
    fresh, reused = Simulator(cfg, num_envs=2), Simulator(cfg, num_envs=2)
    fresh.reset(seed=3)
    reused.reset(seed=3)
    rng = np.random.default_rng(1)
    kept, expected = [], []
    seen = dict.fromkeys(["shield_intervened", "hovered", "picked_up", "dropped_off", "pickups", "blocked"], False)
    for _ in range(30):
        actions = rng.integers(0, 17, size=(2, 4))
        out_fresh = fresh.advance(actions)
        out_reused = reused.advance(actions, events=False)
        for a, b in zip(out_fresh[:3], out_reused[:3], strict=True):
            np.testing.assert_array_equal(a, b)
        info, info_reused = out_fresh[3], out_reused[3]
        assert "events" not in info_reused and set(info_reused) == set(info) - {"events"}
        np.testing.assert_array_equal(info["reward_terms"], info_reused["reward_terms"])
        for name, value in info["events"]._asdict().items():  # the reused arrays hold this step's events
            if name != "actions":
                np.testing.assert_array_equal(getattr(reused._scratch, name), value, err_msg=name)
            if name in seen:
                seen[name] = seen[name] or bool(np.any(value))
        if "_episode" in info:
            for key, value in info["episode"].items():
                np.testing.assert_array_equal(value, info_reused["episode"][key], err_msg=key)
            fresh.end_episodes(info["_episode"])
            reused.end_episodes(info_reused["_episode"])
        returned = [*out_reused[:3], info_reused["reward_terms"]]
        assert not any(np.shares_memory(r, v) for r in returned for v in reused._scratch), "returns a reused array"
        kept.append(out_reused[:3])  # kept without a copy: later steps must not write into them
        expected.append(tuple(x.copy() for x in out_fresh[:3]))
        for name, value in fresh.state._asdict().items():
            np.testing.assert_array_equal(value, getattr(reused.state, name), err_msg=name)
    for got, want in zip(kept, expected, strict=True):
        for a, b in zip(got, want, strict=True):
            np.testing.assert_array_equal(a, b)
    assert all(seen.values()), seen  # events a step sets or counts happened, and were rewritten after
