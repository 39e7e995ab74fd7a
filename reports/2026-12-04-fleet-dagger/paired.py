"""Paired differences (method - the chosen dispatcher) per setting, mean and 95 % interval (t), from fleet-bench CSVs.

python reports/2026-12-04-fleet-dagger/paired.py A.csv [B.csv ...] [--base METHOD]   (default: the chosen dispatcher)
"""

from __future__ import annotations

import csv
import sys
from collections import defaultdict

import numpy as np
from scipy import stats

BASE = "batch_assignment_value:100+wait=1+release+price=1000+guard=600"
METRICS = ("td_per_delivered_m", "wait_p50_s", "wait_p95_s")


def main(paths: list[str], base_name: str = BASE) -> None:
    rows = [r for p in paths for r in csv.DictReader(open(p, encoding="utf-8"))]
    by = defaultdict(dict)  # (family, setting, method) -> seed -> row
    for r in rows:
        by[(r["family"], r["setting"], r["dispatcher"])][int(float(r["seed"]))] = r  # merged rows: "1000000.0"
    for (family, setting, method), episodes in sorted(by.items()):
        base = by.get((family, setting, base_name), {})
        seeds = sorted(set(episodes) & set(base))
        short = sum(int(float(episodes[s]["delivered"])) < int(float(episodes[s]["num_requests"])) for s in episodes)
        losses = sum(float(episodes[s]["separation_violations"]) for s in episodes)
        line = [f"{family} {setting} {method}: n={len(seeds)} short={short} losses={losses:g}"]
        for m in METRICS:
            own = np.array([float(episodes[s][m]) for s in seeds])
            if method == base_name or not seeds:
                line.append(f"{m} {own.mean():.1f}" if seeds else m)
                continue
            d = own - np.array([float(base[s][m]) for s in seeds])
            half = stats.t.ppf(0.975, len(d) - 1) * d.std(ddof=1) / np.sqrt(len(d))
            line.append(f"{m} {own.mean():.1f} diff {d.mean():+.1f} +- {half:.1f}")
        print(" | ".join(line))


if __name__ == "__main__":
    args = sys.argv[1:]
    if "--base" in args:
        i = args.index("--base")
        main(args[:i] + args[i + 2 :], args[i + 1])
    else:
        main(args)
