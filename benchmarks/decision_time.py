"""Decision latency of a learned planner: milliseconds per policy call and per taxi, on one CPU core.

A call is what a deployed planner does every step: normalise the observation, run the network, take the
greedy heading (``GreedyPolicy.__call__``), for a batch of taxis at once. Observations come from real episodes of
the policy's own observer (Berlin instances, random demand), and the policy's first calls (allocations) are not
timed. The observation itself (the stop features and, for the look-ahead policy, ``heading_lookahead``) is built by
the env's step, outside the call: it is timed apart (``Observer.observe`` inside each step), and the last column adds
the two, what a deployed planner spends per decision. Run on one core, with the shipped Berlin generalist or any
checkpoint:

    OMP_NUM_THREADS=1 taskset -c 0 .venv/bin/python benchmarks/decision_time.py
    OMP_NUM_THREADS=1 taskset -c 0 .venv/bin/python benchmarks/decision_time.py --checkpoint runs/x/best.pt
"""

from __future__ import annotations

import copy
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch
import tyro

from uamfleet.presets import make_config
from uamfleet.env.vector_env import VectorEnv
from uamfleet.types import FleetState
from uamfleet.zoo import pretrained_path
from uamfleet.rl.loop_guard import LoopGuard
from uamfleet.rl.policy import load_policy


@dataclass
class Args:
    checkpoint: Path | None = None
    """a checkpoint (default: the shipped Berlin generalist)"""
    batch: tuple[int, ...] = (1, 4, 8, 64)
    """taxis decided per call"""
    calls: int = 300
    threads: int = 1
    traced: bool = False
    """run the actor as TorchScript traces (``GreedyPolicy.trace_actor``: the same logits)"""
    both: bool = False
    """time the eager and the traced actor in turn, call by call, on the same observations (paired)"""


def main(args: Args) -> list[dict[str, float]]:
    torch.set_num_threads(args.threads)
    path = args.checkpoint if args.checkpoint is not None else pretrained_path("berlin")
    policy, _ = load_policy(path)
    assert policy.trained_on is not None
    policy.trace_actor(args.traced)
    if args.both:
        return paired(policy, args)
    print(f"policy: {path} ({sum(p.numel() for p in policy.net.parameters()):,} parameters), "
          f"torch {torch.__version__}, {args.threads} thread(s)")  # fmt: skip
    print(f"{'taxis per call':>15} {'p50 ms/call':>12} {'p95 ms/call':>12} {'p50 ms/taxi':>12} "
          f"{'p50 ms/obs':>11} {'p50 obs+call':>13}")  # fmt: skip
    rows = []
    for batch in args.batch:
        cfg = make_config("berlin_instances", sinr_min_db=-5.0, num_taxis=policy.trained_on.num_taxis)
        env = VectorEnv(cfg, num_envs=batch, observer=policy.spec)  # observed as the policy reads
        observe_times: list[float] = []
        env.observer.observe = _timed(env.observer.observe, observe_times)  # type: ignore[method-assign]
        obs, _ = env.reset(seed=0)
        times, obs_times = [], []
        for i in range(args.calls + 10):
            start = time.perf_counter()
            actions = policy(obs)
            if i >= 10:
                times.append(time.perf_counter() - start)
            before = len(observe_times)
            obs, *_ = env.step(actions)
            if i >= 9:  # the observation the next (timed) call decides on, an episode's first one included
                obs_times.append(sum(observe_times[before:]))
        ms = 1000 * np.array(times)
        obs_ms = 1000 * np.array(obs_times[: len(times)])
        both_ms = ms + obs_ms
        taxis = batch * cfg.num_taxis
        row = {
            "taxis": taxis,
            "p50_ms": float(np.median(ms)),
            "p95_ms": float(np.percentile(ms, 95)),
            "p50_observe_ms": float(np.median(obs_ms)),
            "p50_observe_and_call_ms": float(np.median(both_ms)),
        }
        rows.append(row)
        print(f"{taxis:>15} {row['p50_ms']:>12.3f} {row['p95_ms']:>12.3f} {row['p50_ms'] / taxis:>12.3f} "
              f"{row['p50_observe_ms']:>11.3f} {row['p50_observe_and_call_ms']:>13.3f}")  # fmt: skip
    return rows


def paired(policy, args: Args) -> list[dict[str, float]]:  # type: ignore[no-untyped-def]
    """Eager and traced calls alternated on the same observations; p50 ms per call of each, and whether every
    traced action equals the eager one."""
    traced = copy.copy(policy)  # the same network, its own traces and loop guard
    traced._traces = {}
    traced.loop_guard = LoopGuard() if policy.loop_guard is not None else None
    traced.trace_actor()
    policy.trace_actor(False)
    assert policy.trained_on is not None
    rows = []
    print(f"{'taxis per call':>15} {'eager p50 ms':>13} {'traced p50 ms':>14} {'same actions':>13}")
    for batch in args.batch:
        cfg = make_config("berlin_instances", sinr_min_db=-5.0, num_taxis=policy.trained_on.num_taxis)
        env = VectorEnv(cfg, num_envs=batch, observer=policy.spec)  # observed as the policy reads
        obs, _ = env.reset(seed=0)
        eager_s, traced_s, same = [], [], True
        for i in range(args.calls + 10):
            order = (policy, traced) if i % 2 else (traced, policy)
            out = {}
            for p in order:
                start = time.perf_counter()
                out[id(p)] = p(obs)
                (eager_s if p is policy else traced_s).append(time.perf_counter() - start)
            same &= bool(np.array_equal(out[id(policy)], out[id(traced)]))
            obs, *_ = env.step(out[id(policy)])
        row = {"taxis": batch * cfg.num_taxis, "eager_p50_ms": 1000 * float(np.median(eager_s[10:])),
               "traced_p50_ms": 1000 * float(np.median(traced_s[10:])), "same": float(same)}  # fmt: skip
        rows.append(row)
        print(f"{row['taxis']:>15} {row['eager_p50_ms']:>13.3f} {row['traced_p50_ms']:>14.3f} {same!s:>13}")
    return rows


def _timed(observe: Callable[[FleetState], dict[str, np.ndarray]], into: list[float]):  # type: ignore[no-untyped-def]
    """``observe`` that appends its wall-clock seconds to ``into``."""

    def timed(state: FleetState) -> dict[str, np.ndarray]:
        start = time.perf_counter()
        out = observe(state)
        into.append(time.perf_counter() - start)
        return out

    return timed


if __name__ == "__main__":
    main(tyro.cli(Args))
