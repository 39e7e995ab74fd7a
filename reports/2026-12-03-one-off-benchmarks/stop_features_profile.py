"""The stop features' cost: the step with them against the core without them, and where their time goes.

Part 1 times ``VectorEnv.step`` (dynamics, rewards, observations, autoreset) by this thread's CPU time, side by side
in one run, for each case with ``stop_features`` off and on (the scenario's other settings as they are; distance
tables filled before timing; random allowed actions drawn outside the timed calls).

Part 2 takes the states the observer hands the stop-feature kernels during such a rollout (snapshots, with the
kernels' per-episode caches as they were at that moment) and times, on a fresh copy of each, the kernels whole
(``stop_features``, ``stop_rivals``) and their parts (which overlap: each runs what it needs of the others):
the tour rests (``_update_rests``: the subset DP, or beyond ``MAX_EXACT_STOPS`` pending stops the nearest-stop
order's, when a taxi's stops or seats changed), the rows (the whole less the rests: the per-taxi look-ups to each
stop and after the moves, ``_progress_heading``), and the rivals/claims. With ``--lookahead``, part 1 also times the
step that observes ``heading_lookahead``, and part 2 its kernel (on the states as ``stop_features`` leaves them:
their kept tours up to date). Run on one core:

    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 taskset -c 0 .venv/bin/python reports/2026-12-03-one-off-benchmarks/stop_features_profile.py
    OMP_NUM_THREADS=1 NUMBA_NUM_THREADS=1 taskset -c 0 .venv/bin/python reports/2026-12-03-one-off-benchmarks/stop_features_profile.py \
        --lookahead --cases berlin_instances:64:1 berlin_random:64:1 berlin_random:64:4

Against another checkout (before/after in one session): ``benchmarks/run_against.py``.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass

import numpy as np
import tyro
from numba import njit

import uamfleet
from uamfleet.observe import stops, tours
from uamfleet.observe.tours import _update_rests
from uamfleet.observe.lookahead import heading_lookahead
from uamfleet.observe.observer import Observer
from uamfleet.paths import table_for
from uamfleet.paths.distance_table import TableArrays
from uamfleet.sim.world import WorldArrays
from uamfleet.types import NUM_HEADINGS, FleetState


@dataclass
class Args:
    cases: tuple[str, ...] = ("berlin_instances:64:1", "berlin_fleet:64:4", "berlin_fleet:64:8",
                              "berlin_random:64:4", "berlin_random:64:8")  # fmt: skip
    """scenario:E:A"""
    seconds: float = 3.0
    """time each configuration for about this long (thread CPU time)"""
    snapshots: int = 40
    """states kept for the kernel breakdown (one every few steps)"""
    every: int = 3
    """keep one state every this many steps"""
    lookahead: bool = False
    """with the heading look-ahead (EnvConfig.heading_lookahead) too: its step rate and its kernel's parts"""


def _allowed_actions(mask: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    scores = rng.random(mask.shape) * np.where(mask.any(-1, keepdims=True), mask, 1)
    return np.argmax(scores, axis=-1)


def make_env(
    scenario: str, num_envs: int, num_taxis: int, stop_features: bool, lookahead: bool = False
) -> uamfleet.VectorEnv:
    off = {} if stop_features else {"stop_rivals": False, "stop_claims": False}  # the fleet presets' extras too
    env = uamfleet.vector_env(scenario, num_envs=num_envs, num_taxis=num_taxis, stop_features=stop_features,
                              heading_lookahead=lookahead, **off)  # fmt: skip
    if stop_features:
        table_for(env.world).fill()
    return env


def step_rate(env: uamfleet.VectorEnv, seconds: float) -> float:
    """Agent-steps per second of thread CPU time spent in ``env.step``."""
    obs, _ = env.reset(seed=0)
    rng = np.random.default_rng(0)
    obs, *_ = env.step(_allowed_actions(obs["action_mask"], rng))  # compiles on a cold cache: not timed
    steps, elapsed = 0, 0.0
    while elapsed < seconds or steps < 5:
        actions = _allowed_actions(obs["action_mask"], rng)
        start = time.thread_time()
        obs, *_ = env.step(actions)
        elapsed += time.thread_time() - start
        steps += 1
    return steps * env.num_envs * env.world.cfg.num_taxis / elapsed


def snapshots(env: uamfleet.VectorEnv, count: int, every: int) -> list[FleetState]:
    """States as the observer receives them (after the dynamics, before the stop features), every few steps."""
    kept: list[FleetState] = []
    original = Observer._stop_fields
    calls = [0]

    def keep(self: Observer, state: FleetState, obs: dict[str, np.ndarray]) -> None:
        calls[0] += 1
        if calls[0] % every == 0 and len(kept) < count:
            kept.append(state.copy())
        original(self, state, obs)

    Observer._stop_fields = keep  # type: ignore[method-assign]
    try:
        obs, _ = env.reset(seed=1)
        rng = np.random.default_rng(1)
        while len(kept) < count:
            obs, *_ = env.step(_allowed_actions(obs["action_mask"], rng))
    finally:
        Observer._stop_fields = original  # type: ignore[method-assign]
    return kept


@njit  # not cached: a cached copy would keep the kernels it was compiled against (stale across checkouts)
def tour_rests_only(s: FleetState, w: WorldArrays, t: TableArrays) -> int:
    """Every taxi's tour rests as :func:`stops.stop_features` brings them up to date (``_update_rests``: the
    exact DP, or beyond ``MAX_EXACT_STOPS`` stops the nearest-stop order's, when its stops or seats changed);
    returns how many taxis' rests were computed (not kept from an earlier step)."""
    num_pax = s.pax_status.shape[1]
    pts = np.empty((2 * num_pax, 2))
    computed = 0
    for e in range(s.free_seats.shape[0]):
        for p in range(num_pax):
            pts[2 * p] = s.pax_origin_m[e, p]
            pts[2 * p + 1] = s.pax_dest_m[e, p]
        for a in range(s.free_seats.shape[1]):
            kept = s.stop_tour_key[e, a]
            if kept == tours._pending_key(s.pax_exists, s.pax_status, s.pax_taxi, s.free_seats, e, a):
                continue  # as stop_features: the key checked before the call (which costs ~0.25 us: it passes s)
            _update_rests(s, e, a, s.stop_pair_m[e], pts, t)
            computed += s.stop_tour_key[e, a] != kept
    return computed


def _time(kernel, states: list[FleetState], *args) -> float:  # type: ignore[no-untyped-def]
    """Thread CPU seconds of ``kernel(copy, *args)`` summed over fresh copies of ``states``."""
    kernel(states[0].copy(), *args)  # compile
    total = 0.0
    for s in states:
        c = s.copy()
        start = time.thread_time()
        kernel(c, *args)
        total += time.thread_time() - start
    return total


def breakdown(scenario: str, num_envs: int, num_taxis: int, args: Args) -> None:
    env = make_env(scenario, num_envs, num_taxis, True, args.lookahead)
    states = snapshots(env, args.snapshots, args.every)
    table = table_for(env.world)
    w = env.world.arrays
    agent_steps = len(states) * num_envs * num_taxis
    layout = env.observer.layout
    fields = ("stop_paths", "stop_heading_mask")
    paths = [np.empty((num_envs, num_taxis, *layout[k].shape), layout[k].dtype) for k in fields]
    whole = _time(stops.stop_features, states, w, table.arrays, *paths)
    rests = _time(tour_rests_only, states, w, table.arrays)
    rows: list[tuple[str, float]] = [
        ("stop_features (whole)", whole),
        ("  tour rests (_update_rests)", rests),
        ("  rows: look-ups (whole - rests)", whole - rests),
    ]
    if "stop_rivals" in layout:
        rivals = np.empty((num_envs, num_taxis, *layout["stop_rivals"].shape), np.float32)
        shape = layout["stop_claims"].shape if "stop_claims" in layout else None
        claims = np.empty((num_envs, num_taxis, *shape), np.int8) if shape else np.zeros((0, 0, 0, 0), np.int8)
        rows.append(("stop_rivals (+ claims)", _time(stops.stop_rivals, states, w, table.arrays,
                                                     rivals, claims)))  # fmt: skip
    if args.lookahead:
        after = [s.copy() for s in states]  # the kept tours as stop_features leaves them (not timed)
        for s in after:
            stops.stop_features(s, w, table.arrays, *paths)
        look = np.empty((num_envs, num_taxis, NUM_HEADINGS), np.float32)
        rows.append(("heading_lookahead (whole)", _time(heading_lookahead, after, w, table.arrays, look)))
    exact = 0
    for s in states:
        for e in range(num_envs):
            for a in range(num_taxis):
                exact += tours._pending_stops(s, e, a, np.empty(tours.MAX_EXACT_STOPS, np.int64),
                                                np.empty(tours.MAX_EXACT_STOPS, np.int64)) >= 0  # fmt: skip
    share = 1.0 - exact / (len(states) * num_envs * num_taxis)
    print(f"\n{scenario}, E = {num_envs}, A = {num_taxis}, P = {env.world.cfg.max_passengers}: {len(states)} "
          f"observed states; taxis with more than MAX_EXACT_STOPS pending stops: {share:.0%}")  # fmt: skip
    print(f"{'kernel':<44} {'us / agent-step':>16} {'agent-steps/s':>14}")
    for name, seconds in rows:
        rate = agent_steps / seconds if seconds > 0 else math.inf
        print(f"{name:<44} {1e6 * seconds / agent_steps:>16.2f} {rate:>14,.0f}")


def main(args: Args) -> None:
    cases = [(name, int(e), int(a)) for name, e, a in (c.split(":") for c in args.cases)]
    print("env.step, agent-steps per second of thread CPU time (stop features off | on | on with the look-ahead)")
    print(f"{'scenario':<18} {'E':>4} {'A':>3} {'core':>12} {'+ stop feat.':>13} {'ratio':>6}"
          + (f" {'+ look-ahead':>13}" if args.lookahead else ""))  # fmt: skip
    for scenario, num_envs, num_taxis in cases:
        core = step_rate(make_env(scenario, num_envs, num_taxis, False), args.seconds)
        full = step_rate(make_env(scenario, num_envs, num_taxis, True), args.seconds)
        line = f"{scenario:<18} {num_envs:>4} {num_taxis:>3} {core:>12,.0f} {full:>13,.0f} {core / full:>5.1f}x"
        if args.lookahead:
            line += f" {step_rate(make_env(scenario, num_envs, num_taxis, True, True), args.seconds):>13,.0f}"
        print(line, flush=True)
    for scenario, num_envs, num_taxis in cases:
        breakdown(scenario, num_envs, num_taxis, args)


if __name__ == "__main__":
    main(tyro.cli(Args))
