"""The main job over several seeds: ``uamfleet-quickstart --seed S --no-generalist`` per seed, one row each.

    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/quickstart_seeds.py --recipe fine_tune --seeds 1 2 3 \
        --run-dir /tmp/seeds/ft --out-csv /tmp/seeds/ft.csv [-- extra quickstart flags]

Each seed runs in its own process (as a user would run it), writing only under ``--run-dir``; the row holds what
the quickstart printed for its policy (PR / TD / ATT / AWT / ELR / connectivity, from its best.pt flown again here
by the quickstart's own ``fly``), TD over ``best_known`` (4,900 m at -3 dB, docs/results.md), the agent-steps
trained, when a greedy evaluation first delivered everyone and when the kept one was made (progress.csv; 0 is
the start of a fine-tuning run), and the seconds of training and of the whole command. Rows are appended to
``--out-csv`` (the columns of ``docs/results/quickstart_seeds.csv``), each as soon as its seed ends.
"""

from __future__ import annotations

import argparse
import csv
import subprocess
import sys
import time
from pathlib import Path

BEST_KNOWN_M = {-3.0: 4900.0}  # Berlin P4, endpoint-block rule (docs/results/benchmark_fixed.csv)
COLUMNS = ["recipe", "seed", "pr_pct", "td_m", "att_s", "awt_s", "elr_pct", "connectivity_pct",
           "td_over_best_known", "agent_steps", "steps_to_pr100", "best_step", "train_wall_s", "wall_s"]  # fmt: skip


def seed_row(recipe: str, seed: int, run_dir: Path, extra: list[str]) -> dict[str, object]:
    name = f"seed{seed}"
    command = [sys.executable, "-m", "eval.quickstart", "--seed", str(seed), "--no-generalist", "--run-dir",
               str(run_dir), "--run-name", name, "--overwrite", *extra]  # fmt: skip
    start = time.perf_counter()
    out = subprocess.run(command, check=True, capture_output=True, text=True).stdout
    wall = time.perf_counter() - start
    line = next(x for x in out.splitlines() if "(ours)" in x and x.startswith("MSHA-PPO"))
    pr, td, att, awt, elr, conn = line.split()[-6:]
    with (run_dir / name / "progress.csv").open() as f:
        rows = list(csv.DictReader(f))
    evals = [r for r in rows if r.get("eval/pr_pct")]
    first = next((int(float(r["global_step"])) for r in evals if float(r["eval/pr_pct"]) >= 100.0), "")
    best = min(evals, key=lambda r: (-float(r["eval/pr_pct"]), float(r["eval/td_m"])))
    return {
        "recipe": recipe, "seed": seed, "pr_pct": float(pr), "td_m": float(td), "att_s": att, "awt_s": awt,
        "elr_pct": elr, "connectivity_pct": conn, "td_over_best_known": round(float(td) / BEST_KNOWN_M[-3.0], 4),
        "agent_steps": int(float(rows[-1]["global_step"])), "steps_to_pr100": first,
        "best_step": int(float(best["global_step"])), "train_wall_s": round(float(rows[-1]["wall_s"])),
        "wall_s": round(wall),
    }  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--recipe", required=True)
    parser.add_argument("--seeds", type=int, nargs="+", required=True)
    parser.add_argument("--run-dir", type=Path, required=True)
    parser.add_argument("--out-csv", type=Path, required=True)
    parser.add_argument("extra", nargs="*", help="flags passed on to the quickstart (after --)")
    args = parser.parse_args()
    for seed in args.seeds:
        row = seed_row(args.recipe, seed, args.run_dir, args.extra)
        new = not args.out_csv.exists()
        with args.out_csv.open("a", newline="") as f:  # one row per finished seed: a stopped sweep keeps its rows
            writer = csv.DictWriter(f, fieldnames=COLUMNS)
            if new:
                writer.writeheader()
            writer.writerow(row)
        print(", ".join(f"{k}={v}" for k, v in row.items()), flush=True)


if __name__ == "__main__":
    main()
