"""The batched environment: E independent envs of A taxis each, one policy call per step for all.

:class:`VectorEnv` is a :class:`uamfleet.sim.core.Simulator` (the world, its rules and reward) with an
:class:`~uamfleet.observe.observer.Observer` (what a policy reads) on top; the PettingZoo env is this class with E = 1.

Autoreset (``autoreset=True``, the default): an env that terminates or truncates is reset *within the same*
``step`` call; the returned observation is the first one of its new episode, and the last observation of the
finished episode is in ``info["final_obs"]`` (valid where ``info["_episode"]`` is True), together with the
episode statistics in ``info["episode"]``. This is Gymnasium's ``SAME_STEP`` autoreset mode, which PPO needs
to bootstrap truncated episodes from their real final observation.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from uamfleet.config import EnvConfig, RewardConfig, WorldConfig
from uamfleet.observe.legacy import observed_config
from uamfleet.observe.observer import Observer
from uamfleet.observe.spec import ObserverSpec
from uamfleet.sim.core import Simulator
from uamfleet.sim.pretyped import PreTyped
from uamfleet.sim.reward import Potential
from uamfleet.sim.world import World
from uamfleet.types import FleetState


class VectorEnv:
    """Batched fleet environment: the simulator ``self.sim`` and the observer ``self.observer``.

    Args:
        cfg: the world (a :class:`~uamfleet.config.WorldConfig`), or the world and its observer fields in one
            :class:`~uamfleet.config.EnvConfig` (see :func:`uamfleet.presets.make_config`).
        num_envs: number E of independent envs stepped together, 1 ... :data:`~uamfleet.checks.MAX_ENVS` (65,536).
        autoreset: ``True`` / ``False``: reset finished envs inside ``step`` (see the module docstring).
        observer: what each taxi observes (:class:`~uamfleet.observe.spec.ObserverSpec`); None: the observer
            fields of an ``EnvConfig``, or ``ObserverSpec()`` for a bare world. A spec that cannot read the world
            raises :class:`~uamfleet.config.ConfigError` with :meth:`~uamfleet.observe.spec.ObserverSpec.reads`'s
            line; ``self.cfg`` is then the world joined with the spec
            (:func:`uamfleet.observe.legacy.observed_config`).

    ``reset(seed)`` (an integer 0 ... :data:`~uamfleet.checks.MAX_SEED`, or None) seeds env e with ``seed + e``
    (Gymnasium's vector convention), so env e here and a PettingZoo env reset with ``seed + e`` run the same
    episodes. The simulator's attributes (``state``, ``cfg``, ``world``, ``rngs``, ``episode_terms``, ...) read
    through.
    """

    def __init__(
        self, cfg: WorldConfig, num_envs: int = 1, autoreset: bool = True, observer: ObserverSpec | None = None
    ) -> None:
        cfg, spec = observed_config(cfg, observer)
        self.sim = Simulator(cfg, num_envs, autoreset)
        self.observer = Observer(self.sim.world, spec)
        self.spec = spec  # what each taxi observes
        self.layout = self.observer.layout  # the observation's spec (uamfleet.observe.spec): fields, shapes, kinds
        self.single_observation_space: spaces.Dict = self.observer.observation_space
        self.single_action_space = self.sim.single_action_space
        self.state_space = self.sim.state_space

    # ---- the simulator's attributes ------------------------------------------------------------------
    @property
    def num_envs(self) -> int:
        return self.sim.num_envs

    @property
    def num_taxis(self) -> int:
        return self.sim.num_taxis

    @property
    def autoreset(self) -> bool:
        return self.sim.autoreset

    @property
    def cfg(self) -> EnvConfig:
        return self.sim.cfg

    @property
    def world(self) -> World:
        return self.sim.world

    @property
    def state(self) -> FleetState:
        return self.sim.state

    @property
    def rngs(self) -> list[np.random.Generator]:
        return self.sim.rngs

    @property
    def episode_terms(self) -> np.ndarray:
        return self.sim.episode_terms

    @property
    def needs_reset(self) -> bool:
        return self.sim.needs_reset

    @property
    def potential(self) -> Potential | None:
        return self.sim.potential

    @property
    def _step_kernel(self) -> PreTyped:
        return self.sim._step_kernel

    # ---- reset ---------------------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        return self.observer.observe(self.sim.reset(seed)), {}

    # ---- step ----------------------------------------------------------------------------------------
    def step(
        self, actions: np.ndarray, events: bool = True
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Advance all envs. ``actions`` [E, A] int headings. Returns obs, rewards [E, A], terminated [E],
        truncated [E], info (``reward_terms`` [E, A, T], ``events``, and at episode ends ``episode``,
        ``_episode``, ``final_obs``). ``events=False``: no ``events`` (:meth:`Simulator.advance
        <uamfleet.sim.core.Simulator.advance>`)."""
        rewards, terminated, truncated, info = self.sim.advance(actions, events)
        # observed before the finished envs are drawn anew: their last observation is the episode's final one
        obs = self.observer.observe(self.sim.state)
        done = info.get("_episode")  # terminated | truncated, there when an episode ended
        if done is not None:
            info["final_obs"] = {k: v.copy() for k, v in obs.items()}
            reset_envs = self.sim.end_episodes(done)
            if reset_envs.size:
                fresh = self.observer.observe(self.sim.state.take(reset_envs))
                for key, value in fresh.items():
                    obs[key][reset_envs] = value
        return obs, rewards, terminated, truncated, info

    def set_reward_weights(self, weights: RewardConfig) -> None:
        """Change the reward weights between steps (e.g. a shaping curriculum); the metric of the shaping
        potential is part of the env's geometry and cannot change."""
        self.sim.set_reward_weights(weights)

    # ---- views ---------------------------------------------------------------------------------------
    def global_state(self) -> np.ndarray:
        """[E, S] global state for centralised critics."""
        return self.sim.global_state()
