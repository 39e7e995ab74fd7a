"""Where fleet dispatchers' waits differ: quantiles of the riders' waits, and the median wait by how many taxis
were empty when the request was released.

A diagnostic for issue 21's loaded target (the median wait against ``greedy``'s): it flies each dispatcher on the
first validation episodes of one fleet setting (under the shield with the hover action, as the loaded tables) and
pools every rider's wait (pick-up step − release step, in seconds).

    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/fleet_wait_quantiles.py --family berlin --setting 4x48 --count 4 \
        --dispatchers greedy batch_assignment_value:100 batch_assignment_value:100+wait=1+release
"""

from __future__ import annotations

import argparse

import numpy as np

from uamfleet.baselines import make_policy
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.rollout import fly


def rider_waits(traj) -> tuple[np.ndarray, np.ndarray]:
    """(wait s of every rider picked up, how many taxis had nobody on board in the step before her release)."""
    exists = traj.pax_exists
    picked = traj.stacked("picked_up")[:, exists]
    steps = np.arange(1, traj.num_steps + 1)  # the step index after each transition, as uamfleet.metrics counts
    release = traj.release_step[exists].astype(int)
    pickup = np.where(picked.any(0), steps[np.argmax(picked, axis=0)], -1)
    on_board = np.cumsum(traj.stacked("pickups") - traj.stacked("dropoffs"), axis=0)  # [T, A] after each step
    empty = np.array([(on_board[r - 1] == 0).sum() if r > 0 else on_board.shape[1] for r in release])
    served = pickup >= 0
    return (pickup[served] - release[served]) * traj.slot_s, empty[served]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--family", default="berlin")
    parser.add_argument("--setting", default="4x48", help="taxis x requests")
    parser.add_argument("--count", type=int, default=4, help="first validation episodes")
    parser.add_argument("--dispatchers", nargs="+", default=["greedy", "batch_assignment"])
    args = parser.parse_args()
    taxis, requests = (int(x) for x in args.setting.split("x"))
    waits: dict[str, list[np.ndarray]] = {name: [] for name in args.dispatchers}
    empties: dict[str, list[np.ndarray]] = {name: [] for name in args.dispatchers}
    for seed in split_seeds("validation", args.count, 0):
        cfg = make_fleet_instance(args.family, seed, taxis, requests, separation="shield", hover_action=True)
        for name in args.dispatchers:
            wait, empty = rider_waits(fly(cfg, make_policy(name, num_taxis=taxis)))
            waits[name].append(wait)
            empties[name].append(empty)
    print(f"{args.family} {args.setting}, first {args.count} validation episodes, shield + hover action")
    print("| dispatcher | riders | wait q10 / q25 / q50 / q75 / q90 / q95 s | mean s | median wait s by empty taxis "
          "at release (riders) |")  # fmt: skip
    print("|---|---:|---|---:|---|")
    for name in args.dispatchers:
        wait, empty = np.concatenate(waits[name]), np.concatenate(empties[name])
        quantiles = " / ".join(f"{q:.0f}" for q in np.percentile(wait, [10, 25, 50, 75, 90, 95]))
        counts = {k: int((empty == k).sum()) for k in range(taxis + 1)}
        by_empty = ", ".join(f"{k}: {np.median(wait[empty == k]):.0f} ({n})" for k, n in counts.items() if n)
        print(f"| `{name}` | {len(wait)} | {quantiles} | {wait.mean():.1f} | {by_empty} |")


if __name__ == "__main__":
    main()
