"""The batched environment core: E independent envs of A taxis each, one policy call per step for all.

This is the only place that wires generator, dynamics, reward and observer together; the PettingZoo env is
this class with E = 1.

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

from uamfleet.checks import MAX_ENVS, MAX_SEED, check_flag, check_integer
from uamfleet.config import REWARD_TERMS, EnvConfig, RewardConfig
from uamfleet.env.observer import Observer
from uamfleet.sim import dynamics, generator, motion, reward
from uamfleet.sim.pretyped import PreTyped
from uamfleet.sim.world import World
from uamfleet.types import DELIVERED, FleetState


class VectorEnv:
    """Batched fleet environment.

    Args:
        cfg: the environment config (see :func:`uamfleet.presets.make_config`).
        num_envs: number E of independent envs stepped together, 1 ... :data:`~uamfleet.checks.MAX_ENVS` (65,536).
        autoreset: ``True`` / ``False``: reset finished envs inside ``step`` (see the module docstring).

    ``reset(seed)`` (an integer 0 ... :data:`~uamfleet.checks.MAX_SEED`, or None) seeds env e with ``seed + e``
    (Gymnasium's vector convention), so env e here and a PettingZoo env reset with ``seed + e`` run the same
    episodes.
    """

    def __init__(self, cfg: EnvConfig, num_envs: int = 1, autoreset: bool = True) -> None:
        fix = " (every env is allocated up front; the bound is uamfleet.checks.MAX_ENVS)"
        self.num_envs = check_integer("num_envs", num_envs, 1, MAX_ENVS, fix=fix)
        self.autoreset = check_flag("autoreset", autoreset)
        self.cfg = cfg
        self.num_taxis = cfg.num_taxis
        self.world = World(cfg)
        self.observer = Observer(self.world)
        self._step_kernel = PreTyped(motion.step)  # the step without numba typing the state on every call
        self.source = generator.InstanceSource(self.world)
        self.layout = self.observer.layout  # the observation's spec (uamfleet.env.layout): fields, shapes, kinds
        self.single_observation_space: spaces.Dict = self.observer.observation_space
        self.single_action_space = spaces.Discrete(cfg.num_actions)  # 16 headings (+ the hover, cfg.hover_action)
        self.state_space = self.observer.state_space
        self.state: FleetState = generator.allocate_state(self.world, self.num_envs)
        self.rngs: list[np.random.Generator] = []
        self.episode_terms = np.zeros((self.num_envs, self.num_taxis, len(REWARD_TERMS)))
        self.needs_reset = True
        # Phi of the shaping term; "path" looks distances up in the world's table (rows filled per new stop).
        self.potential = reward.Potential(self.world, cfg.reward.shaping_metric) if cfg.reward.shaping > 0 else None

    # ---- reset ---------------------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        if seed is None:
            # Gymnasium semantics: without a seed, continue the generators of the last seeded reset.
            if not self.rngs:
                self.rngs = [np.random.default_rng(s) for s in np.random.SeedSequence().spawn(self.num_envs)]
        else:
            seed = check_integer("seed", seed, 0, MAX_SEED, fix=" (or None: continue the last seeded generators)")
            self.rngs = [np.random.default_rng(seed + e) for e in range(self.num_envs)]
        for e in range(self.num_envs):
            self._reset_env(e)
        self.needs_reset = False
        return self.observer.observe(self.state), {}

    def _reset_env(self, e: int) -> None:
        starts, requests = self.source.draw(self.rngs[e])
        generator.write_instance(self.state, e, self.world, starts, requests)
        self.episode_terms[e] = 0.0

    # ---- step ----------------------------------------------------------------------------------------
    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Advance all envs. ``actions`` [E, A] int headings. Returns obs, rewards [E, A], terminated [E],
        truncated [E], info (``reward_terms`` [E, A, T], ``events``, and at episode ends ``episode``,
        ``_episode``, ``final_obs``)."""
        if self.needs_reset:
            raise RuntimeError("step() called before reset() (or after an episode ended with autoreset=False).")
        actions = dynamics.check_actions(actions, self.num_envs, self.num_taxis, self.cfg.num_actions)
        state, weights = self.state, self.cfg.reward
        phi_before = None if self.potential is None else self.potential(state)

        events = dynamics.step(state, actions, self.world, self._step_kernel)
        terminated = events.all_delivered  # [E]
        truncated = (state.t >= self.cfg.time_limit_steps) & ~terminated
        if self.cfg.max_block_visits is not None:
            truncated |= np.any(events.block_visits > self.cfg.max_block_visits, axis=1) & ~terminated

        shaping_values = None
        if self.potential is not None and phi_before is not None:
            phi_after = self.potential(state)
            shaping_values = reward.shaping_term(phi_before, phi_after, terminated, weights)
        terms = reward.reward_terms(events, weights, shaping_values)  # [E, A, T]
        self.episode_terms += terms
        rewards = reward.total_reward(terms)

        obs = self.observer.observe(state)
        info: dict[str, Any] = {"reward_terms": terms, "events": events}
        done = terminated | truncated
        if done.any():
            info["_episode"] = done
            info["episode"] = self._episode_stats()
            info["final_obs"] = {k: v.copy() for k, v in obs.items()}
            if self.autoreset:
                self._autoreset(np.nonzero(done)[0], obs)
            else:
                self.needs_reset = True
        return obs, rewards, terminated, truncated, info

    def _autoreset(self, done_envs: np.ndarray, obs: dict[str, np.ndarray]) -> None:
        for e in done_envs:
            self._reset_env(int(e))
        fresh = self.observer.observe(self.state.take(done_envs))
        for key, value in fresh.items():
            obs[key][done_envs] = value

    def _episode_stats(self) -> dict[str, np.ndarray]:
        """Statistics of the episode that just ended, for every env (read them where ``_episode``)."""
        s = self.state
        delivered = np.sum(s.pax_status == DELIVERED, axis=1)
        num_requests = np.sum(s.pax_exists, axis=1)
        stats = {
            "return": reward.total_reward(self.episode_terms),  # [E, A]
            "length": s.t.copy(),  # [E]
            "delivered": delivered,  # [E]
            "num_requests": num_requests,  # [E]
            "service_rate": delivered / np.maximum(num_requests, 1),  # [E]
            "distance_m": s.distance_m.copy(),  # [E, A]
        }
        for i, name in enumerate(REWARD_TERMS):
            stats[f"reward/{name}"] = self.episode_terms[..., i].copy()  # [E, A]
        return stats

    def set_reward_weights(self, weights: RewardConfig) -> None:
        """Change the reward weights between steps (e.g. a shaping curriculum); the metric of the shaping
        potential is part of the env's geometry and cannot change."""
        if weights.shaping_metric != self.cfg.reward.shaping_metric or (weights.shaping > 0) != (
            self.cfg.reward.shaping > 0
        ):
            raise ValueError(
                "set_reward_weights may change weights only: shaping on/off and shaping_metric are fixed at "
                f"construction (was shaping={self.cfg.reward.shaping}, metric={self.cfg.reward.shaping_metric!r})."
            )
        self.cfg = self.cfg.replace(reward=weights)

    # ---- views ---------------------------------------------------------------------------------------
    def global_state(self) -> np.ndarray:
        """[E, S] global state for centralised critics."""
        return self.observer.state(self.state)
