"""Run policies through the batched core and keep what happened (events), for metrics and viewers."""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from uamfleet.config import EnvConfig
from uamfleet.env.protocol import Policy, observer_of
from uamfleet.env.vector_env import VectorEnv
from uamfleet.types import StepEvents


@dataclass
class Trajectory:
    """One episode of a one-env core: the instance, and every step's events, rewards and decision latency.

    Everything a metric or a viewer needs is here (never the simulator itself).
    """

    scenario: str
    radio_name: str
    sinr_min_db: float
    step_m: float
    slot_s: float
    seats: int
    start_pos_m: np.ndarray  # [A, 2]
    pax_exists: np.ndarray  # [P] bool
    release_step: np.ndarray  # [P] int
    origin_m: np.ndarray  # [P, 2]
    destination_m: np.ndarray  # [P, 2]
    events: list[StepEvents] = field(default_factory=list)
    rewards: list[np.ndarray] = field(default_factory=list)  # each [A]
    decision_s: list[float] = field(default_factory=list)  # wall time of each policy call
    episode: dict[str, Any] = field(default_factory=dict)
    terminated: bool = False
    truncated: bool = False

    @property
    def num_steps(self) -> int:
        return len(self.events)

    @property
    def positions_m(self) -> np.ndarray:
        """[A, T + 1, 2] positions from the start to the last step."""
        return np.stack([self.start_pos_m, *[e.pos_m[0] for e in self.events]], axis=1)

    def stacked(self, name: str) -> np.ndarray:
        """[T, ...] one event field of env 0 over the episode (e.g. ``"moved"`` -> [T, A])."""
        return np.stack([getattr(e, name)[0] for e in self.events])


def fly(
    cfg: EnvConfig, policy: Policy | Callable[[dict[str, np.ndarray]], np.ndarray], seed: int | None = 0
) -> Trajectory:
    """One recorded episode of ``policy`` in a fresh one-env core of ``cfg``, observed as the policy reads it (its
    :class:`~uamfleet.observe.spec.ObserverSpec` ``spec``, :class:`~uamfleet.env.protocol.Policy`; none: the
    config's own observer). The world is flown as given; a spec that cannot read it is refused in one line."""
    return run_episode(VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy)), policy, seed=seed)


def run_episode(
    env: VectorEnv,
    policy: Policy | Callable[[dict[str, np.ndarray]], np.ndarray],
    seed: int | None = None,
) -> Trajectory:
    """Play one episode of a one-env core (``num_envs == 1``, ``autoreset=False``) and record it: ``policy.reset``
    with the simulator (:class:`~uamfleet.env.protocol.Policy`; a plain function of the observation has none), then
    ``policy.act`` at every step."""
    if env.num_envs != 1 or env.autoreset:
        raise ValueError(
            f"run_episode needs VectorEnv(cfg, num_envs=1, autoreset=False); got num_envs={env.num_envs}, "
            f"autoreset={env.autoreset}."
        )
    obs, _ = env.reset(seed=seed)
    reset = getattr(policy, "reset", None)
    if callable(reset):
        reset(env.sim)
    act = getattr(policy, "act", policy)
    cfg, s = env.cfg, env.state
    traj = Trajectory(
        scenario=cfg.scenario,
        radio_name=cfg.radio.label,
        sinr_min_db=cfg.sinr_min_db,
        step_m=cfg.step_m,
        slot_s=cfg.slot_s,
        seats=cfg.seats,
        start_pos_m=s.pos_m[0].copy(),
        pax_exists=s.pax_exists[0].copy(),
        release_step=s.pax_release[0].copy(),
        origin_m=s.pax_origin_m[0].copy(),
        destination_m=s.pax_dest_m[0].copy(),
    )
    while True:
        start = time.perf_counter()
        actions = act(obs)
        traj.decision_s.append(time.perf_counter() - start)
        obs, rewards, terminated, truncated, info = env.step(actions)
        traj.events.append(info["events"])
        traj.rewards.append(rewards[0])
        if terminated[0] or truncated[0]:
            traj.episode = {k: v[0] for k, v in info["episode"].items()}
            traj.terminated, traj.truncated = bool(terminated[0]), bool(truncated[0])
            return traj
