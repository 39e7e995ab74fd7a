"""``python -m eval.msha_table``: the ``uamfleet-msha-table`` command (uamfleet/cli/msha_table.py)."""

from uamfleet.cli.msha_table import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m eval.msha_table"))
