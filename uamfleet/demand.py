"""Who asks for a ride: :class:`Request` (one fixed request), :func:`as_requests`, :class:`DemandConfig` (the
random demand model of training) and :class:`DemandLaw` (the law an instance family draws its requests from).
Requests and ``DemandConfig`` are parts of :class:`uamfleet.config.EnvConfig`, which re-exports them.
"""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from uamfleet.checks import MAX_PASSENGERS, ConfigError, check_integer, check_number, check_point, check_sequence


@dataclass(frozen=True)
class Request:
    """One ride request: visible (and pickable on the following steps) from ``release_step`` on."""

    release_step: int
    origin_m: tuple[float, float]
    destination_m: tuple[float, float]

    def __post_init__(self) -> None:
        release = check_integer("Request release_step", self.release_step, 0, fix=" (steps since reset)")
        object.__setattr__(self, "release_step", release)
        for name in ("origin_m", "destination_m"):
            object.__setattr__(self, name, check_point(f"Request {name}", getattr(self, name)))
        if self.origin_m == self.destination_m:
            raise ConfigError(
                f"Request origin_m == destination_m == {self.origin_m}: a ride needs two different places; "
                "drop the request or move one end."
            )


def as_requests(items: Sequence[Any]) -> tuple[Request, ...]:
    """Requests from :class:`Request` objects or ``(release_step, (ox, oy), (dx, dy))`` tuples."""
    out = []
    for item in check_sequence("requests", items):
        if isinstance(item, Request):
            out.append(item)
        elif isinstance(item, (tuple, list)) and len(item) == 3:
            out.append(Request(item[0], item[1], item[2]))
        else:
            raise ConfigError(f"Request {item!r} must be a Request or (release_step, origin_xy, destination_xy).")
    return tuple(out)


ARRIVALS: tuple[str, ...] = ("poisson", "uniform")
"""Values of ``DemandConfig.arrivals``."""


@dataclass(frozen=True)
class DemandConfig:
    """Random demand: Poisson arrivals of ride requests.

    ``arrivals="poisson"``: ``num_initial`` requests are released at step 0; afterwards requests arrive with
    ``rate_per_step`` until ``horizon_steps`` (at most ``max_requests`` in all). ``arrivals="uniform"``: the
    number of requests is drawn uniformly from ``min_requests`` ... ``max_requests``; ``num_initial`` of them
    (at least one) are released at step 0 and the others at steps drawn uniformly from 0 ... ``horizon_steps``
    (the held-out instances of :mod:`uamfleet.instances` are drawn this way). Origins and destinations are drawn
    on feasible blocks (or from ``vertiports`` when given), at least ``min_trip_m`` apart.
    """

    num_initial: int = 3
    rate_per_step: float = 0.05
    horizon_steps: int = 60
    max_requests: int = 8
    min_trip_m: float = 500.0
    vertiports: tuple[tuple[float, float], ...] = ()
    arrivals: str = "poisson"
    min_requests: int = 1  # arrivals="uniform" only

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put("max_requests", check_integer("DemandConfig.max_requests", self.max_requests, 1, MAX_PASSENGERS))
        put("num_initial", check_integer("DemandConfig.num_initial", self.num_initial, 0, self.max_requests))
        put("rate_per_step", check_number("DemandConfig.rate_per_step", self.rate_per_step, minimum=0))
        put("horizon_steps", check_integer("DemandConfig.horizon_steps", self.horizon_steps, 0))
        put("min_trip_m", check_number("DemandConfig.min_trip_m", self.min_trip_m, minimum=0))
        if self.arrivals not in ARRIVALS:
            raise ConfigError(f"DemandConfig.arrivals={self.arrivals!r} is unknown; use one of {ARRIVALS}.")
        put("min_requests", check_integer("DemandConfig.min_requests", self.min_requests, 1, self.max_requests))
        ports = tuple(
            check_point(f"DemandConfig.vertiports[{i}]", p)
            for i, p in enumerate(check_sequence("DemandConfig.vertiports", self.vertiports))
        )
        if len(ports) == 1:
            raise ConfigError("DemandConfig.vertiports needs at least 2 sites (origin != destination), got 1.")
        if len(set(ports)) != len(ports):
            raise ConfigError(
                f"DemandConfig.vertiports={ports} lists a site twice: a ride between them would not move; "
                "give each site once."
            )
        put("vertiports", ports)


LAW_ARRIVALS: tuple[str, ...] = ("uniform_window", "poisson_stream", "peak")
"""Values of ``DemandLaw.arrivals``."""


@dataclass(frozen=True)
class DemandLaw:
    """The law an instance family draws its requests from (:mod:`uamfleet.instances`).

    Release steps, by ``arrivals``:

    - ``"uniform_window"``: the count N is uniform over ``min_requests`` … ``max_requests``; ``initial`` requests
      are released at step 0 and the N − ``initial`` others at steps uniform over 0 … ``window_s // slot_s``;
    - ``"peak"``: as ``uniform_window``, but each other request is released at a time drawn from a normal law of
      mean ``peak_s`` and deviation ``peak_sd_s`` truncated to [0, ``window_s``), at step ``floor(time / slot_s)``;
    - ``"poisson_stream"``: ``initial`` requests at step 0, then a Poisson stream of ``rate_per_min`` over the
      service (0, ``window_s``], a request arriving at time τ released at step ``ceil(τ / slot_s)``; the stream
      stops at the cap ``max_requests`` (later arrivals are lost). ``min_requests`` must equal ``initial``.

    Trips: the origin is drawn from :meth:`site_pmf`'s origin law (uniform over the sites without ``hotspots``;
    with them, a share ``hotspot_floor`` uniform and the rest ∝ the sum of the hot spots' Gaussian bumps
    ``(x_m, y_m, sd_m)``), over the sites with another site at least ``min_trip_m`` away; the destination is uniform
    over the sites at least ``min_trip_m`` from the origin."""

    arrivals: str
    min_requests: int
    max_requests: int
    initial: int = 1
    window_s: float = 120.0
    rate_per_min: float = 0.0
    peak_s: float = 0.0
    peak_sd_s: float = 0.0
    hotspots: tuple[tuple[float, float, float], ...] = ()
    hotspot_floor: float = 0.1
    min_trip_m: float = 500.0

    def __post_init__(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        if self.arrivals not in LAW_ARRIVALS:
            raise ConfigError(f"DemandLaw.arrivals={self.arrivals!r} is unknown; use one of {LAW_ARRIVALS}.")
        put("max_requests", check_integer("DemandLaw.max_requests", self.max_requests, 1, MAX_PASSENGERS))
        put("min_requests", check_integer("DemandLaw.min_requests", self.min_requests, 1, self.max_requests))
        put("initial", check_integer("DemandLaw.initial", self.initial, 1, self.min_requests,
                                     fix=" (requests at step 0, at most min_requests)"))  # fmt: skip
        if self.arrivals == "poisson_stream" and self.initial != self.min_requests:
            raise ConfigError(
                f"DemandLaw.min_requests={self.min_requests} with a poisson_stream of initial={self.initial}: a "
                "stream's fewest requests are its initial ones; set min_requests = initial."
            )
        put("window_s", check_number("DemandLaw.window_s", self.window_s, positive=True))
        put("rate_per_min", check_number("DemandLaw.rate_per_min", self.rate_per_min, minimum=0))
        put("peak_s", check_number("DemandLaw.peak_s", self.peak_s, minimum=0))
        put("peak_sd_s", check_number("DemandLaw.peak_sd_s", self.peak_sd_s, minimum=0))
        if self.arrivals == "peak" and not (self.peak_sd_s > 0 and self.peak_s <= self.window_s):
            raise ConfigError(
                f"DemandLaw peak_s={self.peak_s:g}, peak_sd_s={self.peak_sd_s:g}: a peak needs a positive deviation "
                f"and its mean inside the window [0, {self.window_s:g}] s."
            )
        spots = []
        for i, spot in enumerate(check_sequence("DemandLaw.hotspots", self.hotspots)):
            if not isinstance(spot, (tuple, list)) or len(spot) != 3:
                raise ConfigError(f"DemandLaw.hotspots[{i}]={spot!r} must be (x_m, y_m, sd_m).")
            x, y = check_point(f"DemandLaw.hotspots[{i}]", spot[:2])
            spots.append((x, y, check_number(f"DemandLaw.hotspots[{i}] sd_m", spot[2], positive=True)))
        put("hotspots", tuple(spots))
        floor = check_number("DemandLaw.hotspot_floor", self.hotspot_floor, minimum=0)
        if floor > 1:
            raise ConfigError(f"DemandLaw.hotspot_floor={floor!r} is a share of the origins; use a value in [0, 1].")
        put("hotspot_floor", floor)
        put("min_trip_m", check_number("DemandLaw.min_trip_m", self.min_trip_m, minimum=0))

    def window_steps(self, slot_s: float) -> int:
        """The last step a request may be released at, with slots of ``slot_s`` seconds."""
        if self.arrivals == "poisson_stream":  # an arrival at time τ is released at step ceil(τ / slot)
            return math.ceil(self.window_s / slot_s - 1e-9)
        if self.arrivals == "peak":  # a time τ < window_s is released at step floor(τ / slot)
            return math.ceil(self.window_s / slot_s - 1e-9) - 1
        return int(self.window_s // slot_s)

    def count_pmf(self) -> np.ndarray:
        """P(N = n) for n = 0 … ``max_requests`` (the stream's from its Poisson count, capped)."""
        pmf = np.zeros(self.max_requests + 1)
        if self.arrivals != "poisson_stream":
            pmf[self.min_requests :] = 1.0 / (self.max_requests - self.min_requests + 1)
            return pmf
        mean = self.rate_per_min * self.window_s / 60.0
        room = self.max_requests - self.initial
        more = np.array([math.exp(-mean + k * math.log(mean) - math.lgamma(k + 1)) if mean > 0 else float(k == 0)
                         for k in range(room)])  # fmt: skip
        pmf[self.initial : self.max_requests] = more
        pmf[self.max_requests] = max(0.0, 1.0 - more.sum())
        return pmf

    def step_intensity(self, slot_s: float) -> np.ndarray:
        """The stream's expected arrivals in each step 1 … :meth:`window_steps` (index 0 is step 0: 0)."""
        steps = self.window_steps(slot_s)
        ends = np.minimum(np.arange(steps + 1) * slot_s, self.window_s)
        out = np.zeros(steps + 1)
        out[1:] = self.rate_per_min / 60.0 * np.diff(ends)
        return out

    def release_pmf(self, slot_s: float) -> np.ndarray:
        """P(release step = s), s = 0 … :meth:`window_steps`, of each request after the ``initial`` ones of a
        ``uniform_window`` or ``peak`` law (the stream's are not independent: see :meth:`step_intensity`)."""
        steps = self.window_steps(slot_s)
        if self.arrivals == "uniform_window":
            return np.full(steps + 1, 1.0 / (steps + 1))
        if self.arrivals != "peak":
            raise ValueError(f"release_pmf is for uniform_window and peak laws; this law is a {self.arrivals}.")
        edges = np.minimum(np.arange(steps + 2) * slot_s, self.window_s)
        cdf = np.array([self._normal_cdf(x) for x in edges])
        return np.diff(cdf) / (cdf[-1] - cdf[0])

    def _normal_cdf(self, x: float) -> float:
        return 0.5 * (1.0 + math.erf((x - self.peak_s) / (self.peak_sd_s * math.sqrt(2.0))))

    def site_pmf(self, sites: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(origin pmf, destination pmf) over ``sites`` [S, 2], exactly as :meth:`draw` draws trips."""
        sites = np.asarray(sites, dtype=float)
        far = np.linalg.norm(sites[:, None] - sites[None], axis=-1) >= self.min_trip_m
        origin = np.ones(len(sites))
        if self.hotspots:
            bumps = sum(np.exp(-0.5 * np.sum((sites - (x, y)) ** 2, -1) / sd**2) for x, y, sd in self.hotspots)
            origin = self.hotspot_floor / len(sites) + (1.0 - self.hotspot_floor) * bumps / bumps.sum()
        origin = np.where(far.any(1), origin, 0.0)
        if not origin.sum() > 0:
            raise ConfigError(f"no two sites are {self.min_trip_m:g} m apart: lower DemandLaw.min_trip_m.")
        origin = origin / origin.sum()
        rows = far / np.maximum(far.sum(1, keepdims=True), 1)
        return origin, origin @ rows

    def draw_releases(self, rng: np.random.Generator, slot_s: float) -> np.ndarray:
        """The sorted release steps of one instance's requests."""
        steps = self.window_steps(slot_s)
        if self.arrivals == "poisson_stream":
            arrivals = rng.poisson(self.rate_per_min * self.window_s / 60.0)
            times = np.sort(rng.uniform(0.0, self.window_s, size=arrivals))[: self.max_requests - self.initial]
            later = np.clip(np.ceil(times / slot_s), 1, steps).astype(int)
        else:
            num = int(rng.integers(self.min_requests, self.max_requests + 1)) - self.initial
            if self.arrivals == "uniform_window":
                later = rng.integers(0, steps + 1, size=num)
            else:
                times = self._truncated_normal(rng, num)
                later = np.minimum(np.floor(times / slot_s), steps).astype(int)
        return np.sort(np.concatenate([np.zeros(self.initial, int), later])).astype(int)

    def _truncated_normal(self, rng: np.random.Generator, num: int) -> np.ndarray:
        out = np.empty(0)
        while len(out) < num:  # rejection: the window holds most of the mass of any sensible peak
            times = rng.normal(self.peak_s, self.peak_sd_s, size=2 * (num - len(out)) + 4)
            out = np.concatenate([out, times[(times >= 0) & (times < self.window_s)]])
        return out[:num]

    def draw_trips(self, rng: np.random.Generator, sites: np.ndarray, count: int) -> list[tuple[int, int]]:
        """``count`` (origin, destination) site indices drawn from :meth:`site_pmf`'s laws."""
        sites = np.asarray(sites, dtype=float)
        origin_pmf = _origin_pmf(self, sites.tobytes(), sites.shape)
        trips = []
        for _ in range(count):
            o = int(rng.choice(len(sites), p=origin_pmf))
            far = np.flatnonzero(np.linalg.norm(sites - sites[o], axis=-1) >= self.min_trip_m)
            trips.append((o, int(far[rng.integers(len(far))])))
        return trips

    def draw(self, rng: np.random.Generator, sites: np.ndarray, slot_s: float) -> list[Request]:
        """One instance's requests on ``sites`` [S, 2] (release steps, then trips), sorted by release."""
        release = self.draw_releases(rng, slot_s)
        trips = self.draw_trips(rng, sites, len(release))
        return [Request(int(s), tuple(sites[o]), tuple(sites[d])) for s, (o, d) in zip(release, trips, strict=True)]


@functools.lru_cache(maxsize=16)
def _origin_pmf(law: DemandLaw, sites: bytes, shape: tuple[int, ...]) -> np.ndarray:
    """``law``'s origin pmf over the sites (as bytes), kept: an instance family draws on a few site sets only."""
    return law.site_pmf(np.frombuffer(sites).reshape(shape))[0]


def binned_intensity(releases: Sequence[np.ndarray], cap: int, bin_steps: int) -> np.ndarray:
    """[horizon + 1] arrivals per step after step 0, per bin of ``bin_steps``: a bin's arrivals over its at-risk
    steps (those of each episode before it reached ``cap``); half an arrival in a bin without any; the horizon one
    bin past the bin of the last release (:meth:`uamfleet.baselines.demand_models.EstimatedDemand.fit`)."""
    last = max(int(r.max()) for r in releases)
    horizon = (-(-last // bin_steps) + 1) * bin_steps
    intensity = np.zeros(horizon + 1)
    arrivals, at_risk = np.zeros(horizon + 1), np.zeros(horizon + 1)
    steps = np.arange(horizon + 1)
    for r in releases:
        np.add.at(arrivals, r[r > 0], 1)
        before = np.searchsorted(r, steps, side="left")  # released before each step
        at_risk += before < cap
    for b in range(horizon // bin_steps):
        span = slice(1 + b * bin_steps, 1 + (b + 1) * bin_steps)
        if at_risk[span].sum() > 0:  # half an arrival in a bin without any: unlikely there, not impossible
            intensity[span] = max(arrivals[span].sum(), 0.5) / at_risk[span].sum()
    return intensity
