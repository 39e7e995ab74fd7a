"""Decision time per taxi and step on Berlin and on Munich, side by side in one run: the shipped fleet policy and a
dispatcher on the same fleet setting, with and without the shield.

    OMP_NUM_THREADS=1 OMP_WAIT_POLICY=PASSIVE .venv/bin/python benchmarks/decision_time_maps.py \\
        --out-csv docs/results/decision_time_maps.csv

Each map's instances are the fleet benchmark's (:func:`uamfleet.instances.make_fleet_instance`, test seeds 2,000,000,
...): Berlin's family, and Munich's packaged ray-traced map (``uamfleet.load_radio_map("munich")``) drawn by Berlin's
rules as ``scripts/fly_city.py`` registers it (the family ``munich``, the preset ``munich_random``), so its seeds draw
the instances that ``fly_city.py --fleet 4x24`` flew. Every method flies with the hover action, as the shipped fleet
policy (``uamfleet.pretrained("berlin_fleet")``, zero-shot on Munich) was trained to. The episodes are interleaved
seed by seed, shield mode by shield mode, alternating which map flies first, so that both maps see the same load of a
shared machine. Before timing, one whole episode of each (map, shield, method) on a seed that is not measured is
flown untimed (numba compiles the shield's and the dispatchers' kernels at first use, torch allocates at its first
call); the first call of that warm-up is printed apart (``first call ms``). A dispatcher's per-stop distance fields
are computed before it flies, untimed, as in the fleet benchmark.

Timed per step: the policy's call (wall clock, ``time.perf_counter``, as the fleet benchmark's decision column, and
the thread's CPU, ``time.thread_time``, which time spent descheduled does not inflate), divided by the taxis; and the
env's step (dynamics, shield and the observation the policy reads next) per taxi. Per (map, shield, method), over
every step of every measured episode: p50, p95 and max of each, and the ratio Munich / Berlin of the p50 and p95.
``--threads`` sets torch's intra-op threads (default 1; the rows record it).
"""

from __future__ import annotations

import os
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

import uamfleet
from uamfleet import instances
from uamfleet.baselines.fleet_steering import shared_fields
from uamfleet.cli._common import run
from uamfleet.cli.fleet_benchmark import dispatcher, setting_size
from uamfleet.env.protocol import observer_of
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import FLEET_ARRIVAL_WINDOW_S, make_fleet_instance, split_seeds
from uamfleet.io import write_csv_atomic
from uamfleet.metrics import episode_metrics
from uamfleet.rollout import run_episode

COLUMNS = ("map", "setting", "taxis", "separation", "method", "threads", "episodes", "steps", "delivered_pct",
           "td_per_delivered_m", "p50_ms", "p95_ms", "max_ms", "mean_ms", "cpu_p50_ms", "cpu_p95_ms", "cpu_max_ms",
           "step_p50_ms", "step_p95_ms", "first_call_ms")  # fmt: skip


@dataclass
class Args:
    maps: tuple[str, ...] = ("berlin", "munich")
    """instance families (munich: the packaged map by Berlin's rules, registered here)"""
    setting: str = "4x24"
    """taxis x requests"""
    seeds: int = 3
    """measured episodes per (map, shield, method): test seeds from the first"""
    policies: tuple[str, ...] = ("berlin_fleet",)
    """shipped policies (uamfleet.pretrained names), flown as they are"""
    dispatchers: tuple[str, ...] = ("batch_assignment",)
    separations: tuple[str, ...] = ("none", "shield")
    threads: int = 1
    """torch intra-op threads"""
    out_csv: Path | None = None
    """the summary rows (one per map, shield and method); none: printed only"""


class Timed:
    """A policy whose calls are timed: wall clock and the thread's CPU, seconds per call."""

    def __init__(self, policy: Any) -> None:
        self.policy = policy
        self.spec = observer_of(policy)
        self.wall_s: list[float] = []
        self.cpu_s: list[float] = []

    def reset(self, sim: Any) -> None:
        reset = getattr(self.policy, "reset", None)
        if callable(reset):
            reset(sim)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        act = getattr(self.policy, "act", self.policy)
        start, cpu = time.perf_counter(), time.thread_time()
        actions = act(obs)
        self.cpu_s.append(time.thread_time() - cpu)
        self.wall_s.append(time.perf_counter() - start)
        return actions


def register_munich() -> None:
    """The family ``munich`` as the recorded rows drew it: the packaged map's preset ``munich_random`` drawn by
    Berlin's rules unscaled (thresholds -7 ... -3 dB, trips >= 500 m), named in place of the packaged map's derived
    family (uamfleet.instances.map_family)."""
    berlin = instances.FAMILIES["berlin"]
    instances.FAMILIES["munich"] = instances.InstanceFamily("munich_random", berlin.thresholds_db,
                                                            berlin.min_trip_m)  # fmt: skip


def fly_timed(cfg: Any, name: str, policy: Any, is_dispatcher: bool) -> dict[str, Any]:
    """One episode of ``policy`` on ``cfg``: its per-step call times, env step times and metrics."""
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy))
    if is_dispatcher:  # the fields every dispatcher steers by, computed before it flies (the fleet benchmark's rule)
        env.reset(seed=0)
        shared_fields(env.sim, warm=True)
    step, step_s = env.step, []

    def timed_step(actions: np.ndarray) -> Any:
        start = time.perf_counter()
        out = step(actions)
        step_s.append(time.perf_counter() - start)
        return out

    env.step = timed_step  # type: ignore[method-assign]
    timed = Timed(policy)
    traj = run_episode(env, timed, seed=0)
    m = episode_metrics(traj, cfg.radio)
    return {"wall_s": timed.wall_s, "cpu_s": timed.cpu_s, "step_s": step_s, "pr_pct": m.pr_pct, "td_m": m.td_m,
            "delivered": m.delivered, "name": name}  # fmt: skip


def summary(key: tuple[str, str, str], taxis: int, setting: str, threads: int, runs: list[dict[str, Any]],
            first_call_ms: float) -> dict[str, Any]:  # fmt: skip
    """One row: the percentiles over every step of the episodes ``runs``, in ms per taxi."""
    wall = 1000.0 * np.concatenate([r["wall_s"] for r in runs]) / taxis
    cpu = 1000.0 * np.concatenate([r["cpu_s"] for r in runs]) / taxis
    step = 1000.0 * np.concatenate([r["step_s"] for r in runs]) / taxis
    delivered = sum(r["delivered"] for r in runs)
    return {
        "map": key[0], "setting": setting, "taxis": taxis, "separation": key[1], "method": key[2],
        "threads": threads, "episodes": len(runs), "steps": len(wall),
        "delivered_pct": float(np.mean([r["pr_pct"] for r in runs])),
        "td_per_delivered_m": sum(r["td_m"] for r in runs) / max(delivered, 1),
        "p50_ms": float(np.median(wall)), "p95_ms": float(np.percentile(wall, 95)), "max_ms": float(wall.max()),
        "mean_ms": float(wall.mean()), "cpu_p50_ms": float(np.median(cpu)),
        "cpu_p95_ms": float(np.percentile(cpu, 95)), "cpu_max_ms": float(cpu.max()),
        "step_p50_ms": float(np.median(step)), "step_p95_ms": float(np.percentile(step, 95)),
        "first_call_ms": first_call_ms,
    }  # fmt: skip


def fleet_config(args: Args, family: str, seed: int, separation: str) -> Any:
    """The fleet instance of ``seed`` at ``args.setting``, hovering, under ``separation``."""
    taxis, requests = setting_size(args.setting)
    return make_fleet_instance(family, seed, taxis, requests, separation=separation, hover_action=True)


def warm_up(args: Args, methods: dict[str, tuple[Any, bool]], seed: int) -> dict[tuple[str, str, str], float]:
    """One untimed episode of each method on each map and shield on a seed not measured; the first call's ms per
    taxi of each (map, separation, method)."""
    taxis, _ = setting_size(args.setting)
    first_call: dict[tuple[str, str, str], float] = {}
    for separation in args.separations:
        for family in args.maps:
            cfg = fleet_config(args, family, seed, separation)
            for name, (policy, is_dispatcher) in methods.items():
                run = fly_timed(cfg, name, policy, is_dispatcher)
                first_call[(family, separation, name)] = 1000.0 * run["wall_s"][0] / taxis
    return first_call


def measure(
    args: Args, methods: dict[str, tuple[Any, bool]], seeds: list[int]
) -> dict[tuple[str, str, str], list[dict[str, Any]]]:
    """Each method's timed episodes on each seed, map and shield (the maps' order alternating by seed, so neither
    map always runs first), printed as they end."""
    taxis, _ = setting_size(args.setting)
    runs: dict[tuple[str, str, str], list[dict[str, Any]]] = {}
    for i, seed in enumerate(seeds):
        for separation in args.separations:
            for family in args.maps if i % 2 == 0 else args.maps[::-1]:
                cfg = fleet_config(args, family, seed, separation)
                for name, (policy, is_dispatcher) in methods.items():
                    run = fly_timed(cfg, name, policy, is_dispatcher)
                    runs.setdefault((family, separation, name), []).append(run)
                    ms = 1000.0 * np.asarray(run["wall_s"]) / taxis
                    print(f"{seed} {family:>7} {separation:>6} {name:>22}: {len(ms)} steps, delivered "
                          f"{run['delivered']}, TD {run['td_m']:,.0f} m; ms per taxi-step p50 {np.median(ms):.3f} "
                          f"max {ms.max():.1f}", flush=True)  # fmt: skip
    return runs


def main(args: Args) -> list[dict[str, Any]]:
    taxis, _ = setting_size(args.setting)
    if args.seeds < 1 or args.threads < 1:
        raise ValueError(f"--seeds {args.seeds} --threads {args.threads}: give both >= 1.")
    torch.set_num_threads(args.threads)
    register_munich()
    for family in args.maps:
        instances.check_family(family)
    methods: dict[str, tuple[Any, bool]] = {f"learned:{p}": (uamfleet.pretrained(p), False) for p in args.policies}
    methods |= {d: (dispatcher(d, taxis, None, FLEET_ARRIVAL_WINDOW_S), True) for d in args.dispatchers}
    omp = ", ".join(f"{k}={os.environ.get(k, '(unset)')}" for k in ("OMP_WAIT_POLICY", "OMP_NUM_THREADS"))
    print(f"torch {torch.__version__}, {torch.get_num_threads()} thread(s); {omp}; {args.setting}, {args.seeds} "
          f"seed(s), methods {list(methods)}", flush=True)  # fmt: skip
    *seeds, warm_seed = split_seeds("test", args.seeds + 1)
    start = time.perf_counter()
    first_call = warm_up(args, methods, warm_seed)
    print(f"warm-up: {time.perf_counter() - start:.1f} s; first call ms per taxi: "
          + ", ".join(f"{'/'.join(k)} {v:.1f}" for k, v in first_call.items()), flush=True)  # fmt: skip
    runs = measure(args, methods, seeds)
    rows = [summary(key, taxis, args.setting, args.threads, r, first_call[key]) for key, r in runs.items()]
    print_table(rows, args.maps)
    print(f"wall-clock {time.perf_counter() - start:.0f} s")
    if args.out_csv is not None:
        write_csv_atomic(args.out_csv, rows, COLUMNS)
        print(f"wrote {args.out_csv}")
    return rows


def print_table(rows: list[dict[str, Any]], maps: tuple[str, ...]) -> None:
    """Per shield and method: each map's decision ms per taxi-step (wall p50 / p95 / max, CPU p50) and env step
    ms per taxi (p50), and the ratio of each other map to the first (p50, p95)."""
    print(f"\n{'shield':>6} {'method':>22} {'map':>7} {'p50':>7} {'p95':>7} {'max':>7} {'cpu p50':>8} "
          f"{'step p50':>9} {'ratio p50':>10} {'ratio p95':>10}")  # fmt: skip
    by_key = {(r["separation"], r["method"], r["map"]): r for r in rows}
    for separation, method in dict.fromkeys((r["separation"], r["method"]) for r in rows):
        base = by_key.get((separation, method, maps[0]))
        for family in maps:
            r = by_key[(separation, method, family)]
            ratio = (f"{r['p50_ms'] / base['p50_ms']:>10.2f} {r['p95_ms'] / base['p95_ms']:>10.2f}"
                     if base is not None and family != maps[0] else "")  # fmt: skip
            print(f"{separation:>6} {method:>22} {family:>7} {r['p50_ms']:>7.3f} {r['p95_ms']:>7.3f} "
                  f"{r['max_ms']:>7.1f} {r['cpu_p50_ms']:>8.3f} {r['step_p50_ms']:>9.3f} {ratio}")  # fmt: skip


if __name__ == "__main__":
    sys.exit(run(main, Args, None, "decision_time_maps.py", __doc__))
