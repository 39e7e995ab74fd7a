"""``python -m eval.benchmark``: the ``uamfleet-benchmark`` command (uamfleet/cli/benchmark.py)."""

from uamfleet.cli.benchmark import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m eval.benchmark"))
