"""Several batched cores of one observation layout stepped as one: e.g. one per SINR threshold.

A :class:`~uamfleet.env.vector_env.VectorEnv` has one world (one map at one threshold). A policy meant for any
threshold trains on a mixture: :class:`MixtureVectorEnv` splits its ``num_envs`` envs into contiguous groups,
one :class:`VectorEnv` per config, and concatenates their observations, rewards and episode statistics along the
env axis, so the trainer sees one ``[E, A, ...]`` core. Each env keeps its group's config for the whole run; with
the envs spread evenly over the configs, every batch holds each config in the same share (the "threshold drawn
per episode" of a single env, in expectation, without rebuilding a world per episode).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from uamfleet.config import EnvConfig, RewardConfig
from uamfleet.env.vector_env import VectorEnv


class MixtureVectorEnv:
    """``num_envs`` envs over ``cfgs`` (group g: envs ``bounds[g]:bounds[g + 1]``, sizes as equal as possible).

    Every config must give the same observation space and fleet size (e.g. the same scenario at several
    thresholds); ``reset(seed)`` seeds global env e with ``seed + e`` as :class:`VectorEnv` does."""

    def __init__(self, cfgs: Sequence[EnvConfig], num_envs: int) -> None:
        cfgs = list(cfgs)
        if not cfgs:
            raise ValueError("MixtureVectorEnv needs at least one EnvConfig.")
        if int(num_envs) != num_envs or num_envs < len(cfgs):
            raise ValueError(
                f"num_envs={num_envs!r} must be an integer >= the {len(cfgs)} configs (one env each at least)."
            )
        sizes = [num_envs // len(cfgs) + (g < num_envs % len(cfgs)) for g in range(len(cfgs))]
        self.envs = [VectorEnv(cfg, num_envs=n) for cfg, n in zip(cfgs, sizes, strict=True)]
        self.bounds = np.concatenate([[0], np.cumsum(sizes)])
        first = self.envs[0]
        for cfg, env in zip(cfgs[1:], self.envs[1:], strict=True):
            if env.single_observation_space != first.single_observation_space or env.num_taxis != first.num_taxis:
                raise ValueError(
                    f"config {cfg.scenario!r} at {cfg.sinr_min_db:g} dB has another observation layout or fleet size "
                    f"than {cfgs[0].scenario!r} at {cfgs[0].sinr_min_db:g} dB; a mixture needs one layout "
                    "(same num_taxis, max_passengers, patch_size, history_len, stop_features)."
                )
        self.cfgs = cfgs
        self.cfg = cfgs[0]  # the reward weights and layout shared by all groups
        self.num_envs = int(num_envs)
        self.num_taxis = first.num_taxis
        self.single_observation_space = first.single_observation_space
        self.single_action_space = first.single_action_space
        self.state_space = first.state_space

    def reset(self, seed: int | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        parts = [
            env.reset(seed=None if seed is None else int(seed) + int(lo))[0]
            for env, lo in zip(self.envs, self.bounds, strict=False)
        ]
        return _cat(parts), {}

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """As :meth:`VectorEnv.step`; ``final_obs`` / ``episode`` hold every env (read them where ``_episode``)."""
        actions = np.asarray(actions)
        if actions.shape[:1] != (self.num_envs,):
            raise ValueError(f"actions has shape {actions.shape}, expected ({self.num_envs}, {self.num_taxis}).")
        groups = zip(self.envs, self.bounds[:-1], self.bounds[1:], strict=True)
        results = [env.step(actions[lo:hi]) for env, lo, hi in groups]
        obs = _cat([r[0] for r in results])
        rewards, terminated, truncated = (np.concatenate([r[i] for r in results]) for i in (1, 2, 3))
        info: dict[str, Any] = {"reward_terms": np.concatenate([r[4]["reward_terms"] for r in results])}
        done = terminated | truncated
        if done.any():
            info["_episode"] = done
            # groups without a finished episode contribute placeholders (their rows are not read)
            info["final_obs"] = _cat([r[4].get("final_obs", r[0]) for r in results])
            stats = [r[4].get("episode") for r in results]
            template = next(s for s in stats if s is not None)
            info["episode"] = {
                key: np.concatenate(
                    [s[key] if s is not None else np.zeros((hi - lo, *v.shape[1:]), v.dtype)
                     for s, lo, hi in zip(stats, self.bounds[:-1], self.bounds[1:], strict=True)]
                )
                for key, v in template.items()
            }  # fmt: skip
        return obs, rewards, terminated, truncated, info

    def set_reward_weights(self, weights: RewardConfig) -> None:
        for env in self.envs:
            env.set_reward_weights(weights)
        self.cfg = self.cfg.replace(reward=weights)

    def global_state(self) -> np.ndarray:
        return np.concatenate([env.global_state() for env in self.envs])


def _cat(parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
    return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
