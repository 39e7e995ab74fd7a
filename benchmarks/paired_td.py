"""Paired difference of two methods' TD on the same instances, from benchmark CSVs (``uamfleet-benchmark``'s rows).

    .venv/bin/python benchmarks/paired_td.py docs/results/benchmark_berlin_test_lookahead.csv learned \
        docs/results/benchmark_berlin_test_generalist.csv learned

prints the mean per-instance difference (first minus second) with its 95 % interval (normal approximation, 1.96
standard errors), on how many instances the first is shorter / longer, and both ratios (of means, mean of ratios).
Only the instances both files hold are paired.
"""

from __future__ import annotations

import csv
import sys

import numpy as np


def tds(path: str, method: str) -> dict[str, float]:
    with open(path, newline="") as f:
        return {r["instance"]: float(r["td_m"]) for r in csv.DictReader(f) if r["method"] == method}


def main(argv: list[str]) -> None:
    if len(argv) != 4:
        raise SystemExit("usage: paired_td.py FIRST.csv METHOD SECOND.csv METHOD")
    first, second = tds(argv[0], argv[1]), tds(argv[2], argv[3])
    names = sorted(set(first) & set(second))
    if len(names) < 2:
        raise SystemExit(f"{len(names)} instance(s) in both files: nothing to pair (check the methods' names).")
    a, b = np.array([first[n] for n in names]), np.array([second[n] for n in names])
    diff = a - b
    half = 1.96 * diff.std(ddof=1) / np.sqrt(len(diff))
    print(f"{argv[1]} - {argv[3]} over {len(names)} instances: {diff.mean():+,.0f} ± {half:,.0f} m (95 %), "
          f"shorter on {(diff < 0).sum()}, longer on {(diff > 0).sum()}; ratio of means {a.mean() / b.mean():.4f}, "
          f"mean of ratios {np.mean(a / b):.4f}")  # fmt: skip


if __name__ == "__main__":
    main(sys.argv[1:])
