"""What each shipped policy reads, pinned before the checkpoint format stores it (:func:`spec_of_checkpoint`).

The six files in ``uamfleet/data/pretrained`` are of format 2: what they read is rebuilt from their flat ``args``
through today's presets (and, for ``berlin_fleet_hover.pt``, the start its ``init_from`` names). Each spec below
was computed from the code of this step and checked by hand against the plan's table
(``reports/2026-12-03-one-shape-plan/README.md`` 2.4); the field lists are ``observation_layout(policy.trained_on)``
of ``uamfleet.pretrained(name)`` as it was computed then. ``berlin_stops.pt`` and ``berlin_lookahead1.pt`` fly in no
case of ``tests/fingerprint.json``: their seeded rollouts are hashed here (``tests/fingerprint.py``)."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import torch
from fingerprint import Case, rollout_hashes

from uamfleet.observe.spec import LookaheadSpec, ObserverSpec, StopsSpec, layout_differences, layout_from_dict
from uamfleet.presets import make_config
from uamfleet.rl.checkpoint import CheckpointError
from uamfleet.rl.legacy import spec_of_checkpoint

PRETRAINED_DIR = Path(__file__).resolve().parents[2] / "uamfleet" / "data" / "pretrained"

SIX_ROWS_PER_TAXI = dict(history_len=3, patch_size=10, passenger_window=None, slots_per_taxi=6.0, time_scale_steps=600)
SPECS: dict[str, ObserverSpec] = {
    "berlin.pt": ObserverSpec(**SIX_ROWS_PER_TAXI, stops=StopsSpec(), lookahead=LookaheadSpec(depth=2), hover=False),
    "berlin_lookahead1.pt": ObserverSpec(**SIX_ROWS_PER_TAXI, stops=StopsSpec(), lookahead=LookaheadSpec(depth=1)),
    "berlin_stops.pt": ObserverSpec(**SIX_ROWS_PER_TAXI, stops=StopsSpec(), lookahead=None),
    # 4 taxis, 24 rows: 6 per taxi; claims (and so rivals' field) from today's berlin_fleet preset; no hover logit
    "berlin_fleet.pt": ObserverSpec(**SIX_ROWS_PER_TAXI, stops=StopsSpec(rivals=False, claims=True), hover=False),
    "berlin_fleet4.pt": ObserverSpec(**SIX_ROWS_PER_TAXI, stops=StopsSpec(rivals=False, claims=True), hover=False),
    "berlin_fleet_hover.pt": ObserverSpec(
        history_len=3,
        patch_size=10,
        passenger_window=24,
        slots_per_taxi=None,
        time_scale_steps=None,
        stops=StopsSpec(rivals=False, claims=True),
        lookahead=None,
        hover=True,
        fleet_rows=None,
    ),
}
"""The spec of each shipped file (scenario, taxis, window, slots, time limit, stop fields, look-ahead, hover)."""

WORLDS: dict[str, tuple[str, int]] = {
    "berlin.pt": ("berlin_instances", 1),
    "berlin_lookahead1.pt": ("berlin_instances", 1),
    "berlin_stops.pt": ("berlin_instances", 1),
    "berlin_fleet.pt": ("berlin_fleet", 4),
    "berlin_fleet4.pt": ("berlin_fleet", 4),
    "berlin_fleet_hover.pt": ("berlin_fleet", 8),  # the largest fleet of its mixture (8 x 96)
}
"""The scenario and fleet size each file was evaluated on (the rows of ``others`` follow the fleet)."""

_BASE = [("self", (4,)), ("history", (3, 3))]
_PATCHES = [("sinr_patch", (10, 10)), ("visit_patch", (10, 10))]


def _fields(rows: int, others: int, claims: bool, lookahead: bool) -> list[tuple[str, tuple[int, ...]]]:
    fields = [*_BASE, ("passengers", (rows, 12)), ("passenger_mask", (rows,)), *_PATCHES,
              ("others", (others, 3)), ("others_mask", (others,)), ("action_mask", (16,)),
              ("stop_paths", (rows, 3)), ("stop_heading_mask", (rows, 16))]  # fmt: skip
    if claims:
        fields += [("stop_rivals", (rows, 2)), ("stop_claims", (rows, 2)), ("hover_heading_mask", (16,))]
    if lookahead:
        fields += [("heading_lookahead", (16,))]
    return fields


FIELDS: dict[str, list[tuple[str, tuple[int, ...]]]] = {
    "berlin.pt": _fields(6, 1, claims=False, lookahead=True),
    "berlin_lookahead1.pt": _fields(6, 1, claims=False, lookahead=True),
    "berlin_stops.pt": _fields(6, 1, claims=False, lookahead=False),
    "berlin_fleet.pt": _fields(24, 3, claims=True, lookahead=False),
    "berlin_fleet4.pt": _fields(24, 3, claims=True, lookahead=False),
    "berlin_fleet_hover.pt": _fields(24, 7, claims=True, lookahead=False),
}
"""Each file's observation, field by field in the observer's order (names and shapes)."""

WITH_STORED_LAYOUT = ("berlin.pt", "berlin_lookahead1.pt", "berlin_fleet_hover.pt")


def _saved(name: str) -> dict[str, Any]:
    payload = torch.load(PRETRAINED_DIR / name, weights_only=True)
    assert isinstance(payload, dict)
    return payload


def _spec(payload: dict[str, Any], name: str = "the checkpoint") -> ObserverSpec:
    return spec_of_checkpoint(payload["args"], payload["net_config"], payload.get("obs_layout"), name)


def test_every_shipped_file_is_pinned() -> None:
    assert sorted(p.name for p in PRETRAINED_DIR.glob("*.pt")) == sorted(SPECS) == sorted(FIELDS)


@pytest.mark.parametrize("name", sorted(SPECS))
def test_each_shipped_file_reads_its_pinned_spec_and_fields(name: str) -> None:
    payload = _saved(name)
    spec = _spec(payload, name)
    assert spec == SPECS[name]
    scenario, taxis = WORLDS[name]
    layout = spec.layout(make_config(scenario, num_taxis=taxis).world)
    assert [(k, f.shape) for k, f in layout.items()] == FIELDS[name]
    # every field the network trained on is read, at the shape it trained on
    assert {k: tuple(v) for k, v in payload["obs_shapes"].items()} == {
        k: layout[k].shape for k in payload["obs_shapes"]
    }
    assert (payload.get("obs_layout") is not None) == (name in WITH_STORED_LAYOUT)
    if name in WITH_STORED_LAYOUT:
        assert layout_differences(layout_from_dict(payload["obs_layout"]), layout) == []


def test_a_stored_layout_the_rebuilt_observer_does_not_read_is_refused_naming_the_field() -> None:
    payload = _saved("berlin.pt")
    layout = dict(payload["obs_layout"])
    layout["stop_paths"] = {**layout["stop_paths"], "shape": [5, 3]}
    with pytest.raises(CheckpointError, match=r"berlin\.pt: .*field 'stop_paths': shape \(5, 3\) vs \(6, 3\)"):
        spec_of_checkpoint(payload["args"], payload["net_config"], layout, "berlin.pt")
    del layout["heading_lookahead"]
    layout["stop_paths"] = payload["obs_layout"]["stop_paths"]
    with pytest.raises(CheckpointError, match="field 'heading_lookahead': only in the rebuilt layout"):
        spec_of_checkpoint(payload["args"], payload["net_config"], layout, "berlin.pt")


def test_the_hover_is_the_networks_and_a_linear_encoder_reads_its_fleet_by_position() -> None:
    payload = _saved("berlin_fleet4.pt")  # its world has the hover action; its network has no hover logit
    args, net = payload["args"], payload["net_config"]
    assert spec_of_checkpoint(args, {**net, "hover_logit": True}).hover is True
    with pytest.raises(CheckpointError, match="hover_logit='yes' must be a bool"):
        spec_of_checkpoint(args, {**net, "hover_logit": "yes"})
    linear = spec_of_checkpoint({**args, "variant": "le", "action_head": "headings"}, {**net, "variant": "le"})
    assert linear.fleet_rows == 3  # 4 taxis: the 3 others by position
    assert linear.reads(make_config("berlin_fleet", num_taxis=2).world) is not None


ROLLOUTS: dict[str, dict[str, str]] = {
    "berlin_stops": {
        "actions": "30ec38136a9ae3d593bbeb215a8594488d6acffc6de9b67069ce0844f038bdad",
        "ends": "6c09422536eea2a954bff28ca20618d3771648b8518da233baf905a7eff5a219",
        "obs/action_mask": "b9fa8c41f73d05189e9845f3ef674b812ba6105627fb4088e9a209a1fdce5e02",
        "obs/history": "c72b2e52d406104b3b174376a9938adc3ef53184c84f1b09228eea0d00caff60",
        "obs/others": "8919e875abe851dd39b0e2919a9c0d87352a9706056ff61625476fc74293acb5",
        "obs/others_mask": "2e2e2a9e7a9e98ac52f8658e859d954a6576bf75816b4c4e5deb9f36f864ed5e",
        "obs/passenger_mask": "eabbab62dba514b8a0140a13293be2c96629a8ffc6c6fcfceaed8468192cff99",
        "obs/passengers": "7445f92907933ff730153dad17c5a35587f836451ffcd507e6a89bce0cfc183d",
        "obs/self": "656003e824ea14d5cb0aed65d59b73cb0929c7795b68679c7bef8a67a2f8c65d",
        "obs/sinr_patch": "d06d4d87c6677317cf741e05cecb56e7611f0e42099bfdef0c52cdbfa19a4666",
        "obs/stop_heading_mask": "83e31bc9751f484649c3c53b061c86439eb7ac419b24399e450ae8e2ec9627ca",
        "obs/stop_paths": "e885a52e4ab29888ca80fccc9dfe8341cedcbe1ec44afa2a007567e5925c473b",
        "obs/visit_patch": "a8e81784ec3b0deca0435fd145922fd61c4d5bb686a67d6a6e177e18498d78ea",
        "rewards": "88e9b11ec271b0a61bce789e6fa795ebf861b575bd13acdaf97439b9cf593806",
        "state": "133298abf9d2507e9c6dbf1a286d39b6ee7d52653d332e1fb3f6a6d6802ac07b",
    },
    "berlin_lookahead1": {
        "actions": "dca19a6379657a7c39055877945e9f344ee4e8050a32af61ad39830afb25813c",
        "ends": "9911d7030333ae357a327fd078890b6d6984ca5b13ae7837570ee4512f006976",
        "obs/action_mask": "9a38f8f847090adcb9d83afa650fd8ed9ab02da447b697c0cb87b4bc8bbc3da7",
        "obs/heading_lookahead": "c58b59e929ca929b097b95e3717cf561267012a8cc8c82f7181cf8c81a784ec6",
        "obs/history": "78e257d5c158747c893811924df025c3f9da7cae88977f3d017de6a3b558bd43",
        "obs/others": "8919e875abe851dd39b0e2919a9c0d87352a9706056ff61625476fc74293acb5",
        "obs/others_mask": "2e2e2a9e7a9e98ac52f8658e859d954a6576bf75816b4c4e5deb9f36f864ed5e",
        "obs/passenger_mask": "c17c6792bc6fa6eaeddf9c0b1b6b0ad7c4f1b0db5a177f67ab62cad37171386b",
        "obs/passengers": "2d502c3a798ca7322e222f9553e28f0fb78a214caf2126984a01b4fd52ea2849",
        "obs/self": "97fc40ca717c90b3cd0edea9672a71e753735257fbb141d28a4ef109647aafa9",
        "obs/sinr_patch": "f9068ece95bd552dd615e6a8e9719973e28305b5ffd2862023a6cbdc4c460d1f",
        "obs/stop_heading_mask": "85085484b4028adeba1dce31d36f05e9047c8e80547a87e716149dcb380e0b6f",
        "obs/stop_paths": "ec295a4b8648a28cd14d9c7c3740c24d3388ceb07eae33f5143df1d7aa4b7279",
        "obs/visit_patch": "a8d5653ce322b305d17f9d72628c28245a70579df92bfea23e88c6ff83b8741a",
        "rewards": "88e9b11ec271b0a61bce789e6fa795ebf861b575bd13acdaf97439b9cf593806",
        "state": "9e4581f866089a50069deaea7189a36faa1af7135b25324663ffe25593eaf7ba",
    },
}
"""Seeded rollouts of the two shipped files no fingerprint case flies (recorded on the code of this step)."""


@pytest.mark.parametrize("policy", sorted(ROLLOUTS))
def test_the_shipped_policies_no_fingerprint_flies_roll_out_as_recorded(policy: str) -> None:
    got = rollout_hashes(Case("berlin_instances", policy=policy, steps=150, seed=5))
    changed = sorted(k for k in set(got) | set(ROLLOUTS[policy]) if got.get(k) != ROLLOUTS[policy].get(k))
    assert not changed, f"{policy}: the rollout's {changed} differ from the recorded hashes (behaviour changed)"
