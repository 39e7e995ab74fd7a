"""The network's optional inputs are chosen by NetConfig (never by which fields exist), old checkpoints get
theirs from their stored shapes, and new checkpoints store the observation spec that load_policy compares."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import pytest
import torch

from uamfleet.observe.spec import layout_to_dict, observation_layout, observation_space
from uamfleet.presets import make_config
from uamfleet.rl.checkpoint import Checkpoint, CheckpointError
from uamfleet.rl.networks import MSHAActorCritic, NetConfig, observed_inputs
from uamfleet.rl.options import make_env_config
from uamfleet.rl.policy import load_policy
from uamfleet.zoo import pretrained_path

FLAGS = ("stop_inputs", "rival_inputs", "claim_inputs", "stop_hover")


def _space(**flags: bool):
    """One taxi's observation space of a Berlin fleet of 3 with the given stop flags."""
    if not flags.get("stop_features", True):
        flags = {**flags, "stop_rivals": False, "stop_claims": False}  # the fleet preset's need stop features
    return observation_space(observation_layout(make_config("berlin_fleet", num_taxis=3, **flags)))


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(action_head="stops"), r"action_head='stops' needs the stop features as inputs"),
        (dict(rival_inputs=True), r"rival_inputs=True needs stop_inputs=True"),
        (dict(stop_inputs=True, claim_inputs=True), r"claim_inputs=True needs rival_inputs=True"),
        (dict(stop_inputs=True, rival_inputs=True, stop_hover=True), r"stop_hover=True needs claim_inputs=True"),
        (dict(stop_inputs=True, rival_inputs=True, claim_inputs=True, stop_hover=True), r"needs action_head='stops'"),
        (dict(variant="le", stop_inputs=True), r"linear encoder \('le'\) does not make"),
        (dict(lookahead_inputs=True), r"^lookahead_inputs=True corrects the stop head's flight: it needs action_head="),
    ],
)
def test_inputs_that_cannot_work_together_are_refused(kwargs, message):
    with pytest.raises(ValueError, match=message):
        NetConfig(**kwargs)


def test_an_input_the_observation_lacks_is_named_with_the_fix():
    space = _space(stop_features=True, stop_rivals=False, stop_claims=False)  # stop_paths, no stop_rivals
    cfg = NetConfig(variant="de", d_model=16, num_heads=2, stop_inputs=True, rival_inputs=True)
    with pytest.raises(
        ValueError, match=r"NetConfig\(rival_inputs=True\) reads observation field\(s\) \['stop_rivals'\]"
    ):
        MSHAActorCritic(space, cfg)
    with pytest.raises(ValueError, match=r"\['stop_paths', 'stop_heading_mask'\].*EnvConfig\(stop_features=True\)"):
        MSHAActorCritic(
            _space(stop_features=False),
            NetConfig(variant="de", d_model=16, num_heads=2, stop_inputs=True),
        )


def test_fields_the_config_does_not_ask_for_are_not_read():
    """The same config builds the same network whether or not the observation has the stop fields."""
    cfg = NetConfig(variant="de", d_model=16, num_heads=2)
    shapes = {
        stops: {k: tuple(v.shape) for k, v in MSHAActorCritic(_space(stop_features=stops), cfg).state_dict().items()}
        for stops in (False, True)
    }
    assert shapes[True] == shapes[False]
    read = MSHAActorCritic(_space(stop_features=True), dataclasses.replace(cfg, stop_inputs=True)).state_dict()
    # stop_inputs widens each passenger row by the stop paths and the actionable flag (3 + 1 columns)
    base = shapes[False]["torso.passengers.embed.weight"]
    assert tuple(read["torso.passengers.embed.weight"].shape) == (base[0], base[1] + 4)


def test_observed_inputs_follow_the_spec_of_the_env_flags():
    fleet = observation_layout(make_config("berlin_fleet", num_taxis=3, stop_features=True, stop_claims=True))
    assert observed_inputs(fleet, "de_msfea", "stops") == {**dict.fromkeys(FLAGS, True), "lookahead_inputs": False}
    looking = observation_layout(make_config("berlin_fleet", num_taxis=3, stop_claims=True, heading_lookahead=True))
    assert observed_inputs(looking, "de_msfea", "stops")["lookahead_inputs"] is True
    assert observed_inputs(looking, "de_msfea", "headings")["lookahead_inputs"] is False  # a stop-head correction
    assert observed_inputs(fleet, "de_msfea", "headings")["stop_hover"] is False  # hover is the stop head's
    assert not any(observed_inputs(fleet, "le", "headings").values())  # the linear encoder reads none
    plain = observation_layout(make_config("berlin_fleet", num_taxis=3, stop_features=False, stop_claims=False))
    assert not any(observed_inputs(plain, "full", "headings").values())


def test_the_shipped_checkpoints_predate_the_flags_and_get_them_from_their_shapes():
    expected = {
        "berlin_stops": (True, False, False, False),  # one taxi: stop paths only
        "berlin_fleet_v1": (True, True, True, True),  # rivals, claims and the hover component
        "berlin_fleet4": (True, True, False, False),  # rivals, no claims
    }
    for name, flags in expected.items():
        raw = torch.load(pretrained_path(name), weights_only=True)
        assert not set(FLAGS) & set(raw["net_config"]) and raw.get("obs_layout") is None  # written before both
        ckpt = Checkpoint.load(pretrained_path(name))
        assert tuple(ckpt.net_config[f] for f in FLAGS) == flags, name


def _with_layout(tmp_path: Path, name: str, layout: dict) -> Path:
    ckpt = Checkpoint.load(pretrained_path("berlin_fleet_v1"))
    path = tmp_path / name
    dataclasses.replace(ckpt, obs_layout=layout).save(path)
    return path


def _fleet_layout() -> dict:
    _, args = load_policy(pretrained_path("berlin_fleet_v1"))
    return layout_to_dict(observation_layout(make_env_config(args.env.scenario, args, training=False)))


def test_a_stored_spec_is_kept_and_compared_field_by_field(tmp_path):
    layout = _fleet_layout()
    same = _with_layout(tmp_path, "same.pt", layout)
    assert Checkpoint.load(same).obs_layout == layout
    policy, _ = load_policy(same)
    assert policy.net is not None
    # a column renamed and a bound changed: same shapes, yet another meaning, and load_policy names both
    other = {**layout, "stop_paths": {**layout["stop_paths"], "high": 9.0}}
    other["others"] = {**layout["others"], "columns": ["a", "b", "c"]}
    with pytest.raises(ValueError, match=r"observation field 'others': columns .*'a', 'b', 'c'.*; observation "
                       r"field 'stop_paths': high 9.0 vs"):  # fmt: skip
        load_policy(_with_layout(tmp_path, "other.pt", other))


@pytest.mark.parametrize(
    ("change", "message"),
    [
        (lambda lay: {**lay, "self": {**lay["self"], "low": torch.zeros(1)}}, r"other than dicts, lists"),
        (lambda lay: {**lay, "self": {**lay["self"], "shape": [5]}}, r"disagrees with its obs_shapes"),
        (lambda lay: {**lay, "self": {**lay["self"], "kind": "code"}}, r"is not a spec: .*kind 'code'"),
        (lambda lay: [1, 2], r"other than dicts, lists"),
    ],
)
def test_a_stored_spec_that_is_not_one_is_refused(tmp_path, change, message):
    path = _with_layout(tmp_path, "bad.pt", change(_fleet_layout()))
    with pytest.raises(CheckpointError, match=message):
        Checkpoint.load(path)
