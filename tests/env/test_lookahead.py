"""The ``heading_lookahead`` field (uamfleet/env/lookahead.py) against the env's own step: each heading flown in a
copy of the env over the requests known so far, costed as the move plus the shortest tour the copy then observes."""

from __future__ import annotations

import numpy as np
import pytest

from uamfleet.baselines.step_planner import released_only
from uamfleet.config import ConfigError, make_config
from uamfleet.env.vector_env import VectorEnv
from uamfleet.types import LOOKAHEAD_CLIP, NUM_HEADINGS, STOP_PATH_TO_STOP, STOP_TOUR_VIA_STOP


def _expected_lookahead(env: VectorEnv, e: int, scratch: VectorEnv) -> tuple[np.ndarray, bool]:
    """[16] each heading's move + shortest tour after it, minus the best, in moves, by stepping a copy of env e; and
    whether some heading's move serves a stop."""
    root = released_only(env.state)
    for target, source in zip(scratch.state, root, strict=True):
        target[:] = source[e : e + 1]
    obs, _, terminated, truncated, info = scratch.step(np.arange(NUM_HEADINGS)[:, None])
    assert not truncated.any(), "the test's flight must end before the time limit"
    side, step = env.cfg.side_m, env.cfg.step_m
    cost = np.empty(NUM_HEADINGS)
    for h in range(NUM_HEADINGS):
        paths = obs["stop_paths"][h, 0]
        offered = paths[:, STOP_PATH_TO_STOP] > 0
        tour = 0.0 if terminated[h] or not offered.any() else float(paths[offered, STOP_TOUR_VIA_STOP].min()) * side
        cost[h] = step * info["events"].moved[h, 0] + tour
    allowed = env.state.action_mask[e, 0].astype(bool)
    out = np.full(NUM_HEADINGS, LOOKAHEAD_CLIP)
    out[allowed] = np.minimum((cost[allowed] - cost[allowed].min()) / step, LOOKAHEAD_CLIP)
    served = bool(info["events"].picked_up.any() or info["events"].dropped_off.any())
    return out, served


def test_lookahead_is_the_move_plus_the_tour_the_step_leaves() -> None:
    cfg = make_config("berlin_instances", sinr_min_db=-4.0, heading_lookahead=True)
    env = VectorEnv(cfg, num_envs=4)
    scratch = VectorEnv(cfg, num_envs=NUM_HEADINGS, autoreset=True)
    scratch.reset(seed=0)
    obs, _ = env.reset(seed=3)
    rng = np.random.default_rng(1)
    checked = served_by_a_move = 0
    for _ in range(30):
        for e in range(env.num_envs):
            if not obs["stop_heading_mask"][e, 0].any():
                assert not obs["heading_lookahead"][e, 0].any(), "no stop: all zero"
                continue
            expected, served = _expected_lookahead(env, e, scratch)
            np.testing.assert_allclose(obs["heading_lookahead"][e, 0], expected, atol=2e-3)
            checked += 1
            served_by_a_move += served
        # fly the best look-ahead heading mostly (so that stops get served), sometimes a random allowed one
        allowed = obs["action_mask"][:, 0].astype(bool)
        best = np.where(allowed, obs["heading_lookahead"][:, 0], np.inf).argmin(-1)
        random = np.array([rng.choice(np.flatnonzero(a)) for a in allowed])
        actions = np.where(rng.random(env.num_envs) < 0.8, best, random)
        obs, *_ = env.step(actions[:, None])
    assert checked > 80 and served_by_a_move > 3  # the branch that serves stops at the move's end is exercised


def test_lookahead_needs_the_stop_features() -> None:
    with pytest.raises(ConfigError, match="heading_lookahead=True needs stop_features=True"):
        make_config("berlin_p4", heading_lookahead=True)
