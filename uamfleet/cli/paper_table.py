"""The paper's Table II with our planners beside it, plus route and connectivity figures.

    uamfleet-paper-table                    # all scenarios (a few minutes on 2 cores)
    uamfleet-paper-table --quick            # Berlin at -3 dB only (for smoke tests)

Writes ``docs/results/paper_table.csv`` and PNG figures under ``docs/figures/``, and prints the table; the
results pages are generated from that CSV by ``uamfleet docs-tables``. ``--out-md FILE`` also (re)writes the
marked section ``paper_table`` of the Markdown file FILE.

Every planner is flown through the same environment (same rules, same metrics); TD is the distance flown in
100 m (Berlin) / 320 m (Detroit) steps, ``TD exact`` the shortest feasible path through the exact stops in the
order they were served (what the paper's baselines report). Rows of an earlier table that this run does not
produce (e.g. the learned ``msha-*`` rows of ``--checkpoints`` given then) are kept; existing results are
replaced only with ``--overwrite``, and figures are byte-stable.
"""

from __future__ import annotations

from collections.abc import Sequence

import csv
import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

import uamfleet
from uamfleet.cli._common import fmt as fmt_value
from uamfleet.cli._common import check_outputs, output_paths, run
from uamfleet.cli.docs_tables import REFRESH_HINT
from uamfleet.cli.paper_numbers import PAPER_STRAIGHT_LINE_CONNECTIVITY_PCT, PAPER_TABLE_II
from uamfleet.baselines.planner_policy import (
    PLANNERS,
    PlannerPolicy,
    exact_stop_length,
    planner_configs,
    service_order,
)
from uamfleet.io import replace_section, write_csv_atomic
from uamfleet.metrics import episode_metrics
from uamfleet.rl.policy import load_policy
from uamfleet.rollout import Trajectory
from uamfleet.rollout import fly as fly_episode
from uamfleet.viz.figures import plot_connectivity, plot_routes

# (scenario, paper table key, thresholds, label)
SETTINGS: tuple[tuple[str, str, tuple[float, ...], str], ...] = (
    ("berlin_p4", "berlin", (-7.0, -6.0, -5.0, -4.0, -3.0), "Berlin P4 (WinProp map)"),
    ("detroit_p5", "detroit", (-17.0,), "Detroit P5 (ESTIMATED block map)"),
    ("detroit3gpp_p5", "detroit", (-21.0, -20.0, -19.0, -18.0, -17.0), "Detroit P5 on the SYNTHETIC TR 36.777 map"),
)
COLUMNS = ("setting", "threshold_db", "method", "source", "pr_pct", "td_m", "td_exact_m", "att_s", "awt_s",
           "elr_pct", "connectivity_pct", "min_sinr_db")  # fmt: skip


@dataclass
class Args:
    out_md: Path | None = None
    """Markdown file whose `paper_table` section is (re)written; without it no Markdown is written (the results
    pages are generated from --out-csv by `uamfleet docs-tables`)"""
    out_csv: Path = Path("docs/results/paper_table.csv")
    figures: Path = Path("docs/figures")
    quick: bool = False
    """only Berlin at -3 dB (smoke test)"""
    checkpoints: tuple[Path, ...] = ()
    """trained policies (runs/<name>/best.pt) to add as rows at the scenario and threshold they were trained on"""
    overwrite: bool = False
    """replace an existing --out-csv and paper_table section of --out-md (else the command refuses before flying)"""


def fly(scenario: str, threshold: float, planner: str) -> tuple[Trajectory, PlannerPolicy, uamfleet.EnvConfig]:
    """One episode of ``planner``, with the planner and the config it is scored against."""
    flown, scored = planner_configs(scenario, planner, sinr_min_db=threshold)
    policy = PlannerPolicy(planner)
    return fly_episode(flown, policy), policy, scored


Learned = tuple[str, object, dict[str, object]]  # (method name, greedy policy, env overrides it was trained with)


def evaluate(
    scenario: str,
    label: str,
    threshold: float,
    learned: Sequence[Learned] = (),
) -> tuple[list[dict[str, object]], dict[str, np.ndarray]]:
    """Every planner, then every learned policy trained for this (scenario, threshold), flown once."""
    rows, routes = [], {}
    stop_dist = None
    runs: list[tuple[str, Trajectory, uamfleet.EnvConfig, np.ndarray | None]] = []
    for planner in PLANNERS:
        traj, policy, cfg = fly(scenario, threshold, planner)
        runs.append((planner, traj, cfg, policy.dist_m))
        if planner == "raster_opt":
            stop_dist = policy.dist_m  # shortest feasible paths between this instance's stops
    for name, learned_policy, overrides in learned:
        cfg = uamfleet.make_config(scenario, **{**overrides, "sinr_min_db": threshold})
        runs.append((name, fly_episode(cfg, learned_policy), cfg, stop_dist))  # type: ignore[arg-type]
    for method, traj, cfg, dist_m in runs:
        m = episode_metrics(traj, cfg.radio, threshold_db=threshold)
        picked = traj.stacked("picked_up")
        dropped = traj.stacked("dropped_off")
        steps = np.arange(1, traj.num_steps + 1)
        pick_step = np.where(picked.any(0), steps[np.argmax(picked, 0)], -1)[traj.pax_exists]
        drop_step = np.where(dropped.any(0), steps[np.argmax(dropped, 0)], -1)[traj.pax_exists]
        td_exact = exact_stop_length(service_order(pick_step, drop_step), dist_m) if dist_m is not None else math.nan
        rows.append({
            "setting": label, "threshold_db": threshold, "method": method, "source": "ours", "pr_pct": m.pr_pct,
            "td_m": m.td_m, "td_exact_m": td_exact, "att_s": m.att_s, "awt_s": m.awt_s, "elr_pct": m.elr_pct,
            "connectivity_pct": m.connectivity_pct, "min_sinr_db": m.min_sinr_db,
        })  # fmt: skip
        routes[method] = traj.positions_m[0]
    return rows, routes


def paper_rows(key: str, label: str, threshold: float) -> list[dict[str, object]]:
    out = []
    for method, by_threshold in PAPER_TABLE_II[key].items():
        if threshold in by_threshold:
            td, att, awt, elr = by_threshold[threshold]
            conn = 100.0 if method == "MSHA-RL" else math.nan
            out.append({
                "setting": label, "threshold_db": threshold, "method": method, "source": "paper", "pr_pct": 100.0,
                "td_m": td, "td_exact_m": math.nan, "att_s": att, "awt_s": awt, "elr_pct": elr,
                "connectivity_pct": conn, "min_sinr_db": math.nan,
            })  # fmt: skip
    straight = PAPER_STRAIGHT_LINE_CONNECTIVITY_PCT.get(key, {}).get(threshold)
    if straight is not None:
        out.append({"setting": label, "threshold_db": threshold, "method": "straight (RL order)", "source": "paper",
                    **{c: math.nan for c in COLUMNS[4:]}, "connectivity_pct": straight})  # fmt: skip
    return out


def fmt(value: object, digits: int = 1) -> str:
    """A table cell: a float with ``digits`` decimals ("–" where undefined), anything else as text."""
    return fmt_value(value, f".{digits}f") if isinstance(value, float) else str(value)


def markdown(rows: list[dict[str, object]]) -> str:
    lines = []
    for label in dict.fromkeys(str(r["setting"]) for r in rows):
        header = (
            "| γ_T dB | method | source | PR % | TD m | TD exact m | ATT s | AWT s | ELR % | conn. % | min SINR dB |"
        )
        lines += [f"### {label}", "", header, "|---:|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
        for r in (r for r in rows if r["setting"] == label):
            lines.append(
                f"| {fmt(r['threshold_db'], 0)} | {r['method']} | {r['source']} | {fmt(r['pr_pct'], 0)} | "
                f"{fmt(r['td_m'], 0)} | {fmt(r['td_exact_m'], 0)} | {fmt(r['att_s'], 2)} | {fmt(r['awt_s'], 2)} | "
                f"{fmt(r['elr_pct'], 2)} | {fmt(r['connectivity_pct'], 1)} | {fmt(r['min_sinr_db'], 2)} |"
            )
        lines.append("")
    return "\n".join(lines)


def read_rows(path: Path) -> list[dict[str, object]]:
    """The rows of an earlier table's CSV (numbers as floats; none when the file is absent)."""
    if not path.is_file():
        return []
    text = ("setting", "method", "source")
    with path.open(encoding="utf-8") as f:
        return [{k: (v if k in text else float(v)) for k, v in r.items()} for r in csv.DictReader(f)]


def keep_other_rows(rows: list[dict[str, object]], earlier: list[dict[str, object]]) -> list[dict[str, object]]:
    """This run's rows with every earlier row it did not produce (same setting, threshold, method and source),
    ordered by setting (as in :data:`SETTINGS`) and threshold; within one, this run's rows first."""
    key = ("setting", "threshold_db", "method", "source")
    produced = {tuple(r[k] for k in key) for r in rows}
    merged = rows + [r for r in earlier if tuple(r[k] for k in key) not in produced]
    labels = [label for *_, label in SETTINGS]

    def place(r: dict[str, object]) -> tuple[int, float]:
        label = str(r["setting"])
        return (labels.index(label) if label in labels else len(labels), float(r["threshold_db"]))  # type: ignore[arg-type]

    return sorted(merged, key=place)


def learned_policies(checkpoints: Sequence[Path]) -> dict[tuple[str, float], list[Learned]]:
    """The trained policies of ``checkpoints`` by the (scenario, threshold) they were trained on."""
    learned: dict[tuple[str, float], list[Learned]] = {}
    for path in checkpoints:
        policy, trained = load_policy(path)
        at = (
            trained.sinr_min_db
            if trained.sinr_min_db is not None
            else uamfleet.make_config(trained.scenario).sinr_min_db
        )
        overrides = {"feasibility": trained.feasibility, "time_limit_steps": trained.time_limit_steps}
        learned.setdefault((trained.scenario, float(at)), []).append((f"msha-{trained.variant}", policy, overrides))
    return learned


def main(args: Args) -> list[dict[str, object]]:
    output_paths({"--out-csv": args.out_csv, "--out-md": args.out_md})
    check_outputs(args.overwrite, [args.out_csv], args.out_md, "paper_table")
    settings = ((SETTINGS[0][0], SETTINGS[0][1], (-3.0,), SETTINGS[0][3]),) if args.quick else SETTINGS
    rows: list[dict[str, object]] = []
    learned = learned_policies(args.checkpoints)
    for scenario, key, thresholds, label in settings:
        connectivity: dict[str, list[float]] = {p: [] for p in PLANNERS}
        for threshold in thresholds:
            ours, routes = evaluate(scenario, label, threshold, learned.get((scenario, threshold), []))
            rows += paper_rows(key, label, threshold) + ours
            for r in ours:
                if r["method"] in connectivity:
                    connectivity[str(r["method"])].append(float(r["connectivity_pct"]))  # type: ignore[arg-type]
                print(
                    f"{label:<45} {threshold:>5.0f} dB  {r['method']:<9} PR {r['pr_pct']:5.1f} %  "
                    f"TD {fmt(r['td_m'], 0):>7} m  exact {fmt(r['td_exact_m'], 0):>7} m  "
                    f"ATT {fmt(r['att_s'], 2):>7} s  AWT {fmt(r['awt_s'], 2):>7} s  ELR {fmt(r['elr_pct']):>5} %  "
                    f"conn {fmt(r['connectivity_pct']):>5} %"
                )
            if threshold in (thresholds[0], thresholds[-1]):
                cfg = uamfleet.make_config(scenario, sinr_min_db=threshold)
                requests = cfg.requests or ()
                plot_routes(
                    cfg.radio, threshold, routes,
                    np.array([r.origin_m for r in requests]), np.array([r.destination_m for r in requests]),
                    np.array(cfg.starts_m[0] if cfg.starts_m else (0.0, 0.0)),
                    f"{label}, γ_T = {threshold:g} dB: routes flown by each planner",
                    args.figures / f"routes_{scenario}_{threshold:g}dB.png",
                )  # fmt: skip
        if len(thresholds) > 1:
            plot_connectivity(list(thresholds), connectivity, f"{label}: connectivity along the flown path",
                              args.figures / f"connectivity_{scenario}.png")  # fmt: skip
    rows = keep_other_rows(rows, read_rows(args.out_csv))
    write_csv_atomic(args.out_csv, rows, COLUMNS)
    if args.out_md is None:
        print(markdown(rows))
        print(f"wrote {args.out_csv}, figures in {args.figures}/")
        print(REFRESH_HINT)
    else:
        replace_section(args.out_md, "paper_table", markdown(rows))
        print(f"wrote {args.out_csv}, the paper_table section of {args.out_md}, figures in {args.figures}/")
    return rows


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-paper-table") -> int:
    """The ``uamfleet-paper-table`` command (``python -m eval.paper_table``)."""
    return run(main, Args, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.paper_table"))
