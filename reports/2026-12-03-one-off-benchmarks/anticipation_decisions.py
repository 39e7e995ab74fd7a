"""What anticipation does: ``replan_futures``' decisions beside ``replan``'s flight, instance by instance.

    OMP_NUM_THREADS=1 .venv/bin/python reports/2026-12-03-one-off-benchmarks/anticipation_decisions.py --split validation --count 8

For each Berlin instance of the split, flies ``replan`` (beam 64, rank slack 1.0, as the benchmark) and
``replan_futures`` (uamfleet/baselines/anticipation.py, its defaults) and prints both TDs and mean waits, then every
decision of ``replan_futures``: its step, how many candidates it scored, whether ``replan``'s plan or a sampled
future's won, the winner's mean scored moves, how many actions it committed to, and the decision's wall seconds.
About a minute per instance on one core. Validation instances only in docs/results.md (never tune on the test set).
"""

from __future__ import annotations

import argparse

from uamfleet.baselines.anticipation import AnticipatingReplan, DemandPrior
from uamfleet.baselines.step_planner import SearchSettings, StepPlannerPolicy
from uamfleet.instances import make_instance, split_seeds
from uamfleet.metrics import episode_metrics
from uamfleet.rollout import fly


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--split", default="validation")
    parser.add_argument("--first", type=int, default=0)
    parser.add_argument("--count", type=int, default=8)
    args = parser.parse_args()
    for seed in split_seeds(args.split, args.count, args.first):
        cfg = make_instance("berlin", seed)
        online = episode_metrics(fly(cfg, StepPlannerPolicy("replan", [SearchSettings(64, rank_slack=1.0)])), cfg.radio)
        anticipating = AnticipatingReplan(DemandPrior.of_family("berlin", cfg))
        m = episode_metrics(fly(cfg, anticipating), cfg.radio)
        releases = sorted(int(r.release_step) for r in cfg.requests or ())
        print(f"{seed} requests {cfg.num_passengers} released at steps {releases}: replan {online.td_m:.0f} m, mean "
              f"wait {online.awt_s:.0f} s | replan_futures {m.td_m:.0f} m, mean wait {m.awt_s:.0f} s | "
              f"difference {m.td_m - online.td_m:+.0f} m", flush=True)  # fmt: skip
        for t, candidates, best, mean, committed, seconds in anticipating.plans:
            chose = "replan" if best == 0 else "a future's plan"
            print(f"    step {t:3d}: {candidates} candidates, chose {chose} (mean {mean:.1f} moves), committed to "
                  f"{committed} actions, {seconds:.1f} s", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
