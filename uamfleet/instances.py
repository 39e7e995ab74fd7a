"""Seeded random single-taxi instances with disjoint train / validation / test seed ranges.

An instance is an :class:`~uamfleet.config.EnvConfig` with a fixed start (``starts_m``), fixed requests and a
fixed threshold (``sinr_min_db``): the same seed gives the same instance on every machine. Per instance, drawn in
this order from ``np.random.default_rng(SeedSequence([seed, family id]))``:

1. the threshold, uniformly from the family's thresholds (Berlin −7 … −3 dB; Detroit-like 3GPP −21 … −17 dB);
2. the number of passengers, uniformly from 2 … 6;
3. the start, uniformly from the flyable block centres of the largest flyable component at that threshold
   (:func:`uamfleet.env.generator.flyable_sites`, as the env's own random starts);
4. release steps: the first request at step 0, the others uniformly over the first ``release_window_s``
   (2 minutes: 40 steps of 3 s in Berlin, 12 of 9.6 s in Detroit), sorted;
5. each request's origin and destination: two flyable block centres at least ``min_trip_m`` apart.

Every start and stop is then checked (in the block under the threshold, in the start's flyable component, and
reachable on the raster graph the planners use); an instance that fails is redrawn from the same generator, so
the result stays a function of the seed. Seeds: :data:`TRAIN_SEEDS`, :data:`VALIDATION_SEEDS` and
:data:`TEST_SEEDS` are disjoint ranges; choose checkpoints on validation seeds, report on test seeds.
"""

from __future__ import annotations

import zlib
from dataclasses import dataclass

import numpy as np

from uamfleet.config import EnvConfig, FeasibilityRule, Request, make_config
from uamfleet.env.generator import InfeasibleInstanceError, flyable_sites, validate_instance
from uamfleet.env.world import World
from uamfleet.paths import DistanceFields
from uamfleet.paths.grid_graph import UnreachableStopError

TRAIN_SEEDS = range(0, 1_000_000)
VALIDATION_SEEDS = range(1_000_000, 1_010_000)
TEST_SEEDS = range(2_000_000, 2_010_000)
SPLITS: dict[str, range] = {"train": TRAIN_SEEDS, "validation": VALIDATION_SEEDS, "test": TEST_SEEDS}
MAX_ATTEMPTS = 1000


@dataclass(frozen=True)
class InstanceFamily:
    """How the instances of one map are drawn (see the module docstring)."""

    scenario: str  # the preset that gives the map, step length and slot
    thresholds_db: tuple[float, ...]
    min_trip_m: float
    min_passengers: int = 2
    max_passengers: int = 6
    release_window_s: float = 120.0


FAMILIES: dict[str, InstanceFamily] = {
    "berlin": InstanceFamily("berlin_random", (-7.0, -6.0, -5.0, -4.0, -3.0), min_trip_m=500.0),
    "detroit3gpp": InstanceFamily("detroit3gpp_random", (-21.0, -20.0, -19.0, -18.0, -17.0), min_trip_m=2000.0),
}


def split_seeds(split: str, count: int, first: int = 0) -> list[int]:
    """``count`` seeds of a split (``train``, ``validation``, ``test``), starting at its ``first``-th seed."""
    if split not in SPLITS:
        raise ValueError(f"unknown split {split!r}; choose one of {tuple(SPLITS)}.")
    seeds = SPLITS[split]
    if first < 0 or count < 0 or first + count > len(seeds):
        raise ValueError(f"seeds {first}..{first + count - 1} lie outside the {len(seeds)} seeds of split {split!r}.")
    return list(seeds[first : first + count])


def make_instance(
    family: str, seed: int, feasibility: FeasibilityRule = "endpoint_block", max_passengers: int | None = None
) -> EnvConfig:
    """The instance of ``seed`` in ``family`` (:data:`FAMILIES`): a one-taxi config with a fixed start, fixed
    requests and a fixed threshold. ``max_passengers`` pads the passenger axis (e.g. 6 for a learned policy)."""
    if family not in FAMILIES:
        raise ValueError(f"unknown instance family {family!r}; choose one of {tuple(FAMILIES)}.")
    if int(seed) != seed or seed < 0:
        raise ValueError(f"seed={seed!r} must be an integer >= 0.")
    fam = FAMILIES[family]
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(family.encode())]))
    threshold = float(rng.choice(fam.thresholds_db))
    base = make_config(fam.scenario, sinr_min_db=threshold, num_taxis=1, feasibility=feasibility)
    world = World(base)
    sites = flyable_sites(world)
    graph = DistanceFields(world).graph
    window_steps = int(fam.release_window_s // base.slot_s)
    for _ in range(MAX_ATTEMPTS):
        num = int(rng.integers(fam.min_passengers, fam.max_passengers + 1))
        start = sites[int(rng.integers(len(sites)))]
        release = np.sort(np.concatenate([[0], rng.integers(0, window_steps + 1, size=num - 1)]))
        requests = []
        for step in release:
            o = int(rng.integers(len(sites)))
            far = np.flatnonzero(np.linalg.norm(sites - sites[o], axis=-1) >= fam.min_trip_m)
            d = int(far[rng.integers(len(far))]) if len(far) else (o + 1) % len(sites)
            requests.append(Request(int(step), tuple(sites[o]), tuple(sites[d])))
        try:
            validate_instance(world, start[None], requests)
            stops = np.array([start] + [p for r in requests for p in (r.origin_m, r.destination_m)])
            if not np.all(np.isfinite(graph.shortest_paths(stops).distance_m)):
                continue
        except (InfeasibleInstanceError, UnreachableStopError):
            continue
        return base.replace(
            starts_m=(tuple(start),),
            requests=tuple(requests),
            demand=base.demand,
            max_passengers=max_passengers,
            scenario=f"{family}_seed{seed}",
        )
    raise RuntimeError(f"no valid instance for {family!r} seed {seed} in {MAX_ATTEMPTS} draws; check the map.")


__all__ = [
    "FAMILIES",
    "SPLITS",
    "TEST_SEEDS",
    "TRAIN_SEEDS",
    "VALIDATION_SEEDS",
    "InstanceFamily",
    "make_instance",
    "split_seeds",
]
