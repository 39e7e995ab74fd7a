"""Roll a policy out on a scenario and print what it did.

python -m eval.rollout --scenario berlin_p4 --policy random --episodes 3
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import tyro

import uamfleet
from uamfleet.baselines import make_policy, planner_configs
from uamfleet.metrics import episode_metrics
from uamfleet.rollout import run_episode


@dataclass
class Args:
    scenario: str = "berlin_p4"
    """scenario name (one of uamfleet.SCENARIOS)"""
    sinr_min_db: float | None = None
    """SINR threshold in dB (default: the scenario's)"""
    num_taxis: int | None = None
    """fleet size (default: the scenario's)"""
    policy: str = "random"
    """a planner (one taxi: cptsp, pdpcc, raster_replan, raster_opt, straight, replan, best_known), greedy
    (fleet dispatcher) or random"""
    episodes: int = 3
    """number of episodes"""
    seed: int = 0
    """seed of the first episode (episode i uses seed + i)"""
    time_limit_steps: int | None = None
    """episode time limit in steps (default: the scenario's)"""


def main(args: Args) -> list[dict[str, float]]:
    overrides = {
        k: v
        for k, v in (
            ("sinr_min_db", args.sinr_min_db),
            ("num_taxis", args.num_taxis),
            ("time_limit_steps", args.time_limit_steps),
        )
        if v is not None
    }
    flown, cfg = planner_configs(args.scenario, args.policy, **overrides)  # cfg: the rules it is scored against
    env = uamfleet.VectorEnv(flown, num_envs=1, autoreset=False)
    policy = make_policy(args.policy, args.seed, cfg.num_taxis)
    print(
        f"{cfg.scenario} on {cfg.radio.label}: {cfg.num_taxis} taxi(s), γ_T = {cfg.sinr_min_db:g} dB, "
        f"{cfg.num_passengers} passenger slot(s), policy={args.policy}"
    )
    rows = []
    for i in range(args.episodes):
        traj = run_episode(env, policy, seed=args.seed + i)
        m = episode_metrics(traj, cfg.radio, threshold_db=cfg.sinr_min_db)
        rows.append(m.as_dict())
        end = "terminated" if traj.terminated else "truncated"
        print(
            f"  episode {i}: {end} after {m.steps} steps, PR {m.pr_pct:.0f} % ({m.delivered}/{m.num_requests}), "
            f"TD {m.td_m:.0f} m, ATT {m.att_s:.1f} s, AWT {m.awt_s:.1f} s, ELR {m.elr_pct:.1f} %, "
            f"connectivity {m.connectivity_pct:.1f} % (min {m.min_sinr_db:.2f} dB), "
            f"return {float(np.sum(traj.episode['return'])):.1f}"
        )
    return rows


if __name__ == "__main__":
    main(tyro.cli(Args))
