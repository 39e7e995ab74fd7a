"""DAgger for a fleet: one shared fleet policy taught by a fleet dispatcher.

uamfleet/rl/fleet_imitation.py: it starts from a fleet policy (the shipped ``berlin_fleet`` by default) and flies
Berlin training episodes of a mixture of fleet sizes under the shield with the dispatcher watching every step; each
taxi's state is labelled with the dispatcher's action there, the labels are aggregated over rounds and the one
network is fitted to them.

    uamfleet fleet-imitate --run-name fleet_dagger
    uamfleet fleet-imitate --rounds 1 --mixture 2x12 --run-name try     # a quick look
    uamfleet fleet-imitate --labels stop --beta-decay 0.7 --run-name stop   # the dispatcher's stop, not its heading

``--labels stop`` labels each taxi with the network's own heading for the stop the dispatcher flies it to;
``--hover-anytime`` (with ``--fit-improbable``) also lets it learn the dispatcher's hover where it reads a stop;
``--kl-anchor`` holds each round's fit near the round's start (reports/2026-12-04-fleet-labels/).
``--dispatch-claims`` gives each passenger row the dispatcher's claim on it (on my schedule, another taxi's, my next
stop, my schedule's order; zero weights at first); fly the result with the dispatcher alongside,
``--dispatchers fleet_claims:source=runs/<name>/round<r>.pt`` (reports/2026-12-04-fleet-claims/).

Writes runs/<name>/progress.csv (one row per round), runs/<name>/round<r>.pt and last.pt (loadable with
load_policy; any fleet size). Choose a round on validation episodes with ``uamfleet fleet-bench --split validation
--checkpoints runs/<name>/round<r>.pt --passenger-window 24 --separation shield --hover-action``.
"""

from __future__ import annotations

from collections.abc import Sequence

from uamfleet.cli._common import run
from uamfleet.rl.fleet_imitation import FleetImitationArgs, fleet_imitate


def main(args: FleetImitationArgs) -> int:
    rows = fleet_imitate(args)
    last = rows[-1]
    print(
        f"{len(rows)} round(s): {int(last['samples'])} labelled taxi-steps, last fit agreement "
        f"{last['bc_agreement']:.3f}; checkpoints and progress.csv in {args.run_dir / args.run_name}"
    )
    return 0


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-fleet-imitate") -> int:
    """The ``uamfleet fleet-imitate`` command (``python -m uamfleet.cli.fleet_imitate``)."""
    return run(main, FleetImitationArgs, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.fleet_imitate"))
