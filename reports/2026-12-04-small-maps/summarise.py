"""The report's figures from its CSVs: per method, mean TD, everyone-delivered count, and TD paired against replan
(mean and 95 % interval) on the instances both flew.

    python reports/2026-12-04-small-maps/summarise.py REPLAN_CSV CSV [CSV ...]
"""

from __future__ import annotations

import csv
import math
import statistics
import sys


def rows_of(path: str) -> dict[str, dict[str, tuple[float, float]]]:
    """{method: {instance: (td_m, pr_pct)}}"""
    out: dict[str, dict[str, tuple[float, float]]] = {}
    with open(path, newline="") as f:
        for r in csv.DictReader(f):
            out.setdefault(r["method"], {})[r["instance"]] = (float(r["td_m"]), float(r["pr_pct"]))
    return out


def main() -> None:
    replan = rows_of(sys.argv[1])["replan"]
    for path in sys.argv[2:]:
        for method, flown in rows_of(path).items():
            both = [i for i in flown if i in replan]
            diff = [flown[i][0] - replan[i][0] for i in both]
            half = 1.96 * statistics.stdev(diff) / math.sqrt(len(diff)) if len(diff) > 1 else 0.0
            ratio = sum(flown[i][0] for i in both) / sum(replan[i][0] for i in both)
            delivered = sum(v[1] >= 100 for v in flown.values())
            print(
                f"{path.split('/')[-1]:36s} {method:28s} n={len(flown):3d} everyone delivered {delivered:3d}  "
                f"TD {statistics.mean(v[0] for v in flown.values()):8,.1f}  - replan {statistics.mean(diff):+8,.1f}"
                f" +- {half:6,.1f}  / replan {ratio:.3f}"
            )


if __name__ == "__main__":
    main()
