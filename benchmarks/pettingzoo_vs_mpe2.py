"""The PettingZoo face against MPE2's ``simple_spread_v3``, per agent-step, side by side in one run.

Both are PettingZoo ``ParallelEnv`` s stepped the same way: every live agent gets a random action each step
(ours: uniform over the allowed headings of its ``action_mask``; MPE2: uniform over its 5 discrete moves;
both drawn with Python's ``random``), an empty agent list is answered with ``reset()``, and the time includes
the action choice, the steps, the resets and the dicts both return. The two alternate in short rounds (ours,
MPE2, ours, ...) so that a busy machine slows both alike; each figure is the best round. Needs the ``bench``
extra (``pip install -e '.[bench]'``). Run on one core:

    OMP_NUM_THREADS=1 taskset -c 0 .venv/bin/python benchmarks/pettingzoo_vs_mpe2.py
"""

from __future__ import annotations

import random
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any


import uamfleet
from uamfleet.cli._common import run


@dataclass
class Args:
    num_agents: tuple[int, ...] = (1, 3, 8)
    scenario: str = "berlin_p4"
    """our scenario (any of uamfleet.SCENARIOS; its time limit ends our episodes)"""
    max_cycles: int = 25
    """MPE2's episode length (its default)"""
    seconds: float = 0.5
    """length of one timed round"""
    rounds: int = 10
    """rounds per env (alternating); the best is reported"""


Act = Callable[[Any, dict[str, Any], random.Random], dict[str, int]]


def ours(scenario: str, n: int) -> tuple[Any, Act]:
    env = uamfleet.parallel_env(scenario, num_taxis=n)

    def act(env: Any, obs: dict[str, Any], rng: random.Random) -> dict[str, int]:
        out = {}
        for agent in env.agents:
            allowed = obs[agent]["action_mask"].nonzero()[0]
            out[agent] = int(allowed[rng.randrange(len(allowed))]) if len(allowed) else 0
        return out

    return env, act


def simple_spread(n: int, max_cycles: int) -> tuple[Any, Act]:
    from mpe2 import simple_spread_v3

    env = simple_spread_v3.parallel_env(N=n, max_cycles=max_cycles, continuous_actions=False)

    def act(env: Any, obs: dict[str, Any], rng: random.Random) -> dict[str, int]:
        return {agent: rng.randrange(5) for agent in env.agents}

    return env, act


def timed_round(env: Any, act: Act, obs: dict[str, Any], seconds: float) -> tuple[float, Any]:
    """(agent-steps per second, last observations) of stepping ``env`` for about ``seconds``."""
    rng = random.Random(0)
    agent_steps, start = 0, time.perf_counter()
    while True:
        for _ in range(50):
            if not env.agents:
                obs, _ = env.reset()
            actions = act(env, obs, rng)
            obs, *_ = env.step(actions)
            agent_steps += len(actions)
        elapsed = time.perf_counter() - start
        if elapsed >= seconds:
            return agent_steps / elapsed, obs


def main(args: Args) -> dict[int, tuple[float, float]]:
    from importlib.metadata import version

    print(f"PettingZoo face ({args.scenario}, uamfleet {uamfleet.__version__}) vs MPE2 simple_spread_v3 "
          f"(mpe2 {version('mpe2')}, max_cycles {args.max_cycles}); "
          f"best of {args.rounds} x {args.seconds:g} s")  # fmt: skip
    print(f"{'N':>3} {'ours agent-steps/s':>19} {'MPE2 agent-steps/s':>19} {'ours / MPE2':>12}")
    out = {}
    for n in args.num_agents:
        runs = {"ours": ours(args.scenario, n), "mpe2": simple_spread(n, args.max_cycles)}
        best = dict.fromkeys(runs, 0.0)
        last_obs = {}
        for name, (env, act) in runs.items():
            last_obs[name], _ = env.reset(seed=0)
            timed_round(env, act, last_obs[name], 0.2)  # warm-up (numba dispatch, caches)
            last_obs[name], _ = env.reset(seed=0)
        for _ in range(args.rounds):
            for name, (env, act) in runs.items():
                rate, last_obs[name] = timed_round(env, act, last_obs[name], args.seconds)
                best[name] = max(best[name], rate)
        for env, _ in runs.values():
            env.close()
        out[n] = (best["ours"], best["mpe2"])
        print(f"{n:>3} {best['ours']:>19,.0f} {best['mpe2']:>19,.0f} {best['ours'] / best['mpe2']:>11.2f}x")
    return out


if __name__ == "__main__":
    raise SystemExit(run(main, Args, None, "benchmarks/pettingzoo_vs_mpe2.py", __doc__))
