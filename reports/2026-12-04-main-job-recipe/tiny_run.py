"""A tiny seeded run on Berlin P4 (8 iterations of 8 envs x 64 steps, seed 1, one thread): the before/after check.

    PYTHONPATH=<checkout> python reports/2026-12-04-main-job-recipe/tiny_run.py OUT_DIR [option=value ...]

Run it once with main's code and once with the branch's (PYTHONPATH chooses the checkout), then compare the two
runs with compare_runs.py."""

from __future__ import annotations

import sys
import time

import uamfleet
from uamfleet.rl.options import TrainArgs
from uamfleet.rl.trainer import train


def main() -> None:
    print(uamfleet.__file__)
    extra: dict[str, object] = {}
    for pair in sys.argv[2:]:
        key, value = pair.split("=")
        extra[key] = int(value) if value.lstrip("-").isdigit() else value
    start = time.time()
    args = TrainArgs.from_flat(
        dict(
            scenario="berlin_p4", sinr_min_db=-3.0, total_timesteps=4096, num_envs=8, num_steps=64, eval_every=1,
            threads=1, run_dir=sys.argv[1], run_name="t", overwrite=True, progress=False, tensorboard=False,
            shaping_gamma=1.0, **extra,
        )
    )  # fmt: skip
    train(args)
    print(f"wall {time.time() - start:.1f} s")


if __name__ == "__main__":
    main()
