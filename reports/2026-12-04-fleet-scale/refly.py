"""Re-fly recorded fleet-benchmark rows and compare every metric (not the timings) with the CSV, exactly.

    OMP_NUM_THREADS=1 python reports/2026-12-04-fleet-scale/refly.py docs/results/fleet_assignment_guard_test100.csv \
        --settings 4x48 8x96 --seeds 2000000 2000001

The family, setting, seed and dispatcher come from each row; the shield and the hover action from the row
(``shield_interventions`` / ``hover_actions`` columns are not enough to tell, so they are given: ``--separation``,
``--hover-action``). Exit status 1 if any metric differs.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from uamfleet.cli.fleet_benchmark import read_rows, run_episode_set

METRICS = ("num_requests", "delivered", "service_pct", "wait_p50_s", "wait_p95_s", "awt_s", "detour", "td_m",
           "td_per_delivered_m", "occupancy", "separation_violations", "connectivity_pct", "steps",
           "shield_interventions", "hovers", "hover_actions")  # fmt: skip


def main(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("csv", type=Path)
    parser.add_argument("--settings", nargs="+", required=True)
    parser.add_argument("--seeds", nargs="+", type=int, required=True)
    parser.add_argument("--dispatchers", nargs="*", default=None, help="default: every dispatcher of the rows")
    parser.add_argument("--separation", default="shield")
    parser.add_argument("--hover-action", action="store_true")
    args = parser.parse_args(argv)
    recorded = [r for r in read_rows(args.csv) if r["setting"] in args.settings and int(r["seed"]) in args.seeds
                and not r["dispatcher"].startswith("learned")
                and (args.dispatchers is None or r["dispatcher"] in args.dispatchers)]  # fmt: skip
    differ = 0
    for r in recorded:
        job = (r["family"], r["setting"], int(r["seed"]), (r["dispatcher"],), (), args.separation, args.hover_action)
        (now,) = run_episode_set(job)
        diffs = {m: (r[m], now[m]) for m in METRICS if m in r and float(r[m]) != float(now[m])}
        differ += bool(diffs)
        print(f"{r['family']} {r['setting']} {int(r['seed'])} {r['dispatcher']}: "
              f"{'identical' if not diffs else diffs} (TD {now['td_m']:.1f} m, {now['policy_s']:.1f} s)", flush=True)  # fmt: skip
    print(f"{len(recorded) - differ} of {len(recorded)} recorded rows re-flown identically")
    return 1 if differ else 0


if __name__ == "__main__":
    raise SystemExit(main(sys.argv[1:]))
