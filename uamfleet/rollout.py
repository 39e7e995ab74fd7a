"""Run policies through the batched core and keep what happened (events), for metrics and viewers."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, Protocol

import numpy as np

from uamfleet.env.vector_env import VectorEnv
from uamfleet.types import StepEvents


class Policy(Protocol):
    """Maps a batch of observations ``{name: [E, A, ...]}`` to headings [E, A]."""

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray: ...


class RandomPolicy:
    """Uniform over the allowed headings of each taxi (uniform over all 16 when none is allowed)."""

    def __init__(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        mask = obs["action_mask"].astype(bool)  # [E, A, 16]
        mask = np.where(mask.any(-1, keepdims=True), mask, True)
        scores = self.rng.random(mask.shape) * mask  # the max over allowed entries is uniform among them
        return np.argmax(scores, axis=-1)


@dataclass
class Trajectory:
    """One episode of env 0 of a core: the initial positions and every step's events and rewards."""

    start_pos_m: np.ndarray  # [A, 2]
    events: list[StepEvents] = field(default_factory=list)
    rewards: list[np.ndarray] = field(default_factory=list)  # each [A]
    episode: dict[str, Any] = field(default_factory=dict)
    terminated: bool = False
    truncated: bool = False

    @property
    def positions_m(self) -> np.ndarray:
        """[A, T + 1, 2] positions from the start to the last step."""
        steps = [e.pos_m[0] for e in self.events]
        return np.stack([self.start_pos_m, *steps], axis=1)


def run_episode(
    env: VectorEnv,
    policy: Policy | Callable[[dict[str, np.ndarray]], np.ndarray],
    seed: int | None = None,
) -> Trajectory:
    """Play one episode of a one-env core (``num_envs == 1``, ``autoreset=False``) and record it."""
    if env.num_envs != 1 or env.autoreset:
        raise ValueError(
            f"run_episode needs VectorEnv(cfg, num_envs=1, autoreset=False); got num_envs={env.num_envs}, "
            f"autoreset={env.autoreset}."
        )
    obs, _ = env.reset(seed=seed)
    traj = Trajectory(start_pos_m=env.state.pos_m[0].copy())
    while True:
        obs, rewards, terminated, truncated, info = env.step(policy(obs))
        traj.events.append(info["events"])
        traj.rewards.append(rewards[0])
        if terminated[0] or truncated[0]:
            traj.episode = {k: v[0] for k, v in info["episode"].items()}
            traj.terminated, traj.truncated = bool(terminated[0]), bool(truncated[0])
            return traj
