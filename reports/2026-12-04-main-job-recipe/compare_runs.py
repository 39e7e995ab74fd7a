"""Two runs of tiny_run.py: their progress.csv rows column by column (timings left out: wall_s, charts/SPS and the
decision times), the columns only the second has, and whether best.pt / last.pt hold the same weights.

    python reports/2026-12-04-main-job-recipe/compare_runs.py RUN_A RUN_B
"""

from __future__ import annotations

import csv
import sys

import torch

TIMINGS = {"wall_s", "charts/SPS"}


def rows(folder: str) -> list[dict[str, str]]:
    with open(f"{folder}/progress.csv", encoding="utf-8") as f:
        return list(csv.DictReader(f))


def main() -> None:
    a, b = rows(sys.argv[1]), rows(sys.argv[2])
    assert len(a) == len(b), (len(a), len(b))
    differences = [
        (i, k, r[k], s.get(k))
        for i, (r, s) in enumerate(zip(a, b, strict=True))
        for k in r
        if k not in TIMINGS and "_ms" not in k and r[k] != s.get(k)
    ]
    print("rows", len(a), "columns only in the second", sorted(set(b[0]) - set(a[0])), "differences", differences)
    for name in ("best.pt", "last.pt"):
        x = torch.load(f"{sys.argv[1]}/{name}", weights_only=False)["model"]
        y = torch.load(f"{sys.argv[2]}/{name}", weights_only=False)["model"]
        print(name, "same weights:", x.keys() == y.keys() and all(torch.equal(x[k], y[k]) for k in x))


if __name__ == "__main__":
    main()
