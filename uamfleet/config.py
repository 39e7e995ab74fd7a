"""Frozen configuration of a fleet environment and the paper's scenario presets.

Every keyword accepted by :func:`uamfleet.parallel_env` / :func:`uamfleet.vector_env` is a field of
:class:`EnvConfig` (or of its nested :class:`RewardConfig` / :class:`DemandConfig`, which can be passed as
objects). Checks that need only the config live in ``__post_init__``; checks that need the radio map
(stops in infeasible blocks, unreachable stops) live in :func:`uamfleet.env.generator.validate_instance`.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import InitVar, dataclass, field
from typing import Any, Literal

import numpy as np

from uamfleet.radio import RadioMap, load_radio_map
from uamfleet.types import NUM_HEADINGS  # defined there; imported here too by modules that build configs

FeasibilityRule = Literal["endpoint_block", "segment_raster"]
FEASIBILITY_RULES: tuple[str, ...] = ("endpoint_block", "segment_raster")


@dataclass(frozen=True)
class Request:
    """One ride request: visible (and pickable on the following steps) from ``release_step`` on."""

    release_step: int
    origin_m: tuple[float, float]
    destination_m: tuple[float, float]

    def __post_init__(self) -> None:
        if int(self.release_step) != self.release_step or self.release_step < 0:
            raise ValueError(f"Request release_step={self.release_step!r} must be an integer >= 0 (steps since reset).")
        for name in ("origin_m", "destination_m"):
            value = getattr(self, name)
            if len(value) != 2 or not all(math.isfinite(float(v)) for v in value):
                raise ValueError(f"Request {name}={value!r} must be a finite (x, y) pair in metres.")
            object.__setattr__(self, name, (float(value[0]), float(value[1])))
        object.__setattr__(self, "release_step", int(self.release_step))


REWARD_TERMS: tuple[str, ...] = ("step", "explore", "pickup", "dropoff", "blocked", "shaping")
"""Names of the reward terms: term ``name`` is weighted by ``RewardConfig.<name>``, is column
``REWARD_TERMS.index(name)`` of ``info["reward_terms"]`` and is logged as ``reward/<name>`` (docs/rules.md
"Rewards")."""


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the named reward terms (:data:`REWARD_TERMS`; defaults: the authors' code, docs/rules.md
    "Rewards"). Each term's weight is the field of the term's name.

    Per taxi and step: ``step`` every step; ``explore`` on entering a block it never visited, else
    ``explore_repeat`` * (visits - 1); ``pickup`` / ``dropoff`` per passenger; ``blocked`` per move that was not
    allowed (the taxi stays where it is). ``shaping`` > 0 adds the potential-based term
    ``shaping * (shaping_gamma * Phi(s') - Phi(s))`` with ``Phi = -(distance to the taxi's nearest actionable
    stop) / step_m`` (paper Eq. 9-10 style; Ng et al. 1999 keep the optimal policy unchanged), the distance
    measured along feasible paths (``shaping_metric="path"``) or in a straight line (``"euclidean"``).

    ``first_visit`` and ``repeat_visit`` are the earlier names of ``explore`` and ``explore_repeat``, still
    accepted as keywords.
    """

    step: float = -2.0
    explore: float = 1.0
    explore_repeat: float = -0.1
    pickup: float = 200.0
    dropoff: float = 300.0
    blocked: float = -50.0
    shaping: float = 0.0
    shaping_gamma: float = 0.99
    shaping_metric: str = "path"  # "path": distance along feasible paths; "euclidean": straight line
    first_visit: InitVar[float | None] = None  # earlier name of `explore`
    repeat_visit: InitVar[float | None] = None  # earlier name of `explore_repeat`

    def __post_init__(self, first_visit: float | None, repeat_visit: float | None) -> None:
        for old, new, value in (
            ("first_visit", "explore", first_visit),
            ("repeat_visit", "explore_repeat", repeat_visit),
        ):
            if value is not None:
                if getattr(self, new) != _REWARD_DEFAULTS[new] and getattr(self, new) != value:
                    raise ValueError(f"RewardConfig got both {new}= and its earlier name {old}=; pass {new} only.")
                object.__setattr__(self, new, float(value))
        if self.shaping_metric not in ("path", "euclidean"):
            raise ValueError(
                f"RewardConfig.shaping_metric={self.shaping_metric!r} is unknown; use 'path' or 'euclidean'."
            )
        for f in dataclasses.fields(self):
            if f.name != "shaping_metric" and not math.isfinite(getattr(self, f.name)):
                raise ValueError(f"RewardConfig.{f.name}={getattr(self, f.name)!r} must be finite.")
        if self.shaping < 0:
            raise ValueError(f"RewardConfig.shaping={self.shaping} must be >= 0 (0 turns shaping off).")


_REWARD_DEFAULTS = {f.name: f.default for f in dataclasses.fields(RewardConfig)}
assert set(REWARD_TERMS) <= set(_REWARD_DEFAULTS), "every reward term needs a RewardConfig weight of its name"


@dataclass(frozen=True)
class DemandConfig:
    """Random demand: Poisson arrivals of ride requests.

    ``num_initial`` requests are released at step 0; afterwards requests arrive with ``rate_per_step`` until
    ``horizon_steps`` (at most ``max_requests`` in all). Origins and destinations are drawn on feasible blocks
    (or from ``vertiports`` when given), at least ``min_trip_m`` apart.
    """

    num_initial: int = 3
    rate_per_step: float = 0.05
    horizon_steps: int = 60
    max_requests: int = 8
    min_trip_m: float = 500.0
    vertiports: tuple[tuple[float, float], ...] = ()

    def __post_init__(self) -> None:
        if self.max_requests < 1:
            raise ValueError(f"DemandConfig.max_requests={self.max_requests} must be >= 1.")
        if not 0 <= self.num_initial <= self.max_requests:
            raise ValueError(
                f"DemandConfig.num_initial={self.num_initial} must be in [0, max_requests={self.max_requests}]."
            )
        if self.rate_per_step < 0 or self.horizon_steps < 0:
            raise ValueError(
                f"DemandConfig rate_per_step={self.rate_per_step}, horizon_steps={self.horizon_steps} must be >= 0."
            )
        if len(self.vertiports) == 1:
            raise ValueError("DemandConfig.vertiports needs at least 2 sites (origin != destination), got 1.")


@dataclass(frozen=True, eq=False)
class EnvConfig:
    """Everything that defines a fleet environment. Use a preset (:func:`make_config`) and override fields.

    Geometry is in the map's world frame (metres, origin at the map's first data point, x east, y north); the
    taxis operate in the square ``[0, side_m]^2``.
    """

    radio: RadioMap
    sinr_min_db: float = -3.0
    num_taxis: int = 1
    seats: int = 2
    step_m: float = 100.0
    slot_s: float = 3.0
    altitude_m: float = 100.0
    pickup_radius_m: float | None = None  # None -> step_m (the paper's rule)
    block_m: float | None = None  # SINR block size; None -> step_m (the authors' code)
    nc_rule: str = "global_min"
    feasibility: FeasibilityRule = "endpoint_block"
    starts_m: tuple[tuple[float, float], ...] | None = None  # None -> random feasible starts
    requests: tuple[Request, ...] | None = None  # None -> random demand from `demand`
    demand: DemandConfig = field(default_factory=DemandConfig)
    max_passengers: int | None = None  # size of the passenger axis; None -> number of requests / max_requests
    time_limit_steps: int = 500
    history_len: int = 3
    patch_size: int = 10
    min_separation_m: float = 50.0
    max_block_visits: int | None = None  # truncate when a taxi visits one block more often (None: never)
    reward: RewardConfig = field(default_factory=RewardConfig)
    scenario: str = "custom"

    def __post_init__(self) -> None:  # noqa: C901 - a flat list of independent checks
        if not isinstance(self.radio, RadioMap):
            raise TypeError(f"radio={self.radio!r} must be a RadioMap; use uamfleet.load_radio_map(name_or_path).")
        if not math.isfinite(self.sinr_min_db):
            raise ValueError(f"sinr_min_db={self.sinr_min_db} must be a finite threshold in dB.")
        if int(self.num_taxis) != self.num_taxis or self.num_taxis < 1:
            raise ValueError(f"num_taxis={self.num_taxis!r} must be an integer >= 1.")
        if int(self.seats) != self.seats or self.seats < 1:
            raise ValueError(f"seats={self.seats!r} must be an integer >= 1 (the paper's taxis have 2).")
        for name in ("step_m", "slot_s", "altitude_m"):
            value = getattr(self, name)
            if not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name}={value!r} must be a positive number.")
        for name in ("pickup_radius_m", "block_m"):
            value = getattr(self, name)
            if value is not None and not (math.isfinite(value) and value > 0):
                raise ValueError(f"{name}={value!r} must be positive, or None for the default (step_m).")
        if self.nc_rule not in ("global_min", "nanmean"):
            raise ValueError(f"nc_rule={self.nc_rule!r} is unknown; use 'global_min' or 'nanmean'.")
        if self.feasibility not in FEASIBILITY_RULES:
            raise ValueError(f"feasibility={self.feasibility!r} is unknown; use one of {FEASIBILITY_RULES}.")
        if not 1 <= self.time_limit_steps < 2**24:
            raise ValueError(
                f"time_limit_steps={self.time_limit_steps} must be in [1, 2**24): step counts must be exact in float32 "
                "(the observation's visit ratios)."
            )
        if self.history_len < 1 or self.patch_size < 1:
            raise ValueError(f"history_len={self.history_len}, patch_size={self.patch_size} must both be >= 1.")
        if self.min_separation_m < 0:
            raise ValueError(f"min_separation_m={self.min_separation_m} must be >= 0.")
        if self.max_block_visits is not None and self.max_block_visits < 1:
            raise ValueError(f"max_block_visits={self.max_block_visits} must be >= 1 or None.")
        if self.starts_m is not None:
            starts = tuple((float(x), float(y)) for x, y in self.starts_m)
            if len(starts) != self.num_taxis:
                raise ValueError(
                    f"starts_m has {len(starts)} positions but num_taxis={self.num_taxis}; give one start per "
                    "taxi or starts_m=None for random feasible starts."
                )
            object.__setattr__(self, "starts_m", starts)
        if self.requests is not None:
            reqs = as_requests(self.requests)
            if not reqs:
                raise ValueError("requests=() is empty; give at least one Request or None for random demand.")
            object.__setattr__(self, "requests", reqs)
        if self.max_passengers is not None and self.max_passengers < self.num_requests_max:
            raise ValueError(
                f"max_passengers={self.max_passengers} is smaller than the {self.num_requests_max} requests "
                "this config can generate; raise it or leave it None."
            )

    # ---- derived values -------------------------------------------------------------------------------
    @property
    def side_m(self) -> float:
        assert self.radio.side_m is not None
        return float(self.radio.side_m)

    @property
    def radius_m(self) -> float:
        return float(self.pickup_radius_m if self.pickup_radius_m is not None else self.step_m)

    @property
    def block_size_m(self) -> float:
        return float(self.block_m if self.block_m is not None else self.step_m)

    @property
    def num_requests_max(self) -> int:
        return len(self.requests) if self.requests is not None else self.demand.max_requests

    @property
    def num_passengers(self) -> int:
        """Size of the passenger axis P of every array (rows beyond the requests are padding)."""
        return self.max_passengers if self.max_passengers is not None else self.num_requests_max

    def replace(self, **changes: Any) -> EnvConfig:
        return dataclasses.replace(self, **changes)


# ---- the paper's scenarios (as the authors coded them) ----------------------------------------------------


def _berlin_p4(**overrides: Any) -> EnvConfig:
    """Berlin P4 (paper §V, the authors' code): 3 requests at step 0, a 4th at step 5, 100 m steps of 3 s.

    Geometry and thresholds are the paper's; mechanics are corrected (docs/rules.md, "Differences from the
    paper's code"): a blocked move costs one step in place (never the original's bounce), requests are pickable
    only after they are observed, and timeouts are truncations, not terminations. The paper's figure shows P4
    at step 17; the authors' code uses step 5.
    """
    base: dict[str, Any] = dict(
        radio=load_radio_map("berlin"),
        sinr_min_db=-3.0,
        step_m=100.0,
        slot_s=3.0,
        starts_m=((2600.0, 1500.0),),
        requests=(
            Request(0, (2220.0, 1400.0), (1850.0, 1100.0)),
            Request(0, (1450.0, 2000.0), (1270.0, 450.0)),
            Request(0, (650.0, 1000.0), (1700.0, 620.0)),
            Request(5, (1010.0, 2220.0), (400.0, 1200.0)),
        ),
        time_limit_steps=500,
        scenario="berlin_p4",
    )
    return _with_overrides(base, overrides)


def _detroit_p5(**overrides: Any) -> EnvConfig:
    """Detroit P5 on the ESTIMATED Detroit block map: 5 requests, 320 m steps (≈ 9.7 s).

    The authors never published the Detroit radio map; the packaged one is digitised from their figure and is
    faithful only at γ_T = −17 dB (blocks below −17 dB are only known to be below it).
    """
    base: dict[str, Any] = dict(
        radio=load_radio_map("detroit_estimate"),
        sinr_min_db=-17.0,
        step_m=320.0,
        slot_s=320.0 / (120.0 / 3.6),
        starts_m=((6290.0, 9450.0),),
        requests=(
            Request(0, (6594.0, 7563.0), (9570.0, 7210.0)),
            Request(0, (7494.0, 5855.0), (1375.0, 6530.0)),
            Request(5, (3500.0, 5220.0), (5100.0, 2500.0)),
            Request(8, (2175.0, 6906.0), (2234.0, 3850.0)),
            Request(15, (3781.0, 3438.0), (7830.0, 2430.0)),
        ),
        time_limit_steps=500,
        scenario="detroit_p5",
    )
    return _with_overrides(base, overrides)


def _detroit3gpp_p5(**overrides: Any) -> EnvConfig:
    """Detroit P5's requests on the synthetic TR 36.777 Detroit-like map (thresholds −21 … −17 dB)."""
    overrides = {"radio": load_radio_map("detroit_3gpp"), "scenario": "detroit3gpp_p5", **overrides}
    return _detroit_p5(**overrides)


def _berlin_random(**overrides: Any) -> EnvConfig:
    """Random Poisson demand on the Berlin map; any fleet size (defaults: 4 taxis, 12 requests)."""
    base: dict[str, Any] = dict(
        radio=load_radio_map("berlin"),
        sinr_min_db=-3.0,
        num_taxis=4,
        step_m=100.0,
        slot_s=3.0,
        starts_m=None,
        requests=None,
        demand=DemandConfig(num_initial=4, rate_per_step=0.1, horizon_steps=80, max_requests=12),
        time_limit_steps=600,
        scenario="berlin_random",
    )
    return _with_overrides(base, overrides)


def _detroit3gpp_random(**overrides: Any) -> EnvConfig:
    """Random Poisson demand on the synthetic TR 36.777 Detroit-like map, 320 m steps."""
    base: dict[str, Any] = dict(
        radio=load_radio_map("detroit_3gpp"),
        sinr_min_db=-17.0,
        num_taxis=4,
        step_m=320.0,
        slot_s=320.0 / (120.0 / 3.6),
        starts_m=None,
        requests=None,
        demand=DemandConfig(num_initial=4, rate_per_step=0.1, horizon_steps=80, max_requests=12, min_trip_m=2000.0),
        time_limit_steps=600,
        scenario="detroit3gpp_random",
    )
    return _with_overrides(base, overrides)


def _with_overrides(base: dict[str, Any], overrides: dict[str, Any]) -> EnvConfig:
    known = {f.name for f in dataclasses.fields(EnvConfig)}
    unknown = sorted(set(overrides) - known)
    if unknown:
        raise TypeError(
            f"Unknown config keyword(s) {unknown}; valid keywords are the EnvConfig fields: {sorted(known)}."
        )
    merged = {**base, **overrides}
    if isinstance(merged.get("radio"), str):
        merged["radio"] = load_radio_map(merged["radio"])
    if merged.get("starts_m") is not None and "num_taxis" not in overrides:
        merged["num_taxis"] = len(merged["starts_m"])
    elif overrides.get("num_taxis") is not None and "starts_m" not in overrides and base.get("starts_m"):
        # A fleet on a fixed paper instance: all taxis share the paper's start unless starts are given.
        merged["starts_m"] = tuple(base["starts_m"][0] for _ in range(int(overrides["num_taxis"])))
    return EnvConfig(**merged)


PRESETS: dict[str, Callable[..., EnvConfig]] = {
    "berlin_p4": _berlin_p4,
    "detroit_p5": _detroit_p5,
    "detroit3gpp_p5": _detroit3gpp_p5,
    "berlin_random": _berlin_random,
    "detroit3gpp_random": _detroit3gpp_random,
}
SCENARIOS: tuple[str, ...] = tuple(PRESETS)


def make_config(scenario: str | EnvConfig = "berlin_p4", **overrides: Any) -> EnvConfig:
    """The config of a named scenario with keyword overrides (any :class:`EnvConfig` field).

    ``radio`` may be a :class:`RadioMap` or a name/path for :func:`uamfleet.load_radio_map`; ``requests`` a
    sequence of :class:`Request` or ``(release_step, origin, destination)`` tuples.
    """
    if isinstance(scenario, EnvConfig):
        return _with_overrides(_fields(scenario), overrides)
    if scenario not in PRESETS:
        raise ValueError(
            f"Unknown scenario {scenario!r}; choose one of {SCENARIOS} or pass an EnvConfig "
            "(e.g. make_config('berlin_random', radio=my_map))."
        )
    return PRESETS[scenario](**overrides)


def _fields(cfg: EnvConfig) -> dict[str, Any]:
    return {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg)}


def as_requests(items: Sequence[Any]) -> tuple[Request, ...]:
    """Requests from :class:`Request` objects or ``(release_step, (ox, oy), (dx, dy))`` tuples."""
    out = []
    for item in items:
        if isinstance(item, Request):
            out.append(item)
        elif len(item) == 3:
            out.append(Request(item[0], tuple(item[1]), tuple(item[2])))
        else:
            raise ValueError(f"Request {item!r} must be a Request or (release_step, origin_xy, destination_xy).")
    return tuple(out)


def heading_vectors() -> np.ndarray:
    """[NUM_HEADINGS, 2] unit vectors of the flight headings (k * 22.5° counter-clockwise from east)."""
    angles = 2.0 * np.pi * np.arange(NUM_HEADINGS) / NUM_HEADINGS
    return np.stack([np.cos(angles), np.sin(angles)], axis=-1)
