"""Train the shared MSHA policy with PPO on a scenario, then evaluate it greedily beside the planners.

    .venv/bin/python train/ppo.py --scenario berlin_p4 --sinr-min-db -3
    .venv/bin/python train/ppo.py --help                  # every option
    .venv/bin/python train/ppo.py ... --resume            # continue from runs/<name>/last.pt
    .venv/bin/python train/ppo.py ... --overwrite         # replace an existing run of that name

Data-parallel on one machine (N processes; --num-envs and --total-timesteps are global, split among them):

    .venv/bin/torchrun --standalone --nproc_per_node=2 train/ppo.py --scenario berlin_p4 --num-envs 64

and on several (run on every node; node 0's address as the rendezvous endpoint):

    .venv/bin/torchrun --nnodes=2 --nproc_per_node=8 --rdzv-backend=c10d --rdzv-endpoint=HOST:29400 \\
        --rdzv-id=berlin train/ppo.py --scenario berlin_p4 --num-envs 256 --device cuda

Logs: runs/<name>/progress.csv and TensorBoard events in runs/<name>/tb (CleanRL's metric names plus
reward/<term>); checkpoints runs/<name>/last.pt (periodic, atomic) and best.pt (best greedy evaluation).
Ctrl-C saves the last finished iteration and exits with status 130.
"""

from __future__ import annotations

import sys

import torch.distributed as dist
import tyro

from uamfleet.rl.trainer import TrainArgs, train


def main(args: TrainArgs) -> int:
    try:
        result = train(args)
    finally:
        if dist.is_initialized():
            dist.destroy_process_group()
    if result.interrupted:
        return 130  # as a shell reports SIGINT
    if result.rank != 0:
        return 0  # under torchrun rank 0 reports
    best = {k: result.best_eval.get(k, float("nan")) for k in ("pr_pct", "td_m", "att_s", "awt_s", "elr_pct")}
    conn = result.best_eval.get("connectivity_pct", float("nan"))
    print(
        f"done: {result.global_step:,} agent-steps in {result.wall_s:.0f} s; best greedy evaluation at step "
        f"{result.best_step:,}: PR {best['pr_pct']:.0f} %, TD {best['td_m']:.0f} m, ATT {best['att_s']:.1f} s, "
        f"AWT {best['awt_s']:.1f} s, ELR {best['elr_pct']:.1f} %, connectivity {conn:.1f} %"
    )
    if result.target_reached_step is not None:
        print(f"target TD reached after {result.target_reached_step:,} agent-steps, {result.target_reached_s:.0f} s")
    print(f"checkpoints and logs in {result.run_dir}")
    return 0


if __name__ == "__main__":
    sys.exit(main(tyro.cli(TrainArgs)))
