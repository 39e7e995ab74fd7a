"""``python -m eval.paper_table``: the ``uamfleet-paper-table`` command (uamfleet/cli/paper_table.py)."""

from uamfleet.cli.paper_table import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m eval.paper_table"))
