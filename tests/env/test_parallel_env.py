"""The PettingZoo face: API tests, full-rollout determinism, and equality with a slice of the batched core."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import small_config
from pettingzoo.test import api_test, parallel_api_test
from pettingzoo.utils.conversions import parallel_to_aec

import uamfleet
from uamfleet.env.parallel_env import UAMFleetParallelEnv
from uamfleet.env.vector_env import VectorEnv


@pytest.mark.parametrize("num_taxis", [1, 3])
def test_parallel_api(num_taxis):
    env = uamfleet.parallel_env("berlin_random", num_taxis=num_taxis, time_limit_steps=60)
    parallel_api_test(env, num_cycles=200)


def test_paper_scenario_parallel_api_and_aec_api():
    parallel_api_test(uamfleet.parallel_env("berlin_p4", sinr_min_db=-3.0, time_limit_steps=80), num_cycles=100)
    api_test(parallel_to_aec(uamfleet.parallel_env("berlin_p4", time_limit_steps=80)), num_cycles=100)
    api_test(
        parallel_to_aec(uamfleet.parallel_env("berlin_random", num_taxis=2, time_limit_steps=40)),
        num_cycles=60,
    )


def _rollout(env: UAMFleetParallelEnv, seed: int, steps: int):
    obs, _ = env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    trace = []
    for _ in range(steps):
        if not env.agents:
            obs, _ = env.reset()
        actions = {a: int(rng.choice(np.flatnonzero(obs[a]["action_mask"]))) for a in env.agents}
        obs, rew, term, trunc, _ = env.step(actions)
        trace.append((actions, {a: {k: v.copy() for k, v in o.items()} for a, o in obs.items()}, rew, term, trunc))
    return trace


def _assert_same(trace_a, trace_b):
    assert len(trace_a) == len(trace_b)
    for (act_a, obs_a, rew_a, term_a, trunc_a), (act_b, obs_b, rew_b, term_b, trunc_b) in zip(
        trace_a, trace_b, strict=True
    ):
        assert act_a == act_b and rew_a == rew_b and term_a == term_b and trunc_a == trunc_b
        for agent in obs_a:
            for key in obs_a[agent]:
                np.testing.assert_array_equal(obs_a[agent][key], obs_b[agent][key])


def test_full_rollout_determinism_over_several_episodes():
    make = lambda: uamfleet.parallel_env("berlin_random", num_taxis=2, time_limit_steps=30)  # noqa: E731
    a, b = _rollout(make(), seed=7, steps=100), _rollout(make(), seed=7, steps=100)
    _assert_same(a, b)
    c = _rollout(make(), seed=8, steps=100)
    assert any(x[0] != y[0] for x, y in zip(a, c, strict=True))


def test_slice_e_of_core_equals_pettingzoo_env_seeded_seed_plus_e():
    cfg = uamfleet.make_config("berlin_random", num_taxis=2, time_limit_steps=25)
    num_envs, seed, e = 3, 11, 2
    core = VectorEnv(cfg, num_envs=num_envs)
    pz = UAMFleetParallelEnv(cfg)
    core_obs, _ = core.reset(seed=seed)
    pz_obs, _ = pz.reset(seed=seed + e)
    rng = np.random.default_rng(0)
    for _ in range(25):
        actions = np.stack(
            [[rng.choice(np.flatnonzero(core_obs["action_mask"][i, a])) for a in range(2)] for i in range(num_envs)]
        )
        core_obs, core_rew, core_term, core_trunc, _ = core.step(actions)
        pz_obs, pz_rew, pz_term, pz_trunc, _ = pz.step({f"uam_{a}": int(actions[e, a]) for a in range(2)})
        for a in range(2):
            agent = f"uam_{a}"
            assert pz_rew[agent] == core_rew[e, a]
            assert pz_term[agent] == core_term[e] and pz_trunc[agent] == core_trunc[e]
            if pz.agents:
                for key, value in pz_obs[agent].items():
                    np.testing.assert_array_equal(value, core_obs[key][e, a], err_msg=key)
    assert not pz.agents  # the time limit ended the episode on the last step


def test_spaces_are_identical_objects_and_state_space_matches():
    env = uamfleet.parallel_env("berlin_p4")
    assert env.observation_space("uam_0") is env.observation_space("uam_0")
    assert env.action_space("uam_0") is env.action_space("uam_0")
    env.reset(seed=0)
    assert env.state_space.contains(env.state())


def test_reward_terms_and_episode_info():
    env = UAMFleetParallelEnv(small_config())
    env.reset(seed=0)
    _, rew, _, _, infos = env.step({"uam_0": 0})
    terms = infos["uam_0"]["reward_terms"]
    assert set(terms) == set(uamfleet.REWARD_TERMS) and sum(terms.values()) == pytest.approx(rew["uam_0"])
    env.step({"uam_0": 4})
    _, _, term, _, infos = env.step({"uam_0": 4})
    assert term["uam_0"] and infos["uam_0"]["episode"]["delivered"] == 1
    assert env.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        env.step({"uam_0": 0})


def test_rgb_array_render():
    env = uamfleet.parallel_env("berlin_p4", render_mode="rgb_array")
    env.reset(seed=0)
    env.step({"uam_0": 8})
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8 and frame.std() > 0
