"""``replan_futures`` at cheaper settings beside ``replan`` (beam 16), instance by instance, on train instances.

    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/anticipation_settings.py --first 100 --count 10

How much of the anticipating search's gain survives cheaper settings (fewer futures, narrower beams), and at what
CPU cost: the teacher ``uamfleet-imitate --expert futures`` is chosen by it. Each row: the seed, ``replan``'s TD,
then for each setting its TD and thread CPU seconds for the whole instance. Train instances only (never tune on the
validation or test sets).
"""

from __future__ import annotations

import argparse
import time

from uamfleet.baselines.anticipation import AnticipatingReplan, DemandPrior
from uamfleet.baselines.step_planner import SearchSettings, StepPlannerPolicy
from uamfleet.instances import make_instance, split_seeds
from uamfleet.metrics import episode_metrics
from uamfleet.rollout import fly

SETTINGS = {
    "cheap": dict(futures=2, scored=4, replan=SearchSettings(16, rank_slack=0.5), future_beam=8, score_beam=4),
    "mid": dict(futures=4, scored=8, replan=SearchSettings(16, rank_slack=0.5), future_beam=8, score_beam=4),
    "default": dict(),  # replan_futures as the benchmark flies it: 4 futures scored on 8, beams 64 / 16 / 8
}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--first", type=int, default=100)
    parser.add_argument("--count", type=int, default=10)
    args = parser.parse_args()
    print("seed replan16 " + " ".join(f"{name} {name}_cpu_s" for name in SETTINGS), flush=True)
    for seed in split_seeds("train", args.count, args.first):
        cfg = make_instance("berlin", seed)
        replan = StepPlannerPolicy("replan", [SearchSettings(16, rank_slack=0.5)])
        row: list[object] = [seed, episode_metrics(fly(cfg, replan), cfg.radio).td_m]
        for kw in SETTINGS.values():
            policy = AnticipatingReplan(DemandPrior.of_family("berlin", cfg), seed=seed, **kw)  # type: ignore[arg-type]
            start = time.thread_time()
            td = episode_metrics(fly(cfg, policy), cfg.radio).td_m
            row += [td, round(time.thread_time() - start, 1)]
        print(*row, flush=True)


if __name__ == "__main__":
    main()
