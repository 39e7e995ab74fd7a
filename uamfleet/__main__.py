"""``python -m uamfleet <command> [options]``: the ``uamfleet`` command (uamfleet/cli/main.py)."""

from uamfleet.cli.main import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet"))
