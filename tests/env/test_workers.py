"""Env workers (uamfleet.env.workers): the same envs as in process, bit for bit, and errors that name the fix."""

from __future__ import annotations

import numpy as np
import pytest

from uamfleet.env.mixture import MixtureVectorEnv
from uamfleet.env.vector_env import VectorEnv
from uamfleet.env.workers import ShardedVectorEnv, shard_pieces
from uamfleet.presets import make_config


def _thresholds(time_limit_steps: int = 40) -> list:
    cfg = make_config("berlin_instances").replace(time_limit_steps=time_limit_steps)
    return [cfg.replace(sinr_min_db=t) for t in (-7, -5, -3)]


def _assert_same_step(a: tuple, b: tuple) -> int:
    """Two envs' step results equal field for field; returns how many episodes ended."""
    for key in a[0]:
        np.testing.assert_array_equal(a[0][key], b[0][key], err_msg=key)
    for i in (1, 2, 3):
        np.testing.assert_array_equal(a[i], b[i])
    np.testing.assert_array_equal(a[4]["reward_terms"], b[4]["reward_terms"])
    assert ("_episode" in a[4]) == ("_episode" in b[4])
    if "_episode" not in a[4]:
        return 0
    done = a[4]["_episode"]
    np.testing.assert_array_equal(done, b[4]["_episode"])
    for key in a[4]["final_obs"]:
        np.testing.assert_array_equal(a[4]["final_obs"][key][done], b[4]["final_obs"][key][done], err_msg=key)
    for key in a[4]["episode"]:
        np.testing.assert_array_equal(a[4]["episode"][key][done], b[4]["episode"][key][done], err_msg=key)
    return int(done.sum())


def test_shards_cut_the_mixtures_groups_and_cover_every_env_once():
    cfgs = _thresholds()
    pieces = shard_pieces(cfgs, 10, 3)  # groups of 4, 3, 3 envs; shares of 4, 3, 3 envs
    assert [[(p.cfg.sinr_min_db, p.lo, p.num_envs) for p in w] for w in pieces] == [
        [(-7, 0, 4)],
        [(-5, 4, 3)],
        [(-3, 7, 3)],
    ]
    pieces = shard_pieces(cfgs, 10, 2)  # shares of 5 and 5: the second group is cut between the workers
    assert [[(p.cfg.sinr_min_db, p.lo, p.num_envs) for p in w] for w in pieces] == [
        [(-7, 0, 4), (-5, 4, 1)],
        [(-5, 5, 2), (-3, 7, 3)],
    ]


@pytest.mark.parametrize("workers", [2, 3])
def test_workers_step_the_mixtures_envs_bit_for_bit(workers):
    cfgs, num_envs = _thresholds(), 10
    reference = MixtureVectorEnv(cfgs, num_envs)
    rng = np.random.default_rng(workers)
    ended = 0
    with ShardedVectorEnv(cfgs, num_envs, workers) as sharded:
        first, second = reference.reset(seed=11)[0], sharded.reset(seed=11)[0]
        for key in first:
            np.testing.assert_array_equal(first[key], second[key], err_msg=key)
        for _ in range(90):  # two time limits: every env ends an episode and autoresets, twice
            actions = rng.integers(0, 16, (num_envs, 1))
            ended += _assert_same_step(reference.step(actions), sharded.step(actions))
    assert ended >= 2 * num_envs


def test_one_config_with_its_global_state_as_one_vector_env():
    cfg = make_config("berlin_fleet", num_taxis=2).replace(time_limit_steps=25)
    reference = VectorEnv(cfg, num_envs=3)
    rng = np.random.default_rng(0)
    with ShardedVectorEnv([cfg], 3, workers=2, global_state=True) as sharded:
        reference.reset(seed=4), sharded.reset(seed=4)
        np.testing.assert_array_equal(reference.global_state(), sharded.global_state())
        for _ in range(30):
            actions = rng.integers(0, 16, (3, 2))
            _assert_same_step(reference.step(actions), sharded.step(actions))
            np.testing.assert_array_equal(reference.global_state(), sharded.global_state())


def test_bad_input_is_refused_with_the_fix():
    cfgs = _thresholds()
    with pytest.raises(ValueError, match=r"workers=4 must be an integer from 1 to num_envs=3"):
        ShardedVectorEnv(cfgs, 3, workers=4)
    fleets = [make_config("berlin_fleet", num_taxis=n) for n in (2, 4)]
    with pytest.raises(ValueError, match=r"fleets of \[2, 4\] taxis.*without env workers"):
        ShardedVectorEnv(fleets, 4, workers=2)


def test_a_failing_worker_is_raised_with_its_envs_and_traceback():
    sharded = ShardedVectorEnv(_thresholds(), 4, workers=2)
    with pytest.raises(RuntimeError, match=r"step\(\) called before reset"):
        sharded.step(np.zeros((4, 1), np.int64))
    sharded.reset(seed=0)
    bad = np.zeros((4, 1), np.int64)
    bad[3] = 99  # a heading that does not exist, in the second worker's envs
    with pytest.raises(RuntimeError, match=r"(?s)env worker 1 \(envs 2\.\.2 .*3\.\.3 .*\) failed:.*99"):
        sharded.step(bad)
    with pytest.raises(RuntimeError, match="closed"):  # a failure stops every worker
        sharded.reset(seed=0)
