"""Shared test helpers: radio maps drawn as ASCII art, and small configs on them."""

from __future__ import annotations

import math
import os
from typing import Any

import numpy as np
import pytest

from uamfleet.config import EnvConfig, Request, heading_vectors
from uamfleet.radio import RadioMap

# Distance tables are computed in each test, never read from (or written to) the user's disk cache: tests must not
# depend on what an earlier run left there. tests/paths/test_table_cache.py turns it on in a temporary folder.
os.environ["UAMFLEET_CACHE"] = "off"

# Under pytest-xdist (the README's `-n 2`) each worker runs one torch/OpenMP thread: torch's default of every core
# per worker made the workers' threads spin against each other on a 2-core machine. Set before torch is imported
# (the variables also reach the commands a test starts); ``pytest_configure`` below covers a torch already loaded.
XDIST_WORKER = os.environ.get("PYTEST_XDIST_WORKER")
if XDIST_WORKER:
    os.environ.setdefault("OMP_NUM_THREADS", "1")
    os.environ.setdefault("MKL_NUM_THREADS", "1")
    os.environ.setdefault("OMP_WAIT_POLICY", "PASSIVE")

GOOD_DB = 0.0
BAD_DB = -10.0


def drawn_map(art: str, cell_m: float = 100.0) -> RadioMap:
    """A radio map from ASCII art: '.' = 0 dB, '#' = -10 dB, one character per ``cell_m`` block.

    The first line of ``art`` is the north edge. Cell centres sit at block centres (origin cell_m / 2), so
    with ``block_m == cell_m`` every block holds exactly one raster point and its mean is that value.
    """
    rows = [line.strip() for line in art.strip().splitlines()]
    grid = np.array([[GOOD_DB if ch == "." else BAD_DB for ch in row] for row in rows[::-1]])  # [y, x]
    n = grid.shape[0]
    assert grid.shape == (n, n), "drawn maps are square"
    return RadioMap(
        sinr_db=grid.T.copy(),
        resolution_m=cell_m,
        origin_m=(cell_m / 2, cell_m / 2),
        side_m=n * cell_m,
        name="drawn",
    )


OPEN_5 = """
.....
.....
.....
.....
.....
"""


def small_config(art: str = OPEN_5, **overrides: Any) -> EnvConfig:
    """A one-taxi config on a drawn map with 100 m steps, threshold -3 dB, one request by default."""
    base: dict[str, Any] = dict(
        radio=drawn_map(art),
        sinr_min_db=-3.0,
        step_m=100.0,
        starts_m=((150.0, 150.0),),
        requests=(Request(0, (350.0, 150.0), (350.0, 350.0)),),
        time_limit_steps=50,
        patch_size=4,
    )
    base.update(overrides)
    if overrides.get("starts_m") is not None and "num_taxis" not in overrides:
        base["num_taxis"] = len(overrides["starts_m"])
    return EnvConfig(**base)


def pytest_configure(config: pytest.Config) -> None:
    if XDIST_WORKER:
        import torch

        torch.set_num_threads(int(os.environ["OMP_NUM_THREADS"]))


@pytest.fixture
def open_map() -> RadioMap:
    return drawn_map(OPEN_5)


def brute_force_moves(start, requests, side_m, step_m, radius_m, seats, max_moves):
    """Fewest moves that deliver everyone on an all-flyable square map: every sequence of headings, layer by
    layer, identical states (position to the micrometre, passenger phases) merged. The rules are written out
    here from the env's documentation (move unless it leaves the map; drop-offs, then pick-ups in passenger
    order while a seat is free, within the radius), independently of the env's code."""
    moves = step_m * heading_vectors()
    frontier = {(round(start[0], 6), round(start[1], 6), (0,) * len(requests))}
    for k in range(1, max_moves + 1):
        nxt = set()
        for x, y, phases in frontier:
            for dx, dy in moves:
                px, py = x + dx, y + dy
                if not (0 <= px <= side_m and 0 <= py <= side_m):
                    continue
                ph = list(phases)
                for i, r in enumerate(requests):
                    if ph[i] == 1 and math.dist((px, py), r.destination_m) <= radius_m + 1e-9:
                        ph[i] = 2
                for i, r in enumerate(requests):
                    if ph[i] == 0 and ph.count(1) < seats and math.dist((px, py), r.origin_m) <= radius_m + 1e-9:
                        ph[i] = 1
                if all(p == 2 for p in ph):
                    return k
                nxt.add((round(px, 6), round(py, 6), tuple(ph)))
        frontier = nxt
    return None


# One short PPO iteration of a small network, for tests that need a trained checkpoint rather than a good one.
TINY_TRAINING: dict[str, Any] = dict(
    total_timesteps=64,
    num_envs=2,
    num_steps=32,
    num_minibatches=1,
    update_epochs=1,
    run_name="tiny",
    progress=False,
    tensorboard=False,
    threads=1,
    time_limit_steps=40,
    d_model=16,
    num_heads=2,
)


# The same for a two-taxi fleet policy of berlin_random (tests that need a fleet checkpoint).
TINY_FLEET: dict[str, Any] = dict(
    scenario="berlin_random", num_taxis=2, num_envs=1, eval_every=0, run_name="fleet", time_limit_steps=20
)


def tiny_train_args(run_dir: Any, **overrides: Any) -> Any:
    """The training options of :data:`TINY_TRAINING` in ``run_dir``, with ``overrides`` (flat option names)."""
    from uamfleet.rl.options import TrainArgs

    return TrainArgs.from_flat({**TINY_TRAINING, "run_dir": run_dir, **overrides})
