"""Append a sweep's rows (benchmarks/quickstart_seeds.py --out-csv) to docs/results/quickstart_seeds.csv.

python reports/2026-12-04-main-job-r2/append_rows.py /tmp/r2/m4.csv

The committed file predates the script's columns within_5pct, load_before, load_after, start_pr_pct and start_td_m:
its header gains them (after its own), blank in its earlier rows.
"""

from __future__ import annotations

import csv
import sys
from pathlib import Path

from uamfleet.io import write_csv_atomic

DOCS = Path("docs/results/quickstart_seeds.csv")


def main() -> None:
    new_path = Path(sys.argv[1])
    old = list(csv.DictReader(DOCS.open(encoding="utf-8")))
    new = list(csv.DictReader(new_path.open(encoding="utf-8")))
    columns = list(old[0])
    columns += [c for c in new[0] if c not in columns]
    write_csv_atomic(DOCS, old + new, columns)
    print(f"{DOCS}: {len(old)} rows kept, {len(new)} appended")


if __name__ == "__main__":
    main()
