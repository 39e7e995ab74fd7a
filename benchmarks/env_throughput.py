"""Environment throughput: agent-steps per second of the batched core and the PettingZoo face.

A step is the full step: dynamics, rewards, observations and action masks (plus autoreset): the time of
``env.step`` alone. Actions are random allowed headings, drawn outside the timed calls (the policy's time is
not the env's), and the first step (numba compiles on a cold cache) is not timed. Run on one core:

    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 taskset -c 0 .venv/bin/python benchmarks/env_throughput.py --seconds 3

The shaping cases (issue 12) time the same step with the potential-based shaping term on, per
``RewardConfig.shaping_metric``, at one (E, A); ``path`` fills its distance table before the timed steps (the
fill time is printed: a training run pays it once per map and threshold, spread over its first episodes):

    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 taskset -c 0 .venv/bin/python benchmarks/env_throughput.py \
        --num-envs 64 --num-taxis 4 --shaping-metrics none path path_exact euclidean --no-pettingzoo --cpu-time

``--stop-features`` times the step with path shaping and the stop features (the generalist's observation):

    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 taskset -c 0 .venv/bin/python benchmarks/env_throughput.py \
        --num-envs 64 --num-taxis 1 4 --stop-features --shaping-metrics none path --no-pettingzoo --cpu-time
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass

import numpy as np
import tyro

import uamfleet
from uamfleet.env.parallel_env import UAMFleetParallelEnv
from uamfleet.paths import table_for


@dataclass
class Args:
    scenario: str = "berlin_random"
    num_envs: tuple[int, ...] = (1, 64, 256)
    num_taxis: tuple[int, ...] = (1, 4, 16)
    seconds: float = 2.0
    """time each configuration for about this long"""
    pettingzoo_scenario: str = "berlin_p4"
    shaping_metrics: tuple[str, ...] = ()
    """also time the step with shaping (weight 50) under each of these metrics ("none": shaping off), at every
    (E, A) above"""
    stop_features: bool = False
    """also time the step with path shaping AND the stop features (EnvConfig.stop_features: per stop the
    feasible-path distance and progress heading), at every (E, A) above"""
    lookahead: bool = False
    """with --stop-features: also time it with the heading look-ahead (EnvConfig.heading_lookahead), side by side"""
    pettingzoo: bool = True
    """also time the PettingZoo face"""
    cpu_time: bool = False
    """time the core's steps by this thread's CPU time (time.thread_time) instead of the wall clock: on a machine
    shared with other work, time spent descheduled then does not count (caches shared with it still do)"""


def _allowed_actions(mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    scores = rng.random(mask.shape) * np.where(mask.any(-1, keepdims=True), mask, 1)
    return np.argmax(scores, axis=-1)


def bench_core(
    scenario: str, num_envs: int, num_taxis: int, seconds: float, cpu_time: bool = False, shaping: str = "none",
    stop_features: bool = False, lookahead: bool = False,
) -> float:  # fmt: skip
    clock = time.thread_time if cpu_time else time.perf_counter
    reward = uamfleet.RewardConfig(shaping=0.0 if shaping == "none" else 50.0)
    if shaping != "none":
        reward = dataclasses.replace(reward, shaping_metric=shaping)
    env = uamfleet.vector_env(
        scenario, num_envs=num_envs, num_taxis=num_taxis, reward=reward, stop_features=stop_features,
        heading_lookahead=lookahead,
    )  # fmt: skip
    if shaping == "path" or stop_features:
        start = time.perf_counter()
        table = table_for(env.world).fill()
        took = time.perf_counter() - start
        print(f"  (path table: {table.shape[0]} x {table.shape[1]} blocks, filled in {took:.1f} s)")
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    obs, *_ = env.step(_allowed_actions(obs["action_mask"], rng))  # compiles on a cold cache: not timed
    steps, elapsed = 0, 0.0
    while True:
        actions = _allowed_actions(obs["action_mask"], rng)  # the policy's time: not timed
        start = clock()
        obs, *_ = env.step(actions)
        elapsed += clock() - start
        steps += 1
        if elapsed > seconds and steps >= 5:
            return steps * num_envs * num_taxis / elapsed


def bench_pettingzoo(scenario: str, num_taxis: int, seconds: float) -> float:
    env = UAMFleetParallelEnv(uamfleet.make_config(scenario, num_taxis=num_taxis))
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    steps, start = 0, time.perf_counter()
    while True:
        if not env.agents:
            obs, _ = env.reset()
        actions = {a: int(_allowed_actions(obs[a]["action_mask"][None], rng)[0]) for a in env.agents}
        obs, *_ = env.step(actions)
        steps += 1
        elapsed = time.perf_counter() - start
        if elapsed > seconds and steps >= 5:
            return steps / elapsed


def main(args: Args) -> None:
    clock = "thread CPU time" if args.cpu_time else "wall clock"
    print(f"core: {args.scenario}, full step incl. observations and masks ({clock})")
    print(f"{'E':>5} {'A':>4} {'agent-steps/s':>15} {'env-steps/s':>13}")
    for num_envs in args.num_envs:
        for num_taxis in args.num_taxis:
            rate = bench_core(args.scenario, num_envs, num_taxis, args.seconds, args.cpu_time)
            print(f"{num_envs:>5} {num_taxis:>4} {rate:>15,.0f} {rate / num_taxis:>13,.0f}")
    if args.shaping_metrics:
        shaping_table(args, clock)
    if args.stop_features:
        stop_features_table(args, clock)
    if args.pettingzoo:
        pettingzoo_table(args)


def shaping_table(args: Args, clock: str) -> None:
    """The core's rate with shaping on, per metric of ``--shaping-metrics``, at every (E, A)."""
    print(f"\ncore with shaping (weight 50), {args.scenario} ({clock})")
    print(f"{'E':>5} {'A':>4} {'shaping_metric':>15} {'agent-steps/s':>15}")
    for num_envs in args.num_envs:
        for num_taxis in args.num_taxis:
            for metric in args.shaping_metrics:
                rate = bench_core(args.scenario, num_envs, num_taxis, args.seconds, args.cpu_time, metric)
                print(f"{num_envs:>5} {num_taxis:>4} {metric:>15} {rate:>15,.0f}")


def stop_features_table(args: Args, clock: str) -> None:
    """The core's rate with path shaping and the stop features (and the look-ahead beside it) at every (E, A)."""
    print(f"\ncore with path shaping (weight 50) and the stop features, {args.scenario} ({clock})")
    print(f"{'E':>5} {'A':>4} {'agent-steps/s':>15}" + (f" {'with look-ahead':>16}" if args.lookahead else ""))
    for num_envs in args.num_envs:
        for num_taxis in args.num_taxis:
            rate = bench_core(args.scenario, num_envs, num_taxis, args.seconds, args.cpu_time, "path", True)
            line = f"{num_envs:>5} {num_taxis:>4} {rate:>15,.0f}"
            if args.lookahead:
                look = bench_core(args.scenario, num_envs, num_taxis, args.seconds, args.cpu_time, "path", True,
                                  lookahead=True)  # fmt: skip
                line += f" {look:>16,.0f}"
            print(line)


def pettingzoo_table(args: Args) -> None:
    """The PettingZoo face's rate (one env) at every A."""
    print(f"\nPettingZoo face: {args.pettingzoo_scenario} (E = 1)")
    print(f"{'A':>4} {'env-steps/s':>13} {'agent-steps/s':>15}")
    for num_taxis in args.num_taxis:
        rate = bench_pettingzoo(args.pettingzoo_scenario, num_taxis, args.seconds)
        print(f"{num_taxis:>4} {rate:>13,.0f} {rate * num_taxis:>15,.0f}")


if __name__ == "__main__":
    main(tyro.cli(Args))
