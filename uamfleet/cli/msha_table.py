"""MSHA-PPO results (issue 5): Berlin P4 at -7 … -3 dB and Detroit P5 at -17 dB beside the paper and the raster
planners (raster_replan, raster_opt: not optima of the env's moves, see eval.benchmark); the ablation
(LE / DE / DE + MSFea / full) at Berlin -3 dB; and the training cost.

    uamfleet-msha-table                       # trains the missing runs (2 at a time), writes tables
    uamfleet-msha-table --only berlin_p4_-3   # a subset (substring of the run names)
    uamfleet-msha-table --no-train            # tables from the runs already under runs/msha

Each run is ``train/ppo.py`` with the trainer's defaults (one CPU thread each, ``--jobs`` runs side by side);
its log is ``runs/msha/<name>.log``. A run whose ``best.pt`` exists is not trained again unless ``--retrain``.
The best greedy checkpoint of each run is flown once through the same environment as the planners and scored
by :mod:`uamfleet.metrics`. Training cost comes from the run's ``progress.csv`` (greedy evaluation every 5
iterations): agent-steps and wall-clock seconds to the first evaluation that delivers everyone, that is at or
below the paper's TD, and that is within 5 % of raster_opt.

Writes ``docs/results/msha_table.csv`` (``--out-csv`` changes it, e.g. for a second table under the strict
``segment_raster`` rule) and prints the tables; the results pages are generated from that CSV by
``uamfleet docs-tables``. ``--out-md FILE`` also (re)writes the marked section ``msha_table`` (``--section``) of
the Markdown file FILE.
"""

from __future__ import annotations

from collections.abc import Sequence

import math
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal


import uamfleet
from uamfleet.cli._common import UsageError, Variant, check_jobs, check_outputs, output_paths, run
from uamfleet.cli._common import fmt as fmt_value
from uamfleet.cli.docs_tables import REFRESH_HINT
from uamfleet.cli.paper_numbers import PAPER_TABLE_II
from uamfleet.baselines.planner_policy import PlannerPolicy, planner_configs
from uamfleet.io import replace_section, write_csv_atomic
from uamfleet.metrics import EpisodeMetrics, episode_metrics
from uamfleet.rl.networks import VARIANTS
from uamfleet.rl.policy import load_policy
from uamfleet.rl.runs import read_progress
from uamfleet.rollout import fly

PAPER_KEY = {"berlin_p4": "berlin", "detroit_p5": "detroit"}
# The paper's Table III (PR % of each variant; TD only where the task succeeded), Berlin -3 dB and Detroit -17 dB.
PAPER_ABLATION_PR = {"berlin": {"le": 25, "de": 75, "de_msfea": 100, "full": 100},
                     "detroit": {"le": 20, "de": 80, "de_msfea": 100, "full": 100}}  # fmt: skip
PAPER_ABLATION_STATUS = {"berlin": {"de_msfea": "Failure (PR 100 but flagged failed)", "full": "Success, TD 6200"},
                         "detroit": {"de_msfea": "Success, TD 36160", "full": "Success, TD 28160"}}  # fmt: skip
NEAR_OPT = 1.05  # "within 5 % of raster_opt" (a raster planner, not an optimum of the env's moves)


@dataclass(frozen=True)
class Experiment:
    group: str  # "main" (one variant per threshold) or "ablation" (the other variants at Berlin -3 dB)
    scenario: str
    threshold_db: float
    variant: str
    seed: int
    total_timesteps: int

    @property
    def name(self) -> str:
        return f"{self.scenario}_{self.threshold_db:g}dB_{self.variant}_s{self.seed}"


def experiments(seeds: Sequence[int], main_variant: str, steps: int, detroit_steps: int) -> list[Experiment]:
    out = [Experiment("main", "berlin_p4", t, main_variant, s, steps) for t in (-3.0, -4.0, -5.0, -6.0, -7.0)
           for s in seeds]  # fmt: skip
    out += [Experiment("main", "detroit_p5", -17.0, main_variant, s, detroit_steps) for s in seeds]
    out += [Experiment("ablation", "berlin_p4", -3.0, v, s, steps) for v in VARIANTS if v != main_variant
            for s in seeds]  # fmt: skip
    return out


@dataclass
class Args:
    run_dir: Path = Path("runs/msha")
    """folder of the runs (one sub-folder per run, plus <name>.log)"""
    seeds: tuple[int, ...] = (1, 2)
    """training seeds of every configuration"""
    main_variant: Variant = "de_msfea"
    """the variant trained at every threshold (the others are trained at Berlin -3 dB for the ablation)"""
    total_timesteps: int = 150_000
    """agent-steps per Berlin run"""
    detroit_timesteps: int = 300_000
    """agent-steps per Detroit run (5 passengers, longer tours)"""
    feasibility: Literal["endpoint_block", "segment_raster"] = "segment_raster"
    """move rule of training, evaluation and the planners: segment_raster keeps every raster sample along every
    step at or above the threshold (connectivity 100 % by construction); endpoint_block is the authors' rule"""
    only: tuple[str, ...] = ()
    """train and tabulate only the runs whose name contains one of these strings"""
    scenarios: tuple[str, ...] = ("berlin_p4", "detroit_p5")
    """scenarios of the main table"""
    ablation: bool = True
    """also train and tabulate the other variants at Berlin -3 dB"""
    train: bool = True
    """train the runs whose best.pt is missing (False: tabulate what exists)"""
    retrain: bool = False
    """train again even where best.pt exists"""
    jobs: int = 2
    """runs trained side by side (one CPU thread each)"""
    extra: tuple[str, ...] = ()
    """extra train/ppo.py flags for every run, e.g. --extra --total-timesteps 300000"""
    out_md: Path | None = None
    """Markdown file whose marked section is (re)written; without it no Markdown is written (the results pages
    are generated from --out-csv by `uamfleet docs-tables`)"""
    section: str = "msha_table"
    """name of that section (<!-- name:begin --> ... <!-- name:end -->)"""
    out_csv: Path = Path("docs/results/msha_table.csv")
    overwrite: bool = False
    """replace an existing --out-csv or --section of --out-md (else the command refuses before training)"""


def train_command(exp: Experiment, args: Args) -> list[str]:
    """The training of ``exp``: retrained from scratch with --retrain, else continued where an interrupted run
    left its last.pt (never deleted), else new."""
    folder = args.run_dir / exp.name
    start = ["--overwrite"] if args.retrain else ["--resume"] if (folder / "last.pt").exists() else []
    return [
        sys.executable, "-m", "uamfleet.cli.train", "--scenario", exp.scenario,
        "--sinr-min-db", f"{exp.threshold_db:g}", "--variant", exp.variant, "--seed", str(exp.seed),
        "--feasibility", args.feasibility, "--total-timesteps", str(exp.total_timesteps),
        "--run-dir", str(args.run_dir), "--run-name", exp.name, *start, "--threads", "1", "--no-progress",
        *args.extra,
    ]  # fmt: skip


def train_all(todo: list[Experiment], args: Args) -> None:
    """Run the trainings as subprocesses, ``args.jobs`` at a time; a failed run is reported, not fatal."""
    args.run_dir.mkdir(parents=True, exist_ok=True)
    pending: list[Experiment] = list(todo)
    running: list[tuple[Any, ...]] = []
    while pending or running:
        while pending and len(running) < args.jobs:
            exp = pending.pop(0)
            log = (args.run_dir / f"{exp.name}.log").open("w")
            print(f"training {exp.name} (log {args.run_dir / f'{exp.name}.log'})", flush=True)
            running.append((exp, subprocess.Popen(train_command(exp, args), stdout=log, stderr=subprocess.STDOUT),
                            log))  # fmt: skip
        time.sleep(2.0)
        for item in list(running):
            exp, proc, log = item
            if proc.poll() is not None:
                log.close()
                running.remove(item)
                status = "done" if proc.returncode == 0 else f"FAILED (exit {proc.returncode}; see its log)"
                print(f"{exp.name}: {status}", flush=True)


def first_reaching(rows: list[dict[str, float]], td_limit: float) -> tuple[float, float]:
    """(agent-steps, wall s) of the first greedy evaluation delivering everyone within ``td_limit`` m."""
    for r in rows:
        if r.get("eval/pr_pct", 0.0) >= 100.0 and r.get("eval/td_m", math.inf) <= td_limit:
            return r["global_step"], r["wall_s"]
    return math.nan, math.nan


def planner_metrics(scenario: str, threshold: float, planner: str, feasibility: str) -> EpisodeMetrics:
    flown, scored = planner_configs(scenario, planner, sinr_min_db=threshold, feasibility=feasibility)
    return episode_metrics(fly(flown, PlannerPolicy(planner)), scored.radio, threshold_db=scored.sinr_min_db)


def run_row(exp: Experiment, args: Args, opt_td: float) -> dict[str, object] | None:
    best = args.run_dir / exp.name / "best.pt"
    if not best.exists():
        return None
    policy, trained = load_policy(best)
    # the policy reads time as a fraction of its episode limit: fly it under the limit it trained with
    cfg = uamfleet.make_config(exp.scenario, sinr_min_db=exp.threshold_db, feasibility=trained.feasibility,
                               time_limit_steps=trained.time_limit_steps)  # fmt: skip
    m = episode_metrics(fly(cfg, policy), cfg.radio, threshold_db=exp.threshold_db)
    progress = read_progress(args.run_dir / exp.name / "progress.csv")
    last = progress[-1]
    paper_td = PAPER_TABLE_II[PAPER_KEY[exp.scenario]]["MSHA-RL"][exp.threshold_db][0]
    steps_pr, wall_pr = first_reaching(progress, math.inf)
    steps_paper, wall_paper = first_reaching(progress, paper_td)
    steps_opt, wall_opt = first_reaching(progress, NEAR_OPT * opt_td)
    return {
        "group": exp.group, "scenario": exp.scenario, "threshold_db": exp.threshold_db, "variant": exp.variant,
        "seed": exp.seed, "run": exp.name, "pr_pct": m.pr_pct, "td_m": m.td_m, "att_s": m.att_s, "awt_s": m.awt_s,
        "elr_pct": m.elr_pct, "connectivity_pct": m.connectivity_pct, "min_sinr_db": m.min_sinr_db,
        "td_over_opt": m.td_m / opt_td if m.pr_pct >= 100.0 else math.nan, "opt_td_m": opt_td, "paper_td_m": paper_td,
        "steps_to_pr100": steps_pr, "wall_to_pr100_s": wall_pr, "steps_to_paper_td": steps_paper,
        "wall_to_paper_td_s": wall_paper, "steps_to_near_opt": steps_opt, "wall_to_near_opt_s": wall_opt,
        "total_steps": last["global_step"], "total_wall_s": last["wall_s"], "sps": last["charts/SPS"],
    }  # fmt: skip


def fmt(value: object, digits: int = 0) -> str:
    """A table cell: a float with thousands separators and ``digits`` decimals ("–" where undefined), else text."""
    return fmt_value(value, f",.{digits}f") if isinstance(value, float) else str(value)


def steps_s(steps: object, wall: object) -> str:
    if isinstance(steps, float) and math.isnan(steps):
        return "not reached"
    return f"{fmt(steps)} / {fmt(wall)} s"


def metric_cells(pr: float, td: float, att: float, awt: float, elr: float, conn: float) -> str:
    pr, td, att, awt, elr, conn = (float(v) for v in (pr, td, att, awt, elr, conn))  # the paper's are ints
    return f"{fmt(pr)} | {fmt(td)} | {fmt(att, 2)} | {fmt(awt, 2)} | {fmt(elr, 1)} | {fmt(conn, 1)}"


def run_cells(r: dict[str, object]) -> str:
    """The metric cells of one run's row."""
    keys = ("pr_pct", "td_m", "att_s", "awt_s", "elr_pct", "connectivity_pct")
    return metric_cells(*(float(r[k]) for k in keys))  # type: ignore[arg-type]


def ablation_lines(rows: list[dict[str, object]]) -> list[str]:
    """The paper's Table III layout: every variant's runs at Berlin -3 dB."""
    lines = ["", "### Ablation on Berlin P4, γ_T = −3 dB (the paper's Table III)", "",
              "| model | variant | seed | PR % | TD m | ATT s | AWT s | ELR % | conn. % | TD / raster_opt | paper PR % "
              "| paper |",
              "|---:|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---|"]  # fmt: skip
    for number, variant in enumerate(("le", "de", "de_msfea", "full"), start=1):
        for r in rows:
            if r["scenario"] == "berlin_p4" and r["threshold_db"] == -3.0 and r["variant"] == variant:
                cells = run_cells(r)
                paper = PAPER_ABLATION_STATUS["berlin"].get(variant, "Failure")
                lines.append(f"| {number} | {variant} | {r['seed']} | {cells} | {fmt(r['td_over_opt'], 2)} | "
                             f"{PAPER_ABLATION_PR['berlin'][variant]} | {paper} |")  # fmt: skip
    return lines


def markdown(rows: list[dict[str, object]], planners: dict[tuple[str, float], dict[str, EpisodeMetrics]]) -> str:
    lines = ["### MSHA-PPO beside the paper and the planners", "",
             "| setting | γ_T dB | method | PR % | TD m | ATT s | AWT s | ELR % | conn. % | TD / raster_opt |",
             "|---|---:|---|---:|---:|---:|---:|---:|---:|---:|"]  # fmt: skip
    for (scenario, threshold), by_planner in sorted(planners.items()):
        key = PAPER_KEY[scenario]
        td, att, awt, elr = PAPER_TABLE_II[key]["MSHA-RL"][threshold]
        opt = by_planner["raster_opt"].td_m
        head = f"| {scenario} | {threshold:g} |"
        lines.append(f"{head} MSHA-RL (paper) | {metric_cells(100.0, td, att, awt, elr, 100.0)} | {td / opt:.2f} |")
        for r in rows:
            if r["group"] == "main" and r["scenario"] == scenario and r["threshold_db"] == threshold:
                cells = run_cells(r)
                lines.append(f"{head} **MSHA-PPO {r['variant']}, seed {r['seed']}** | {cells} | "
                             f"{fmt(r['td_over_opt'], 2)} |")  # fmt: skip
        for planner, label in (("raster_replan", "raster_replan (ours)"), ("raster_opt", "raster_opt (ours)")):
            m = by_planner[planner]
            cells = metric_cells(m.pr_pct, m.td_m, m.att_s, m.awt_s, m.elr_pct, m.connectivity_pct)
            lines.append(f"{head} {label} | {cells} | {m.td_m / opt:.2f} |")
    if any(r["group"] == "ablation" for r in rows):
        lines += ablation_lines(rows)
    lines += ["", "### Training cost (greedy evaluation every 5 iterations; agent-steps / wall-clock seconds)", "",
              "| run | first PR 100 % | TD ≤ paper | TD ≤ 1.05 × raster_opt | best TD at | total | agent-steps/s |",
              "|---|---:|---:|---:|---:|---:|---:|"]  # fmt: skip
    for r in rows:
        lines.append(
            f"| {r['run']} | {steps_s(r['steps_to_pr100'], r['wall_to_pr100_s'])} | "
            f"{steps_s(r['steps_to_paper_td'], r['wall_to_paper_td_s'])} | "
            f"{steps_s(r['steps_to_near_opt'], r['wall_to_near_opt_s'])} | {fmt(r['td_m'])} m | "
            f"{steps_s(r['total_steps'], r['total_wall_s'])} | {fmt(r['sps'])} |"
        )
    return "\n".join(lines) + "\n"


def selected(args: Args) -> list[Experiment]:
    """The experiments ``--only``, ``--scenarios`` and ``--no-ablation`` select, in the table's order."""
    return [
        e
        for e in experiments(args.seeds, args.main_variant, args.total_timesteps, args.detroit_timesteps)
        if (not args.only or any(s in e.name for s in args.only))
        and e.scenario in args.scenarios
        and (args.ablation or e.group == "main")
    ]


def main(args: Args) -> list[dict[str, object]]:
    if args.main_variant not in VARIANTS:
        raise UsageError(f"--main-variant {args.main_variant!r} is unknown; use one of {VARIANTS}.")
    check_jobs(args.jobs)
    chosen = selected(args)
    if not chosen:
        raise UsageError(
            "no run selected: --only / --scenarios / --no-ablation match none of the experiments; nothing trained "
            "or written."
        )
    output_paths({"--out-csv": args.out_csv, "--out-md": args.out_md})
    check_outputs(args.overwrite, [args.out_csv], args.out_md, args.section)
    if args.train:
        todo = [e for e in chosen if args.retrain or not (args.run_dir / e.name / "best.pt").exists()]
        train_all(todo, args)
    planners = {
        at: {p: planner_metrics(*at, p, args.feasibility) for p in ("raster_replan", "raster_opt")}
        for at in dict.fromkeys((exp.scenario, exp.threshold_db) for exp in chosen)
    }
    rows: list[dict[str, object]] = []
    for exp in chosen:
        row = run_row(exp, args, planners[(exp.scenario, exp.threshold_db)]["raster_opt"].td_m)
        if row is None:
            print(f"{exp.name}: no best.pt under {args.run_dir}; train it (drop --no-train)")
            continue
        rows.append(row)
        print(f"{exp.name:<34} PR {row['pr_pct']:5.1f} %  TD {row['td_m']:7.0f} m  (raster_opt {row['opt_td_m']:.0f}, "
              f"paper {row['paper_td_m']:.0f})  conn {row['connectivity_pct']:5.1f} %  "
              f"to paper TD: {steps_s(row['steps_to_paper_td'], row['wall_to_paper_td_s'])}")  # fmt: skip
    if not rows:
        raise UsageError(f"no trained runs under {args.run_dir}; nothing to tabulate (and nothing written).")
    write_csv_atomic(args.out_csv, rows, list(rows[0]))
    if args.out_md is None:
        print(markdown(rows, planners), end="")
        print(f"wrote {args.out_csv}")
        print(REFRESH_HINT)
    else:
        replace_section(args.out_md, args.section, markdown(rows, planners))
        print(f"wrote {args.out_csv} and the {args.section} section of {args.out_md}")
    return rows


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-msha-table") -> int:
    """The ``uamfleet-msha-table`` command (``python -m eval.msha_table``)."""
    return run(main, Args, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.msha_table"))
