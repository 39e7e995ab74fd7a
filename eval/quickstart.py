"""The main job: a short MSHA-PPO training on the packaged Berlin map, then its evaluation beside the paper.

    .venv/bin/python -m eval.quickstart                 # ~4 minutes of training on 2 CPU cores
    .venv/bin/python -m eval.quickstart --minutes 10    # longer, closer to the optimum

Trains on Berlin P4 at γ_T = -3 dB (the paper's hardest Berlin threshold) for a fixed wall-clock budget, keeps
the best greedy evaluation (runs/quickstart/best.pt), and prints its TD / ATT / AWT / ELR / PR / connectivity
next to the paper's MSHA-RL row and our REPLAN and clairvoyant OPT planners flown under the same rules.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import tyro

import uamfleet
from eval.paper_numbers import PAPER_TABLE_II
from uamfleet.baselines.planner_policy import PlannerPolicy
from uamfleet.metrics import EpisodeMetrics, episode_metrics
from uamfleet.rl.trainer import TrainArgs, load_policy, train
from uamfleet.rollout import fly as fly_episode


@dataclass
class Args:
    minutes: float = 4.0
    """training budget (wall clock)"""
    sinr_min_db: float = -3.0
    seed: int = 1
    variant: str = "full"
    """network variant (full MSHA; "le" trains ~6x faster per step on a CPU)"""
    run_dir: Path = Path("runs")
    run_name: str = "quickstart"


def fly(policy: object, threshold: float, **overrides: object) -> EpisodeMetrics:
    cfg = uamfleet.make_config("berlin_p4", sinr_min_db=threshold, **overrides)
    return episode_metrics(fly_episode(cfg, policy), cfg.radio)  # type: ignore[arg-type]


def main(args: Args) -> dict[str, EpisodeMetrics]:
    train_args = TrainArgs(
        scenario="berlin_p4", sinr_min_db=args.sinr_min_db, seed=args.seed, run_dir=args.run_dir,
        run_name=args.run_name, max_wall_s=60.0 * args.minutes, total_timesteps=600_000,
        variant=args.variant,  # type: ignore[arg-type]
        num_envs=32, num_steps=64,
    )  # fmt: skip
    print(f"training MSHA-PPO on Berlin P4 at {args.sinr_min_db:g} dB for {args.minutes:g} min ...")
    result = train(train_args)
    policy, trained = load_policy(result.run_dir / "best.pt")
    rows = {
        # the policy sees time as a fraction of its episode limit: evaluate it under the limit it trained with
        f"MSHA-PPO {args.variant} (ours)": fly(policy, args.sinr_min_db, time_limit_steps=trained.time_limit_steps),
        "REPLAN (ours)": fly(PlannerPolicy("replan"), args.sinr_min_db),
        "clairvoyant OPT (ours)": fly(PlannerPolicy("opt"), args.sinr_min_db),
    }
    paper = PAPER_TABLE_II["berlin"]["MSHA-RL"].get(args.sinr_min_db)
    print(
        f"\nBerlin P4, γ_T = {args.sinr_min_db:g} dB, after {result.global_step:,} agent-steps ({result.wall_s:.0f} s)"
    )
    print(f"{'method':<26} {'PR %':>5} {'TD m':>6} {'ATT s':>7} {'AWT s':>7} {'ELR %':>6} {'conn. %':>8}")
    if paper is not None:
        td, att, awt, elr = paper
        print(f"{'MSHA-RL (paper)':<26} {100:>5.0f} {td:>6.0f} {att:>7.2f} {awt:>7.2f} {elr:>6.2f} {'100':>8}")
    for name, m in rows.items():
        print(f"{name:<26} {m.pr_pct:>5.0f} {m.td_m:>6.0f} {m.att_s:>7.2f} {m.awt_s:>7.2f} {m.elr_pct:>6.2f} "
              f"{m.connectivity_pct:>8.1f}")  # fmt: skip
    print(f"\ncheckpoints and logs: {result.run_dir} (TensorBoard: tensorboard --logdir {result.run_dir / 'tb'})")
    return rows


if __name__ == "__main__":
    main(tyro.cli(Args))
