"""Behaviour fingerprint: sha256 hashes of seeded rollouts, to show that a refactor changes no behaviour.

Each case flies a seeded policy in a seeded :class:`uamfleet.VectorEnv` (autoreset on, so episodes end and restart)
and hashes, step by step, every observation field (name, dtype, shape and bytes), the global state, the actions,
rewards and episode ends; each stream gets its own hash, so a failure names what changed. The hashes of the code
before issue 23's observation layout are in ``tests/fingerprint.json``; ``tests/test_fingerprint.py`` compares.

Regenerate (only for a change that is *meant* to alter behaviour, and say so in its commit)::

    .venv/bin/python tests/fingerprint.py --write

Config fields the hashes rely on are pinned in :data:`CASES` (``overrides``) where a later default could change
them. A config flag added later that is off by default keeps every hash; one that is on in a preset changes that
preset's cases (pin it off there to keep them).
"""

from __future__ import annotations

import hashlib
import json
import sys
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

FIXTURE = Path(__file__).with_name("fingerprint.json")


@dataclass(frozen=True)
class Case:
    scenario: str
    overrides: dict[str, Any] = field(default_factory=dict)
    policy: str = "random"  # "random" (masked uniform) or a shipped policy name (uamfleet.pretrained)
    num_envs: int = 2
    steps: int = 80
    seed: int = 3


CASES: dict[str, Case] = {
    "berlin_p4": Case("berlin_p4", steps=120),
    "berlin_p4_autoreset": Case("berlin_p4", {"time_limit_steps": 25}, steps=80),  # episodes end and restart
    "berlin_random_4taxis": Case("berlin_random", {"num_taxis": 4}),
    "berlin_instances": Case("berlin_instances", steps=120),
    "berlin_fleet_2taxis": Case("berlin_fleet", {"num_taxis": 2, "separation": "none"}),
    "berlin_fleet_4taxis": Case("berlin_fleet", {"num_taxis": 4, "separation": "none"}),
    "detroit3gpp_fleet": Case("detroit3gpp_fleet", {"num_taxis": 4, "separation": "none"}, steps=60),
    "pretrained_berlin": Case("berlin_instances", policy="berlin", steps=150),
    # the world it has always hashed: berlin_p4 with the 6 passenger rows and the 600-step limit berlin trained on
    "pretrained_berlin_p4": Case(
        "berlin_p4", {"max_passengers": 6, "time_limit_steps": 600}, policy="berlin", num_envs=1, steps=150
    ),
    "pretrained_berlin_fleet_4taxis": Case(
        "berlin_fleet", {"num_taxis": 4, "separation": "none"}, policy="berlin_fleet", steps=100
    ),
    "pretrained_berlin_fleet_2taxis": Case(
        "berlin_fleet", {"num_taxis": 2, "separation": "none"}, policy="berlin_fleet", steps=50
    ),
    # the fleet policy shipped as "berlin_fleet" until 2026-12-02: these hashed as the two cases above did then
    "pretrained_berlin_fleet_v1_4taxis": Case(
        "berlin_fleet", {"num_taxis": 4, "separation": "none"}, policy="berlin_fleet_v1", steps=100
    ),
    "pretrained_berlin_fleet_v1_2taxis": Case(
        "berlin_fleet", {"num_taxis": 2, "separation": "none"}, policy="berlin_fleet_v1", steps=50
    ),
    "pretrained_berlin_fleet4": Case(
        "berlin_fleet", {"num_taxis": 4, "separation": "none"}, policy="berlin_fleet4", steps=40
    ),
}
"""The rollouts hashed. The *_fleet presets' cases pin ``separation="none"``: the shield (on in those presets since
issue 21) must leave a config without it exactly as before."""


class _Streams:
    """One sha256 per named stream; arrays enter with their dtype and shape, so a cast or reshape shows."""

    def __init__(self) -> None:
        self.hashes: dict[str, Any] = {}

    def add(self, name: str, value: np.ndarray) -> None:
        value = np.ascontiguousarray(value)
        h = self.hashes.setdefault(name, hashlib.sha256())
        h.update(f"{value.dtype.str}{value.shape}".encode())
        h.update(value.tobytes())

    def digests(self) -> dict[str, str]:
        return {k: h.hexdigest() for k, h in sorted(self.hashes.items())}


def _random_policy(seed: int) -> Callable[[dict[str, np.ndarray]], np.ndarray]:
    rng = np.random.default_rng(seed)

    def act(obs: dict[str, np.ndarray]) -> np.ndarray:
        scores = rng.random(obs["action_mask"].shape)  # [E, A, 16]
        return np.where(obs["action_mask"] > 0, scores, -1.0).argmax(-1)

    return act


def rollout_hashes(case: Case) -> dict[str, str]:
    """The hashes of one case: ``obs/<field>``, ``state``, ``actions``, ``rewards``, ``ends``."""
    import uamfleet
    from uamfleet.env.vector_env import VectorEnv

    cfg = uamfleet.make_config(case.scenario, **case.overrides)
    policy: Callable[[dict[str, np.ndarray]], np.ndarray]
    if case.policy == "random":
        policy = _random_policy(case.seed)
        env = VectorEnv(cfg, num_envs=case.num_envs)
        obs, _ = env.reset(seed=case.seed)
    else:  # the world as written, observed as the checkpoint's spec says; the policy fits itself to it
        shipped = uamfleet.pretrained(case.policy)
        env = VectorEnv(cfg, num_envs=case.num_envs, observer=shipped.spec)
        obs, _ = env.reset(seed=case.seed)
        shipped.reset(env.sim)
        policy = shipped
    streams = _Streams()
    for _ in range(case.steps):
        for key in sorted(obs):
            streams.add(f"obs/{key}", obs[key])
        streams.add("state", env.global_state())
        actions = np.asarray(policy(obs), np.int64)
        obs, rewards, terminated, truncated, _ = env.step(actions)
        streams.add("actions", actions)
        streams.add("rewards", rewards)
        streams.add("ends", np.stack([terminated, truncated]))
    return streams.digests()


def all_hashes(names: list[str] | None = None) -> dict[str, dict[str, str]]:
    return {name: rollout_hashes(CASES[name]) for name in names or CASES}


if __name__ == "__main__":
    if sys.argv[1:] != ["--write"]:
        sys.exit("usage: python tests/fingerprint.py --write   (rewrites tests/fingerprint.json)")
    FIXTURE.write_text(json.dumps(all_hashes(), indent=1, sort_keys=True) + "\n")
    print(f"wrote {FIXTURE}")
