"""Several batched cores of one observation layout stepped as one: e.g. one per SINR threshold.

A :class:`~uamfleet.env.vector_env.VectorEnv` has one world (one map at one threshold). A policy meant for any
threshold trains on a mixture: :class:`MixtureVectorEnv` splits its ``num_envs`` envs into contiguous groups,
one :class:`VectorEnv` per config, and concatenates their observations, rewards and episode statistics along the
env axis, so the trainer sees one ``[E, A, ...]`` core. Each env keeps its group's config for the whole run; with
the envs spread evenly over the configs, every batch holds each config in the same share (the "threshold drawn
per episode" of a single env, in expectation, without rebuilding a world per episode).

The configs may also differ in fleet size (a policy for any fleet trains on a mixture of sizes): every env then
shows the largest fleet's ``A_max`` taxi columns. The columns past an env's own fleet
(:attr:`MixtureVectorEnv.taxi_mask` False) are padding: zero observations and rewards, their actions ignored;
and each taxi's other-taxi rows (:data:`OTHER_TAXI_FIELDS`, a set of ``A - 1`` rows) are padded to ``A_max - 1``
with masked rows, which a set encoder ignores (the network reads the other taxis by a masked mean), so a padded
taxi reads what it reads unpadded.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np

from gymnasium import spaces

from uamfleet.config import EnvConfig, RewardConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.observe.spec import ObserverSpec

OTHER_TAXI_FIELDS: tuple[str, ...] = ("others", "others_mask")
"""The observation fields whose rows are the other taxis (``max(A - 1, 1)`` rows, docs/rules.md "Observation"): the
only fields whose shape depends on the fleet size."""


def checked_configs(owner: str, cfgs: Sequence[EnvConfig], num_envs: int) -> list[EnvConfig]:
    """``cfgs`` as a list, refused (ValueError naming the fix) when empty or when ``num_envs`` cannot give each of them
    one env at least: the envs of a mixture, in process (``owner`` MixtureVectorEnv) or in workers."""
    cfgs = list(cfgs)
    if not cfgs:
        raise ValueError(f"{owner} needs at least one EnvConfig.")
    if int(num_envs) != num_envs or num_envs < len(cfgs):
        raise ValueError(
            f"num_envs={num_envs!r} must be an integer >= the {len(cfgs)} configs (one env each at least)."
        )
    return cfgs


def group_sizes(num_groups: int, num_envs: int) -> list[int]:
    """``num_envs`` envs split into ``num_groups`` contiguous groups as equal as possible, the first ones larger:
    a mixture's envs per config (and the env workers' shares of a rank's envs, :mod:`uamfleet.env.workers`)."""
    return [num_envs // num_groups + (g < num_envs % num_groups) for g in range(num_groups)]


class MixtureVectorEnv:
    """``num_envs`` envs over ``cfgs`` (group g: envs ``bounds[g]:bounds[g + 1]``, sizes as equal as possible).

    Every config must give the same observation layout up to the fleet size (e.g. the same scenario at several
    thresholds, fleet sizes or loads); configs of several fleet sizes are padded to the largest (module docstring).
    ``observer``: every group's envs observe by this spec (:class:`VectorEnv`'s ``observer``); None: each config's
    own. ``reset(seed)`` seeds global env e with ``seed + e`` as :class:`VectorEnv` does."""

    def __init__(self, cfgs: Sequence[EnvConfig], num_envs: int, observer: ObserverSpec | None = None) -> None:
        cfgs = checked_configs("MixtureVectorEnv", cfgs, num_envs)
        sizes = group_sizes(len(cfgs), num_envs)
        self.envs = [VectorEnv(cfg, num_envs=n, observer=observer) for cfg, n in zip(cfgs, sizes, strict=True)]
        self.bounds = np.concatenate([[0], np.cumsum(sizes)])
        largest = max(self.envs, key=lambda env: env.num_taxis)
        for cfg, env in zip(cfgs, self.envs, strict=True):
            if not _same_layout_but_fleet(env.single_observation_space, largest.single_observation_space):
                raise ValueError(
                    f"config {cfg.scenario!r} at {cfg.sinr_min_db:g} dB ({cfg.num_taxis} taxi(s)) has another "
                    f"observation layout than {largest.cfg.scenario!r} at {largest.cfg.sinr_min_db:g} dB "
                    f"({largest.num_taxis} taxi(s)); a mixture needs one layout up to the fleet size (the same "
                    "max_passengers or passenger_window, patch_size, history_len, stop fields)."
                )
        self.cfgs = cfgs
        self.cfg = cfgs[0]  # the reward weights shared by all groups
        self.num_envs = int(num_envs)
        self.num_taxis = largest.num_taxis  # taxi columns of every env: the largest fleet's
        self.taxis_per_env = np.repeat([env.num_taxis for env in self.envs], sizes)  # [E] each env's own fleet
        self.taxi_mask = np.arange(self.num_taxis)[None, :] < self.taxis_per_env[:, None]  # [E, A_max] real taxis
        self.mixed_sizes = bool((self.taxis_per_env != self.num_taxis).any())
        self.single_observation_space = largest.single_observation_space
        self.single_action_space = largest.single_action_space
        states = {env.state_space.shape for env in self.envs}
        # one global state size (None: the configs' states differ, e.g. other fleet sizes or passenger counts)
        self.state_space = self.envs[0].state_space if len(states) == 1 else None

    def reset(self, seed: int | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        parts = [
            env.reset(seed=None if seed is None else int(seed) + int(lo))[0]
            for env, lo in zip(self.envs, self.bounds, strict=False)
        ]
        return self._cat_obs(parts), {}

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        """As :meth:`VectorEnv.step`; ``final_obs`` / ``episode`` hold every env (read them where ``_episode``)."""
        actions = np.asarray(actions)
        if actions.shape[:1] != (self.num_envs,):
            raise ValueError(f"actions has shape {actions.shape}, expected ({self.num_envs}, {self.num_taxis}).")
        groups = zip(self.envs, self.bounds[:-1], self.bounds[1:], strict=True)
        results = [env.step(actions[lo:hi, : env.num_taxis]) for env, lo, hi in groups]
        obs = self._cat_obs([r[0] for r in results])
        rewards = np.concatenate([self._pad_taxis(r[1]) for r in results])
        terminated, truncated = (np.concatenate([r[i] for r in results]) for i in (2, 3))
        terms = np.concatenate([self._pad_taxis(r[4]["reward_terms"]) for r in results])
        info: dict[str, Any] = {"reward_terms": terms}
        done = terminated | truncated
        if done.any():
            info["_episode"] = done
            # groups without a finished episode contribute placeholders (their rows are not read)
            info["final_obs"] = self._cat_obs([r[4].get("final_obs", r[0]) for r in results])
            info["episode"] = self._cat_stats([r[4].get("episode") for r in results])
        return obs, rewards, terminated, truncated, info

    def set_reward_weights(self, weights: RewardConfig) -> None:
        for env in self.envs:
            env.set_reward_weights(weights)
        self.cfg = self.cfg.replace(reward=weights)

    def global_state(self) -> np.ndarray:
        if self.state_space is None:
            sizes = sorted({int(env.state_space.shape[0]) for env in self.envs})
            raise ValueError(
                f"the configs of this mixture have global states of {sizes} values (other fleet sizes or passenger "
                "counts): no one [E, S] state holds them; a critic of the mixture reads each taxi's own features."
            )
        return np.concatenate([env.global_state() for env in self.envs])

    def close(self) -> None:
        """Nothing to stop: the envs step in this process (the backend interface, :mod:`uamfleet.env.backends`)."""

    # ---- padding a mixture of fleet sizes to the largest -------------------------------------------------------

    def _pad_taxis(self, x: np.ndarray) -> np.ndarray:
        """A group's per-taxi array [E_g, A_g, ...] with zero columns up to [E_g, A_max, ...]; [E_g] unchanged."""
        if x.ndim < 2 or x.shape[1] == self.num_taxis:
            return x
        out = np.zeros((x.shape[0], self.num_taxis, *x.shape[2:]), x.dtype)
        out[:, : x.shape[1]] = x
        return out

    def _cat_stats(self, stats: list[dict[str, np.ndarray] | None]) -> dict[str, np.ndarray]:
        """The groups' episode statistics along the env axis, padded to A_max taxis; a group without a finished
        episode (None) gives zeros."""
        template = {key: self._pad_taxis(v) for key, v in next(s for s in stats if s is not None).items()}
        sizes = np.diff(self.bounds)
        return {
            key: np.concatenate([
                self._pad_taxis(s[key]) if s is not None else np.zeros((n, *v.shape[1:]), v.dtype)
                for s, n in zip(stats, sizes, strict=True)
            ])
            for key, v in template.items()
        }  # fmt: skip

    def _cat_obs(self, parts: list[dict[str, np.ndarray]]) -> dict[str, np.ndarray]:
        """The groups' observations along the env axis, each padded to A_max taxis and A_max - 1 other-taxi rows."""
        if not self.mixed_sizes:
            return {key: np.concatenate([p[key] for p in parts]) for key in parts[0]}
        out = {}
        for key, space in self.single_observation_space.spaces.items():
            full = np.zeros((self.num_envs, self.num_taxis, *(space.shape or ())), space.dtype)
            for part, lo in zip(parts, self.bounds[:-1], strict=False):
                value = part[key]  # [E_g, A_g, ...]; the other-taxi fields also A_g - 1 (or 1) rows
                envs, taxis = slice(lo, lo + value.shape[0]), slice(0, value.shape[1])
                if key in OTHER_TAXI_FIELDS:
                    full[envs, taxis, : value.shape[2]] = value
                else:
                    full[envs, taxis] = value
            out[key] = full
        return out


def _same_layout_but_fleet(space: spaces.Dict, largest: spaces.Dict) -> bool:
    """Whether two observation spaces are one layout up to the fleet size: the same fields and shapes, the
    other-taxi fields with at most the largest fleet's rows."""
    if space.spaces.keys() != largest.spaces.keys():
        return False
    for key, sub in space.spaces.items():
        big = largest.spaces[key]
        if key in OTHER_TAXI_FIELDS:
            small, large = sub.shape or (), big.shape or ()
            if not (small[1:] == large[1:] and small[:1] <= large[:1] and sub.dtype == big.dtype):
                return False
        elif sub != big:
            return False
    return True
