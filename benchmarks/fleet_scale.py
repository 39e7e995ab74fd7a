"""Wall time, peak memory and decision time of every fleet method at a city's scale: the fleet-size table.

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/fleet_scale.py --family berlin munich \\
        --settings 32x1000 --out-csv docs/results/fleet_scale_32x1000.csv
    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/fleet_scale.py --settings 4x125 8x250 16x500 \\
        32x1000 64x2000 --methods greedy learned --out-csv docs/results/fleet_scale_sizes.csv

Each (family, setting, seed, method) is one episode of :func:`uamfleet.cli.fleet_benchmark.run_episode_set` (the
fleet benchmark's own flight: the same instance, env, dispatchers and metrics) in a fresh spawned process with one
torch thread, one process at a time, so that its peak RSS is that method's alone. Requests are released over
``--arrival-window-s`` (default 3 hours), under the separation shield with the hover action (as the recorded
fleet tables). ``learned`` is ``uamfleet.pretrained("berlin_fleet")`` reading a passenger window of
``--passenger-window`` rows (24, as recorded). Before the measured episode the worker flies the same method on a
2-taxi, 4-request instance, so that compiling the kernels is not in the figures.

Columns: wall s (the per-stop distance fields the dispatchers share, ``fields_s``, plus the flight), s per step
(the flight ÷ steps, env step included), peak RSS MB of the worker, decision ms per taxi and step (the policy's
wall time per step ÷ taxis: median and maximum over the steps), service %, separation losses (taxi-steps closer
than the minimum separation) and shield interventions. Rows are written to ``--out-csv`` after each episode.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import resource
import sys
import time
from pathlib import Path
from typing import Any

from uamfleet.baselines.assignment_value import CHOSEN_DISPATCHER
from uamfleet.cli.fleet_benchmark import limit_threads, run_episode_set, setting_size
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.io import write_csv_atomic
from uamfleet.policies import available, make, parse
from uamfleet.policies.registry import PolicyNameError
from uamfleet.zoo import pretrained_path

METHODS = ("greedy", "insertion", "batch_assignment", CHOSEN_DISPATCHER, "learned")
COLUMNS = ("family", "setting", "taxis", "requests", "seed", "arrival_window_s", "method", "steps", "wall_s",
           "fields_s", "fly_s", "s_per_step", "peak_rss_mb", "decision_p50_ms", "decision_max_ms", "service_pct",
           "delivered", "separation_violations", "shield_interventions", "wait_p50_s", "wait_p95_s",
           "td_per_delivered_m")  # fmt: skip
Job = tuple[str, str, int, str, float, int]  # (family, setting, seed, method, arrival_window_s, passenger_window)


def method_error(name: str) -> str | None:
    """Why ``name`` is no method this benchmark flies (``learned``, or a fleet dispatcher of the registry with its
    options checked), in the registry's words; None when it is one."""
    if name == "learned":
        return None
    try:
        call, options = parse(name)
        if available()[call][0] != "dispatcher":
            kind = available()[call][0]
            return f"--methods {name!r} is a {kind}; name a fleet dispatcher (e.g. {METHODS}) or learned."
        make(call, **options)
    except (PolicyNameError, ValueError) as err:
        return str(err)
    return None


def episode_job(family: str, setting: str, seed: int, method: str, arrival_s: float, window: int) -> tuple:
    """The fleet benchmark's job of one method on one instance, shielded, with the hover action."""
    dispatchers, checkpoints = ((), (pretrained_path("berlin_fleet"),)) if method == "learned" else ((method,), ())
    return (family, setting, seed, dispatchers, checkpoints, "shield", True, window, arrival_s, None)


def measure(job: Job) -> dict[str, Any]:
    """One episode of one method in this (fresh) process, after a small warm-up episode; its row."""
    family, setting, seed, method, arrival_s, window = job
    limit_threads(1)
    run_episode_set(episode_job(family, "2x4", seed, method, 60.0, window))  # compiles the kernels, untimed
    (row,) = run_episode_set(episode_job(family, setting, seed, method, arrival_s, window))
    taxis, requests = setting_size(setting)
    return {
        "family": family, "setting": setting, "taxis": taxis, "requests": requests, "seed": seed,
        "arrival_window_s": arrival_s, "method": row["dispatcher"], "steps": row["steps"],
        "wall_s": row["fields_s"] + row["policy_s"], "fields_s": row["fields_s"], "fly_s": row["policy_s"],
        "s_per_step": row["policy_s"] / row["steps"],
        "peak_rss_mb": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0,  # Linux: KiB
        "decision_p50_ms": row["decision_p50_ms"], "decision_max_ms": row["decision_max_ms"],
        "service_pct": row["service_pct"], "delivered": row["delivered"],
        "separation_violations": row["separation_violations"], "shield_interventions": row["shield_interventions"],
        "wait_p50_s": row["wait_p50_s"], "wait_p95_s": row["wait_p95_s"],
        "td_per_delivered_m": row["td_per_delivered_m"],
    }  # fmt: skip


def table(rows: list[dict[str, Any]]) -> str:
    lines = [
        "| family | taxis | requests | method | steps | wall s | s / step | peak RSS MB | decision / taxi-step p50 "
        "/ max ms | service % | separation losses | shield interventions |",
        "|---|---:|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    for r in rows:
        lines.append(
            f"| {r['family']} | {r['taxis']} | {r['requests']} | {r['method']} | {r['steps']:.0f} | "
            f"{r['wall_s']:,.1f} | {r['s_per_step']:.4f} | {r['peak_rss_mb']:,.0f} | "
            f"{r['decision_p50_ms']:.3f} / {r['decision_max_ms']:,.1f} | {r['service_pct']:.1f} | "
            f"{r['separation_violations']:.0f} | {r['shield_interventions']:.0f} |"
        )
    return "\n".join(lines)


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--family", nargs="+", default=["berlin"], help="families or packaged maps (munich)")
    parser.add_argument("--settings", nargs="+", default=["32x1000"], help="<taxis>x<requests>")
    parser.add_argument(
        "--methods", nargs="+", default=list(METHODS), help=f"default {METHODS}; any fleet dispatcher name, or learned"
    )
    parser.add_argument("--split", default="test")
    parser.add_argument("--count", type=int, default=1, help="episodes (seeds) per family and setting")
    parser.add_argument("--first", type=int, default=0, help="index of the first seed in the split")
    parser.add_argument("--arrival-window-s", type=float, default=3 * 3600.0)
    parser.add_argument("--passenger-window", type=int, default=24, help="rows the learned policy reads")
    parser.add_argument("--out-csv", type=Path, required=True)
    args = parser.parse_args(argv)
    errors = [e for e in map(method_error, args.methods) if e is not None]
    if errors or args.count < 1:
        parser.error(errors[0] if errors else "--count must be >= 1")
    seeds = split_seeds(args.split, args.count, args.first)
    for family in args.family:  # a setting or family the instances refuse is refused before anything flies
        for setting in args.settings:
            make_fleet_instance(family, seeds[0], *setting_size(setting), arrival_window_s=args.arrival_window_s)
    if args.out_csv.exists():
        parser.error(f"--out-csv {args.out_csv} exists; remove it or write elsewhere")
    jobs = [(family, setting, seed, method, args.arrival_window_s, args.passenger_window)
            for seed in seeds for family in args.family for setting in args.settings
            for method in args.methods]  # fmt: skip
    rows: list[dict[str, Any]] = []
    start = time.perf_counter()
    for job in jobs:  # one fresh process per episode: its peak RSS is the method's own
        with mp.get_context("spawn").Pool(1) as pool:
            row = pool.apply(measure, (job,))
        rows.append(row)
        write_csv_atomic(args.out_csv, rows, COLUMNS)
        print(table(rows[-1:]).splitlines()[-1], flush=True)
    print(table(rows))
    print(f"wrote {args.out_csv} ({(time.perf_counter() - start) / 60:.1f} min)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
