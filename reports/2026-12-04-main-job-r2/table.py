"""The R2 screen's rows as the README's table: per seed, the warm start's greedy evaluation (iteration 0, before
any PPO update), PPO's best evaluation after it, what the quickstart kept and flew again, and the costs.

python reports/2026-12-04-main-job-r2/table.py /tmp/r2/screen.csv /tmp/r2/screen [screen.csv]
(a CSV of benchmarks/quickstart_seeds.py, its --run-dir holding seed<S>/progress.csv, and the name of the CSV with
the added columns written beside this script)
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

HERE = Path(__file__).parent
BEST_KNOWN_M = 4900.0


def ppo_best(progress: list[dict[str, str]]) -> tuple[float, float, int]:
    """(PR %, TD m, agent-steps) of the best greedy evaluation after a PPO update (iteration >= 1; the first of
    equals)."""
    evals = [r for r in progress[1:] if r.get("eval/td_m")]
    best = min(evals, key=lambda r: (-float(r["eval/pr_pct"]), float(r["eval/td_m"])))
    return float(best["eval/pr_pct"]), float(best["eval/td_m"]), int(float(best["global_step"]))


def main() -> None:
    screen, run_dir = Path(sys.argv[1]), Path(sys.argv[2])
    rows = list(csv.DictReader(screen.open(encoding="utf-8")))
    out = []
    for r in rows:
        progress = list(csv.DictReader((run_dir / f"seed{r['seed']}" / "progress.csv").open(encoding="utf-8")))
        start = progress[0]
        pr, td, step = ppo_best(progress)
        out.append({
            **r, "start_pr_pct": start["eval/pr_pct"], "start_td_m": start["eval/td_m"],
            "warm_wall_s": round(float(start["warm/wall_s"])), "warm_solves": int(float(start["warm/solves"])),
            "warm_solve_s": round(float(start["warm/solve_s"])), "ppo_best_pr_pct": pr, "ppo_best_td_m": td,
            "ppo_best_step": step, "iterations": int(progress[-1]["iteration"]),
            "last_pr_pct": float(progress[-1]["eval/pr_pct"]), "last_td_m": float(progress[-1]["eval/td_m"]),
        })  # fmt: skip
    with (HERE / (sys.argv[3] if len(sys.argv) > 3 else "screen.csv")).open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(out[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(out)
    print("| seed | warm start: PR % / TD m (s, solves) | PPO's best: PR % / TD m at step | last evaluation: PR % / TD m | kept and flown: PR % / TD m | "
          "within 5 % | agent-steps trained | train s | load before / after |")  # fmt: skip
    print("|---|---|---|---|---|---|---|---|---|")
    for r in out:
        print(f"| {r['seed']} | {float(r['start_pr_pct']):.0f} / {float(r['start_td_m']):,.0f} ({r['warm_wall_s']} s, "
              f"{r['warm_solves']}) | {r['ppo_best_pr_pct']:.0f} / {r['ppo_best_td_m']:,.0f} at {r['ppo_best_step']:,} | "
              f"{r['last_pr_pct']:.0f} / {r['last_td_m']:,.0f} | "
              f"{float(r['pr_pct']):.0f} / {float(r['td_m']):,.0f} | {'yes' if r['within_5pct'] == '1' else 'no'} | "
              f"{int(r['agent_steps']):,} | {r['train_wall_s']} | {r['load_before']} / {r['load_after']} |")  # fmt: skip
    tds = [float(r["td_m"]) for r in out]
    within = sum(r["within_5pct"] == "1" for r in out)
    improved = sum(r["ppo_best_td_m"] < float(r["start_td_m"]) or r["ppo_best_pr_pct"] > float(r["start_pr_pct"])
                   for r in out)  # fmt: skip
    secs = sorted(int(r["train_wall_s"]) for r in out)
    print(f"\n- {within} of {len(out)} seeds within 5 % of best_known ({BEST_KNOWN_M:,.0f} m); TD {min(tds):,.0f}-"
          f"{max(tds):,.0f} m (mean {sum(tds) / len(tds):,.0f}); PPO beat its warm start on {improved} of {len(out)}; "
          f"training {secs[0]}-{secs[-1]} s")  # fmt: skip


if __name__ == "__main__":
    main()
