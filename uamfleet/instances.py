"""Seeded random single-taxi instances with disjoint train / validation / test seed ranges.

An instance is an :class:`~uamfleet.config.EnvConfig` with a fixed start (``starts_m``), fixed requests and a
fixed threshold (``sinr_min_db``): the same seed gives the same instance on every machine. Per instance, drawn in
this order from ``np.random.default_rng(SeedSequence([seed, family id]))``:

1. the threshold, uniformly from the family's thresholds (Berlin −7 … −3 dB; Detroit-like 3GPP −21 … −17 dB);
2. the number of passengers, uniformly from 2 … 6;
3. the start, uniformly from the flyable block centres of the largest flyable component at that threshold
   (:func:`uamfleet.sim.generator.flyable_sites`, as the env's own random starts);
4. release steps: the first request at step 0, the others uniformly over the first ``release_window_s``
   (2 minutes: 40 steps of 3 s in Berlin, 12 of 9.6 s in Detroit), sorted;
5. each request's origin and destination: two flyable block centres at least ``min_trip_m`` apart.

A family with a :class:`~uamfleet.demand.DemandLaw` (``InstanceFamily.law``: ``berlin_stream``, ``berlin_peak``,
``berlin_burst``) draws the threshold and the start as above, then its requests from the law
(:meth:`~uamfleet.demand.DemandLaw.draw`: release steps, then trips); ``berlin`` and ``detroit3gpp`` have none.

Fleet instances (:func:`make_fleet_instance`: ``num_taxis`` taxis, ``num_requests`` requests) are drawn from
``SeedSequence([seed, family id, FLEET_TAG])`` (so fleet seed s is not the single-taxi instance of seed s, but
the same split ranges keep train / validation / test disjoint), in this order: the threshold; ``num_vertiports``
vertiport sites when asked (else every flyable block centre is a site); the taxis' starts (distinct flyable
block centres); Poisson arrivals over the first ``arrival_window_s`` (10 minutes): ``num_requests`` arrival
times uniform over the window (a Poisson process conditioned on its count), as release steps, sorted; each
request's origin and destination among the sites, at least ``min_trip_m`` apart. :data:`FLEET_SETTINGS` names
the settings of the fleet table (1 taxi / 6 requests, 2 / 12, 4 / 24, 8 / 48).

Families of any map (:func:`map_family`): a packaged map's name (:data:`uamfleet.radio.packaged.RADIO_MAPS`, e.g.
``"munich"``) or a map file's path (a ``.npz`` of ``uamfleet-radio-map`` or a WinProp ASCII file) names a family
wherever a family's name is taken (``make_instance("munich", seed)``, ``make_fleet_instance("city.npz", ...)``,
``FAMILIES["munich"]``): it is derived from the map alone, in any process (a spawned worker rebuilds it from the
name or path), with Berlin's rules scaled to the map (:func:`map_family`). The named families come first: the
packaged ``"berlin"`` is the ``berlin`` family.

Every start and stop is then checked (in the block under the threshold, in the start's flyable component, and
reachable on the raster graph the planners use); an instance that fails is redrawn from the same generator, so
the result stays a function of the seed. Seeds: :data:`TRAIN_SEEDS`, :data:`VALIDATION_SEEDS` and
:data:`TEST_SEEDS` are disjoint ranges; choose checkpoints on validation seeds, report on test seeds.
"""

from __future__ import annotations

import functools
import os
import zlib
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uamfleet.checks import MAX_SEED, MAX_TIME_LIMIT_STEPS
from uamfleet.config import (
    FLEET_ARRIVAL_WINDOW_S,
    FLEET_REQUESTS_PER_TAXI,
    FLEET_TIME_LIMIT_WINDOWS,
    MAX_PASSENGERS,
    MAX_TAXIS,
    ConfigError,
    EnvConfig,
    FeasibilityRule,
    Request,
    check_integer,
    check_number,
    fleet_time_limit,
    fleet_window_steps,
)
from uamfleet.demand import DemandLaw
from uamfleet.env.mixture import MixtureVectorEnv
from uamfleet.env.protocol import observer_of
from uamfleet.observe.legacy import observed_config, split_env_config
from uamfleet.observe.spec import ObserverSpec
from uamfleet.paths import DistanceFields
from uamfleet.paths.grid_graph import UnreachableStopError
from uamfleet.presets import make_config
from uamfleet.radio import RadioMap, load_radio_map
from uamfleet.radio.packaged import RADIO_MAPS
from uamfleet.map_rules import (
    BERLIN_FEASIBLE_SHARES,
    BERLIN_SIDE_M,
    BERLIN_STEP_M,
    BERLIN_THRESHOLDS_DB,
    MAP_SUFFIXES,
    MIN_FEASIBLE_SHARE,
    MIN_INFEASIBLE_SHARE,
    map_family_name,
    map_provenance,
    map_step_m,
    map_thresholds,
    scaled_steps,
)
from uamfleet.sim.generator import InfeasibleInstanceError, flyable_sites, validate_instance
from uamfleet.sim.world import World

TRAIN_SEEDS = range(0, 1_000_000)
VALIDATION_SEEDS = range(1_000_000, 1_010_000)
TEST_SEEDS = range(2_000_000, 2_010_000)
SPLITS: dict[str, range] = {"train": TRAIN_SEEDS, "validation": VALIDATION_SEEDS, "test": TEST_SEEDS}
MAX_ATTEMPTS = 1000
FLEET_TAG = 13  # mixed into fleet instance seeds so they differ from the single-taxi instances of equal seed
FLEET_SETTINGS: dict[str, tuple[int, int]] = {
    f"{n}x{FLEET_REQUESTS_PER_TAXI * n}": (n, FLEET_REQUESTS_PER_TAXI * n) for n in (1, 2, 4, 8)
}
"""Fleet table settings: name -> (taxis, requests per episode)."""


def fleet_setting(setting: str, flag: str = "--settings") -> tuple[int, int]:
    """(taxis, requests) of a fleet setting ``<taxis>x<requests>`` (e.g. ``8x96``; :data:`FLEET_SETTINGS` names such
    settings), both >= 1; a ConfigError naming ``flag`` and the setting otherwise."""
    taxis, sep, requests = setting.partition("x")
    if not (sep and taxis.isdigit() and requests.isdigit() and int(taxis) >= 1 and int(requests) >= 1):
        raise ConfigError(f"{flag} setting {setting!r} is not <taxis>x<requests> with both >= 1 (e.g. 4x48).")
    return int(taxis), int(requests)


@dataclass(frozen=True)
class InstanceFamily:
    """How the instances of one map are drawn (see the module docstring)."""

    scenario: str  # the preset that gives the map, step length and slot
    thresholds_db: tuple[float, ...]
    min_trip_m: float
    min_passengers: int = 2
    max_passengers: int = 6
    release_window_s: float = 120.0
    law: DemandLaw | None = None
    """None: the requests are drawn as the module docstring says (``berlin``, ``detroit3gpp``); a law: the start,
    then :meth:`DemandLaw.draw` (the count, trip length and window fields above then repeat the law's)."""
    radio: str | None = None
    """A family of a map (:func:`map_family`): the packaged name or file path of its map, flown on
    ``scenario``'s preset; None: the preset's own map."""
    name: str | None = None
    """A family of a map: its name (the packaged name, or the file's stem), which seeds its instances and names
    its scenarios; None: the family's key in :data:`FAMILIES`."""
    step_m: float | None = None
    """A family of a map whose raster is coarser than the preset's steps: its steps (one raster cell), flown at the
    preset's speed; None: the preset's."""

    def config(self, **overrides: object) -> EnvConfig:
        """The family's preset with ``overrides`` (on the family's map, named ``<name>_random``)."""
        if self.radio is None:
            return make_config(self.scenario, **overrides)
        return make_config(
            self.scenario, radio=_map(self.radio), **scaled_steps(self.scenario, self.step_m), **overrides
        ).replace(scenario=f"{self.name}_random")

    def seed_name(self, family: str) -> str:
        """The name mixed into the family's seeds (``crc32``) and its instances' scenario names."""
        return self.name or family

    def window_steps(self, slot_s: float) -> int:
        """The last step a request may be released at, with slots of ``slot_s`` seconds (releases are drawn from
        steps 0 … this)."""
        if self.law is not None:
            return self.law.window_steps(slot_s)
        return int(self.release_window_s // slot_s)

    def demand_law(self) -> DemandLaw:
        """The family's law: :attr:`law`, or for ``law=None`` the ``uniform_window`` law its drawing code follows
        (one request at step 0, uniform trips)."""
        if self.law is not None:
            return self.law
        return DemandLaw("uniform_window", self.min_passengers, self.max_passengers, initial=1,
                         window_s=self.release_window_s, min_trip_m=self.min_trip_m)  # fmt: skip


def law_family(scenario: str, thresholds_db: tuple[float, ...], law: DemandLaw) -> InstanceFamily:
    """A family of ``scenario``'s map whose requests follow ``law`` (its count bounds, window and trip length
    repeated in the family's fields, which :class:`~uamfleet.baselines.anticipation.DemandPrior` reads)."""
    return InstanceFamily(scenario, thresholds_db, law.min_trip_m, law.min_requests, law.max_requests,
                          law.window_s, law=law)  # fmt: skip


BERLIN_HOTSPOTS = ((650.0, 650.0, 300.0), (2050.0, 1550.0, 300.0), (2850.0, 2850.0, 300.0))
"""The ``berlin_stream`` family's hot spots (x_m, y_m, sd_m): three block centres flyable at every threshold."""


class Families(dict[str, InstanceFamily]):
    """The named instance families; looking up a packaged map's name or a map file's path (a key that is no named
    family) gives that map's family (:func:`map_family`), derived afresh in each process. Iteration, ``len`` and
    ``keys`` list the named families only."""

    def __missing__(self, key: str) -> InstanceFamily:
        return map_family(key)

    def __contains__(self, key: object) -> bool:
        return dict.__contains__(self, key) or is_map_name(key)

    def get(self, key: str, default: InstanceFamily | None = None) -> InstanceFamily | None:  # type: ignore[override]
        return self[key] if key in self else default


FAMILIES: Families = Families(
    {
        "berlin": InstanceFamily("berlin_random", BERLIN_THRESHOLDS_DB, min_trip_m=500.0),
        "detroit3gpp": InstanceFamily("detroit3gpp_random", (-21.0, -20.0, -19.0, -18.0, -17.0), min_trip_m=2000.0),
        # a longer service (6 minutes) with a Poisson stream of 0.6 requests per minute from three hot spots, capped
        # at the 6 rows of the shipped policies' observer (reached on about 29 % of the instances)
        "berlin_stream": law_family(
            "berlin_random",
            BERLIN_THRESHOLDS_DB,
            DemandLaw("poisson_stream", 1, 6, window_s=360.0, rate_per_min=0.6, hotspots=BERLIN_HOTSPOTS),
        ),
        # a peak of releases in the middle of a 4-minute window
        "berlin_peak": law_family(
            "berlin_random", BERLIN_THRESHOLDS_DB, DemandLaw("peak", 3, 6, window_s=240.0, peak_s=120.0, peak_sd_s=30.0)
        ),
        # two requests at once, the others over the first 90 s
        "berlin_burst": law_family(
            "berlin_random", BERLIN_THRESHOLDS_DB, DemandLaw("uniform_window", 4, 5, initial=2, window_s=90.0)
        ),
    }
)
"""The instance families by name, and a family for any map (:class:`Families`). Each has its own seed stream
(``SeedSequence([seed, crc32(name)])``) on the same train / validation / test ranges."""


def is_map_name(key: object) -> bool:
    """``key`` names a map rather than a named family: a packaged map's name or the path of an existing map file
    (:data:`MAP_SUFFIXES`; another file, e.g. a demand model's ``.json``, names no family)."""
    if not isinstance(key, (str, os.PathLike)) or (isinstance(key, str) and dict.__contains__(FAMILIES, key)):
        return False
    if isinstance(key, str) and key in RADIO_MAPS:
        return True
    try:
        return Path(key).suffix in MAP_SUFFIXES and Path(key).is_file()
    except OSError:  # a name too long for a path, say
        return False


@functools.cache
def _map(key: str) -> RadioMap:
    """A map by name or path, read once per process (its block maps and graphs are cached on it)."""
    return load_radio_map(key)


@functools.cache
def _map_family(key: str) -> InstanceFamily:
    radio = _map(key)
    berlin = FAMILIES["berlin"]
    assert radio.side_m is not None  # a RadioMap infers its side when built without one
    min_trip_m = float(round(berlin.min_trip_m * radio.side_m / BERLIN_SIDE_M))
    return InstanceFamily(
        "berlin_random", map_thresholds(radio), min_trip_m, radio=key, name=map_family_name(key),
        step_m=map_step_m(radio),
    )  # fmt: skip


def map_family(name_or_path: str | os.PathLike[str]) -> InstanceFamily:
    """The instance family of a map (a packaged map's name, or the path of a ``.npz`` / WinProp ``.txt`` file): Berlin's
    rules (2-6 passengers, the first at step 0 and the others over the first 2 minutes, 100 m steps of 3 s, or of
    one raster cell at that speed on a coarser map (:func:`map_step_m`), and ``berlin_random``'s time limit) scaled
    to the map: trips at least ``500 m x side / 3,260 m`` (Berlin's
    shortest trip as the same share of the map's side, rounded to the metre) and the thresholds of
    :func:`map_thresholds`. Named ``<map name>`` (a file: its stem), which seeds its instances; built from the
    name or path alone, so any process derives the same family. A bad name or file is refused in one line."""
    if isinstance(name_or_path, str) and dict.__contains__(FAMILIES, name_or_path):
        return dict.__getitem__(FAMILIES, name_or_path)
    check_family(name_or_path)
    fam = _map_family(os.fspath(name_or_path))
    _MAP_KEYS[map_family_name(name_or_path)] = os.fspath(name_or_path)
    return fam


_MAP_KEYS: dict[str, str] = {}  # the name of each map family this process derived -> its map's name or path


def map_family_key(name: str) -> str | None:
    """The key (map name or path) of the map family named ``name``: a packaged map's name, or a file's family
    this process has derived (its instances were drawn here); None for any other name. A world knows its family's
    name (its scenario, ``<name>_seed<seed>``), not the path of its file: this reads the path back."""
    if name in RADIO_MAPS and not dict.__contains__(FAMILIES, name):
        return name
    return _MAP_KEYS.get(name)


def check_family(family: str | os.PathLike[str]) -> None:
    # A non-string (e.g. a list, unhashable) is refused by the same message instead of a TypeError of the lookup.
    if not isinstance(family, (str, os.PathLike)) or family not in FAMILIES:
        raise ValueError(
            f"unknown instance family {family!r}; choose one of {tuple(FAMILIES)}, a packaged map "
            f"({', '.join(RADIO_MAPS)}) or the path of an existing map file (.npz of uamfleet-radio-map, or WinProp "
            ".txt)."
        )


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
    check_family(family)
    seed = check_integer("seed", seed, 0, MAX_SEED)
    fam = FAMILIES[family]
    name = fam.seed_name(family)
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(name.encode())]))
    threshold = float(rng.choice(fam.thresholds_db))
    base = fam.config(sinr_min_db=threshold, num_taxis=1, feasibility=feasibility)
    world = World(base)
    sites = flyable_sites(world)
    graph = DistanceFields(world).graph
    window_steps = fam.window_steps(base.slot_s)
    for _ in range(MAX_ATTEMPTS):
        start, requests = _draw_instance(fam, rng, sites, window_steps, base.slot_s)
        try:
            validate_instance(world, start[None], requests)
            stops = np.array([start] + [p for r in requests for p in (r.origin_m, r.destination_m)])
            if not np.all(np.isfinite(graph.stop_distances(stops))):
                continue
        except (InfeasibleInstanceError, UnreachableStopError):
            continue
        return base.replace(
            starts_m=(tuple(start),),
            requests=tuple(requests),
            demand=base.demand,
            max_passengers=max_passengers,
            scenario=f"{name}_seed{seed}",
        )
    raise RuntimeError(f"no valid instance for {family!r} seed {seed} in {MAX_ATTEMPTS} draws; check the map.")


def _draw_instance(
    fam: InstanceFamily, rng: np.random.Generator, sites: np.ndarray, window_steps: int, slot_s: float
) -> tuple[np.ndarray, list[Request]]:
    """One draw of an instance's start and requests (module docstring; a family with a :class:`DemandLaw`: the
    start, then :meth:`DemandLaw.draw`)."""
    if fam.law is not None:
        start = sites[int(rng.integers(len(sites)))]
        return start, fam.law.draw(rng, sites, slot_s)
    num = int(rng.integers(fam.min_passengers, fam.max_passengers + 1))
    start = sites[int(rng.integers(len(sites)))]
    release = np.sort(np.concatenate([[0], rng.integers(0, window_steps + 1, size=num - 1)]))
    requests = []
    for step in release:
        o = int(rng.integers(len(sites)))
        far = np.flatnonzero(np.linalg.norm(sites - sites[o], axis=-1) >= fam.min_trip_m)
        d = int(far[rng.integers(len(far))]) if len(far) else (o + 1) % len(sites)
        requests.append(Request(int(step), tuple(sites[o]), tuple(sites[d])))
    return start, requests


def make_fleet_instance(
    family: str,
    seed: int,
    num_taxis: int = 4,
    num_requests: int = 4 * FLEET_REQUESTS_PER_TAXI,
    feasibility: FeasibilityRule = "endpoint_block",
    num_vertiports: int = 0,
    arrival_window_s: float = FLEET_ARRIVAL_WINDOW_S,
    max_passengers: int | None = None,
    separation: str = "none",
    hover_action: bool | None = None,
) -> EnvConfig:
    """The fleet instance of ``seed`` in ``family`` (:data:`FAMILIES`): ``num_taxis`` fixed starts,
    ``num_requests`` fixed requests released by Poisson arrivals over ``arrival_window_s`` and a fixed threshold
    (module docstring). ``num_vertiports`` > 0 draws that many vertiport sites per instance and puts every origin
    and destination on them; 0 uses every flyable block centre. Every stop is reachable along feasible paths from
    every start (the env's component rule and the dispatchers' distance fields); a draw that fails is redrawn.
    ``max_passengers`` pads the passenger axis; ``separation``: "none" (as every recorded table) or "shield";
    ``hover_action``: action 16 hovers; None: as the family's ``*_fleet`` preset has it (on: a fleet policy waits with
    it), False: the 16 headings alone (idle taxis zig-zag)."""
    seed, num_taxis, num_requests, num_vertiports = _check_fleet_args(
        family, seed, num_taxis, num_requests, num_vertiports, arrival_window_s
    )
    fam = FAMILIES[family]
    name = fam.seed_name(family)
    if hover_action is None:  # the family's fleet preset's rule (a map's: Berlin's): a fleet policy hovers to wait
        hover_action = make_config("berlin_fleet" if fam.radio is not None else f"{family}_fleet").hover_action
    rng = np.random.default_rng(np.random.SeedSequence([int(seed), zlib.crc32(name.encode()), FLEET_TAG]))
    threshold = float(rng.choice(fam.thresholds_db))
    base = fam.config(
        sinr_min_db=threshold, num_taxis=num_taxis, feasibility=feasibility, separation=separation,
        hover_action=hover_action,
    )  # fmt: skip
    _check_window(arrival_window_s, base.slot_s)
    world = World(base)
    flyable = flyable_sites(world)
    _check_sites(flyable, family, seed, threshold, num_taxis=num_taxis, num_vertiports=num_vertiports)
    fields = DistanceFields(world)
    window_steps = fleet_window_steps(base.slot_s, arrival_window_s)
    for _ in range(MAX_ATTEMPTS):
        sites = flyable[rng.choice(len(flyable), num_vertiports, replace=False)] if num_vertiports else flyable
        starts = flyable[rng.choice(len(flyable), num_taxis, replace=False)]
        release = np.sort(rng.integers(0, window_steps, size=num_requests))
        requests = _draw_trips(rng, sites, release, fam.min_trip_m)
        if len(requests) < num_requests or not _fleet_draw_valid(world, fields, starts, requests):
            continue
        return base.replace(
            starts_m=tuple(map(tuple, starts)),
            requests=tuple(requests),
            time_limit_steps=fleet_time_limit(base.time_limit_steps, window_steps),
            max_passengers=max_passengers,
            scenario=f"{name}_fleet{num_taxis}x{num_requests}_seed{seed}",
        )
    raise RuntimeError(f"no valid fleet instance for {family!r} seed {seed} in {MAX_ATTEMPTS} draws; check the map.")


def _fleet_draw_valid(world: World, fields: DistanceFields, starts: np.ndarray, requests: list[Request]) -> bool:
    """A fleet draw's starts and stops pass the env's checks, and every stop is reachable from the first start
    (the starts share its component: validate_instance)."""
    try:
        validate_instance(world, starts, requests)
    except InfeasibleInstanceError:
        return False
    stops = np.array([p for r in requests for p in (r.origin_m, r.destination_m)])
    return bool(np.isfinite(fields.remaining_m(starts[0], stops)).all())


def _check_fleet_args(
    family: str, seed: int, num_taxis: int, num_requests: int, num_vertiports: int, arrival_window_s: float
) -> tuple[int, int, int, int]:
    """:func:`make_fleet_instance`'s arguments checked in order: (seed, num_taxis, num_requests, num_vertiports)."""
    check_family(family)
    seed = check_integer("seed", seed, 0, MAX_SEED)
    num_taxis = check_integer("num_taxis", num_taxis, 1, MAX_TAXIS)
    num_requests = check_integer("num_requests", num_requests, 1, MAX_PASSENGERS, fix=" (one passenger slot each)")
    num_vertiports = check_integer("num_vertiports", num_vertiports, 0)
    if num_vertiports == 1:
        raise ValueError(f"num_vertiports={num_vertiports} must be 0 (random sites) or >= 2.")
    check_number("arrival_window_s", arrival_window_s, positive=True)
    return seed, num_taxis, num_requests, num_vertiports


def _check_window(arrival_window_s: float, slot_s: float) -> None:
    """The episode lasts FLEET_TIME_LIMIT_WINDOWS arrival windows, and an episode's steps are bounded."""
    longest_s = MAX_TIME_LIMIT_STEPS // FLEET_TIME_LIMIT_WINDOWS * slot_s
    if arrival_window_s > longest_s:
        raise ConfigError(
            f"arrival_window_s={arrival_window_s!r} is too long: an episode lasts {FLEET_TIME_LIMIT_WINDOWS} arrival "
            f"windows, {MAX_TIME_LIMIT_STEPS} steps of {slot_s:g} s at most; use at most {longest_s:.0f} s."
        )


def _check_sites(flyable: np.ndarray, family: str, seed: int, threshold: float, **counts: int) -> None:
    """Starts and vertiports are distinct flyable sites (drawn without replacement): too few would end in NumPy."""
    for name, count in counts.items():
        if count > len(flyable):
            fix = " (0: every site)" if name == "num_vertiports" else ""
            raise ConfigError(
                f"{name}={count}: {family!r} seed {seed} (at {threshold:g} dB) has only {len(flyable)} flyable "
                f"sites, one per {name[4:-1]}; use {name} <= {len(flyable)}{fix}."
            )


def draw_trip(rng: np.random.Generator, sites: np.ndarray, min_trip_m: float) -> tuple[int, int | None]:
    """(origin, destination) site indices of one trip as the families draw it: a uniform origin, then a uniform
    destination among the sites at least ``min_trip_m`` from it (None, and no second draw, where there is none)."""
    o = int(rng.integers(len(sites)))
    far = np.flatnonzero(np.linalg.norm(sites - sites[o], axis=-1) >= min_trip_m)
    return o, (int(far[rng.integers(len(far))]) if len(far) else None)


def _draw_trips(rng: np.random.Generator, sites: np.ndarray, release: np.ndarray, min_trip_m: float) -> list[Request]:
    """One request per release step (:func:`draw_trip`); stops early (fewer requests) at an origin with no site
    that far."""
    requests = []
    for step in release:
        o, d = draw_trip(rng, sites, min_trip_m)
        if d is None:
            break
        requests.append(Request(int(step), tuple(sites[o]), tuple(sites[d])))
    return requests


def family_of(scenario: str) -> str:
    """The instance family a training scenario draws like: ``berlin_instances`` / ``berlin_fleet`` -> ``berlin``;
    a packaged map's (``munich_instances``) -> the map's family (``munich``)."""
    for family, fam in FAMILIES.items():
        if scenario in (fam.scenario, f"{family}_instances", f"{family}_fleet"):
            return family
    for name in RADIO_MAPS:  # a packaged map's scenarios (munich_random, munich_instances): its map family
        if scenario in (f"{name}_random", f"{name}_instances", f"{name}_fleet"):
            return name
    raise ValueError(
        f"scenario {scenario!r} belongs to no instance family; use one of {tuple(FAMILIES)} + '_instances'."
    )


def instance_for_policy(family: str, seed: int, like: EnvConfig) -> EnvConfig:
    """Instance ``seed`` of ``family`` under the rules of the config ``like`` a policy trains on (its feasibility
    rule, passenger rows, reward and, without a passenger window, its time limit), observed as ``like`` observes
    (:func:`~uamfleet.observe.legacy.split_env_config`). A fleet config (``*_fleet``) gets the fleet instance of
    ``seed`` with its taxis, its demand's request count and its separation rule and hover action (a policy trained
    under the shield is evaluated under it)."""
    if like.scenario.endswith("_fleet"):
        cfg = make_fleet_instance(
            family, seed, like.num_taxis, like.demand.max_requests, feasibility=like.feasibility,
            max_passengers=like.num_passengers, separation=like.separation, hover_action=like.hover_action,
        )  # fmt: skip
    else:
        cfg = make_instance(family, seed, feasibility=like.feasibility, max_passengers=like.num_passengers)
    rules: dict[str, object] = {"reward": like.reward}
    if like.passenger_window is None:  # a run without a window reads time as a share of its own limit
        rules["time_limit_steps"] = like.time_limit_steps
    return observed_config(cfg.replace(**rules).world, split_env_config(like)[1])[0]


_BATCHES: dict[tuple[str, tuple[int, ...], EnvConfig, ObserverSpec | None], MixtureVectorEnv] = {}
MAX_BATCHES = 4
"""Batches :func:`fly_instances` keeps (the oldest goes first): one per family a run validates on each round, e.g.
imitation's mixture of maps (``--also-maps``), so none is rebuilt every round."""


def fly_instances(
    policy: Callable[[dict[str, np.ndarray]], np.ndarray], family: str, seeds: Sequence[int], like: EnvConfig
) -> tuple[np.ndarray, np.ndarray]:
    """Fly ``policy`` (``obs [E, A, ...] -> actions [E, A]``) once on each instance ``seeds`` of ``family`` under
    ``like``'s rules (:func:`instance_for_policy`), observed by the policy's spec when it has one, all in one batch
    (one policy call per step for all). Returns (share of passengers delivered [n], distance flown [n] metres).
    The batches of the last :data:`MAX_BATCHES` calls are kept: a trainer evaluating on the same seeds every few
    iterations (on one family or several) builds the instances and worlds once."""
    observer = observer_of(policy)  # observed as the policy reads, else as ``like`` observes
    key = (family, tuple(int(s) for s in seeds), like, observer)  # the config itself (hashed by identity, kept alive)
    if key not in _BATCHES:
        while len(_BATCHES) >= MAX_BATCHES:
            del _BATCHES[next(iter(_BATCHES))]
        cfgs = [instance_for_policy(family, seed, like) for seed in key[1]]
        _BATCHES[key] = MixtureVectorEnv(cfgs, num_envs=len(cfgs), observer=observer)
    venv = _BATCHES[key]
    count = venv.num_envs
    obs, _ = venv.reset(seed=0)
    served, distance, finished = np.zeros(count), np.zeros(count), np.zeros(count, bool)
    while not finished.all():
        obs, _, terminated, truncated, info = venv.step(policy(obs))
        ended = (terminated | truncated) & ~finished
        if ended.any():
            served[ended] = info["episode"]["service_rate"][ended]
            distance[ended] = info["episode"]["distance_m"][ended].sum(-1)
            finished |= ended
    return served, distance


def validation_metrics(
    policy: Callable[[dict[str, np.ndarray]], np.ndarray], family: str, count: int, like: EnvConfig
) -> dict[str, float]:
    """Fly ``policy`` on the first ``count`` validation instances of ``family`` (:func:`fly_instances`).

    Returns ``pr_pct`` (mean share of passengers delivered, %), ``solved_pct`` (instances with everyone
    delivered, %), ``td_m`` (mean distance flown) and ``instances``. The trainer keeps its best checkpoint by
    these; choose on validation seeds only, the test seeds are for the report."""
    served, distance = fly_instances(policy, family, split_seeds("validation", count), like)
    return {
        "pr_pct": float(100 * served.mean()),
        "solved_pct": float(100 * (served >= 1.0).mean()),
        "td_m": float(distance.mean()),
        "instances": float(count),
    }


__all__ = [
    "BERLIN_FEASIBLE_SHARES",
    "BERLIN_HOTSPOTS",
    "BERLIN_SIDE_M",
    "BERLIN_STEP_M",
    "BERLIN_THRESHOLDS_DB",
    "FAMILIES",
    "FLEET_SETTINGS",
    "MAP_SUFFIXES",
    "MIN_FEASIBLE_SHARE",
    "MIN_INFEASIBLE_SHARE",
    "SPLITS",
    "TEST_SEEDS",
    "TRAIN_SEEDS",
    "VALIDATION_SEEDS",
    "Families",
    "InstanceFamily",
    "draw_trip",
    "family_of",
    "fleet_setting",
    "fly_instances",
    "instance_for_policy",
    "law_family",
    "make_fleet_instance",
    "make_instance",
    "map_family",
    "map_family_key",
    "map_family_name",
    "map_provenance",
    "map_step_m",
    "map_thresholds",
    "split_seeds",
    "validation_metrics",
]
