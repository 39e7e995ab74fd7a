"""The batched simulator: E independent worlds of A taxis each, stepped together; it computes no observation.

:class:`Simulator` wires the generator, the dynamics and the reward: ``reset(seed)`` draws every env's instance
and returns the state, ``step(actions)`` moves every taxi and returns the rewards, the episode ends and the step's
information. The faces (:class:`uamfleet.env.vector_env.VectorEnv`, the PettingZoo env) add an observer on top.

Autoreset (``autoreset=True``, the default): an env that terminates or truncates is drawn anew inside the same
``step`` call, after its episode statistics are taken (``info["episode"]``, valid where ``info["_episode"]`` is
True). A face that observes the finished state first calls :meth:`Simulator.advance` (the step without the
reset), observes, then :meth:`Simulator.end_episodes`; :meth:`Simulator.step` is the two calls back to back.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium import spaces

from uamfleet.checks import MAX_ENVS, MAX_SEED, check_flag, check_integer
from uamfleet.config import REWARD_TERMS, EnvConfig, RewardConfig
from uamfleet.sim import dynamics, generator, motion, reward
from uamfleet.sim.pretyped import PreTyped
from uamfleet.sim.world import World
from uamfleet.types import (
    DELIVERED,
    HIDDEN,
    ON_BOARD,
    STATE_PASSENGER_FEATURES,
    STATE_TAXI_FEATURES,
    STATE_TAXI_INDEX,
    WAITING,
    FleetState,
    StepEvents,
)

__all__ = ["Simulator", "global_state", "global_state_size"]


class Simulator:
    """Batched fleet simulator (no observation).

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
        self._step_kernel = PreTyped(motion.step)  # the step without numba typing the state on every call
        # advance(events=False): the events arrays it reuses and its pre-typed motion.step_into, made by its first
        # call (a core that always returns events never compiles or allocates them)
        self._scratch: StepEvents | None = None
        self._scratch_kernel: PreTyped | None = None
        self.source = generator.InstanceSource(self.world)
        self.single_action_space = spaces.Discrete(cfg.num_actions)  # 16 headings (+ the hover, cfg.hover_action)
        self.state_size = global_state_size(cfg)
        self.state_space = spaces.Box(-np.inf, np.inf, (self.state_size,), np.float32)
        self.state: FleetState = generator.allocate_state(self.world, self.num_envs)
        self.rngs: list[np.random.Generator] = []
        self.episode_terms = np.zeros((self.num_envs, self.num_taxis, len(REWARD_TERMS)))
        self.needs_reset = True
        # Phi of the shaping term; "path" looks distances up in the world's table (rows filled per new stop).
        self.potential = reward.Potential(self.world, cfg.reward.shaping_metric) if cfg.reward.shaping > 0 else None

    # ---- reset ---------------------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> FleetState:
        """Draw every env's instance (env e from ``seed + e``) and return the state."""
        if seed is None:
            # Gymnasium semantics: without a seed, continue the generators of the last seeded reset.
            if not self.rngs:
                self.rngs = [np.random.default_rng(s) for s in np.random.SeedSequence().spawn(self.num_envs)]
        else:
            seed = check_integer("seed", seed, 0, MAX_SEED, fix=" (or None: continue the last seeded generators)")
            self.rngs = [np.random.default_rng(seed + e) for e in range(self.num_envs)]
        for e in range(self.num_envs):
            self.reset_env(e)
        self.needs_reset = False
        return self.state

    def reset_env(self, e: int) -> None:
        """Draw env e's next instance from its generator into the state."""
        starts, requests = self.source.draw(self.rngs[e])
        generator.write_instance(self.state, e, self.world, starts, requests)
        self.episode_terms[e] = 0.0

    # ---- step ----------------------------------------------------------------------------------------
    def step(self, actions: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Advance all envs and end the finished episodes (:meth:`advance`, then :meth:`end_episodes`)."""
        rewards, terminated, truncated, info = self.advance(actions)
        if "_episode" in info:  # terminated | truncated, there when an episode ended
            self.end_episodes(info["_episode"])
        return rewards, terminated, truncated, info

    def advance(
        self, actions: np.ndarray, events: bool = True
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """Move all envs one step, finished ones left as they ended. ``actions`` [E, A] int headings. Returns
        rewards [E, A], terminated [E], truncated [E], info (``reward_terms`` [E, A, T], ``events``, and where an
        episode ended ``_episode`` [E] and ``episode``, its statistics). ``events=False``: info holds no
        ``events`` (the step writes them into arrays of the simulator's own, which every such step reuses: a
        face that returns none, the PettingZoo env, saves making them)."""
        if self.needs_reset:
            raise RuntimeError("step() called before reset() (or after an episode ended with autoreset=False).")
        actions = dynamics.check_actions(actions, self.num_envs, self.num_taxis, self.cfg.num_actions)
        state, weights = self.state, self.cfg.reward
        phi_before = None if self.potential is None else self.potential(state)

        if events:
            step_events = dynamics.step(state, actions, self.world, self._step_kernel)
        else:
            if self._scratch is None or self._scratch_kernel is None:
                self._scratch = motion.new_events(state, np.zeros_like(actions))
                self._scratch_kernel = PreTyped(motion.step_into)
            step_events = dynamics.step(state, actions, self.world, self._scratch_kernel, into=self._scratch)
        # [E]; a copy where the arrays are the simulator's (the caller may keep it past the next step)
        terminated = step_events.all_delivered if events else step_events.all_delivered.copy()
        truncated = (state.t >= self.cfg.time_limit_steps) > terminated  # on bools, a > b is a & ~b: one call less
        if self.cfg.max_block_visits is not None:
            truncated |= np.any(step_events.block_visits > self.cfg.max_block_visits, axis=1) & ~terminated

        shaping_values = None
        if self.potential is not None and phi_before is not None:
            phi_after = self.potential(state)
            shaping_values = reward.shaping_term(phi_before, phi_after, terminated, weights)
        terms = reward.reward_terms(step_events, weights, shaping_values)  # [E, A, T]
        self.episode_terms += terms
        rewards = reward.total_reward(terms)

        info: dict[str, Any] = {"reward_terms": terms}
        if events:
            info["events"] = step_events
        # count_nonzero, not any(): any()'s call overhead is several times larger on the few values of a step
        if np.count_nonzero(terminated) or np.count_nonzero(truncated):
            info["_episode"] = terminated | truncated
            info["episode"] = self.episode_stats()
        return rewards, terminated, truncated, info

    def end_episodes(self, done: np.ndarray) -> np.ndarray:
        """End the episodes of the envs where ``done`` [E] is True: with autoreset each draws its next instance,
        else the simulator needs a :meth:`reset` before the next step. Returns the indices of the envs reset."""
        if not self.autoreset:
            self.needs_reset = True
            return np.zeros(0, np.int64)
        done_envs = np.nonzero(done)[0]
        for e in done_envs:
            self.reset_env(int(e))
        return done_envs

    def episode_stats(self) -> dict[str, np.ndarray]:
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
        """[E, S] global state for centralised critics (:func:`global_state`)."""
        return global_state(self.world, self.state)


def global_state_size(cfg: EnvConfig) -> int:
    """S, the length of one env's global state: the taxis, the passenger rows and the time."""
    taxi_size, pax_size = len(STATE_TAXI_FEATURES), len(STATE_PASSENGER_FEATURES)
    return cfg.num_taxis * taxi_size + cfg.num_passengers * pax_size + 1  # + time


def global_state(world: World, state: FleetState) -> np.ndarray:
    """[E, S] float32 global state for centralised critics: taxis (x, y, seats, time in episode) and the
    released passengers (origin, destination, status one-hot, carrier); unreleased rows are zero."""
    side, cfg = world.side_m, world.cfg
    E, A = state.num_envs, state.num_taxis
    taxis = np.concatenate(
        [state.pos_m / side, (state.free_seats / cfg.seats)[..., None], np.zeros((E, A, 1))], axis=-1
    )  # [E, A, STATE_TAXI_FEATURES]; last column: taxi index / A tells the taxis apart
    taxis[..., STATE_TAXI_INDEX] = np.arange(A) / A
    status = state.pax_status
    visible = ((status != HIDDEN) & state.pax_exists)[..., None]
    pax = (
        np.concatenate(
            [
                state.pax_origin_m / side,
                state.pax_dest_m / side,
                status[..., None] == np.array([WAITING, ON_BOARD, DELIVERED]),
                ((state.pax_taxi + 1) / A)[..., None],
                ((state.t[:, None] - state.pax_release) / cfg.time_limit_steps)[..., None],
            ],
            axis=-1,
        )
        * visible
    )  # [E, P, STATE_PASSENGER_FEATURES]
    time = np.minimum(state.t / cfg.time_limit_steps, 1.0)[:, None]
    return np.concatenate([taxis.reshape(E, -1), pax.reshape(E, -1), time], axis=-1).astype(np.float32)
