"""``python train/imitate.py``: the ``uamfleet-imitate`` command (uamfleet/cli/imitate.py)."""

from uamfleet.cli.imitate import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="train/imitate.py"))
