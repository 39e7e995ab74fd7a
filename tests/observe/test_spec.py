"""What a policy reads, apart from the world (:class:`uamfleet.observe.spec.ObserverSpec`): the split of the legacy
config gives back today's layout, the spec refuses in one line a world it cannot read, and it travels as plain
values."""

from __future__ import annotations

import dataclasses
import io
import itertools

import pytest
import torch
from conftest import small_config

from uamfleet.config import ConfigError, EnvConfig, Request, WorldConfig
from uamfleet.observe.legacy import split_env_config
from uamfleet.observe.spec import (
    LookaheadSpec,
    ObserverSpec,
    StopsSpec,
    layout_differences,
    observation_layout,
)
from uamfleet.presets import PRESETS

OBSERVER_FIELDS = {"passenger_window", "history_len", "patch_size", "stop_features", "stop_rivals", "stop_claims",
                   "heading_lookahead", "lookahead_depth"}  # fmt: skip
OPEN_7 = "\n".join(["......."] * 7)
REQUESTS = (
    Request(0, (250.0, 250.0), (550.0, 450.0)),
    Request(0, (450.0, 150.0), (150.0, 550.0)),
    Request(3, (650.0, 650.0), (50.0, 50.0)),
)


def world(**overrides: object) -> WorldConfig:
    base: dict[str, object] = {"starts_m": None, "num_taxis": 2, "requests": REQUESTS, "seats": 1}
    base.update(overrides)
    return small_config(OPEN_7, **base).world


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_the_split_of_every_preset_observes_its_layout_field_for_field(name: str) -> None:
    cfg = PRESETS[name]()
    world_cfg, spec = split_env_config(cfg)
    assert type(world_cfg) is WorldConfig
    assert layout_differences(observation_layout(cfg), spec.layout(world_cfg)) == []
    assert spec.reads(world_cfg) is None
    kept = {f.name for f in dataclasses.fields(WorldConfig)}
    assert all(getattr(world_cfg, n) == getattr(cfg, n) for n in kept)


def test_the_world_holds_the_22_world_fields_and_none_of_the_observers() -> None:
    world_fields = {f.name for f in dataclasses.fields(WorldConfig)}
    env_fields = {f.name for f in dataclasses.fields(EnvConfig)}
    assert len(world_fields) == 22 and env_fields - world_fields == OBSERVER_FIELDS


@pytest.mark.parametrize(
    ("taxis", "flags", "window", "depth"),
    [(t, f, w, d) for t, f, w, d in itertools.product(
        [1, 3], [(False, False, False, False), (True, False, False, False), (True, True, False, True),
                 (True, False, True, True)], [None, 2], [1, 2]) if d == 1 or f[3]],
)  # fmt: skip
def test_the_split_of_a_config_gives_back_its_layout(taxis: int, flags: tuple, window: int | None, depth: int) -> None:
    stops, rivals, claims, lookahead = flags
    cfg = small_config(
        OPEN_7, starts_m=None, num_taxis=taxis, requests=REQUESTS, seats=1, max_passengers=5, history_len=2,
        patch_size=3, passenger_window=window, stop_features=stops, stop_rivals=rivals, stop_claims=claims,
        heading_lookahead=lookahead, lookahead_depth=depth,
    )  # fmt: skip
    world_cfg, spec = split_env_config(cfg)
    assert layout_differences(observation_layout(cfg), spec.layout(world_cfg)) == []
    if window is None:  # the rows and the time scale it observes are pinned to the config's
        assert (spec.slots_per_taxi, spec.time_scale_steps) == (5 / taxis, 50)
    else:
        assert (spec.slots_per_taxi, spec.time_scale_steps, spec.passenger_window) == (None, None, window)


def test_a_spec_without_a_window_reads_its_slots_per_taxi_of_another_fleet() -> None:
    spec = ObserverSpec(slots_per_taxi=6.0)  # 24 slots trained for 4 taxis -> 12 rows at 2 taxis
    assert spec.layout(world(num_taxis=2))["passengers"].shape[0] == 12
    assert spec.layout(world(num_taxis=1))["passenger_mask"].shape == (6,)
    assert ObserverSpec(slots_per_taxi=7 / 3).layout(world(num_taxis=3))["passengers"].shape[0] == 7
    assert ObserverSpec().layout(world(max_passengers=9))["passengers"].shape[0] == 9  # None: the world's rows


def test_reads_refuses_more_passengers_than_it_reads() -> None:
    spec = ObserverSpec(slots_per_taxi=1.5)
    assert spec.reads(world(num_taxis=2, max_passengers=3)) is None
    assert spec.reads(world(num_taxis=2, max_passengers=4)) == (
        "the world has 4 passenger rows; this policy reads 3: give it at most 3 requests, or fly it with a "
        "passenger window"
    )
    assert ObserverSpec(slots_per_taxi=1.0, passenger_window=2).reads(world(max_passengers=30)) is None


def test_reads_refuses_another_fleet_size_when_it_reads_the_others_by_position() -> None:
    spec = ObserverSpec(fleet_rows=3)
    assert spec.reads(world(num_taxis=4)) is None
    assert ObserverSpec().reads(world(num_taxis=3)) is None
    assert spec.reads(world(num_taxis=2)) == (
        "this policy reads the other taxis by position (3 rows), but the world has 2 taxis: fly it with 4 taxis"
    )


def test_reads_refuses_a_window_below_the_seats_with_the_legacy_message() -> None:
    with pytest.raises(ConfigError) as legacy:
        small_config(OPEN_7, requests=REQUESTS, seats=3, passenger_window=2)
    assert ObserverSpec(passenger_window=2).reads(world(seats=3)) == str(legacy.value)
    assert ObserverSpec(passenger_window=3).reads(world(seats=3)) is None


def test_reads_refuses_the_hover_in_a_world_without_it() -> None:
    assert ObserverSpec(hover=True).reads(world(hover_action=True)) is None
    assert ObserverSpec(hover=True).reads(world()) == (
        "this policy waits with the hover action (16), which this world refuses: build it with hover_action=True"
    )


def test_reads_changes_nothing_of_the_world() -> None:
    world_cfg = world(num_taxis=2, max_passengers=4)
    before = {f.name: getattr(world_cfg, f.name) for f in dataclasses.fields(WorldConfig)}
    assert ObserverSpec(slots_per_taxi=1.0, fleet_rows=4, hover=True).reads(world_cfg) is not None
    assert {f.name: getattr(world_cfg, f.name) for f in dataclasses.fields(WorldConfig)} == before


@pytest.mark.parametrize(
    ("legacy", "spec"),
    [
        (dict(heading_lookahead=True), dict(lookahead=LookaheadSpec())),
        (dict(stop_features=True, heading_lookahead=True, lookahead_depth=3), dict(stops=StopsSpec(), depth=3)),
        (dict(history_len=0), dict(history_len=0)),
        (dict(history_len=1.5), dict(history_len=1.5)),
        (dict(patch_size=65), dict(patch_size=65)),
    ],
)
def test_the_spec_refuses_what_the_legacy_config_refuses_with_the_same_line(legacy: dict, spec: dict) -> None:
    with pytest.raises(ConfigError) as old:
        small_config(**legacy)
    depth = spec.pop("depth", None)
    with pytest.raises(ConfigError) as new:
        ObserverSpec(**spec) if depth is None else ObserverSpec(lookahead=LookaheadSpec(depth=depth), **spec)
    assert str(new.value) == str(old.value) and "\n" not in str(new.value)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        (dict(passenger_window=0), "passenger_window=0"),
        (dict(slots_per_taxi=-1.0), "slots_per_taxi"),
        (dict(time_scale_steps=0), "time_scale_steps"),
        (dict(fleet_rows=-1), "fleet_rows"),
        (dict(hover=1), "hover=1"),
        (dict(stops={"claims": True}), "StopsSpec()"),
    ],
)
def test_the_spec_refuses_a_bad_value_naming_it(kwargs: dict, words: str) -> None:
    with pytest.raises(ConfigError, match=words.replace("(", r"\(").replace(")", r"\)")):
        ObserverSpec(**kwargs)


SPECS = [
    ObserverSpec(),
    ObserverSpec(history_len=2, patch_size=5, passenger_window=24, stops=StopsSpec(claims=True), hover=True),
    ObserverSpec(slots_per_taxi=7 / 3, time_scale_steps=600, stops=StopsSpec(rivals=True),
                 lookahead=LookaheadSpec(depth=2), fleet_rows=3),
]  # fmt: skip


@pytest.mark.parametrize("spec", SPECS)
def test_a_spec_travels_as_plain_values_that_torch_reads_with_weights_only(spec: ObserverSpec) -> None:
    assert ObserverSpec.from_dict(spec.to_dict()) == spec
    buffer = io.BytesIO()
    torch.save({"observer": spec.to_dict()}, buffer)
    buffer.seek(0)
    assert ObserverSpec.from_dict(torch.load(buffer, weights_only=True)["observer"]) == spec


def test_from_dict_refuses_an_unknown_key_naming_it() -> None:
    with pytest.raises(ConfigError, match="'stop_features'"):
        ObserverSpec.from_dict({"stop_features": True})
    with pytest.raises(ConfigError, match="stops="):
        ObserverSpec.from_dict({"stops": {"rival": True}})


@pytest.mark.parametrize("name", sorted(PRESETS))
def test_each_presets_named_observer_is_what_its_config_observes(name: str) -> None:
    from uamfleet.presets import OBSERVERS

    _, split = split_env_config(PRESETS[name]())
    named = ObserverSpec.from_dict(OBSERVERS[name])
    pinned = {"slots_per_taxi": None, "time_scale_steps": None, "hover": False}  # the split pins these to the world
    assert dataclasses.replace(split, **pinned) == named
    assert set(OBSERVERS) == set(PRESETS)
