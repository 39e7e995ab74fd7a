"""``python -m eval.fleet_benchmark``: the ``uamfleet-fleet-benchmark`` command (uamfleet/cli/fleet_benchmark.py)."""

from uamfleet.cli.fleet_benchmark import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m eval.fleet_benchmark"))
