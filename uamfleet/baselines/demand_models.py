"""Demand models an online planner samples futures from: the family's true law, one estimated from past episodes,
and a deliberately wrong one.

A :class:`DemandModel` answers what :class:`~uamfleet.baselines.anticipation.DemandPrior` answers (and has its
``sample`` contract): given the requests released by step t, a future with the requests still to come added as
hidden rows (never a release <= t, never more than the cap, the released rows untouched, every trip at least
``min_trip_m`` long), or None when none comes. It also gives the log-likelihood of an episode's requests, so models
can be compared on held-out episodes (``uamfleet demand check``).

- :class:`FamilyLaw`: the law an instance family draws from (:class:`uamfleet.demand.DemandLaw`); for ``berlin``
  and ``detroit3gpp`` it samples exactly as ``DemandPrior`` does, draw for draw.
- :class:`EstimatedDemand`: fitted on the requests of past episodes (:meth:`EstimatedDemand.fit`): the count at
  step 0, a non-homogeneous Poisson intensity per bin of steps (the cap handled by at-risk counts), and kernel
  densities of origins and destinations with a leave-one-out bandwidth and a uniform floor. Stored as JSON.
- :func:`wrong_model`: a law declared wrong on purpose (the timing of the other kind, the hot spots elsewhere).
- :func:`demand_model`: one of them by name (``family``, a family's name, ``<path>.json``, ``wrong``).
"""

from __future__ import annotations

import dataclasses
import json
import math
import re
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from uamfleet.checks import ConfigError, check_integer, check_number
from uamfleet.config import EnvConfig
from uamfleet.demand import DemandLaw, Request, binned_intensity
from uamfleet.instances import FAMILIES, check_family, draw_trip, map_family_key
from uamfleet.io import write_text_atomic
from uamfleet.sim.generator import flyable_sites
from uamfleet.sim.world import World
from uamfleet.types import HIDDEN, FleetState

FORMAT = 1
"""Version of :meth:`EstimatedDemand.to_dict`'s layout."""


class NoDemandModelError(ValueError):
    """A policy that reads an instance family's demand model was reset in a world no family draws (a fixed
    scenario)."""


def world_family(cfg: EnvConfig, policy: str) -> str:
    """The instance family whose demand model draws ``cfg``'s requests, read from its scenario: a family's instances
    (``berlin_seed3``, ``berlin_fleet4x48_seed3``, :func:`uamfleet.instances.make_instance`) and its training
    scenarios (``berlin_instances``, ``berlin_fleet``, ``berlin_random``), and a map's family
    (:func:`uamfleet.instances.map_family_key`: ``munich_seed3``, or a file's whose instances this process drew).
    :class:`NoDemandModelError`, naming ``policy``, for any other world (the paper's fixed scenarios have none)."""
    scenario = cfg.scenario
    for family, fam in FAMILIES.items():
        if scenario in (fam.scenario, f"{family}_instances", f"{family}_fleet"):
            return family
        if re.fullmatch(rf"{re.escape(family)}_(fleet\d+x\d+_)?seed\d+", scenario):
            return family
    named = re.fullmatch(r"(.+?)_(random|instances|fleet|(fleet\d+x\d+_)?seed\d+)", scenario)
    key = map_family_key(named.group(1)) if named else None
    if key is not None:  # a map's family (uamfleet.instances.map_family): munich_seed3, city_fleet2x12_seed3
        return key
    raise NoDemandModelError(
        f"{policy} reads an instance family's demand model, and scenario {scenario!r} is none of "
        f"{tuple(FAMILIES)}'s: fly it on an instance (uamfleet.instances.make_instance), not a fixed scenario."
    )


class DemandModel(Protocol):
    """What a planner may know of the demand: ``max_requests`` (the cap), ``window_steps`` (the last step a request
    may be released at), :meth:`sample` and :meth:`log_likelihood`."""

    max_requests: int
    window_steps: int

    def sample(self, known: FleetState, rng: np.random.Generator) -> FleetState | None:
        """A future of env 0 of ``known`` (released requests only, on a passenger axis of ``max_requests`` rows or
        more): a copy with the requests still to come added as hidden rows; None when none comes."""
        ...

    def to_dict(self) -> dict[str, Any]: ...

    def log_likelihood(self, requests: Sequence[Request], slot_s: float) -> float:
        """log P(an episode's requests) under the model, on the sites it is bound to."""
        ...


# --- shared pieces -----------------------------------------------------------------------------------------------


def _known_count(known: FleetState) -> tuple[int, np.ndarray]:
    return int(known.t[0]), known.pax_exists[0]


def _with_requests(
    known: FleetState, releases: Sequence[int], trips: Sequence[tuple[int, int]], sites: np.ndarray, cap: int
) -> FleetState:
    """A copy of ``known`` with one hidden request per (release, trip) in its first free passenger rows."""
    free = np.flatnonzero(~known.pax_exists[0])
    if len(free) < len(releases):
        raise ValueError(f"the state has {len(free)} free passenger rows for {len(releases)} sampled requests: lay it "
                         f"out with max_passengers >= {cap}.")  # fmt: skip
    future = known.copy()
    for row, release, (o, d) in zip(free, releases, trips, strict=False):
        future.pax_exists[0, row] = True
        future.pax_release[0, row] = int(release)
        future.pax_origin_m[0, row] = sites[o]
        future.pax_dest_m[0, row] = sites[d]
        future.pax_status[0, row] = HIDDEN
        future.pax_taxi[0, row] = -1
        future.pax_pickup_step[0, row] = -1
        future.pax_dropoff_step[0, row] = -1
    return future


def _far(sites: np.ndarray, min_trip_m: float) -> np.ndarray:
    return np.linalg.norm(sites[:, None] - sites[None], axis=-1) >= min_trip_m


def _site_index(sites: np.ndarray) -> dict[tuple[float, float], int]:
    return {(float(x), float(y)): i for i, (x, y) in enumerate(sites)}


def _release_counts(requests: Sequence[Request], steps: int) -> np.ndarray | None:
    """Requests per release step 0 … ``steps``; None when one is released later."""
    releases = np.array([r.release_step for r in requests], int)
    if len(releases) and releases.max() > steps:
        return None
    return np.bincount(releases, minlength=steps + 1).astype(float)


def _poisson_log_pmf(n: float, mean: float) -> float:
    if mean <= 0:
        return 0.0 if n == 0 else -math.inf
    return n * math.log(mean) - mean - math.lgamma(n + 1)


def _poisson_log_sf(n: float, mean: float) -> float:
    """log P(Poisson(mean) >= n)."""
    if n <= 0:
        return 0.0
    below = sum(math.exp(_poisson_log_pmf(k, mean)) for k in range(int(n)))
    return math.log(max(1.0 - below, 1e-300)) if below < 1 else -math.inf


def _stream_log_likelihood(counts: np.ndarray, initial_pmf: np.ndarray, intensity: np.ndarray, cap: int) -> float:
    """log P(counts per step) of ``initial_pmf``'s count at step 0, then a Poisson count of mean ``intensity[s]`` at
    each step s while fewer than ``cap`` are released (the step that reaches the cap: P(count >= what was left))."""
    n0 = int(counts[0])
    if n0 >= len(initial_pmf) or initial_pmf[n0] <= 0 or counts.sum() > cap:
        return -math.inf
    total, released = math.log(initial_pmf[n0]), n0
    for step in range(1, len(counts)):
        if released >= cap:
            break
        mean = float(intensity[step]) if step < len(intensity) else 0.0
        n, left = int(counts[step]), cap - released
        total += _poisson_log_sf(n, mean) if n == left else _poisson_log_pmf(n, mean)
        released += n
    return total


def _draw_stream(rng: np.random.Generator, intensity: np.ndarray, t: int, room: int) -> list[int]:
    """Release steps after ``t`` of a Poisson count per step of mean ``intensity[step]``, the first ``room`` kept."""
    steps = np.arange(t + 1, len(intensity))
    counts = rng.poisson(intensity[t + 1 :]) if len(steps) else np.zeros(0, int)
    return [int(s) for s in np.repeat(steps, counts)[:room]]


def _trip_log_likelihood(
    requests: Sequence[Request], sites: np.ndarray, origin: np.ndarray, dest: np.ndarray, far: np.ndarray
) -> float:
    """Σ log P(origin) + log P(destination | origin), the destination's law ``dest`` restricted to the sites far
    enough from the origin; -inf for a point that is no site of the world or a trip too short."""
    index = _site_index(sites)
    total = 0.0
    for r in requests:
        o = index.get((float(r.origin_m[0]), float(r.origin_m[1])))
        d = index.get((float(r.destination_m[0]), float(r.destination_m[1])))
        if o is None or d is None or not far[o, d]:
            return -math.inf
        reach = float(dest[far[o]].sum())
        if origin[o] <= 0 or dest[d] <= 0 or reach <= 0:
            return -math.inf
        total += math.log(origin[o]) + math.log(dest[d] / reach)
    return total


def _check_slot(slot_s: float, own: float, what: str) -> None:
    if not math.isclose(slot_s, own, rel_tol=1e-9):
        raise ConfigError(f"slot_s={slot_s:g} s: {what} counts steps of {own:g} s; score episodes of that world.")


# --- the true law ------------------------------------------------------------------------------------------------


@dataclass
class FamilyLaw:
    """A :class:`~uamfleet.demand.DemandLaw` on one world's ``sites`` [S, 2] with slots of ``slot_s`` seconds.

    Sampling given k requests released by step t: a stream draws the rest of its Poisson stream after t, the first
    cap − k kept (exact: a Poisson stream forgets its past); a window or peak law draws the count from its
    posterior (each of the N − ``initial`` later requests is released by t with P = F(t), the law's release CDF)
    and each missing release from the law's release pmf after t. Trips as the law draws them."""

    law: DemandLaw
    sites: np.ndarray
    slot_s: float
    name: str = "law"
    max_requests: int = field(init=False)
    window_steps: int = field(init=False)

    def __post_init__(self) -> None:
        self.sites = np.asarray(self.sites, dtype=float)
        self.max_requests = self.law.max_requests
        self.window_steps = self.law.window_steps(self.slot_s)
        self.origin_pmf, self.dest_pmf = self.law.site_pmf(self.sites)
        # a law without hot spots draws its trips as the families without a law do (instances.draw_trip), so that
        # the true law of berlin and detroit3gpp samples exactly as DemandPrior
        self._uniform_trips = not self.law.hotspots
        self._far: np.ndarray | None = None

    @classmethod
    def of_family(cls, family: str, cfg: EnvConfig) -> FamilyLaw:
        """The law of ``family``'s instances on ``cfg``'s map and threshold (its flyable sites); for a family
        without a law (``berlin``, ``detroit3gpp``) the one its drawing code follows, sampled as ``DemandPrior``."""
        check_family(family)
        return cls(FAMILIES[family].demand_law(), flyable_sites(World(cfg)), cfg.slot_s, name=family)

    def count_posterior(self, known: int, t: int) -> tuple[np.ndarray, np.ndarray]:
        """(counts, probabilities) of a window or peak law's count given ``known`` released by step ``t``:
        P(N | known) ∝ C(N − initial, known − initial) F(t)^(known − initial) (1 − F(t))^(N − known)."""
        law = self.law
        counts = np.arange(max(law.min_requests, known), law.max_requests + 1)
        if law.arrivals == "uniform_window":
            p = min(1.0, (t + 1) / (self.window_steps + 1))
        else:
            p = min(1.0, float(law.release_pmf(self.slot_s)[: t + 1].sum()))
        if p >= 1.0 or len(counts) <= 1:
            return counts[:1], np.ones(min(1, len(counts)))
        k = max(known - law.initial, 0)
        weight = np.array([math.comb(n - law.initial, k) * p**k * (1 - p) ** (n - known) for n in counts])
        return counts, weight / weight.sum()

    def sample(self, known: FleetState, rng: np.random.Generator) -> FleetState | None:
        t, exists = _known_count(known)
        k = int(exists.sum())
        if self.law.arrivals == "poisson_stream":
            if t >= self.window_steps or k >= self.max_requests:
                return None
            releases = _draw_stream(rng, self.law.step_intensity(self.slot_s), t, self.max_requests - k)
            if not releases:
                return None
            return _with_requests(known, releases, self._trips(rng, len(releases)), self.sites, self.max_requests)
        counts, probs = self.count_posterior(k, t)
        more = int(rng.choice(counts, p=probs)) - k
        if more <= 0 or t >= self.window_steps:
            return None
        pmf = self.law.release_pmf(self.slot_s)[t + 1 :]
        if self.law.arrivals == "peak" and not pmf.sum() > 0:
            return None
        trips, releases = [], []
        for _ in range(more):  # trip, then release, in turn: DemandPrior's order of draws
            trips.extend(self._trips(rng, 1))
            if self.law.arrivals == "uniform_window":
                releases.append(int(rng.integers(t + 1, self.window_steps + 1)))
            else:
                releases.append(t + 1 + int(rng.choice(len(pmf), p=pmf / pmf.sum())))
        return _with_requests(known, releases, trips, self.sites, self.max_requests)

    def _trips(self, rng: np.random.Generator, count: int) -> list[tuple[int, int]]:
        if not self._uniform_trips:
            return self.law.draw_trips(rng, self.sites, count)
        trips = []
        for _ in range(count):
            origin, dest = draw_trip(rng, self.sites, self.law.min_trip_m)
            trips.append((origin, dest if dest is not None else (origin + 1) % len(self.sites)))
        return trips

    def log_likelihood(self, requests: Sequence[Request], slot_s: float) -> float:
        _check_slot(slot_s, self.slot_s, f"{self.name}'s law")
        law = self.law
        counts = _release_counts(requests, self.window_steps)
        if counts is None:
            return -math.inf
        if law.arrivals == "poisson_stream":
            initial = np.zeros(law.initial + 1)
            initial[law.initial] = 1.0
            timing = _stream_log_likelihood(counts, initial, law.step_intensity(slot_s), law.max_requests)
        else:
            n, later = len(requests), counts.copy()
            later[0] -= law.initial
            if not law.min_requests <= n <= law.max_requests or later[0] < 0:
                return -math.inf
            pmf = law.release_pmf(slot_s)
            if np.any((later > 0) & (pmf <= 0)):
                return -math.inf
            seen = later > 0
            timing = (
                math.log(law.count_pmf()[n])
                + math.lgamma(n - law.initial + 1)
                - sum(math.lgamma(m + 1) for m in later)
                + float((later[seen] * np.log(pmf[seen])).sum())
            )
        if self._far is None:
            self._far = _far(self.sites, law.min_trip_m)
        # destinations: uniform over the sites far enough from the origin (a uniform dest law restricted)
        return timing + _trip_log_likelihood(requests, self.sites, self.origin_pmf, np.ones(len(self.sites)),
                                             self._far)  # fmt: skip

    def to_dict(self) -> dict[str, Any]:
        return {"kind": "law", "name": self.name, "slot_s": self.slot_s, "law": dataclasses.asdict(self.law)}


# --- the estimated model -----------------------------------------------------------------------------------------


def _kernel(a: np.ndarray, b: np.ndarray, bandwidth_m: float) -> np.ndarray:
    d2 = np.sum((a[:, None] - b[None]) ** 2, axis=-1)
    return np.exp(-0.5 * d2 / bandwidth_m**2)


def _loo_bandwidth(points: np.ndarray, counts: np.ndarray, bandwidths_m: Sequence[float], floor: float) -> float:
    """The bandwidth of largest leave-one-out log-likelihood of the observed sites: each observation scored by the
    pmf over the observed sites of a KDE of the others, mixed with a uniform ``floor``."""
    best, best_ll = float(bandwidths_m[0]), -math.inf
    for h in bandwidths_m:
        k = _kernel(points, points, float(h))
        mass = k @ counts  # kernel mass at each site of every observation
        colsum = k.sum(0)  # what one observation at a site adds to the total mass
        total = float(colsum @ counts)
        rest = np.maximum(total - colsum, 1e-300)
        loo = (1 - floor) * np.maximum(mass - np.diag(k), 0.0) / rest + floor / len(points)
        ll = float(counts @ np.log(np.maximum(loo, 1e-300)))
        if ll > best_ll:
            best, best_ll = float(h), ll
    return best


@dataclass
class EstimatedDemand:
    """A demand model fitted on past episodes' requests (:meth:`fit`); bound to a world's sites by
    :meth:`on_world` before it samples or scores.

    ``initial_pmf[n]``: P(n requests at step 0); ``intensity[s]``: expected arrivals at step s (0 at step 0 and
    past ``window_steps``), from bins of ``bin_steps``; ``cap``: the most requests of an episode; trips: origins
    and destinations from Gaussian KDEs of the observed ``points`` (``origin_counts`` / ``dest_counts``
    observations each) with bandwidths ``origin_bw_m`` / ``dest_bw_m``, a share ``floor`` uniform over the sites,
    destinations restricted to the sites at least ``min_trip_m`` from the origin."""

    initial_pmf: np.ndarray
    intensity: np.ndarray
    cap: int
    slot_s: float
    bin_steps: int
    min_trip_m: float
    points: np.ndarray
    origin_counts: np.ndarray
    dest_counts: np.ndarray
    origin_bw_m: float
    dest_bw_m: float
    floor: float
    episodes: int
    sites: np.ndarray | None = None
    max_requests: int = field(init=False)
    window_steps: int = field(init=False)

    def __post_init__(self) -> None:
        self.max_requests = self.cap
        self.window_steps = len(self.intensity) - 1
        if self.sites is not None:
            self.sites = np.asarray(self.sites, dtype=float)
            self.origin_pmf = self._site_pmf(self.origin_counts, self.origin_bw_m)
            self.dest_pmf = self._site_pmf(self.dest_counts, self.dest_bw_m)
            self._far = _far(self.sites, self.min_trip_m)
            self.origin_pmf = np.where(self._far.any(1), self.origin_pmf, 0.0)
            self.origin_pmf /= self.origin_pmf.sum()

    @classmethod
    def fit(
        cls,
        episodes: Sequence[Sequence[Request]],
        slot_s: float,
        bin_steps: int = 5,
        bandwidths_m: Sequence[float] = (100.0, 200.0, 400.0, 800.0),
        floor: float = 0.05,
    ) -> EstimatedDemand:
        """The model of the requests of ``episodes`` (each an instance's requests, slots of ``slot_s`` seconds).

        The intensity of bin b is its arrivals (after step 0) over its at-risk steps: the steps of each episode
        before it reached the cap (the most requests seen), so that the arrivals a capped episode lost do not lower
        it; a bin without arrivals counts half of one, so that a release there is unlikely, not impossible. The
        horizon (``window_steps``): one bin past the bin of the last observed release. Bandwidths: the largest
        leave-one-out log-likelihood among ``bandwidths_m``. ``min_trip_m``: the shortest observed trip, floored to
        100 m."""
        if not episodes or not all(len(e) for e in episodes):
            raise ConfigError(f"EstimatedDemand.fit needs episodes with requests; got {len(episodes)} episodes, "
                              f"{sum(not len(e) for e in episodes)} of them empty.")  # fmt: skip
        slot_s = check_number("slot_s", slot_s, positive=True)
        bin_steps = check_integer("bin_steps", bin_steps, 1)
        floor = check_number("floor", floor, minimum=0)
        if not 0 < floor <= 1 or not bandwidths_m:
            raise ConfigError(f"floor={floor!r}, bandwidths_m={tuple(bandwidths_m)!r}: use 0 < floor <= 1 (e.g. "
                              "0.05) and at least one bandwidth.")  # fmt: skip
        releases = [np.sort([r.release_step for r in e]) for e in episodes]
        cap = max(map(len, releases))
        initial_pmf = np.bincount([int((r == 0).sum()) for r in releases], minlength=cap + 1) / len(releases)
        intensity = binned_intensity(releases, cap, bin_steps)
        origins = np.array([r.origin_m for e in episodes for r in e], dtype=float)
        dests = np.array([r.destination_m for e in episodes for r in e], dtype=float)
        points, inverse = np.unique(np.vstack([origins, dests]), axis=0, return_inverse=True)
        inverse = inverse.reshape(-1)
        origin_counts = np.bincount(inverse[: len(origins)], minlength=len(points)).astype(float)
        dest_counts = np.bincount(inverse[len(origins) :], minlength=len(points)).astype(float)
        trips = np.linalg.norm(origins - dests, axis=-1)
        return cls(
            initial_pmf=initial_pmf,
            intensity=intensity,
            cap=cap,
            slot_s=slot_s,
            bin_steps=bin_steps,
            min_trip_m=max(100.0, math.floor(float(trips.min()) / 100.0) * 100.0),
            points=points,
            origin_counts=origin_counts,
            dest_counts=dest_counts,
            origin_bw_m=_loo_bandwidth(points, origin_counts, bandwidths_m, floor),
            dest_bw_m=_loo_bandwidth(points, dest_counts, bandwidths_m, floor),
            floor=floor,
            episodes=len(episodes),
        )

    def on_world(self, sites: np.ndarray) -> EstimatedDemand:
        """This model on a world's flyable ``sites`` [S, 2] (the KDEs evaluated there, the floor spread over them)."""
        return dataclasses.replace(self, sites=np.asarray(sites, dtype=float))

    def _site_pmf(self, counts: np.ndarray, bandwidth_m: float) -> np.ndarray:
        assert self.sites is not None
        mass = _kernel(self.sites, self.points, bandwidth_m) @ counts
        return (1 - self.floor) * mass / mass.sum() + self.floor / len(self.sites)

    def _bound(self) -> np.ndarray:
        if self.sites is None:
            raise ValueError("this EstimatedDemand is bound to no world: call .on_world(sites) (or demand_model) "
                             "before sample or log_likelihood.")  # fmt: skip
        return self.sites

    def sample(self, known: FleetState, rng: np.random.Generator) -> FleetState | None:
        sites = self._bound()
        t, exists = _known_count(known)
        k = int(exists.sum())
        if t >= self.window_steps or k >= self.cap:
            return None
        releases = _draw_stream(rng, self.intensity, t, self.cap - k)
        if not releases:
            return None
        trips = []
        for _ in releases:
            o = int(rng.choice(len(sites), p=self.origin_pmf))
            reach = np.where(self._far[o], self.dest_pmf, 0.0)
            trips.append((o, int(rng.choice(len(sites), p=reach / reach.sum()))))
        return _with_requests(known, releases, trips, sites, self.cap)

    def log_likelihood(self, requests: Sequence[Request], slot_s: float) -> float:
        sites = self._bound()
        _check_slot(slot_s, self.slot_s, "the estimated model")
        counts = _release_counts(requests, self.window_steps)
        if counts is None:
            return -math.inf
        timing = _stream_log_likelihood(counts, self.initial_pmf, self.intensity, self.cap)
        return timing + _trip_log_likelihood(requests, sites, self.origin_pmf, self.dest_pmf, self._far)

    def to_dict(self) -> dict[str, Any]:
        """Plain JSON values of every fitted parameter (not the world it is bound to)."""
        return {
            "kind": "estimated",
            "format": FORMAT,
            "initial_pmf": self.initial_pmf.tolist(),
            "intensity": self.intensity.tolist(),
            "cap": self.cap,
            "slot_s": self.slot_s,
            "bin_steps": self.bin_steps,
            "min_trip_m": self.min_trip_m,
            "points": self.points.tolist(),
            "origin_counts": self.origin_counts.tolist(),
            "dest_counts": self.dest_counts.tolist(),
            "origin_bw_m": self.origin_bw_m,
            "dest_bw_m": self.dest_bw_m,
            "floor": self.floor,
            "episodes": self.episodes,
        }

    @classmethod
    def from_dict(cls, data: dict[str, Any]) -> EstimatedDemand:
        if not isinstance(data, dict) or data.get("kind") != "estimated" or data.get("format") != FORMAT:
            raise ConfigError(f"not an estimated demand model of format {FORMAT} (kind 'estimated'); write it with "
                              "`uamfleet demand fit`.")  # fmt: skip
        arrays = {"initial_pmf", "intensity", "points", "origin_counts", "dest_counts"}
        values: dict[str, Any] = {k: (np.asarray(v, dtype=float) if k in arrays else v) for k, v in data.items()}
        values.pop("kind"), values.pop("format")
        values["points"] = values["points"].reshape(-1, 2)
        return cls(**values)

    def save(self, path: str | Path) -> Path:
        """Write :meth:`to_dict` as JSON, atomically."""
        return write_text_atomic(path, json.dumps(self.to_dict(), indent=1) + "\n")

    @classmethod
    def load(cls, path: str | Path) -> EstimatedDemand:
        """The model of a JSON file written by :meth:`save` (FileNotFoundError naming it when it is missing)."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(f"demand model {path} does not exist; write one with `uamfleet demand fit`.")
        try:
            data = json.loads(path.read_text(encoding="utf-8"))
        except (json.JSONDecodeError, UnicodeDecodeError) as err:
            raise ConfigError(
                f"demand model {path} is not JSON ({err}); write it with `uamfleet demand fit`."
            ) from None
        return cls.from_dict(data)


# --- the wrong model and the registry ----------------------------------------------------------------------------


def wrong_law(law: DemandLaw, sites: np.ndarray) -> DemandLaw:
    """``law`` made wrong on purpose, declared before any run. Timing: the other kind over the same window (a
    stream becomes a peak in the middle of its window with a deviation of an eighth of it and the count uniform
    over initial … cap, over a window a minute longer so that the stream's last steps stay possible; a window or
    peak law becomes a stream of the same mean count, capped as the law). Places: the hot spots mirrored through
    the centre of the map's ``sites`` (a law without any gets one at the sites' lower left corner, with a
    deviation of a sixth of the map's width)."""
    lo, hi = sites.min(0), sites.max(0)
    centre = (lo + hi) / 2
    if law.hotspots:
        spots = tuple((float(2 * centre[0] - x), float(2 * centre[1] - y), sd) for x, y, sd in law.hotspots)
    else:
        spots = ((float(lo[0]), float(lo[1]), float((hi - lo).max() / 6)),)
    if law.arrivals == "poisson_stream":
        timing: dict[str, Any] = {"arrivals": "peak", "min_requests": law.initial, "peak_s": law.window_s / 2,
                                  "peak_sd_s": law.window_s / 8, "rate_per_min": 0.0,
                                  "window_s": law.window_s + 60.0}  # fmt: skip
    else:
        extra = (law.min_requests + law.max_requests) / 2 - law.initial
        timing = {"arrivals": "poisson_stream", "min_requests": law.initial, "peak_s": 0.0, "peak_sd_s": 0.0,
                  "rate_per_min": max(extra, 0.5) / law.window_s * 60.0}  # fmt: skip
    return dataclasses.replace(law, hotspots=spots, hotspot_floor=0.1, **timing)


def wrong_model(family: str, cfg: EnvConfig) -> FamilyLaw:
    """:func:`wrong_law` of ``family``'s law on ``cfg``'s world."""
    true = FamilyLaw.of_family(family, cfg)
    return FamilyLaw(wrong_law(true.law, true.sites), true.sites, cfg.slot_s, name=f"wrong {family}")


SPECS = ("family", "<family name>", "<path>.json", "wrong")
"""The forms of :func:`demand_model`'s ``spec``."""


def demand_model(spec: str, cfg: EnvConfig) -> FamilyLaw | EstimatedDemand:
    """The demand model ``spec`` names, on ``cfg``'s world: ``family`` (the true law of the family that draws
    ``cfg``, :func:`world_family`), a family's name (its true law), ``<path>.json`` (an :class:`EstimatedDemand`
    file) or ``wrong`` (:func:`wrong_model` of ``cfg``'s family)."""
    if not isinstance(spec, str):
        raise ConfigError(f"demand model {spec!r} is no name; use one of {SPECS}.")
    if spec == "family":
        return FamilyLaw.of_family(world_family(cfg, "the demand model 'family'"), cfg)
    if spec == "wrong":
        return wrong_model(world_family(cfg, "the demand model 'wrong'"), cfg)
    if spec in FAMILIES:
        return FamilyLaw.of_family(spec, cfg)
    if spec.endswith(".json"):
        return EstimatedDemand.load(spec).on_world(flyable_sites(World(cfg)))
    raise ConfigError(f"demand model {spec!r} is unknown; use one of {SPECS} (families: {tuple(FAMILIES)}).")


__all__ = [
    "DemandModel",
    "EstimatedDemand",
    "FamilyLaw",
    "NoDemandModelError",
    "demand_model",
    "world_family",
    "wrong_law",
    "wrong_model",
]
