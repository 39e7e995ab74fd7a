"""``python train/ppo.py`` (also under torchrun): the ``uamfleet-train`` command (uamfleet/cli/train.py)."""

from uamfleet.cli.train import cli

if __name__ == "__main__":
    raise SystemExit(cli(prog="train/ppo.py"))
