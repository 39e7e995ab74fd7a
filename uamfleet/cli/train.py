"""Train the shared MSHA policy with PPO on a scenario (greedy evaluations on the way; checkpoints and logs in
runs/<name>/, relative to the current folder).

    uamfleet-train --scenario berlin_p4 --sinr-min-db -3   # or: .venv/bin/python train/ppo.py ...
    uamfleet-train ... --resume                            # continue from runs/<name>/last.pt
    uamfleet-train ... --overwrite                         # replace an existing run of that name
    uamfleet-train --scenario berlin_instances --map munich # another map: a packaged one, or a map file's path

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

import faulthandler
import os
from collections.abc import Sequence

import torch.distributed as dist

from uamfleet.cli._common import fmt, run
from uamfleet.instances import map_provenance
from uamfleet.rl.distributed import leave_rank
from uamfleet.rl.trainer import TrainArgs, TrainResult, train


def main(args: TrainArgs) -> int:
    if args.env.map is not None and int(os.environ.get("RANK", "0")) == 0:
        print(f"Map: {map_provenance(args.env.map)}.", flush=True)
    try:
        result = train(args)
    except BaseException:
        if dist.is_initialized():
            dist.destroy_process_group()
        raise
    code = report(result)
    if dist.is_initialized():  # a torchrun rank: leave without finalising the interpreter with gloo threads alive
        faulthandler.enable(all_threads=True)
        leave_rank(code)
    return code


def report(result: TrainResult) -> int:
    """Print rank 0's summary; the exit status (130 after Ctrl-C, as a shell reports SIGINT)."""
    if result.interrupted:
        return 130
    if result.rank != 0:
        return 0  # under torchrun rank 0 reports
    best = result.best_eval
    print(
        f"done: {result.global_step:,} agent-steps in {result.wall_s:.0f} s; best greedy evaluation at step "
        f"{result.best_step:,}: PR {fmt(best.get('pr_pct'), '.0f', ' %')}, TD {fmt(best.get('td_m'), '.0f', ' m')}, "
        f"ATT {fmt(best.get('att_s'), '.1f', ' s')}, AWT {fmt(best.get('awt_s'), '.1f', ' s')}, "
        f"ELR {fmt(best.get('elr_pct'), '.1f', ' %')}, connectivity {fmt(best.get('connectivity_pct'), '.1f', ' %')}"
    )
    if result.target_reached_step is not None:
        print(f"target TD reached after {result.target_reached_step:,} agent-steps, {result.target_reached_s:.0f} s")
    print(f"checkpoints and logs in {result.run_dir}")
    return 0


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-train") -> int:
    """The ``uamfleet-train`` command (``python train/ppo.py``)."""
    return run(main, TrainArgs, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.train"))
