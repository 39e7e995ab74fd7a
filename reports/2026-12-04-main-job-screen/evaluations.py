"""Per screened seed, what the evaluations after PPO updates did (how many delivered everyone, the range of their
tours) and the learning curve's validation panel (progress.csv's val_pr_pct / val_td_m: the greedy policy on the
first 10 Berlin validation instances, mean TD flown).

python reports/2026-12-04-main-job-screen/evaluations.py /tmp/mjscreen/runs 15 16 17
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path


def seed_line(seed: str, rows: list[dict[str, str]]) -> str:
    after = [r for r in rows[1:] if r.get("eval/td_m")]  # the evaluations after a PPO update (iteration >= 1)
    full = [float(r["eval/td_m"]) for r in after if float(r["eval/pr_pct"]) >= 100.0]
    short = [float(r["eval/pr_pct"]) for r in after if float(r["eval/pr_pct"]) < 100.0]
    short_text = f"{len(short)} ({min(short):.0f}-{max(short):.0f} %)" if short else "0"
    val = [r for r in rows if r.get("val_pr_pct")]
    best_val = max(float(r["val_pr_pct"]) for r in val)
    return (
        f"| {seed} | {len(after)} | {len(full)} | {min(full):,.0f}-{max(full):,.0f} | {short_text} | "
        f"{float(val[0]['val_pr_pct']):.1f} / {float(val[0]['val_td_m']):,.0f} | {best_val:.1f} | "
        f"{float(val[-1]['val_pr_pct']):.1f} / {float(val[-1]['val_td_m']):,.0f} |"
    )


def main() -> None:
    run_dir, seeds = Path(sys.argv[1]), sys.argv[2:]
    print(
        "| seed | evaluations after PPO | delivering everyone | their TD m | delivering fewer (PR) | "
        "validation at the warm start: PR % / TD m | best validation PR % | last validation: PR % / TD m |"
    )
    print("|---|---|---|---|---|---|---|---|")
    for seed in seeds:
        rows = list(csv.DictReader((run_dir / f"seed{seed}" / "progress.csv").open(encoding="utf-8")))
        print(seed_line(seed, rows))


if __name__ == "__main__":
    main()
