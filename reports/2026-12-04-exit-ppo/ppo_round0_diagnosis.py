"""Round 0 of the PPO run again, per validation instance: the fit (ppo/fit0.pt, bit-identical to the fit-only run's
round0.pt) against the same fit after the run's PPO (fine_tune, seeded as the loop seeds it), on the loop's 80
validation instances (1,000,200-279, hover worlds): delivered %, TD, AWT and hover steps, paired.

    PYTHONPATH=. python reports/2026-12-04-exit-ppo/ppo_round0_diagnosis.py runs/exitppo_ppo > .../ppo_round0_diagnosis.log
"""

import copy
import sys
from pathlib import Path

import numpy as np

from uamfleet.instances import split_seeds
from uamfleet.metrics import episode_metrics
from uamfleet.rl.checkpoint import Checkpoint
from uamfleet.rl.expert_iteration import ExItOptions, fine_tune, instance_world, paired
from uamfleet.rl.policy import load_policy
from uamfleet.rollout import fly


def flights(policy, seeds):
    rows = []
    for seed in seeds:
        cfg = instance_world("berlin", seed, True)
        episode = fly(cfg, policy)
        m = episode_metrics(episode, cfg.radio, threshold_db=cfg.sinr_min_db)
        steps = episode.num_steps  # a step is a move of step_m or a hover (no distance)
        rows.append((m.pr_pct, m.td_m, m.awt_s, steps - round(m.td_m / episode.step_m), float(episode.truncated)))
    return np.array(rows, float)


def main() -> None:
    run = Path(sys.argv[1])
    fitted = run / "ppo" / "fit0.pt"
    source = Checkpoint.load(fitted)
    fit = load_policy(fitted)[0]
    tuned = copy.deepcopy(fit)
    figures = fine_tune(tuned, source, ExItOptions(ppo_after=25600), Path("/tmp/exitppo_diag"), 0)
    print("PPO:", {k: round(v, 4) for k, v in figures.items()})
    seeds = [int(s) for s in split_seeds("validation", 80, 200)]
    a, b = flights(fit, seeds), flights(tuned, seeds)
    for name, rows in (("fit", a), ("PPO", b)):
        pr, td, awt, hovers, truncated = np.nanmean(rows, 0)
        print(f"{name}: delivered {pr:.2f} %, TD {td:.1f} m, AWT {awt:.1f} s, hover steps {hovers:.1f}, "
              f"truncated {truncated:.3f}")  # fmt: skip
    mean, half = paired(b[:, 1], a[:, 1])
    print(f"PPO - fit, TD paired: {mean:+.1f} ± {half:.1f} m")
    full = (a[:, 0] == 100) & (b[:, 0] == 100)
    mean, half = paired(b[full, 1], a[full, 1])
    print(f"on the {full.sum()} instances both deliver fully: {mean:+.1f} ± {half:.1f} m")
    for i in np.flatnonzero(~full):
        print(
            f"seed {seeds[i]}: fit {a[i].round(1).tolist()}, PPO {b[i].round(1).tolist()} (pr %, td m, awt s, hover steps, truncated)"
        )


if __name__ == "__main__":
    main()
