"""``python -m eval.rollout``: the ``uamfleet-rollout`` command (uamfleet/cli/rollout.py)."""

from uamfleet.cli.rollout import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m eval.rollout"))
