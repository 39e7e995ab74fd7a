"""Per method of benchmark CSVs: instances, all delivered %, mean TD, TD / best_known (mean of ratios), AWT, and the
paired difference to ``replan`` (mean m per instance, 95 % interval, normal approximation). Rows are paired by
instance; methods of several files (the same instances) are read together.

    python reports/2026-12-04-hedge-hover-demand/summarize.py hover.csv forbidden.csv
"""

from __future__ import annotations

import csv
import sys
from collections import defaultdict

import numpy as np


def main(paths: list[str]) -> None:
    rows: dict[str, dict[str, dict[str, float]]] = defaultdict(dict)  # method -> instance -> row
    for path in paths:
        with open(path, newline="") as f:
            for r in csv.DictReader(f):
                rows[r["method"]][r["instance"]] = {k: float(r[k]) for k in ("td_m", "pr_pct", "awt_s")}
    best, replan = rows.get("best_known", {}), rows.get("replan", {})
    print(
        f"{'method':<70} {'n':>4} {'all del. %':>10} {'TD m':>9} {'TD/best':>8} {'AWT s':>7} {'- replan m (95 %)':>20}"
    )
    for method, by in rows.items():
        names = sorted(by)
        td = np.array([by[n]["td_m"] for n in names])
        ratio = [by[n]["td_m"] / best[n]["td_m"] for n in names if n in best]
        paired = np.array([by[n]["td_m"] - replan[n]["td_m"] for n in names if n in replan])
        half = 1.96 * paired.std(ddof=1) / np.sqrt(len(paired)) if len(paired) > 1 else float("nan")
        done = 100 * np.mean([by[n]["pr_pct"] >= 100 for n in names])
        awt = np.mean([by[n]["awt_s"] for n in names])
        diff = f"{paired.mean():+.0f} ± {half:.0f}" if len(paired) else "–"
        print(f"{method[:70]:<70} {len(names):>4} {done:>10.1f} {td.mean():>9.1f} "
              f"{np.mean(ratio) if ratio else float('nan'):>8.3f} {awt:>7.1f} {diff:>20}")  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1:])
