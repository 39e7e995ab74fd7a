"""What the two-move look-ahead and the loop guard cost per decision, thread CPU time on one core.

The look-ahead kernel (``heading_lookahead``) alone, at depth 1 and 2, on 64 envs of ``berlin_instances`` at
-4 dB flying the least look-ahead heading (the kernel timed between steps, per taxi-step); then the loop guard's
call (``LoopGuard.choose``) on a lone taxi's observation of the shipped policy (docs/benchmarks.md):

    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/lookahead_cost.py
"""

from __future__ import annotations

import time

import numpy as np

import uamfleet
from uamfleet.observe.lookahead import heading_lookahead
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import instance_for_policy, split_seeds
from uamfleet.presets import make_config
from uamfleet.rl.loop_guard import LoopGuard


def kernel_us(depth: int, num_envs: int = 64, steps: int = 150, warm_up: int = 10) -> float:
    cfg = make_config("berlin_instances", sinr_min_db=-4.0, heading_lookahead=True, lookahead_depth=depth)
    env = VectorEnv(cfg, num_envs=num_envs)
    obs, _ = env.reset(seed=0)
    table = env.observer.table
    assert table is not None
    out = np.empty((num_envs, 1, 16), np.float32)
    total, count = 0.0, 0
    for k in range(steps):
        allowed = obs["action_mask"][:, 0].astype(bool)
        best = np.where(allowed, obs["heading_lookahead"][:, 0], np.inf).argmin(-1)
        obs, *_ = env.step(best[:, None])
        start = time.thread_time()
        heading_lookahead(env.state, env.world.arrays, table.arrays, out, depth)
        if k >= warm_up:
            total, count = total + time.thread_time() - start, count + num_envs
    return 1e6 * total / count


def guard_us(calls: int = 2000) -> float:
    policy = uamfleet.pretrained("berlin")
    assert policy.trained_on is not None
    cfg = policy.layout(instance_for_policy("berlin", split_seeds("validation", 1)[0], policy.trained_on))
    obs, _ = VectorEnv(cfg, num_envs=1, autoreset=False).reset(seed=0)
    logits = policy.logits_of(policy.network_input(obs)).numpy()
    guard = LoopGuard()
    for _ in range(200):
        guard.choose(obs, logits)
    times = []
    for _ in range(calls):
        start = time.thread_time_ns()
        guard.choose(obs, logits)
        times.append(time.thread_time_ns() - start)
    return float(np.median(times)) / 1e3


if __name__ == "__main__":
    for depth in (1, 2):
        print(f"look-ahead kernel, depth {depth}: {kernel_us(depth):.1f} us per taxi-step (thread CPU)")
    print(f"loop guard, a lone taxi's call: {guard_us():.1f} us (p50 of 2,000, thread CPU)")
