"""The main job over several seeds: ``python -m uamfleet.cli.quickstart --seed S --no-generalist`` per seed, a row each.

    OMP_WAIT_POLICY=PASSIVE nice python benchmarks/quickstart_seeds.py --recipe scratch --seeds 11 12 13 \
        --run-dir /tmp/seeds/scratch --out-csv /tmp/seeds/scratch.csv [-- extra quickstart flags]

Each seed runs in its own process (as a user would run it), one after the other, writing only under ``--run-dir``.
``--recipe`` is handed to the quickstart (``--recipe NAME``) unless ``--label-only`` is given, when it only labels the
rows (for a quickstart without ``--recipe``: give the recipe's flags after ``--``). The row holds what the
quickstart printed for its policy (PR / TD / ATT / AWT / ELR / connectivity, from its best.pt flown again by the
quickstart's own ``fly``), TD over ``best_known`` (4,900 m at -3 dB, endpoint-block rule:
docs/results/benchmark_fixed.csv), whether that is within 5 % of it, the agent-steps trained, when a greedy
evaluation first delivered everyone and when the kept one was made (progress.csv), the seconds of training and of
the whole command, the machine's 1-minute load average before and after the seed (the machine may be shared), and
the greedy evaluation of the run's start (iteration 0: a fine-tuning run's start, a warm-started run's warm start;
blank from scratch).
Rows are appended to ``--out-csv`` as each seed ends, so a stopped sweep keeps its rows. ``--plot PATH`` then draws
the seeds' learning curves in one figure (uamfleet.viz.curves: each seed's line, their median and range, best_known
and its 5 % band); with ``--plot-only`` it draws the seeds already under ``--run-dir`` without training.
"""

from __future__ import annotations

import argparse
import csv
import os
import subprocess
import sys
import time
from pathlib import Path

BEST_KNOWN_M = {-3.0: 4900.0}  # Berlin P4, endpoint-block rule (docs/results/benchmark_fixed.csv, best_known)
WITHIN = 1.05  # the target: within 5 % of best_known
COLUMNS = ["recipe", "seed", "pr_pct", "td_m", "att_s", "awt_s", "elr_pct", "connectivity_pct",
           "td_over_best_known", "within_5pct", "agent_steps", "steps_to_pr100", "best_step", "train_wall_s",
           "wall_s", "load_before", "load_after", "start_pr_pct", "start_td_m"]  # fmt: skip


def seed_row(recipe: str, seed: int, run_dir: Path, extra: list[str], pass_recipe: bool) -> dict[str, object]:
    name = f"seed{seed}"
    command = [sys.executable, "-m", "uamfleet.cli.quickstart", "--seed", str(seed), "--no-generalist",
               "--run-dir", str(run_dir), "--run-name", name, "--overwrite"]  # fmt: skip
    if pass_recipe:
        command += ["--recipe", recipe]
    command += extra
    load_before = os.getloadavg()[0]
    start = time.perf_counter()
    out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    wall = time.perf_counter() - start
    (run_dir / name / "quickstart.log").write_text(" ".join(command) + "\n" + out, encoding="utf-8")
    line = next(x for x in out.splitlines() if "(ours)" in x and x.startswith("MSHA-PPO"))
    pr, td, att, awt, elr, conn = line.split()[-6:]
    with (run_dir / name / "progress.csv").open() as f:
        rows = list(csv.DictReader(f))
    evals = [r for r in rows if r.get("eval/pr_pct")]
    first = next((int(float(r["global_step"])) for r in evals if float(r["eval/pr_pct"]) >= 100.0), "")
    best = min(evals, key=lambda r: (-float(r["eval/pr_pct"]), float(r["eval/td_m"])))
    start = rows[0] if rows[0]["iteration"] == "0" else {}  # a fine-tuning or warm-started run's start
    ratio = float(td) / BEST_KNOWN_M[-3.0]
    return {
        "recipe": recipe, "seed": seed, "pr_pct": float(pr), "td_m": float(td), "att_s": att, "awt_s": awt,
        "elr_pct": elr, "connectivity_pct": conn, "td_over_best_known": round(ratio, 4),
        "within_5pct": int(float(pr) >= 100.0 and ratio <= WITHIN),
        "agent_steps": int(float(rows[-1]["global_step"])), "steps_to_pr100": first,
        "best_step": int(float(best["global_step"])), "train_wall_s": round(float(rows[-1]["wall_s"])),
        "wall_s": round(wall), "load_before": round(load_before, 2), "load_after": round(os.getloadavg()[0], 2),
        "start_pr_pct": start.get("eval/pr_pct", ""), "start_td_m": start.get("eval/td_m", ""),
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--recipe", required=True)
    parser.add_argument("--label-only", action="store_true", help="do not pass --recipe to the quickstart")
    parser.add_argument("--seeds", type=int, nargs="+", required=True)
    parser.add_argument("--run-dir", type=Path, required=True)
    parser.add_argument("--out-csv", type=Path, required=True)
    parser.add_argument("--plot", type=Path, help="draw the seeds' learning curves into this PNG")
    parser.add_argument("--plot-only", action="store_true", help="only draw --plot from the runs under --run-dir")
    parser.add_argument("extra", nargs="*", help="flags passed on to the quickstart (after --)")
    args = parser.parse_args()
    if not args.plot_only:
        run_seeds(args)
    if args.plot is not None:
        from uamfleet.viz.curves import plot_learning_curve

        runs = [args.run_dir / f"seed{seed}" for seed in args.seeds if (args.run_dir / f"seed{seed}").is_dir()]
        title = f"Berlin P4 at -3 dB, recipe {args.recipe}, seeds {', '.join(str(s) for s in args.seeds)}"
        print(plot_learning_curve(runs, out=args.plot, best_known_m=BEST_KNOWN_M[-3.0], title=title))


def run_seeds(args: argparse.Namespace) -> None:
    for seed in args.seeds:
        row = seed_row(args.recipe, seed, args.run_dir, args.extra, pass_recipe=not args.label_only)
        new = not args.out_csv.exists()
        with args.out_csv.open("a", newline="") as f:
            writer = csv.DictWriter(f, fieldnames=COLUMNS)
            if new:
                writer.writeheader()
            writer.writerow(row)
        print(", ".join(f"{k}={v}" for k, v in row.items()), flush=True)


if __name__ == "__main__":
    main()
