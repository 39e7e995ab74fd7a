"""``python -m eval.quickstart``: the ``uamfleet-quickstart`` command (uamfleet/cli/quickstart.py)."""

from uamfleet.cli.quickstart import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m eval.quickstart"))
