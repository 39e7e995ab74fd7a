"""Every planner over many seeded instances (and the paper's fixed ones), in parallel: the yardstick table.

    uamfleet-benchmark --count 200 --jobs 2                  # 200 Berlin test instances
    uamfleet-benchmark --fixed --count 0 --jobs 2             # Berlin P4 / Detroit P5 only
    uamfleet-benchmark --count 20 --checkpoint runs/x/best.pt # a learned policy beside them
    uamfleet-benchmark --count 50 --methods replan_futures   # replan scored on sampled futures (minutes each)

Instances come from :func:`uamfleet.instances.make_instance` (``--split test`` by default: never tune on it).
Every policy is flown through the same env and scored by :mod:`uamfleet.metrics`. Per set it writes PR, TD,
ATT, AWT and connectivity as means with 95 % intervals (normal approximation, 1.96 standard errors), TD /
best-known per instance (mean, p95, worst; instances where both delivered everyone), the mean lower bound
(:func:`uamfleet.baselines.step_planner.lower_bound_m`) and ``replan``'s decision latency. Outputs: a CSV of
every (instance, policy) row and the printed table (with ``--out-md FILE``, also the marked section ``benchmark``,
or ``--section``, of FILE; the results pages are generated from the CSVs by ``uamfleet docs-tables``), written
once, at the end of a complete run, and replacing existing results only with ``--overwrite``; a long run keeps
its partial rows beside the CSV (``<name>.partial.csv``; ``--from-csv`` renders them).
"""

from __future__ import annotations

import csv
import math
import multiprocessing as mp
import time
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np

import uamfleet
from uamfleet.baselines.planner_policy import PLANNERS, planner_env_overrides
from uamfleet.baselines.step_planner import STEP_PLANNERS, instance_lower_bound_m
from uamfleet.cli._common import (
    Family,
    Feasibility,
    MapName,
    Scenario,
    Split,
    UsageError,
    check_jobs,
    check_map,
    check_outputs,
    earlier_rows,
    fmt,
    output_paths,
    run,
    with_provenance,
)
from uamfleet.cli.benchmark_tables import markdown
from uamfleet.cli.docs_tables import REFRESH_HINT
from uamfleet.config import EnvConfig
from uamfleet.instances import make_instance, split_seeds
from uamfleet.io import partial_path, replace_section, write_csv_atomic
from uamfleet.metrics import episode_metrics
from uamfleet.policies import make, parse
from uamfleet.policies.learned import learned_policy
from uamfleet.policies.registry import BASE
from uamfleet.rl.guided import MAX_EXPERT_BEAM, MAX_FUTURES, MAX_SAMPLES, MAX_STEPS, check_demand_spec
from uamfleet.rollout import fly
from uamfleet.sim.generator import InfeasibleInstanceError, validate_instance
from uamfleet.sim.world import World
from uamfleet.types import NUM_HEADINGS

METHODS: tuple[str, ...] = (*PLANNERS, *STEP_PLANNERS)
"""The methods flown by default."""
FAMILY_MODELS: tuple[str, ...] = ("replan_futures", "hedge", "finish")
"""Policies that read the instance family's demand model (instances only: a fixed scenario has none)."""
SLOW_METHODS: tuple[str, ...] = ("replan_futures",)
"""Methods flown only when named (seconds per release): ``replan_futures``, the online search that scores its
plans on futures sampled from the instance family's demand (uamfleet/baselines/anticipation.py)."""
FIXED: tuple[tuple[str, tuple[float, ...]], ...] = (
    ("berlin_p4", (-7.0, -6.0, -5.0, -4.0, -3.0)),
    ("detroit_p5", (-17.0,)),
    ("detroit3gpp_p5", (-21.0, -20.0, -19.0, -18.0, -17.0)),
)
COLUMNS = ("set", "instance", "threshold_db", "feasibility", "num_requests", "method", "pr_pct", "td_m", "att_s",
           "awt_s", "connectivity_pct", "lower_bound_m", "steps", "policy_s", "decision_p50_ms",
           "decision_max_ms")  # fmt: skip


@dataclass
class Args:
    family: Family = "berlin"
    """instance family"""
    map: MapName = None
    split: Split = "test"
    count: int = 200
    """instances of the split (0: only --fixed)"""
    first: int = 0
    """index of the first seed in the split"""
    feasibility: Feasibility = "endpoint_block"
    fixed: bool = False
    """also the paper's fixed scenarios (Berlin P4 -7..-3 dB, Detroit P5) under both feasibility rules"""
    fixed_rules: tuple[Feasibility, ...] = ("endpoint_block", "segment_raster")
    fixed_scenarios: tuple[Scenario, ...] = tuple(s for s, _ in FIXED)
    fixed_thresholds: tuple[float, ...] = ()
    """only these thresholds of the fixed scenarios (empty: all)"""
    methods: tuple[str, ...] = METHODS
    """planners to fly: every one but the slow ``replan_futures`` unless named"""
    checkpoint: Path | None = None
    """a learned policy (runs/<name>/best.pt) flown beside the planners"""
    guided: bool = False
    """with --checkpoint: also fly that policy with search at decision time (method learned_guided,
    uamfleet/rl/guided.py): at each release its greedy flights after its --guided-top-k first headings and
    --guided-samples sampled flights, rolled forward over the known requests; the shortest is flown"""
    guided_top_k: int = 8
    guided_samples: int = 24
    guided_temperature: float = 2.0
    """softmax temperature of the sampled flights (the defaults were chosen on 25 validation instances)"""
    guided_expert_beam: int = 0
    """> 0: replan's beam search of this width over the known requests is one more candidate of guided search"""
    guided_horizon: int = 0
    """> 0: guided search rolls each candidate at most this many steps, ranks it by its moves plus its tour bound,
    flies that many steps and searches again (a rolling horizon: bounded latency on large maps); 0: to the end"""
    hedge: bool = False
    """with --checkpoint: also fly that policy with search over sampled futures (method learned_hedge,
    uamfleet/rl/guided.py AnticipatingGuidedSearch): while a request may still come, every --hedge-commit steps and
    at each release, its --hedge-first-headings most likely first headings, each followed by the policy, flown in
    --hedge-futures futures drawn from the instance family's demand model; the first heading of least mean distance
    is taken, or a wait in place where one is possible. Once nothing can come, one guided search of the policy's
    --guided-top-k first headings and --hedge-samples sampled flights. The defaults were chosen on 60 validation
    instances (reports/2026-12-03-results-history/README.md, "Hedging for the requests to come"). Instances only"""
    hedge_first_headings: int = 4
    hedge_futures: int = 8
    hedge_commit: int = 4
    hedge_samples: int = 8
    hedge_tail: int = 10
    """rollouts end this many steps after the demand model's last possible release, then a tour bound (-1: to the
    end)"""
    hedge_wait_action: Literal["forbidden", "hover"] = "forbidden"
    """the hedge's wait candidate: a heading the rule forbids, where one is, or the hover action (16) at any step
    (needs --hover-action)"""
    hedge_demand: tuple[str, ...] = ()
    """with --checkpoint: also fly the hedge with each of these demand models (method
    hedge:demand=<model>(learned:traced=true)): family (the true law of the instance family), a family's name, wrong
    (a deliberately wrong law), or a fitted model's .json (uamfleet demand fit)"""
    hover_action: bool = False
    """fly every instance in a world with the hover action (16: stay in place); its rows' set is named
    "<family> <split> hover". The planners never choose it"""
    finish_beam: int = 0
    """> 0 with --checkpoint: also fly that policy (and its guided search, with --guided) until the instance family's
    demand model says no request can come, then one step-level search of this width over the then-known requests
    (methods learned_finish, learned_guided_finish; uamfleet/baselines/finish.py); instances only"""
    best_known_beams: tuple[int, ...] = (256,)
    """beam widths of best_known's searches (rank slack 1.0 then 0.0 alternately; raster_opt is always a candidate)"""
    replan_beam: int = 64
    """beam width of replan's search at each release"""
    jobs: int = 2
    out_csv: Path = Path("docs/results/benchmark.csv")
    out_md: Path | None = None
    """Markdown file whose marked section is (re)written; without it no Markdown is written (the results pages are
    generated from --out-csv by `uamfleet docs-tables`)"""
    section: str = "benchmark"
    from_csv: Path | None = None
    """re-render the table from the CSV of an earlier run (lower bounds recomputed), flying nothing"""
    merge_csv: Path | None = None
    """add the rows of an earlier run's CSV (e.g. the planners) on the instances flown now to this run's, which
    flies only what is new (e.g. --methods with no planner and --checkpoint); rows of a method flown now replace
    its earlier rows"""
    wall_min: float = math.nan
    """with --from-csv: the wall-clock minutes of that run, for the table's note"""
    command: str = ""
    """the command line to print above the table (empty: this one, reconstructed)"""
    overwrite: bool = False
    """replace an existing --out-csv or --section of --out-md (else the command refuses before flying)"""


Task = tuple[str, str, Any, float | None, str]  # (set label, family or scenario, seed, threshold, feasibility)


def _config(task: Task) -> EnvConfig:
    label, source, seed, threshold, rule = task
    if label == "fixed":
        return uamfleet.make_config(source, sinr_min_db=threshold, feasibility=rule)
    return make_instance(source, int(seed), feasibility=rule)  # type: ignore[arg-type]


@dataclass(frozen=True)
class Job:
    """One instance and what flies on it (one worker process's work): ``methods`` by their recorded names
    (:func:`uamfleet.policies.parse` reads each as its call), ``checkpoint`` the learned methods' policy, and
    ``options`` the command line's options of each registered policy (``{"replan": {"beam": 64}, ...}``)."""

    task: Task
    methods: tuple[str, ...]
    checkpoint: Path | None = None
    options: dict[str, dict[str, Any]] = field(default_factory=dict)
    hover_action: bool = False  # the instance's world has the hover action


def job_options(args: Args) -> dict[str, dict[str, Any]]:
    """The options of each registered policy that ``args`` sets (the benchmark's defaults are the registry's)."""
    horizon = args.guided_horizon or None  # 0: to the end
    guided = {"top_k": args.guided_top_k, "temperature": args.guided_temperature,
              "expert_beam": args.guided_expert_beam, "horizon": horizon}  # fmt: skip
    return {
        "replan": {"beam": args.replan_beam},
        "best_known": {"beams": tuple(args.best_known_beams)},
        "guided": {**guided, "samples": args.guided_samples},
        "hedge": {**guided, "samples": args.hedge_samples, "first_headings": args.hedge_first_headings,
                  "futures": args.hedge_futures, "commit": args.hedge_commit, "tail": args.hedge_tail,
                  "wait_action": args.hedge_wait_action},
        "finish": {"beam": args.finish_beam},
    }  # fmt: skip


def hedge_method(model: str) -> str:
    """The method name of the hedge over the checkpoint's policy with the demand model ``model``."""
    return f"hedge:demand={model}(learned:traced=true)"


def method_call(name: str, options: dict[str, Any], job: Job) -> tuple[str, dict[str, Any]]:
    """The call of a method on the job's instance: the job's options of ``name`` under the method's own and the
    checkpoint for a learned policy (bases filled alike; a demand model's family is read from the world at reset)."""
    out = {**job.options.get(name, {}), **options}
    if name == "learned":
        assert job.checkpoint is not None
        out["source"] = str(job.checkpoint)
    if BASE in out:
        base_name, base_options = out[BASE]
        out[BASE] = method_call(base_name, base_options, job)
    return name, out


def is_learned_call(method: str, checkpoint: Path | None) -> bool:
    """``method`` is ``learned:<options>`` and a checkpoint is given for it (its options are checked by parsing)."""
    return checkpoint is not None and method.startswith("learned:") and parse(method)[0] == "learned"


def check_checkpoint(path: Path) -> None:
    """The benchmark's instances have one taxi: refuse a fleet policy (or an unreadable file) before flying."""
    policy = learned_policy(path)
    if policy.num_taxis != 1:
        raise UsageError(
            f"--checkpoint {path} was trained with {policy.num_taxis} taxis; the benchmark's instances have one "
            "taxi: give a policy trained with --num-taxis 1."
        )


def flown(method: str, job: Job, cfg: EnvConfig, name: str) -> tuple[EnvConfig, Any] | None:
    """(the config it flies, the policy) of ``method`` on the instance ``name``; None, after a line saying why,
    for one it cannot fly (a demand model on a fixed scenario, more passengers than a learned policy's slots)."""
    call = method_call(*parse(method), job)
    if job.task[0] == "fixed" and call[0] in FAMILY_MODELS:
        print(f"{method} skipped on {name}: a fixed scenario has no demand model", flush=True)
        return None
    overrides = planner_env_overrides(method) if method in PLANNERS else {}
    run_cfg = cfg.replace(**overrides) if overrides else cfg
    policy = make(call[0], **call[1])
    if method.startswith("learned"):  # the world as it is, observed by the policy's spec (rows beyond it padded)
        windowed = policy.spec.passenger_window is not None  # reads any number of requests
        if not windowed and run_cfg.num_passengers > policy.spec.slots(run_cfg.world):
            print(f"learned skipped on {name}: {run_cfg.num_passengers} passengers, the policy was trained on "
                  f"{policy.spec.slots(run_cfg.world)} slots", flush=True)  # fmt: skip
            return None
    return run_cfg, policy


def run_instance(job: Job) -> list[dict[str, Any]]:
    """Every method on one instance (one worker process)."""
    task = job.task
    try:
        cfg = _config(task)
        if job.hover_action:
            cfg = cfg.replace(hover_action=True)
        validate_instance(World(cfg), np.array(cfg.starts_m), cfg.requests or ())
    except InfeasibleInstanceError as err:  # e.g. a paper stop below the threshold under the strict rule
        print(f"skipped {task[1]} at {task[3]} dB ({task[4]}): {err}", flush=True)
        return []
    label, source, seed, _, rule = task
    name = f"{source}@{cfg.sinr_min_db:g}dB" if label == "fixed" else str(seed)
    bound = instance_lower_bound_m(cfg)
    rows = []
    for method in job.methods:
        flight = flown(method, job, cfg, name)
        if flight is None:
            continue
        start = time.perf_counter()
        traj = fly(*flight)
        elapsed = time.perf_counter() - start
        m = episode_metrics(traj, cfg.radio, threshold_db=cfg.sinr_min_db)
        decisions = np.asarray(traj.decision_s) * 1000.0
        rows.append({
            "set": (label if label == "fixed" else f"{source} {label}") + (" hover" if job.hover_action else ""),
            "instance": name,
            "threshold_db": cfg.sinr_min_db, "feasibility": rule, "num_requests": m.num_requests, "method": method,
            "pr_pct": m.pr_pct, "td_m": m.td_m, "att_s": m.att_s, "awt_s": m.awt_s,
            "connectivity_pct": m.connectivity_pct, "lower_bound_m": bound, "steps": m.steps, "policy_s": elapsed,
            "decision_p50_ms": float(np.median(decisions)), "decision_max_ms": float(decisions.max()),
        })  # fmt: skip
    return rows


def tasks(args: Args) -> list[Task]:
    family = args.family if args.map is None else args.map
    out: list[Task] = [
        (args.split, family, seed, None, args.feasibility) for seed in split_seeds(args.split, args.count, args.first)
    ]
    if args.fixed:
        for rule in args.fixed_rules:
            for scenario, thresholds in FIXED:
                if scenario in args.fixed_scenarios:
                    chosen = [t for t in thresholds if not args.fixed_thresholds or t in args.fixed_thresholds]
                    out += [("fixed", scenario, None, t, rule) for t in chosen]
    return out


def _instance_config(row: dict[str, Any]) -> EnvConfig:
    """The config of a CSV row's instance (``scenario@-3dB`` for fixed ones, the seed for generated ones)."""
    if row["set"] == "fixed":
        scenario, threshold = str(row["instance"]).split("@")
        return uamfleet.make_config(scenario, sinr_min_db=float(threshold[:-2]), feasibility=row["feasibility"])
    return make_instance(str(row["set"]).split()[0], int(row["instance"]), feasibility=row["feasibility"])


def read_rows(path: Path) -> list[dict[str, Any]]:
    """Rows of a benchmark CSV with numbers as floats and lower bounds recomputed (the bound may have improved)."""
    with path.open(encoding="utf-8") as f:
        rows: list[dict[str, Any]] = [
            {k: (v if k in ("set", "instance", "feasibility", "method") else float(v)) for k, v in r.items()}
            for r in csv.DictReader(f)
        ]
    bounds: dict[tuple[str, str, str], float] = {}
    for r in rows:
        key = (r["set"], r["instance"], r["feasibility"])
        if key not in bounds:
            bounds[key] = instance_lower_bound_m(_instance_config(r))
        r["lower_bound_m"] = bounds[key]
    return rows


def check_guided(args: Args) -> None:
    """The guided-search options make sense (with a checkpoint, within their bounds)."""
    if (args.guided or args.hedge) and args.checkpoint is None:
        flag = "--guided" if args.guided else "--hedge"
        raise UsageError(f"{flag} searches with a learned policy: give its --checkpoint as well.")
    _check_hedge(args)
    if (args.finish_beam and args.checkpoint is None) or not 0 <= args.finish_beam <= 4096:
        raise UsageError(f"--finish-beam {args.finish_beam}: a search width 0 <= beam <= 4096 (0: off, e.g. 16), for "
                         "the policy of a --checkpoint.")  # fmt: skip
    _check_guided_search(args)


def _check_hedge(args: Args) -> None:
    if not (1 <= args.hedge_first_headings <= NUM_HEADINGS and 1 <= args.hedge_futures <= MAX_FUTURES
            and 1 <= args.hedge_commit <= MAX_STEPS and -1 <= args.hedge_tail <= MAX_STEPS
            and 0 <= args.hedge_samples <= MAX_SAMPLES):  # fmt: skip
        raise UsageError(
            f"--hedge-first-headings {args.hedge_first_headings} / --hedge-futures {args.hedge_futures} / "
            f"--hedge-commit {args.hedge_commit} / --hedge-tail {args.hedge_tail} / --hedge-samples "
            f"{args.hedge_samples}: need 1 <= first headings <= {NUM_HEADINGS}, 1 <= futures <= {MAX_FUTURES}, "
            f"commit >= 1, tail >= -1 (-1: to the end), both at most {MAX_STEPS}, and 0 <= samples <= {MAX_SAMPLES} "
            "(e.g. 4, 8, 4, 10 and 8)."
        )


def _check_guided_search(args: Args) -> None:
    if not (1 <= args.guided_top_k <= NUM_HEADINGS and 0 <= args.guided_samples <= MAX_SAMPLES
            and math.isfinite(args.guided_temperature) and args.guided_temperature > 0
            and 0 <= args.guided_expert_beam <= MAX_EXPERT_BEAM and 0 <= args.guided_horizon <= MAX_STEPS):  # fmt: skip
        raise UsageError(
            f"--guided-top-k {args.guided_top_k} / --guided-samples {args.guided_samples} / --guided-temperature "
            f"{args.guided_temperature} / --guided-horizon {args.guided_horizon}: need 1 <= top-k <= {NUM_HEADINGS}, "
            f"0 <= samples <= {MAX_SAMPLES}, a finite temperature > 0 (e.g. 8, 24 and 2), 0 <= --guided-expert-beam "
            f"<= {MAX_EXPERT_BEAM} and --guided-horizon >= 0 (0: to the end), at most {MAX_STEPS}."
        )


def check_hedge_demand(args: Args) -> None:
    """Each --hedge-demand model: a known spec (a fitted model's .json must exist), with a learned policy to hedge."""
    for model in args.hedge_demand:
        if args.checkpoint is None:
            raise UsageError(f"--hedge-demand {model} hedges with a learned policy: give --checkpoint.")
        try:
            check_demand_spec(model)
        except ValueError as err:
            raise UsageError(f"--hedge-demand {model}: {err}") from None
        if model.endswith(".json") and not Path(model).is_file():
            raise UsageError(f"--hedge-demand {model}: no such file; fit one with `uamfleet demand fit`.")


def check_args(args: Args) -> list[Task]:
    """The instances to fly, once every option is valid, the selection is not empty and no existing result would
    be replaced without --overwrite: all checked before anything is flown or written."""
    if args.from_csv is not None:
        return []
    check_jobs(args.jobs)
    if args.map is not None:
        check_map(args.map)
    # "learned:<options>" flies the --checkpoint's policy with those options (e.g. learned:idle_wait=true)
    unknown = [m for m in args.methods if m not in METHODS + SLOW_METHODS and not is_learned_call(m, args.checkpoint)]
    if unknown:
        raise ValueError(
            f"unknown --methods {unknown}; choose from {METHODS + SLOW_METHODS}, or with --checkpoint "
            "learned:<options> (e.g. learned:idle_wait=true)."
        )
    if not args.methods and args.checkpoint is None:
        raise UsageError("--methods is empty and no --checkpoint is given: nothing to fly; name at least one method.")
    check_guided(args)
    check_hedge_demand(args)
    selected = tasks(args)
    if not selected:
        raise UsageError(
            f"no instance selected (--count {args.count}"
            + (", and --fixed-rules / --fixed-scenarios / --fixed-thresholds match none of the fixed instances"
               if args.fixed else " without --fixed")
            + "): fly at least one instance, e.g. --count 20."
        )  # fmt: skip
    if args.checkpoint is not None:
        check_checkpoint(args.checkpoint)
    output_paths({"--out-csv": args.out_csv, "--out-md": args.out_md})
    check_outputs(args.overwrite, [args.out_csv], args.out_md, args.section)
    return selected


def main(args: Args) -> list[dict[str, Any]]:
    selected = check_args(args)
    if args.from_csv is not None:
        earlier = earlier_rows(read_rows, args.from_csv)
        check_outputs(args.overwrite, [args.out_csv], args.out_md, args.section)
        write_outputs(args, earlier, 60.0 * args.wall_min)
        return earlier
    learned: tuple[str, ...] = ("learned", "learned_guided") if args.guided else ("learned",)
    learned += tuple(f"{m}_finish" for m in learned) if args.finish_beam else ()  # recorded names (aliases)
    learned += ("learned_hedge",) if args.hedge else ()
    learned += tuple(hedge_method(model) for model in args.hedge_demand)
    methods = tuple(args.methods) + (learned if args.checkpoint is not None else ())
    jobs = [Job(t, methods, args.checkpoint, job_options(args), args.hover_action) for t in selected]
    start = time.perf_counter()
    rows = fly_all(args, jobs)
    if not rows:
        raise UsageError(f"none of the {len(jobs)} selected instances could be flown (see above); nothing written.")
    if args.merge_csv is not None:
        rows = merged(read_rows(args.merge_csv), rows)
    write_outputs(args, rows, time.perf_counter() - start)
    partial_path(args.out_csv).unlink(missing_ok=True)
    return rows


def fly_all(args: Args, jobs: list[Any]) -> list[dict[str, Any]]:
    """Every job on ``args.jobs`` processes, a line per instance as it finishes; the rows so far are kept beside
    the CSV (every 10 instances, or each of fewer than 50) so an interruption loses little."""
    rows: list[dict[str, Any]] = []
    with mp.get_context("spawn").Pool(min(args.jobs, len(jobs))) as pool:
        for i, result in enumerate(pool.imap(run_instance, jobs)):
            rows += result
            if not result:
                continue
            best = next((r for r in result if r["method"] == "best_known"), None)
            print(f"[{i + 1}/{len(jobs)}] {result[0]['instance']} {result[0]['feasibility']}: "
                  + "  ".join(f"{r['method']} {r['td_m']:.0f}" for r in result)
                  + (f"  (LB {best['lower_bound_m']:.0f})" if best else ""), flush=True)  # fmt: skip
            if ((i + 1) % 10 == 0 or len(jobs) < 50) and i + 1 < len(jobs):  # survive an interruption, beside
                write_csv_atomic(partial_path(args.out_csv), rows, COLUMNS)
    return rows


def merged(earlier: list[dict[str, Any]], rows: list[dict[str, Any]]) -> list[dict[str, Any]]:
    """``--merge-csv``: an earlier run's rows on the instances flown now, of the other methods, before the new."""
    flown = {r["method"] for r in rows}
    instances = {(r["set"], r["instance"], r["feasibility"]) for r in rows}
    kept = [
        r for r in earlier
        if r["method"] not in flown and (r["set"], r["instance"], r["feasibility"]) in instances
    ]  # fmt: skip
    return kept + rows


def guided_flags(args: Args) -> str:
    """The guided-search and hedging options of a run, as its recorded command line gives them ("" without
    --guided or --hedge)."""
    hedge = (f" --hedge --hedge-first-headings {args.hedge_first_headings} --hedge-futures {args.hedge_futures} "
             f"--hedge-commit {args.hedge_commit} --hedge-tail {args.hedge_tail} --hedge-samples {args.hedge_samples}"
             ) if args.hedge else ""  # fmt: skip
    if not args.guided:
        return hedge
    flags = (f" --guided --guided-top-k {args.guided_top_k} --guided-samples {args.guided_samples} "
             f"--guided-temperature {args.guided_temperature:g}")  # fmt: skip
    flags += f" --guided-expert-beam {args.guided_expert_beam}" if args.guided_expert_beam else ""
    return flags + (f" --guided-horizon {args.guided_horizon}" if args.guided_horizon else "") + hedge


def write_outputs(args: Args, rows: list[dict[str, Any]], wall: float, note: str = "") -> None:
    """The CSV and the Markdown section of a complete run (each written atomically)."""
    write_csv_atomic(args.out_csv, rows, COLUMNS)
    command = args.command or (
        "uamfleet-benchmark "
        + (f"--family {args.family} " if args.map is None else f"--map {args.map} ")
        + f"--split {args.split} --count {args.count} "
        f"--first {args.first} --feasibility {args.feasibility} --jobs {args.jobs} "
        f"--best-known-beams {' '.join(map(str, args.best_known_beams))} --replan-beam {args.replan_beam}"
        + (" --fixed" if args.fixed else "")
        + (f" --methods {' '.join(args.methods)}" if tuple(args.methods) != METHODS else "")
        + (f" --checkpoint {args.checkpoint}" if args.checkpoint is not None else "")
        + guided_flags(args)
        + (f" --finish-beam {args.finish_beam}" if args.finish_beam else "")
        + (f" --merge-csv {args.merge_csv}" if args.merge_csv is not None else "")
        + (" --overwrite" if args.overwrite else "")
    )
    minutes = fmt(wall / 60, ".1f", " min")  # "–" when re-rendered from a CSV of unknown wall-clock
    body = with_provenance(markdown(rows, command, wall, note), args.map)
    if args.out_md is None:
        print(body)
        print(f"wrote {args.out_csv} ({minutes}){note}")
        print(REFRESH_HINT)
    else:
        replace_section(args.out_md, args.section, body)
        print(f"wrote {args.out_csv} and the {args.section} section of {args.out_md} ({minutes}){note}")


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-benchmark") -> int:
    """The ``uamfleet-benchmark`` command (``python -m eval.benchmark``)."""
    return run(main, Args, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.benchmark"))
