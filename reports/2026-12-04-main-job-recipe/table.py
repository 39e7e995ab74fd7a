"""The screen's rows (screen.csv) as the README's table: per seed, R0 and R1 side by side, and a count per recipe.

python reports/2026-12-04-main-job-recipe/table.py /tmp/recipe_screen/r0.csv /tmp/recipe_screen/r1.csv
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

HERE = Path(__file__).parent


def main() -> None:
    rows = [r for path in sys.argv[1:] for r in csv.DictReader(open(path, encoding="utf-8"))]
    rows.sort(key=lambda r: (int(r["seed"]), r["recipe"]))
    with (HERE / "screen.csv").open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(rows[0]), lineterminator="\n")
        writer.writeheader()
        writer.writerows(rows)
    print(
        "| seed | recipe | PR % | TD m | TD / best_known | within 5 % | first PR 100 at | kept at | train s | load before / after |"
    )
    print("|---|---|---|---|---|---|---|---|---|---|")
    for r in rows:
        print(
            f"| {r['seed']} | {r['recipe']} | {float(r['pr_pct']):.0f} | {float(r['td_m']):,.0f} | "
            f"{float(r['td_over_best_known']):.3f} | {'yes' if r['within_5pct'] == '1' else 'no'} | "
            f"{int(r['steps_to_pr100']):,} | {int(r['best_step']):,} | {r['train_wall_s']} | "
            f"{r['load_before']} / {r['load_after']} |"
            if r["steps_to_pr100"]
            else f"| {r['seed']} | {r['recipe']} | {float(r['pr_pct']):.0f} | {float(r['td_m']):,.0f} | "
            f"{float(r['td_over_best_known']):.3f} | no | never | {int(r['best_step']):,} | {r['train_wall_s']} | "
            f"{r['load_before']} / {r['load_after']} |"
        )
    print()
    for recipe in sorted({r["recipe"] for r in rows}):
        mine = [r for r in rows if r["recipe"] == recipe]
        tds = sorted(float(r["td_m"]) for r in mine)
        secs = sorted(int(r["train_wall_s"]) for r in mine)
        within = sum(r["within_5pct"] == "1" for r in mine)
        print(
            f"- `{recipe}`: {within} of {len(mine)} seeds within 5 % of best_known; TD {tds[0]:,.0f}-{tds[-1]:,.0f} m "
            f"(mean {sum(tds) / len(tds):,.0f}); training {secs[0]}-{secs[-1]} s"
        )


if __name__ == "__main__":
    main()
