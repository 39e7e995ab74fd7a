"""Fine-tune a claims fleet policy with the return: PPO-style policy gradient, the dispatcher alongside.

uamfleet/rl/fleet_finetune.py: it starts from a fleet policy that reads the chosen dispatcher's claims (by default
reports/2026-12-04-fleet-claims/claims_r3.pt) and flies Berlin training episodes of a mixture of fleet sizes under
the shield, the dispatcher watching every step, each taxi's action sampled from softmax(logits / T); each instance is
flown K times and each sample's fleet cost-to-go (distance flown + λ × passenger-seconds of wait) is compared with
the other samples'; the one network is updated by the clipped surrogate with a KL anchor to the start.

    uamfleet fleet-finetune --run-name ppo1
    uamfleet fleet-finetune --iterations 1 --mixture 2x12 --run-name try     # a quick look
    uamfleet fleet-finetune --learning-rate 3e-5 --kl-anchor 0.3 --run-name ppo2

Writes runs/<name>/progress.csv (one row per iteration: mean return, KL to the start, ...), runs/<name>/iter<i>.pt
and last.pt (loadable with load_policy; any fleet size). Fly one with the dispatcher alongside,
``uamfleet fleet-bench --split validation --dispatchers fleet_claims:source=runs/<name>/iter<i>.pt --separation
shield --hover-action`` (reports/2026-12-04-fleet-finetune/).
"""

from __future__ import annotations

from collections.abc import Sequence

from uamfleet.cli._common import run
from uamfleet.rl.fleet_finetune import FleetFinetuneArgs, fleet_finetune


def main(args: FleetFinetuneArgs) -> int:
    rows = fleet_finetune(args)
    last = rows[-1]
    print(
        f"{len(rows)} iteration(s): last mean return {last['mean_return']:.4g}, KL to the start "
        f"{last['kl_to_start']:.3g}; checkpoints and progress.csv in {args.run_dir / args.run_name}"
    )
    return 0


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-fleet-finetune") -> int:
    """The ``uamfleet fleet-finetune`` command (``python -m uamfleet.cli.fleet_finetune``)."""
    return run(main, FleetFinetuneArgs, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.fleet_finetune"))
