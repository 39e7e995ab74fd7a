"""Checkpoint format 3: a checkpoint stores what its policy reads (``observer``, an ``ObserverSpec`` as plain values)
and the world it trained in (``world``, plain fields, the radio map by name), ``torch.load(weights_only=True)``
reads both, and loading flies the stored spec (a file of format 2 falls back to ``spec_of_checkpoint``)."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import torch
from test_checkpoints import ONE_PASSENGER, args
from test_shipped_specs import PRETRAINED_DIR, SPECS, WORLDS

from uamfleet.observe.spec import ObserverSpec
from uamfleet.policies.learned import export_policy
from uamfleet.rl.checkpoint import CHECKPOINT_FORMAT, Checkpoint, CheckpointError, world_record
from uamfleet.rl.policy import load_policy
from uamfleet.rl.trainer import train


def test_the_current_format_is_3() -> None:
    assert CHECKPOINT_FORMAT == 3


@pytest.mark.parametrize("name", sorted(SPECS))
def test_a_shipped_file_and_its_export_load_with_weights_only_and_the_export_stores_its_spec(
    name: str, tmp_path: Path
) -> None:
    shipped = torch.load(PRETRAINED_DIR / name, weights_only=True)
    assert shipped["format"] == 2 and "observer" not in shipped and "world" not in shipped
    out = export_policy(PRETRAINED_DIR / name, tmp_path / name)
    exported = torch.load(out, weights_only=True)
    assert exported["format"] == 3
    assert exported["observer"] == SPECS[name].to_dict()
    scenario, taxis = WORLDS[name]
    world = exported["world"]
    assert world["scenario"] == scenario and world["num_taxis"] == taxis and world["radio"] == "berlin"
    assert world["hover_action"] is (scenario == "berlin_fleet") and world["time_limit_steps"] == 600
    assert isinstance(world["demand"], dict) and isinstance(world["reward"], dict)
    # the export flies the spec it stores, at the shapes the original reads
    original, _ = load_policy(PRETRAINED_DIR / name)
    policy, _ = load_policy(out)
    assert policy.spec == original.spec == SPECS[name]
    assert policy.obs_shapes == original.obs_shapes


def test_loading_reads_the_stored_spec_checked_against_the_layout_the_weights_trained_on(tmp_path: Path) -> None:
    out = export_policy(PRETRAINED_DIR / "berlin.pt", tmp_path / "berlin.pt")
    ckpt = Checkpoint.load(out)
    assert ckpt.observer is not None
    without_stops = ObserverSpec.from_dict({**ckpt.observer, "stops": None, "lookahead": None})
    dataclasses.replace(ckpt, observer=without_stops.to_dict()).save(tmp_path / "edited.pt")
    with pytest.raises(ValueError, match=r"edited\.pt: .*field 'heading_lookahead'.*not observed by this env"):
        load_policy(tmp_path / "edited.pt")


def test_a_stored_observer_or_world_that_is_not_plain_values_or_not_a_spec_is_refused(tmp_path: Path) -> None:
    ckpt = Checkpoint.load(export_policy(PRETRAINED_DIR / "berlin_stops.pt", tmp_path / "a.pt"))
    assert ckpt.observer is not None
    with pytest.raises(CheckpointError, match=r"b\.pt: its observer is not an observer spec: .*'window'"):
        Checkpoint.from_bytes(dataclasses.replace(ckpt, observer={**ckpt.observer, "window": 3}).to_bytes(), "b.pt")
    with pytest.raises(CheckpointError, match=r"c\.pt: its world holds something other than dicts"):
        Checkpoint.from_bytes(dataclasses.replace(ckpt, world={"radio": {1, 2}}).to_bytes(), "c.pt")


def test_a_trained_checkpoint_is_of_format_3_with_its_spec_and_world(tmp_path: Path) -> None:
    train(args(tmp_path, iterations=1), env_config=ONE_PASSENGER)
    payload = torch.load(tmp_path / "run" / "last.pt", weights_only=True)
    assert payload["format"] == 3
    spec = ObserverSpec.from_dict(payload["observer"])
    # ONE_PASSENGER: one taxi, one request, 4 x 4 patches, a 30-step limit (eval_time_limit_steps), no stop fields
    assert spec == ObserverSpec(patch_size=4, slots_per_taxi=1.0, time_scale_steps=30)
    expected = world_record(ONE_PASSENGER.replace(time_limit_steps=30).world)
    world = payload["world"]
    assert {k: v for k, v in world.items() if k != "reward"} == {k: v for k, v in expected.items() if k != "reward"}
    assert set(world["reward"]) == set(expected["reward"])  # the run's weights (its shaping options), by term
    assert payload["world"]["requests"][0]["origin_m"] == [350.0, 150.0]
    policy, _ = load_policy(tmp_path / "run" / "best.pt", env_config=ONE_PASSENGER)
    assert policy.spec == spec
