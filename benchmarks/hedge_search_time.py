"""CPU seconds of each search of the single-taxi hedge (``hedge(learned)``, uamfleet/rl/guided.py
``AnticipatingGuidedSearch``), on one core.

Issue 41 asks for "each hedge search ≤ 1 s of one core". The benchmark CSVs record a decision's wall time, which
on a shared machine counts other processes' time too; this script times every search (``_search``: the search over
sampled futures, and the last search over the known requests once nothing can come) with ``time.thread_time()``,
the CPU seconds of the searching thread alone, with one torch and one OpenMP thread. The hedge is flown as the
recorded tables fly it (``uamfleet bench --checkpoint ... --hedge --hover-action --hedge-wait-action hover``: the
registry's hedge defaults, its base traced) on validation instances, so the figures are of the same searches:

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/hedge_search_time.py --count 20
    OMP_NUM_THREADS=1 .venv/bin/python benchmarks/hedge_search_time.py --settings berlin:segment_raster --count 5

It prints, per setting, the searches' p50 / p95 / max CPU seconds and how many took over 1 s, and writes one row per
search to ``--out-csv`` when given.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch
import tyro

from uamfleet.instances import make_instance, split_seeds
from uamfleet.io import write_csv_atomic
from uamfleet.policies import make
from uamfleet.rollout import fly

EXIT_CHECKPOINT = Path("reports/2026-12-04-expert-iteration/berlin_exit.pt")


@dataclass
class Args:
    checkpoint: Path = EXIT_CHECKPOINT
    """the hedge's base policy (default: the expert-iteration policy of the recorded hedge tables)"""
    settings: tuple[str, ...] = ("berlin:endpoint_block", "berlin:segment_raster", "detroit3gpp:endpoint_block")
    """family:feasibility rule of each set of instances"""
    count: int = 20
    """instances per setting"""
    first: int = 0
    """the first seed's index in the split"""
    split: Literal["validation", "test"] = "validation"
    """the instances' split (timing the test set's searches chooses nothing)"""
    budget_s: float = 1.0
    """the target: CPU seconds a search may take"""
    out_csv: Path | None = None
    """one row per search (setting, seed, td_m, warmup, step, kind, cpu_s, wall_s)"""


def timed_searches(policy: Any, into: list[dict[str, Any]]) -> None:
    """Wrap ``policy._search`` so that each call appends its step, kind and thread CPU / wall seconds to ``into``;
    and the tracing at reset (``_trace_search_shapes``, before the first search), as kind ``reset``."""
    search, trace = policy._search, policy._trace_search_shapes

    def timed_trace() -> None:
        cpu, wall = time.thread_time(), time.perf_counter()
        trace()
        into.append(
            {"step": 0, "kind": "reset", "cpu_s": time.thread_time() - cpu, "wall_s": time.perf_counter() - wall}
        )

    def timed() -> list[int]:
        t = int(policy.sim.state.t[0])
        cpu, wall = time.thread_time(), time.perf_counter()
        out: list[int] = search()
        kind = "known" if policy._known_search_done else "futures"  # the search over the known requests alone
        into.append({"step": t, "kind": kind, "cpu_s": time.thread_time() - cpu, "wall_s": time.perf_counter() - wall})
        return out

    policy._search, policy._trace_search_shapes = timed, timed_trace


def fly_setting(args: Args, family: str, rule: str) -> list[dict[str, Any]]:
    """Every search of the hedge on ``args.count`` validation instances of ``family`` under ``rule``, by one policy
    loaded once (as a deployed planner is), and its tracing at each reset (kind ``reset``: the first instance's
    makes the traces); ``warmup`` marks the first instance's rows."""
    rows: list[dict[str, Any]] = []
    policy = make("hedge", base=("learned", {"source": str(args.checkpoint), "traced": True}), wait_action="hover")
    searches: list[dict[str, Any]] = []
    timed_searches(policy, searches)
    seeds = split_seeds(args.split, args.count, args.first)
    for seed in seeds:
        cfg = make_instance(family, seed, feasibility=rule).replace(hover_action=True)  # type: ignore[arg-type]
        searches.clear()
        traj = fly(cfg, policy)
        td = float(np.asarray(traj.episode["distance_m"]).sum())
        for row in searches:
            rows.append(
                {"setting": f"{family}:{rule}", "seed": seed, "td_m": td, "warmup": int(seed == seeds[0]), **row}
            )
    return rows


def summary(rows: list[dict[str, Any]], budget_s: float) -> str:
    cpu = np.array([r["cpu_s"] for r in rows])
    wall = np.array([r["wall_s"] for r in rows])
    over = int((cpu > budget_s).sum())
    return (f"{len(cpu):>8} {np.median(cpu):>8.3f} {np.percentile(cpu, 95):>8.3f} {cpu.max():>8.3f} "
            f"{over:>6} {np.median(wall):>9.3f} {wall.max():>9.3f}")  # fmt: skip


def main(args: Args) -> list[dict[str, Any]]:
    torch.set_num_threads(1)
    print(f"hedge(learned) over {args.checkpoint}, hover wait, torch {torch.__version__}, 1 thread; "
          f"{args.split} seeds from {split_seeds(args.split, 1, args.first)[0]}, {args.count} per setting")  # fmt: skip
    print(f"{'setting':<28} {'kind':<8} {'searches':>8} {'p50 CPU':>8} {'p95 CPU':>8} {'max CPU':>8} "
          f"{'> ' + format(args.budget_s, 'g') + ' s':>6} {'p50 wall':>9} {'max wall':>9}")  # fmt: skip
    rows: list[dict[str, Any]] = []
    for setting in args.settings:
        family, _, rule = setting.partition(":")
        flown = fly_setting(args, family, rule or "endpoint_block")
        rows += flown
        first = next(r for r in flown if r["kind"] != "reset")
        print(f"{setting:<28} {'first':<8} {1:>8} {first['cpu_s']:>8.3f} (the first search of the loaded policy)")
        for kind in ("reset", "all", "futures", "known"):
            part = [r for r in flown if kind == r["kind"] or (kind == "all" and r["kind"] != "reset")]
            if part:
                print(f"{setting:<28} {kind:<8} {summary(part, args.budget_s)}", flush=True)
        if args.out_csv is not None:  # after each setting: a long run stopped keeps the settings it finished
            write_csv_atomic(args.out_csv, rows, list(rows[0]))
    return rows


if __name__ == "__main__":
    main(tyro.cli(Args))
