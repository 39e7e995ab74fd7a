"""Fly every planner and the shipped generalist (zero-shot) on a ray-traced city map: uamfleet-benchmark's table.

    .venv/bin/python scripts/fly_city.py --map munich.npz --count 20 --jobs 2 --out-md munich_benchmark.md
    .venv/bin/python scripts/fly_city.py --map munich.npz --fleet 4x24 --count 20 --jobs 2 --out-md munich_fleet.md

The instances are the test instances of the map's family (:func:`uamfleet.instances.map_family`: Berlin's rules
scaled to the map, thresholds from its SINR quantiles where Berlin's do not bind; ``--map`` is a packaged map's
name or a map file's path, and the family is named after it, so the seeds draw other instances than Berlin's),
exactly as ``uamfleet-benchmark --map MAP`` flies them. Each instance is flown by
:func:`uamfleet.cli.benchmark.run_instance`, the rows summarised by :func:`uamfleet.cli.benchmark_tables.markdown`
under the map's provenance. The generalist is ``uamfleet.pretrained("berlin")``'s checkpoint, never trained on this
map. Workers are spawned: each rebuilds the family from the map's name or path.

``--fleet 4x24`` flies the fleet dispatchers and the first shipped fleet policy
(``uamfleet.pretrained("berlin_fleet_v1")``, zero-shot, as its recorded rows were flown) on fleet instances of that
setting instead (:func:`uamfleet.instances.make_fleet_instance`), with
:func:`uamfleet.cli.fleet_benchmark.run_episode_set` and its table.
"""

from __future__ import annotations

import argparse
import multiprocessing as mp
import sys
import time
from pathlib import Path

from uamfleet import instances
from uamfleet.baselines import FLEET_DISPATCHERS
from uamfleet.cli import benchmark, fleet_benchmark
from uamfleet.cli._common import UsageError, check_map, with_provenance
from uamfleet.io import write_csv_atomic, write_text_atomic
from uamfleet.zoo import pretrained_path


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--map", required=True, help="a packaged map's name or a map file (.npz of uamfleet-radio-map)")
    parser.add_argument("--count", type=int, default=20, help="test instances (seeds 2000000, ...)")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument(
        "--threads",
        type=int,
        default=1,
        help="torch CPU threads per worker (default 1: the workers "
        "share the cores; torch's default of every core made Munich's decisions 8 x slower)",
    )
    parser.add_argument("--methods", nargs="*", default=list(benchmark.METHODS))
    parser.add_argument("--no-generalist", action="store_true", help="fly only the planners")
    parser.add_argument("--fleet", default=None, help="a fleet setting (e.g. 4x24): the fleet table instead")
    parser.add_argument("--out-csv", type=Path, default=None)
    parser.add_argument("--out-md", type=Path, required=True)
    args = parser.parse_args(argv)
    for path in (args.out_md, args.out_csv):
        if path is not None and path.exists():
            print(f"fly_city.py: error: {path} exists; remove it or write elsewhere", file=sys.stderr)
            return 2
    if args.threads < 1:
        print(f"fly_city.py: error: --threads {args.threads}: give at least 1 thread per worker", file=sys.stderr)
        return 2
    try:
        family = check_map(args.map)
    except UsageError as err:
        print(f"fly_city.py: error: {err}", file=sys.stderr)
        return 2
    seeds = instances.split_seeds("test", args.count)
    if args.fleet is not None:
        policies = () if args.no_generalist else (pretrained_path("berlin_fleet_v1"),)  # as recorded: no hover action
        jobs: list = [(family, args.fleet, seed, FLEET_DISPATCHERS, policies, "none", False) for seed in seeds]
        flight, table, columns = fleet_benchmark.run_episode_set, fleet_benchmark.markdown, fleet_benchmark.COLUMNS
    else:
        checkpoint = None if args.no_generalist else pretrained_path("berlin")
        methods = tuple(args.methods) + (() if checkpoint is None else ("learned",))
        options = benchmark.job_options(benchmark.Args())  # best_known 256, replan 64, guided 8 / 24 / 2.0
        jobs = [benchmark.Job(("test", family, seed, None, "endpoint_block"), methods, checkpoint, options)
                for seed in seeds]  # fmt: skip
        flight, table, columns = benchmark.run_instance, benchmark.markdown, benchmark.COLUMNS
    start = time.perf_counter()
    rows = []
    with mp.get_context("spawn").Pool(args.jobs, fleet_benchmark.limit_threads, (args.threads,)) as pool:
        for i, result in enumerate(pool.imap(flight, jobs)):
            rows += result
            print(f"[{i + 1}/{len(jobs)}] {len(result)} rows", flush=True)
    wall = time.perf_counter() - start
    command = "python scripts/fly_city.py " + " ".join(argv)
    if args.out_csv is not None:
        write_csv_atomic(args.out_csv, rows, columns)
    body = with_provenance(table(rows, command, wall), args.map)
    write_text_atomic(args.out_md, body)
    print(body)
    return 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
