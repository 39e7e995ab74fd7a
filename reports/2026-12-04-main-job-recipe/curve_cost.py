"""The cost of the curve's flights: a P4 policy (a screen run's best.pt) on the first 10 and 20 Berlin validation
instances, reading its 4 nearest requests, as the trainer's --curve-instances flies them (each count twice: the
first call builds the instances, the second reuses them, as every evaluation after the first does).

    OMP_NUM_THREADS=1 PYTHONPATH=. python reports/2026-12-04-main-job-recipe/curve_cost.py RUN/best.pt
"""

from __future__ import annotations

import dataclasses
import sys
import time

from uamfleet.instances import validation_metrics
from uamfleet.rl.policy import load_policy


def main() -> None:
    policy, _ = load_policy(sys.argv[1])
    assert policy.spec is not None and policy.trained_on is not None
    window = policy.reading(dataclasses.replace(policy.spec, passenger_window=4, slots_per_taxi=None))
    like = policy.trained_on.replace(max_passengers=6)
    for count in (10, 10, 20, 20):
        wall, cpu = time.perf_counter(), time.process_time()
        metrics = validation_metrics(window, "berlin", count, like)
        print(count, f"wall {time.perf_counter() - wall:.2f} s cpu {time.process_time() - cpu:.2f} s", metrics)


if __name__ == "__main__":
    main()
