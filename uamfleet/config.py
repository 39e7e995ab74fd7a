"""Frozen configuration of a fleet environment: the world and its rules (:class:`WorldConfig`), its
:class:`RewardConfig` and their constants, and :class:`EnvConfig`, a world together with what a policy reads of it.

Every keyword accepted by :func:`uamfleet.parallel_env` / :func:`uamfleet.vector_env` is a field of
:class:`EnvConfig` (or of its nested :class:`RewardConfig` / :class:`DemandConfig`, which can be passed as
objects). Checks that need only the config live in ``__post_init__``; checks that need the radio map
(stops in infeasible blocks, unreachable stops) live in :func:`uamfleet.sim.generator.validate_instance`. The
paper's scenario presets and :func:`~uamfleet.presets.make_config` live in :mod:`uamfleet.presets`.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import InitVar, dataclass, field
from typing import Any, Literal, Self

import numpy as np

from uamfleet.checks import (
    MAX_HISTORY_LEN,
    MAX_PASSENGERS,
    MAX_PATCH_SIZE,
    MAX_TAXIS,
    MAX_TIME_LIMIT_STEPS,
    ConfigError,
    check_flag,
    check_integer,
    check_number,
    check_point,
    check_sequence,
)
from uamfleet.demand import DemandConfig, Request, as_requests
from uamfleet.radio import RadioMap
from uamfleet.types import NUM_HEADINGS  # defined there; imported here too by modules that build configs

FeasibilityRule = Literal["endpoint_block", "segment_raster"]
FEASIBILITY_RULES: tuple[str, ...] = ("endpoint_block", "segment_raster")
SEPARATION_MODES: tuple[str, ...] = ("none", "shield")
"""Values of ``EnvConfig.separation`` (docs/rules.md "Separation shield"): ``"none"`` records losses of separation
only; ``"shield"`` resolves every conflict before the moves are flown."""

TAXI_SPEED_MPS = 120.0 / 3.6
"""Cruise speed of every preset (120 km/h): a step of ``step_m`` takes ``step_m / TAXI_SPEED_MPS`` seconds."""
DETROIT_STEP_M = 320.0
"""The Detroit maps' step (the authors' P5 scenario); its slot is :data:`DETROIT_SLOT_S` (≈ 9.6 s)."""
DETROIT_SLOT_S = DETROIT_STEP_M / TAXI_SPEED_MPS

# The fleet demand, one source for the *_fleet presets and uamfleet.instances.make_fleet_instance.
FLEET_REQUESTS_PER_TAXI = 6
FLEET_ARRIVAL_WINDOW_S = 600.0
"""Requests are released over the first 10 minutes."""
FLEET_TIME_LIMIT_WINDOWS = 3
"""A fleet episode's time limit is at least this many arrival windows."""


def fleet_window_steps(slot_s: float, window_s: float = FLEET_ARRIVAL_WINDOW_S) -> int:
    """Steps of the arrival window (releases at steps 0 ... this - 1), at least one."""
    return max(int(window_s // slot_s), 1)


def fleet_time_limit(time_limit_steps: int, window_steps: int) -> int:
    """A fleet episode's time limit: the preset's, or :data:`FLEET_TIME_LIMIT_WINDOWS` arrival windows if longer."""
    return max(time_limit_steps, FLEET_TIME_LIMIT_WINDOWS * window_steps)


SHAPING_METRICS: tuple[str, ...] = ("path", "path_exact", "euclidean")
"""Values of ``RewardConfig.shaping_metric`` (docs/rules.md "Rewards")."""

REWARD_TERMS: tuple[str, ...] = (
    "step", "explore", "pickup", "dropoff", "blocked", "shaping", "separation", "shield", "hover",
)  # fmt: skip
"""Names of the reward terms: term ``name`` is weighted by ``RewardConfig.<name>``, is column
``REWARD_TERMS.index(name)`` of ``info["reward_terms"]`` and is logged as ``reward/<name>`` (docs/rules.md
"Rewards")."""


@dataclass(frozen=True)
class RewardConfig:
    """Weights of the named reward terms (:data:`REWARD_TERMS`; defaults: the authors' code, docs/rules.md
    "Rewards"). Each term's weight is the field of the term's name.

    Per taxi and step: ``step`` every step; ``explore`` on entering a block it never visited, else
    ``explore_repeat`` * (visits - 1); ``pickup`` / ``dropoff`` per passenger; ``blocked`` per move that was not
    allowed (the taxi stays where it is); ``separation`` per step that another taxi is closer than
    ``EnvConfig.min_separation_m`` after the move (0 in the authors' reward: they fly one taxi); ``shield`` per move
    the separation shield replaced (``EnvConfig.separation="shield"`` only) and ``hover`` per step the taxi hovered
    (the hover action of ``EnvConfig.hover_action``, or the shield held it; an energy price of hover, docs/rules.md
    "Motion"); both 0 by default. ``shaping`` > 0
    adds the potential-based term ``shaping * (shaping_gamma * Phi(s') - Phi(s))`` with
    ``Phi = -(distance to the taxi's nearest actionable stop) / step_m`` (paper Eq. 9-10 style; Ng et al. 1999
    keep the optimal policy unchanged), the distance measured along feasible paths (``shaping_metric="path"``:
    looked up in a table of distances between block centres, fast; ``"path_exact"``: a 10 m Dijkstra field per
    stop, slow on random demand) or in a straight line (``"euclidean"``).

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
    separation: float = 0.0
    shield: float = 0.0
    hover: float = 0.0
    shaping_gamma: float = 0.99
    shaping_metric: str = "path"  # along feasible paths: "path" (table), "path_exact"; "euclidean": straight line
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
        if self.shaping_metric not in SHAPING_METRICS:
            raise ConfigError(
                f"RewardConfig.shaping_metric={self.shaping_metric!r} is unknown; use one of {SHAPING_METRICS}."
            )
        for f in dataclasses.fields(self):
            if f.name != "shaping_metric":
                object.__setattr__(self, f.name, check_number(f"RewardConfig.{f.name}", getattr(self, f.name)))
        if self.shaping < 0:
            raise ConfigError(f"RewardConfig.shaping={self.shaping} must be >= 0 (0 turns shaping off).")


_REWARD_DEFAULTS = {f.name: f.default for f in dataclasses.fields(RewardConfig)}
assert set(REWARD_TERMS) <= set(_REWARD_DEFAULTS), "every reward term needs a RewardConfig weight of its name"


@dataclass(frozen=True, eq=False)
class WorldConfig:
    """The world and its rules: the map, the threshold, the fleet, the demand, the starts, feasibility, separation,
    hover, seats, the step and the reward. What a policy reads of it is not here: that is an observer's spec
    (:class:`uamfleet.observe.spec.ObserverSpec`).

    Geometry is in the map's world frame (metres, origin at the map's first data point, x east, y north); the
    taxis operate in the square ``[0, side_m]^2``.

    Every field is checked on construction and a bad one raises :class:`ConfigError` (a ``ValueError``) naming
    the field, the value and the fix; nothing is rounded, clamped or parsed from a string. Counts are integers
    (``500.0`` is accepted as 500, ``1.5`` is not); distances and thresholds are finite numbers. Sizes that set
    the memory of every state have upper bounds: ``num_taxis`` <= :data:`MAX_TAXIS` (1024), ``max_passengers`` and
    ``DemandConfig.max_requests`` <= :data:`MAX_PASSENGERS` (1024). SINR blocks (``block_m``, default ``step_m``)
    must not be finer than the radio raster. A fixed request must be released before ``time_limit_steps``. Checks
    that need the radio map at the threshold (stops in bad blocks, stops out of reach) raise
    :class:`uamfleet.sim.generator.InfeasibleInstanceError` when the env is built.
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
    min_separation_m: float = 50.0
    separation: str = "none"  # "shield": conflicts resolved before moves (SEPARATION_MODES; the *_fleet presets)
    hover_action: bool = False  # action 16 (HOVER_ACTION) stays in place, always allowed (the *_fleet presets)
    max_block_visits: int | None = None  # truncate when a taxi visits one block more often (None: never)
    reward: RewardConfig = field(default_factory=RewardConfig)
    scenario: str = "custom"

    def __post_init__(self) -> None:
        if not isinstance(self.radio, RadioMap):
            raise TypeError(f"radio={self.radio!r} must be a RadioMap; use uamfleet.load_radio_map(name_or_path).")
        for name, cls in (("demand", DemandConfig), ("reward", RewardConfig)):
            if not isinstance(getattr(self, name), cls):
                raise ConfigError(f"{name}={getattr(self, name)!r} must be a {cls.__name__}, e.g. {cls.__name__}().")
        self._check_numbers()
        self._check_choices()
        if self.starts_m is not None:
            starts = tuple(
                check_point(f"starts_m[{a}]", p) for a, p in enumerate(check_sequence("starts_m", self.starts_m))
            )
            if len(starts) != self.num_taxis:
                raise ConfigError(
                    f"starts_m has {len(starts)} positions but num_taxis={self.num_taxis}; give one start per "
                    "taxi or starts_m=None for random feasible starts."
                )
            object.__setattr__(self, "starts_m", starts)
        if self.requests is not None:
            self._check_requests()
        if self.max_passengers is not None and self.max_passengers < self.num_requests_max:
            raise ConfigError(
                f"max_passengers={self.max_passengers} is smaller than the {self.num_requests_max} requests "
                "this config can generate; raise it or leave it None."
            )
        self._check_separation_room()

    def _check_numbers(self) -> None:
        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put("sinr_min_db", check_number("sinr_min_db", self.sinr_min_db))
        put("num_taxis", check_integer("num_taxis", self.num_taxis, 1, MAX_TAXIS))
        put("seats", check_integer("seats", self.seats, 1, fix=" (the paper's taxis have 2)"))
        for name in ("step_m", "slot_s", "altitude_m"):
            put(name, check_number(name, getattr(self, name), positive=True))
        for name in ("pickup_radius_m", "block_m"):
            if getattr(self, name) is not None:
                put(name, check_number(f"{name} (None: step_m)", getattr(self, name), positive=True))
        fix = " (step counts must stay exact in float32 for the observation's visit ratios)"
        limit = check_integer("time_limit_steps", self.time_limit_steps, 1, MAX_TIME_LIMIT_STEPS, fix=fix)
        put("time_limit_steps", limit)
        put("min_separation_m", check_number("min_separation_m", self.min_separation_m, minimum=0))
        if self.max_block_visits is not None:
            put("max_block_visits", check_integer("max_block_visits (or None: never)", self.max_block_visits, 1))
        if self.max_passengers is not None:
            put("max_passengers", check_integer("max_passengers (or None)", self.max_passengers, 1, MAX_PASSENGERS))
        if self.block_size_m > self.side_m:
            raise ConfigError(
                f"SINR blocks of {self.block_size_m:g} m (block_m, default step_m) are larger than the whole "
                f"{self.side_m:g} m map; use block_m <= {self.side_m:g}."
            )
        if self.block_size_m < self.radio.resolution_m:
            raise ConfigError(
                f"SINR blocks of {self.block_size_m:g} m (block_m, default step_m) are finer than the radio map's "
                f"{self.radio.resolution_m:g} m raster, so some would hold no SINR value; use block_m >= "
                f"{self.radio.resolution_m:g}."
            )

    def _check_choices(self) -> None:
        if self.nc_rule not in ("global_min", "nanmean"):
            raise ConfigError(f"nc_rule={self.nc_rule!r} is unknown; use 'global_min' or 'nanmean'.")
        if self.feasibility not in FEASIBILITY_RULES:
            raise ConfigError(f"feasibility={self.feasibility!r} is unknown; use one of {FEASIBILITY_RULES}.")
        object.__setattr__(self, "hover_action", check_flag("hover_action", self.hover_action))
        if not isinstance(self.scenario, str):
            raise ConfigError(f"scenario={self.scenario!r} must be a string (a label for logs and figures).")
        if self.separation not in SEPARATION_MODES:
            raise ConfigError(
                f"separation={self.separation!r} is unknown; use 'shield' (moves deconflicted before they are "
                "flown) or 'none' (losses of separation only recorded)."
            )

    def _check_separation_room(self) -> None:
        """Under the shield the taxis must fit ``min_separation_m`` apart on the map at all, or it could never
        separate them: at most :func:`separation_room_bound` of the square map. A necessary condition only; the
        flyable blocks are checked when the env is built (:func:`uamfleet.sim.generator.check_separation_room`)."""
        sep, taxis = self.min_separation_m, self.num_taxis
        if self.separation != "shield" or taxis < 2 or sep <= 0:
            return
        room = separation_room_bound(self.side_m, self.side_m, sep)
        if taxis > room:
            raise ConfigError(
                f"min_separation_m={sep:g} leaves room for at most {room} taxi(s) that far apart on the "
                f"{self.side_m:g} m square map, but num_taxis={taxis} fly under separation='shield', which could "
                f"never separate them; lower min_separation_m (two taxis fit up to the map's diagonal, "
                f"{self.side_m * math.sqrt(2.0):.0f} m), fly fewer taxis, or use separation='none'."
            )

    def _check_requests(self) -> None:
        reqs = as_requests(check_sequence("requests", self.requests))
        if not reqs:
            raise ConfigError("requests=() is empty; give at least one Request or None for random demand.")
        for i, req in enumerate(reqs):
            if req.release_step >= self.time_limit_steps:
                raise ConfigError(
                    f"request {i} (P{i + 1}) has release_step={req.release_step}, not before "
                    f"time_limit_steps={self.time_limit_steps}: it could never be seen or served; raise "
                    "time_limit_steps or release it earlier."
                )
        object.__setattr__(self, "requests", reqs)

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
    def num_actions(self) -> int:
        """Size of the action space: the 16 headings, and the hover (action 16) with ``hover_action``."""
        return NUM_HEADINGS + 1 if self.hover_action else NUM_HEADINGS

    @property
    def num_requests_max(self) -> int:
        return len(self.requests) if self.requests is not None else self.demand.max_requests

    @property
    def num_passengers(self) -> int:
        """Size of the passenger axis P of the state's arrays (rows beyond the requests are padding)."""
        return self.max_passengers if self.max_passengers is not None else self.num_requests_max

    def replace(self, **changes: Any) -> Self:
        return dataclasses.replace(self, **changes)


# The observer's rules, one wording for the legacy EnvConfig and uamfleet.observe.spec.ObserverSpec.
NEEDS_STOP_FEATURES: dict[str, str] = {
    "stop_rivals": "stop_rivals=True needs stop_features=True (the rivals use the same path distances).",
    "stop_claims": "stop_claims=True needs stop_features=True (the claims use the same path distances).",
    "heading_lookahead": (
        "heading_lookahead=True needs stop_features=True (the look-ahead reads the stop features' tours)."
    ),
}
"""The refusal of each stop option given without the stop features."""
PATCH_SIZE_FIX = " (blocks per side of the SINR and visit patches)"


def lookahead_depth_message(depth: Any) -> str:
    """The refusal of a look-ahead depth other than 1 or 2."""
    return (
        f"lookahead_depth={depth!r} must be 1 (each heading's move and the tour after it) or 2 "
        "(its move, the best second move and the tour after both)."
    )


def passenger_window_fix(seats: int) -> str:
    """The fix named when a passenger window is below the world's seats."""
    return f" (or None: every request); at least seats={seats}, so a taxi always observes its riders"


@dataclass(frozen=True, eq=False)
class EnvConfig(WorldConfig):
    """A world (:class:`WorldConfig`) and what a policy reads of it, in one constructor: every keyword accepted by
    :func:`uamfleet.parallel_env` / :func:`uamfleet.vector_env`. Use a preset (:func:`uamfleet.presets.make_config`)
    and override fields. :func:`uamfleet.observe.legacy.split_env_config` splits it into the world and its observer
    spec (:class:`uamfleet.observe.spec.ObserverSpec`).

    The observer's fields are checked like the world's: ``patch_size`` <= :data:`MAX_PATCH_SIZE` (64),
    ``history_len`` <= :data:`MAX_HISTORY_LEN` (256), ``passenger_window`` at least ``seats``; the stop options
    need ``stop_features``.
    """

    passenger_window: int | None = None  # each taxi observes at most this many passenger rows (rules.md); None: all
    history_len: int = 3
    patch_size: int = 10
    stop_features: bool = False  # observe "stop_paths" and "stop_heading_mask" (feasible-path features per stop)
    stop_rivals: bool = False  # with stop_features: observe "stop_rivals" (what the other taxis offer per stop)
    stop_claims: bool = False  # with stop_features: "stop_rivals", "stop_claims" and "hover_heading_mask" (rules.md)
    heading_lookahead: bool = False  # with stop_features: "heading_lookahead", each heading's move + tour after it
    lookahead_depth: int = 1  # 2: each heading's move + the best second move + the tour after both (read only
    # with heading_lookahead, so a copy that turns the look-ahead off keeps a valid config)

    def _check_numbers(self) -> None:
        super()._check_numbers()

        def put(name: str, value: Any) -> None:
            object.__setattr__(self, name, value)

        put("history_len", check_integer("history_len", self.history_len, 1, MAX_HISTORY_LEN))
        put("patch_size", check_integer("patch_size", self.patch_size, 1, MAX_PATCH_SIZE, fix=PATCH_SIZE_FIX))
        if self.passenger_window is not None:
            put("passenger_window", check_integer("passenger_window", self.passenger_window, self.seats,
                                                  MAX_PASSENGERS, fix=passenger_window_fix(self.seats)))  # fmt: skip

    def _check_choices(self) -> None:
        super()._check_choices()
        for name in ("stop_features", "stop_rivals", "stop_claims", "heading_lookahead"):
            object.__setattr__(self, name, check_flag(name, getattr(self, name)))
        for name, message in NEEDS_STOP_FEATURES.items():
            if getattr(self, name) and not self.stop_features:
                raise ConfigError(message)
        if self.lookahead_depth not in (1, 2):
            raise ConfigError(lookahead_depth_message(self.lookahead_depth))

    @property
    def world(self) -> WorldConfig:
        """The world of this config: every field but the observer's."""
        return WorldConfig(**{f.name: getattr(self, f.name) for f in dataclasses.fields(WorldConfig)})

    @property
    def observed_passengers(self) -> int:
        """Passenger rows of each taxi's observation: ``passenger_window`` when set, else :attr:`num_passengers`."""
        return self.passenger_window if self.passenger_window is not None else self.num_passengers


def separation_room_bound(width_m: float, height_m: float, min_separation_m: float, area_m2: float | None = None,
                          perimeter_m: float | None = None) -> int:  # fmt: skip
    """At most how many points of a ``width_m`` x ``height_m`` rectangle (or of a convex set of that bounding box,
    ``area_m2`` and ``perimeter_m``) can lie pairwise ``min_separation_m`` apart: the fewest of one per square of
    side ``min_separation_m / sqrt(2)`` (two points in one half-open square are closer than its diagonal; the
    squares of a grid laid from a corner), Oler's bound ``2 / sqrt(3) * A / s^2 + P / (2 s) + 1`` for a convex set
    of area A and perimeter P, and 1 when the diagonal is shorter than the separation. Never below the true
    number (a refusal on it is certain), often above it."""
    area = width_m * height_m if area_m2 is None else area_m2
    perimeter = 2.0 * (width_m + height_m) if perimeter_m is None else perimeter_m
    s = min_separation_m
    if math.hypot(width_m, height_m) < s:
        return 1
    cell = s / math.sqrt(2.0)
    slack = 1.0 + 1e-9  # rounding never lowers a bound
    grid = (math.floor(width_m / cell * slack) + 1) * (math.floor(height_m / cell * slack) + 1)
    oler = math.floor((2.0 / math.sqrt(3.0) * area / (s * s) + perimeter / (2.0 * s) + 1.0) * slack)
    return min(grid, oler)


def heading_vectors() -> np.ndarray:
    """[NUM_HEADINGS, 2] unit vectors of the flight headings (k * 22.5° counter-clockwise from east)."""
    angles = 2.0 * np.pi * np.arange(NUM_HEADINGS) / NUM_HEADINGS
    return np.stack([np.cos(angles), np.sin(angles)], axis=-1)


def world_record(world: WorldConfig) -> dict[str, Any]:
    """The plain fields of ``world`` (numbers, strings, booleans, None, lists and dicts of them): a checkpoint's
    record of the world it trained in, read by ``torch.load(weights_only=True)``. The radio map is named, never
    stored (``"radio"``: its name; ``"scenario"``: the preset it came from); demand, reward and fixed requests as
    dicts of their fields."""
    record: dict[str, Any] = {}
    for f in dataclasses.fields(WorldConfig):
        value = getattr(world, f.name)
        record[f.name] = value.name if f.name == "radio" else _plain_value(value)
    return record


def _plain_value(value: Any) -> Any:
    """``value`` with dataclasses as dicts of their fields, tuples as lists and NumPy scalars as Python numbers."""
    if dataclasses.is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain_value(getattr(value, f.name)) for f in dataclasses.fields(value)}
    if isinstance(value, list | tuple):
        return [_plain_value(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


# The checks and size bounds live in uamfleet.checks, the demand in uamfleet.demand; both import from here too.
__all__ = [
    "DETROIT_SLOT_S",
    "DETROIT_STEP_M",
    "FEASIBILITY_RULES",
    "FLEET_ARRIVAL_WINDOW_S",
    "FLEET_REQUESTS_PER_TAXI",
    "FLEET_TIME_LIMIT_WINDOWS",
    "MAX_HISTORY_LEN",
    "MAX_PASSENGERS",
    "MAX_PATCH_SIZE",
    "MAX_TAXIS",
    "NEEDS_STOP_FEATURES",
    "NUM_HEADINGS",
    "PATCH_SIZE_FIX",
    "REWARD_TERMS",
    "SEPARATION_MODES",
    "SHAPING_METRICS",
    "TAXI_SPEED_MPS",
    "ConfigError",
    "DemandConfig",
    "EnvConfig",
    "FeasibilityRule",
    "RadioMap",
    "Request",
    "RewardConfig",
    "WorldConfig",
    "as_requests",
    "check_integer",
    "check_number",
    "check_point",
    "check_sequence",
    "fleet_time_limit",
    "fleet_window_steps",
    "heading_vectors",
    "lookahead_depth_message",
    "passenger_window_fix",
]
