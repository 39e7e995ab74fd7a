"""``python -m eval.render``: the ``uamfleet-render`` command (uamfleet/cli/render.py)."""

from uamfleet.cli.render import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m eval.render"))
