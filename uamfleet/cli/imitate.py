"""Teach a policy to fly like the online step-level search (DAgger; uamfleet/rl/imitation.py): start from a
checkpoint (the shipped Berlin generalist by default), add a heading residual to its stop head, label the states it
visits with ``replan``'s solver over the requests released so far, fit, and keep the checkpoint that flies the
validation instances shortest.

    uamfleet-imitate --run-name berlin_dagger                  # or: .venv/bin/python train/imitate.py ...
    uamfleet-imitate --rounds 2 --steps-per-round 30 --eval-instances 10 --run-name try   # a quick look
    uamfleet-imitate --init berlin --map berlin --also-maps munich munich_3km --run-name mix   # several maps at
        # once: one group of envs per map and threshold, validated on the mean over the maps' validation instances
    uamfleet-imitate --init berlin --lookahead --lookahead-depth 2 --expert futures --run-name fut   # teacher:
        # replan_futures' decisions (it anticipates releases; ~1 s per decision at the default futures settings)

Writes runs/<name>/progress.csv (one row per round: samples, expert solves, fit loss and agreement, validation PR
and TD), runs/<name>/last.pt and runs/<name>/best.pt (atomic, loadable with load_policy and export_policy).
"""

from __future__ import annotations

from collections.abc import Sequence

from uamfleet.cli._common import fmt, run
from uamfleet.instances import map_provenance
from uamfleet.rl.imitation import ImitationArgs, imitate


def main(args: ImitationArgs) -> int:
    for name in args.maps():  # --map, then --also-maps
        print(f"Map: {map_provenance(name)}.", flush=True)
    best = imitate(args)
    print(
        f"best validation round {int(best['round'])}: PR {fmt(best['val_pr_pct'], '.1f', ' %')}, mean TD "
        f"{fmt(best['val_td_m'], '.0f', ' m')} over {args.eval.eval_instances} instances; checkpoints and progress.csv "
        f"in {args.run.run_dir / args.run.run_name}"
    )
    return 0


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-imitate") -> int:
    """The ``uamfleet-imitate`` command (``python train/imitate.py``)."""
    return run(main, ImitationArgs, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.imitate"))
