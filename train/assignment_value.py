"""``python -m train.assignment_value``: fit the value of ``batch_assignment_value`` (cli/assignment_value.py)."""

from uamfleet.cli.assignment_value import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="train/assignment_value.py"))
