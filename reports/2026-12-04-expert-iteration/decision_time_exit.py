"""Greedy decision time of berlin_exit.pt against the shipped berlin, traced, one torch thread, in one run:

OMP_NUM_THREADS=1 taskset -c 0 .venv/bin/python reports/2026-12-04-expert-iteration/decision_time_exit.py
"""

import numpy as np
import torch

import uamfleet
from uamfleet.instances import make_instance, split_seeds
from uamfleet.rl.policy import load_policy
from uamfleet.rollout import fly


def main() -> None:
    torch.set_num_threads(1)
    exit_policy = load_policy("reports/2026-12-04-expert-iteration/berlin_exit.pt")[0].trace_actor()
    shipped = uamfleet.pretrained("berlin").trace_actor()
    decisions: dict[str, list[float]] = {"exit": [], "berlin": []}
    for seed in split_seeds("validation", 6, 300):
        cfg = make_instance("berlin", int(seed)).replace(hover_action=True)
        for name, policy in (("exit", exit_policy), ("berlin", shipped)):
            decisions[name] += list(np.asarray(fly(cfg, policy).decision_s)[1:] * 1000)  # the first call traces
    for name, ms in decisions.items():
        print(f"{name}: {len(ms)} decisions, p50 {np.median(ms):.3f} ms, p95 {np.percentile(ms, 95):.3f} ms")


if __name__ == "__main__":
    main()
