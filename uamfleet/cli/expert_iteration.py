"""Expert iteration: teach the single-taxi network the hedge's decisions on its own states, round by round.

    uamfleet expert-iteration --run-name exit_berlin                       # 4 rounds from the shipped berlin
    uamfleet expert-iteration --rounds 1 --label-instances 4 --val-instances 4 --run-name try   # a quick look
    uamfleet expert-iteration --map munich --run-name exit_munich          # another map's instances (or a file's)
    uamfleet expert-iteration --ppo-after 25600 --run-name exit_ppo        # PPO on each round's fit before validating

Each round labels fresh training instances with the hedge over the current network (worker processes), fits the
network to the labels held near the round's start (with ``--ppo-after N``, then N agent-steps of PPO on the family's
random episodes with a KL term toward the fit), and keeps the result only if it flies shorter on the validation
block (paired per instance). Writes runs/<name>/progress.csv (per round: labelling cost, fit, validation TD paired
against the round's start and against replan), start.pt, round<k>.pt, best.pt, labels/<round>/*.npz and, with
PPO, ppo/fit<k>.pt (each round's fit before PPO).
"""

from __future__ import annotations

import dataclasses
from collections.abc import Sequence
from dataclasses import dataclass

from uamfleet.cli._common import MapName, check_map, run
from uamfleet.instances import map_provenance
from uamfleet.rl.expert_iteration import ExItOptions, expert_iteration


@dataclass(frozen=True)
class ExItArgs(ExItOptions):
    """:class:`~uamfleet.rl.expert_iteration.ExItOptions` and ``--map``."""

    map: MapName = None
    """(labels and validates on the map's instance family, in place of --family)"""


def main(args: ExItArgs) -> int:
    if args.map is not None:
        check_map(args.map)
        print(f"Map: {map_provenance(args.map)}.", flush=True)
        args = dataclasses.replace(args, family=args.map)
    last = expert_iteration(args)
    print(
        f"last round {int(last['round'])}: validation TD {last['val_td_m']:,.0f} m, against replan "
        f"{last['vs_replan_m']:+,.0f} ± {last['vs_replan_ci_m']:,.0f} m per instance; best.pt and progress.csv in "
        f"{args.run_dir / args.run_name}"
    )
    return 0


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet expert-iteration") -> int:
    """The ``uamfleet expert-iteration`` command."""
    return run(main, ExItArgs, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.expert_iteration"))
