"""Per episode, whether a method's flight is identical to a reference method's (TD, p50, p95 and steps all equal).

python reports/2026-12-04-fleet-finetune/same_episodes.py REF.csv REF_NAME NEW.csv [NEW.csv ...]
"""

from __future__ import annotations

import csv
import sys

METRICS = ("td_m", "wait_p50_s", "wait_p95_s", "steps")


def main(ref_path: str, ref_name: str, paths: list[str]) -> None:
    with open(ref_path, encoding="utf-8") as f:
        ref = {(r["family"], r["setting"], r["seed"]): r for r in csv.DictReader(f) if r["dispatcher"] == ref_name}
    for path in paths:
        with open(path, encoding="utf-8") as f:
            rows = list(csv.DictReader(f))
        for name in sorted({r["dispatcher"] for r in rows}):
            mine = [r for r in rows if r["dispatcher"] == name]
            differ = [
                r["seed"]
                for r in mine
                if any(float(r[m]) != float(ref[(r["family"], r["setting"], r["seed"])][m]) for m in METRICS)
            ]
            print(f"{path} {name}: {len(differ)} of {len(mine)} episodes differ from {ref_name}: {differ}")


if __name__ == "__main__":
    main(sys.argv[1], sys.argv[2], sys.argv[3:])
