"""The paper's scenario presets: :func:`make_config`, the config of a named scenario with keyword overrides.

:data:`PRESETS` maps each name of :data:`SCENARIOS` to its preset, a function of :class:`~uamfleet.config.EnvConfig`
field overrides that returns the scenario's config (the paper's fixed instances, random demand, the held-out
instances' demand and the fleets').
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable
from typing import Any

from uamfleet.checks import MAX_TAXIS, ConfigError, check_integer
from uamfleet.config import (
    DETROIT_SLOT_S,
    DETROIT_STEP_M,
    FLEET_REQUESTS_PER_TAXI,
    EnvConfig,
    RewardConfig,
    WorldConfig,
    fleet_time_limit,
    fleet_window_steps,
)
from uamfleet.demand import DemandConfig, Request
from uamfleet.radio import load_radio_map


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
    """Detroit P5 on the ESTIMATED Detroit block map: 5 requests, 320 m steps (≈ 9.6 s).

    The authors never published the Detroit radio map; the packaged one is digitised from their figure and is
    faithful only at γ_T = −17 dB (blocks below −17 dB are only known to be below it).
    """
    base: dict[str, Any] = dict(
        radio=load_radio_map("detroit_estimate"),
        sinr_min_db=-17.0,
        step_m=DETROIT_STEP_M,
        slot_s=DETROIT_SLOT_S,
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
        step_m=DETROIT_STEP_M,
        slot_s=DETROIT_SLOT_S,
        starts_m=None,
        requests=None,
        demand=DemandConfig(num_initial=4, rate_per_step=0.1, horizon_steps=80, max_requests=12, min_trip_m=2000.0),
        time_limit_steps=600,
        scenario="detroit3gpp_random",
    )
    return _with_overrides(base, overrides)


def _munich_random(**overrides: Any) -> EnvConfig:
    """:func:`_berlin_random` (threshold -3 dB, 100 m steps of 3 s, the same demand) on the packaged ray-traced
    Munich map (Sionna RT, 1,200 m operating square, 4 GBS): a city no shipped policy was trained on."""
    return _berlin_random(**{"radio": load_radio_map("munich"), "scenario": "munich_random", **overrides})


def _munich_3km_random(**overrides: Any) -> EnvConfig:
    """:func:`_berlin_random` on the packaged ``munich_3km`` map (Munich's scene ray-traced over a 3 km square, 16
    GBS), where the radio binds: at -3 dB 15 % of its 100 m blocks are not flyable."""
    return _berlin_random(**{"radio": load_radio_map("munich_3km"), "scenario": "munich_3km_random", **overrides})


INSTANCE_REWARD = RewardConfig(explore=0.0, explore_repeat=0.0, pickup=0.0, dropoff=0.0)
"""The *_instances scenarios' reward: the distance flown is what is scored, so ``step`` per step and nothing
else. An episode ends only when everyone is delivered, so the return is the shorter the sooner the tour ends,
for any discount. Pick-up and drop-off bonuses (tried: a tenth of the authors') pay, through the discount, for
serving someone sooner at the price of a longer tour: with them PPO moved the stop head away from its
shortest-tour prior (validation TD 9,708 -> 9,786 m in 190k agent-steps)."""


def _berlin_instances(**overrides: Any) -> EnvConfig:
    """One taxi on the Berlin map with the demand of the held-out instances (:mod:`uamfleet.instances`): 2-6
    requests, the first at step 0 and the others over the first 2 minutes (40 steps), trips >= 500 m, a padded
    passenger axis of 6 and the feasible-path stop features; what a generalist policy trains on (one threshold
    per env: the trainer's ``--thresholds`` mixes several)."""
    demand = DemandConfig(
        arrivals="uniform", num_initial=1, min_requests=2, max_requests=6, horizon_steps=40, min_trip_m=500.0
    )
    base = _fields(_berlin_random(num_taxis=1, demand=demand))
    base.update(max_passengers=6, stop_features=True, reward=INSTANCE_REWARD, scenario="berlin_instances")
    return _with_overrides(base, overrides)


def _detroit3gpp_instances(**overrides: Any) -> EnvConfig:
    """:func:`_berlin_instances` on the synthetic TR 36.777 Detroit-like map (320 m steps, releases over the
    first 12 steps, trips >= 2 km)."""
    demand = DemandConfig(
        arrivals="uniform", num_initial=1, min_requests=2, max_requests=6, horizon_steps=12, min_trip_m=2000.0
    )
    base = _fields(_detroit3gpp_random(num_taxis=1, demand=demand))
    base.update(max_passengers=6, stop_features=True, reward=INSTANCE_REWARD, scenario="detroit3gpp_instances")
    return _with_overrides(base, overrides)


def _munich_instances(**overrides: Any) -> EnvConfig:
    """:func:`_berlin_instances` (one taxi, Berlin's instance demand, the generalist's layout) on the packaged
    ray-traced Munich map."""
    return _berlin_instances(**{"radio": load_radio_map("munich"), "scenario": "munich_instances", **overrides})


def _munich_3km_instances(**overrides: Any) -> EnvConfig:
    """:func:`_berlin_instances` on the packaged ``munich_3km`` map."""
    return _berlin_instances(**{"radio": load_radio_map("munich_3km"), "scenario": "munich_3km_instances", **overrides})


FLEET_REWARD = RewardConfig(explore=0.0, explore_repeat=0.0, separation=-20.0, shield=-20.0)
"""The *_fleet scenarios' reward: the authors' pick-up / drop-off bonuses (200 / 300, so that a passenger left
waiting costs about as much per step, through the discount, as a taxi's step) without the exploration bonus, and
-20 (ten steps' worth) per step a taxi flies closer than the separation minimum to another. Under their separation
shield that price falls on each move the shield replaces (``shield``), so a policy still learns to keep its
distance rather than lean on the shield; a hover costs its time (the ``step`` term, the riders' wait), no more."""


def _fleet(
    random_preset: Callable[..., EnvConfig], scenario: str, slot_s: float, overrides: dict[str, Any]
) -> EnvConfig:
    """A fleet with the demand of the held-out fleet instances (:func:`uamfleet.instances.make_fleet_instance`):
    6 requests per taxi, released uniformly over the first 10 minutes, on flyable block centres; the separation
    shield and the hover action on (docs/rules.md "Separation shield", "Motion")."""
    taxis = check_integer("num_taxis", overrides.get("num_taxis", 4), 1, MAX_TAXIS)
    min_trip = 2000.0 if scenario.startswith("detroit") else 500.0
    requests, window = FLEET_REQUESTS_PER_TAXI * taxis, fleet_window_steps(slot_s)
    demand = DemandConfig(
        arrivals="uniform", num_initial=0, min_requests=requests, max_requests=requests,
        horizon_steps=window - 1, min_trip_m=min_trip,
    )  # fmt: skip
    base = _fields(random_preset(num_taxis=taxis, demand=demand))
    base.update(
        max_passengers=requests,
        stop_features=True,
        stop_claims=True,
        reward=FLEET_REWARD,
        separation="shield",
        hover_action=True,
        scenario=scenario,
    )
    base["time_limit_steps"] = fleet_time_limit(base["time_limit_steps"], window)
    return _with_overrides(base, {k: v for k, v in overrides.items() if k != "num_taxis"})


def _berlin_fleet(**overrides: Any) -> EnvConfig:
    """A Berlin fleet (default 4 taxis) with 6 requests per taxi over the first 10 minutes: what a learned fleet
    trains on (the fleet table's settings 1x6 ... 8x48)."""
    return _fleet(_berlin_random, "berlin_fleet", 3.0, overrides)


def _detroit3gpp_fleet(**overrides: Any) -> EnvConfig:
    """:func:`_berlin_fleet` on the synthetic TR 36.777 Detroit-like map."""
    return _fleet(_detroit3gpp_random, "detroit3gpp_fleet", DETROIT_SLOT_S, overrides)


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
        num_taxis = check_integer("num_taxis", overrides["num_taxis"], 1, MAX_TAXIS)
        merged["starts_m"] = tuple(base["starts_m"][0] for _ in range(num_taxis))
    return EnvConfig(**merged)


PRESETS: dict[str, Callable[..., EnvConfig]] = {
    "berlin_p4": _berlin_p4,
    "detroit_p5": _detroit_p5,
    "detroit3gpp_p5": _detroit3gpp_p5,
    "berlin_random": _berlin_random,
    "detroit3gpp_random": _detroit3gpp_random,
    "munich_random": _munich_random,
    "munich_3km_random": _munich_3km_random,
    "berlin_instances": _berlin_instances,
    "detroit3gpp_instances": _detroit3gpp_instances,
    "munich_instances": _munich_instances,
    "munich_3km_instances": _munich_3km_instances,
    "berlin_fleet": _berlin_fleet,
    "detroit3gpp_fleet": _detroit3gpp_fleet,
}
SCENARIOS: tuple[str, ...] = tuple(PRESETS)

_STOPS: dict[str, Any] = {"stops": {"rivals": False, "claims": False}}
_CLAIMS: dict[str, Any] = {"stops": {"rivals": False, "claims": True}}
OBSERVERS: dict[str, dict[str, Any]] = {
    "berlin_p4": {}, "detroit_p5": {}, "detroit3gpp_p5": {},
    "berlin_random": {}, "detroit3gpp_random": {}, "munich_random": {}, "munich_3km_random": {},
    "berlin_instances": _STOPS, "detroit3gpp_instances": _STOPS, "munich_instances": _STOPS,
    "munich_3km_instances": _STOPS,
    "berlin_fleet": _CLAIMS, "detroit3gpp_fleet": _CLAIMS,
}  # fmt: skip
"""The observer each scenario is flown with, as ``uamfleet.observe.spec.ObserverSpec.from_dict`` values (plain
values: the presets sit below the observer): the paper's observation (``{}``: ``ObserverSpec()``), the stop
features for ``*_instances``, the stop features with claims for ``*_fleet``. Until the presets build their worlds
without the observer's fields, each preset's config also carries them; ``tests/observe/test_spec.py`` holds the two
equal (:func:`uamfleet.observe.legacy.split_env_config` of the config gives this spec)."""


def make_config(scenario: str | WorldConfig = "berlin_p4", **overrides: Any) -> EnvConfig:
    """The config of a named scenario with keyword overrides (any :class:`EnvConfig` field). A config given in
    place of a name is overridden; a bare :class:`WorldConfig` becomes an :class:`EnvConfig` with the observer
    fields at their defaults.

    ``radio`` may be a :class:`~uamfleet.radio.RadioMap` or a name/path for :func:`uamfleet.load_radio_map`;
    ``requests`` a sequence of :class:`Request` or ``(release_step, origin, destination)`` tuples.
    """
    if isinstance(scenario, WorldConfig):
        return _with_overrides(_fields(scenario), overrides)
    if not isinstance(scenario, str) or scenario not in PRESETS:  # a list would fail the lookup with a TypeError
        raise ConfigError(
            f"Unknown scenario {scenario!r}; choose one of {SCENARIOS} or pass an EnvConfig "
            "(e.g. make_config('berlin_random', radio=my_map))."
        )
    return PRESETS[scenario](**overrides)


def _fields(cfg: WorldConfig) -> dict[str, Any]:
    return {f.name: getattr(cfg, f.name) for f in dataclasses.fields(cfg)}


__all__ = ["FLEET_REWARD", "INSTANCE_REWARD", "OBSERVERS", "PRESETS", "SCENARIOS", "make_config"]
