"""Compile the numba kernels once, into numba's on-disk cache, so that the first run on a fresh machine starts at once.

    python -m uamfleet.warmup          # scripts/setup.sh runs it after installing

Every kernel is compiled on its first call and cached beside its source (``cache=True``); on a fresh machine that
took about 24 s of the first training command (the generalist's recipe logged its first iteration 40 s after the
command; 16 s with the kernels cached). This flies a few steps of what the commands fly, on the packaged Berlin map
at one threshold, with random allowed actions: a lone taxi with the stop features and the two-move heading
look-ahead under both feasibility rules (the shipped policy), and the generalist's preset with path shaping; the fleet
preset (shield, hover action, claims, passenger window); and a schedule dispatcher, whose exact sequencing and
stop look-ups have kernels of their own. The distance tables it needs are computed here and not written to the
table cache (``UAMFLEET_CACHE``): a command fills those it needs (about 2 s per map and threshold).

The kernels' types do not depend on sizes, so these small runs compile what the large ones call; what a command
calls that is not here compiles on first use, as before. Safe to run again: a cached kernel loads in milliseconds.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

from uamfleet.config import EnvConfig

WARM_STEPS = 12


def _fly(cfg: EnvConfig, steps: int, seed: int) -> None:
    """A few steps of random allowed actions in a two-env batch (observations and rewards included)."""
    from uamfleet.env.vector_env import VectorEnv

    env = VectorEnv(cfg, num_envs=2, autoreset=True)
    env.reset(seed=seed)
    rng = np.random.default_rng(seed)
    for _ in range(steps):
        mask = env.state.action_mask  # [E, A, headings]
        scores = np.where(mask, rng.random(mask.shape), -1.0)
        env.step(scores.argmax(-1))


def warm(steps: int = WARM_STEPS, verbose: bool = True) -> float:
    """Compile (or load) the kernels the CLIs call; returns the seconds it took."""
    table_cache = os.environ.get("UAMFLEET_CACHE")
    os.environ["UAMFLEET_CACHE"] = "off"  # the tables of a warm-up are not worth keeping on disk
    try:
        return _warm(steps, verbose)
    finally:
        if table_cache is None:
            del os.environ["UAMFLEET_CACHE"]
        else:
            os.environ["UAMFLEET_CACHE"] = table_cache


def _warm(steps: int, verbose: bool) -> float:
    start = time.perf_counter()
    from uamfleet.config import Request, RewardConfig
    from uamfleet.env.vector_env import VectorEnv
    from uamfleet.instances import make_fleet_instance, make_instance
    from uamfleet.policies import make_flown
    from uamfleet.presets import make_config

    def done(what: str) -> None:
        if verbose:
            print(f"  {what}: {time.perf_counter() - start:.1f} s", flush=True)

    for feasibility in ("endpoint_block", "segment_raster"):
        single = make_instance("berlin", 0, feasibility=feasibility, max_passengers=6)
        lookahead = single.replace(stop_features=True, heading_lookahead=True, lookahead_depth=2)
        _fly(lookahead, steps, seed=0)
        _fly(lookahead.replace(lookahead_depth=1), steps, seed=1)
    shaped = RewardConfig(shaping=1.0)  # the potential along feasible paths (train --shaping)
    _fly(make_config("berlin_instances", sinr_min_db=single.sinr_min_db, reward=shaped), steps, seed=2)
    done("one taxi, stop features and look-ahead")
    fleet = make_config("berlin_fleet", sinr_min_db=single.sinr_min_db, num_taxis=4)
    _fly(fleet, steps, seed=3)
    _fly(fleet.replace(passenger_window=4), steps, seed=4)
    done("a fleet under the shield")
    dispatched = make_fleet_instance("berlin", 0, 2, 4, separation="shield", hover_action=True)
    at_once = tuple(Request(0, r.origin_m, r.destination_m) for r in dispatched.requests or ())
    env = VectorEnv(dispatched.replace(requests=at_once), num_envs=1, autoreset=False)
    env.reset(seed=0)
    policy = make_flown("batch_assignment+wait=1+release", num_taxis=2)
    policy.reset(env.sim)
    for _ in range(steps):
        env.step(policy(None))
    done("a schedule dispatcher")
    return time.perf_counter() - start


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=WARM_STEPS, help="steps flown per configuration")
    args = parser.parse_args()
    print("uamfleet: compiling the numba kernels into their cache (once per machine and source change)")
    seconds = warm(args.steps)
    print(f"uamfleet: kernels ready ({seconds:.0f} s)")


if __name__ == "__main__":
    main()
