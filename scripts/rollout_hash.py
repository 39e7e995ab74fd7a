"""Fingerprints of seeded rollouts, to show that a refactor changed no number.

Steps the batched core (300 steps, random allowed actions, some disallowed ones) on berlin_random (E = 8,
A = 4), berlin_p4 with path shaping (E = 8, 60-step episodes, so autoreset runs; the table metric "path", and
"path_exact", the name since issue 12 of the earlier "path" metric, whose hashes it keeps), berlin_p4 as a 3-taxi
fleet under the segment rule with euclidean shaping and the stuck rule, and the PettingZoo face; hashes every
observation, reward, flag, info (events, terms, episode statistics, final observations) and global state. Run it
before and after a change and compare the output:

    OMP_NUM_THREADS=1 .venv/bin/python scripts/rollout_hash.py
"""

from __future__ import annotations

import dataclasses
import hashlib
from typing import Any

import numpy as np

import uamfleet


def feed(h: Any, x: Any) -> None:
    if isinstance(x, dict):
        for key in sorted(x):
            h.update(key.encode())
            feed(h, x[key])
    elif isinstance(x, tuple) and hasattr(x, "_fields"):
        for key in x._fields:
            h.update(key.encode())
            feed(h, getattr(x, key))
    elif isinstance(x, list | tuple):
        for v in x:
            feed(h, v)
    else:
        a = np.ascontiguousarray(np.asarray(x))
        h.update(str(a.dtype).encode())
        h.update(str(a.shape).encode())
        h.update(a.tobytes())


def core(name: str, env: uamfleet.VectorEnv, steps: int = 300) -> None:
    h = hashlib.sha256()
    rng = np.random.default_rng(123)
    obs, _ = env.reset(seed=7)
    feed(h, obs)
    for t in range(steps):
        mask = obs["action_mask"]
        actions = np.argmax(rng.random(mask.shape) * np.where(mask.any(-1, keepdims=True), mask, 1), -1)
        if t % 17 == 0:  # now and then a move that may be blocked
            actions = rng.integers(0, mask.shape[-1], size=actions.shape)
        obs, rew, term, trunc, info = env.step(actions)
        feed(h, (obs, rew, term, trunc, info))
        feed(h, env.global_state())
    print(f"{name:<40} {h.hexdigest()[:16]}")


def pettingzoo(name: str, env: uamfleet.UAMFleetParallelEnv, steps: int = 300) -> None:
    h = hashlib.sha256()
    rng = np.random.default_rng(5)
    feed(h, env.reset(seed=3)[0])
    for _ in range(steps):
        if not env.agents:
            feed(h, env.reset()[0])
        actions = {a: int(rng.integers(16)) for a in env.agents}
        for part in (*env.step(actions), env.state()):
            feed(h, part)
    print(f"{name:<40} {h.hexdigest()[:16]}")


def main() -> None:
    path = uamfleet.RewardConfig(shaping=50.0, shaping_gamma=0.9, shaping_metric="path")
    euclid = uamfleet.RewardConfig(shaping=5.0, shaping_metric="euclidean")
    core("berlin_random E8 A4", uamfleet.vector_env("berlin_random", num_envs=8, num_taxis=4))
    core("berlin_p4 E8 path shaping", uamfleet.vector_env("berlin_p4", num_envs=8, reward=path, time_limit_steps=60))
    exact = dataclasses.replace(path, shaping_metric="path_exact")
    core(
        "berlin_p4 E8 path_exact shaping",
        uamfleet.vector_env("berlin_p4", num_envs=8, reward=exact, time_limit_steps=60),
    )
    core(
        "berlin_p4 E4 A3 segment_raster euclidean",
        uamfleet.vector_env(
            "berlin_p4", num_envs=4, num_taxis=3, feasibility="segment_raster", reward=euclid, max_block_visits=6
        ),
    )
    pettingzoo("pettingzoo berlin_random A3", uamfleet.parallel_env("berlin_random", num_taxis=3))


if __name__ == "__main__":
    main()
