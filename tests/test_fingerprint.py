"""Seeded rollouts hash as they did before issue 23's observation layout (:mod:`tests.fingerprint`): observations
of every field, the global state, actions, rewards and episode ends of random and shipped policies."""

from __future__ import annotations

import json

import pytest
from fingerprint import CASES, FIXTURE, rollout_hashes

EXPECTED: dict[str, dict[str, str]] = json.loads(FIXTURE.read_text())
LONG = {
    "pretrained_berlin",
    "pretrained_berlin_p4",
    "pretrained_berlin_fleet_4taxis",
    "pretrained_berlin_fleet_v1_4taxis",
}  # 5-20 s each under load


def test_the_fixture_covers_every_case() -> None:
    assert set(EXPECTED) == set(CASES)


@pytest.mark.parametrize("name", [pytest.param(n, marks=pytest.mark.slow) if n in LONG else n for n in sorted(CASES)])
def test_seeded_rollout_hashes_as_recorded(name: str) -> None:
    got = rollout_hashes(CASES[name])
    changed = sorted(k for k in set(got) | set(EXPECTED[name]) if got.get(k) != EXPECTED[name].get(k))
    assert not changed, f"{name}: the rollout's {changed} differ from tests/fingerprint.json (behaviour changed)"
