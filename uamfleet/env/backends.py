"""One constructor for the batched training envs, whatever steps them: :func:`make_vector`.

Three backends step ``num_envs`` envs over one or several configs and show one interface
(:class:`VectorBackend`), so a collector or a loop never asks which it holds:

- ``"inline"`` (:class:`InlineVectorEnv`): one config, every env stepped on the calling thread (a
  :class:`~uamfleet.env.vector_env.VectorEnv`);
- ``"mixture"`` (:class:`~uamfleet.env.mixture.MixtureVectorEnv`): one group of envs per config (e.g. SINR
  thresholds, fleet sizes), in this process, smaller fleets padded to the largest;
- ``"workers"`` (:class:`~uamfleet.env.workers.ShardedVectorEnv`): the mixture's envs stepped by worker processes,
  one core each (configs of one fleet size);
- ``"auto"``: ``"workers"`` with ``workers >= 1``, else ``"mixture"`` with several configs, else ``"inline"``.

Global env e is reset with ``seed + e`` by every backend, so the three run the same episodes.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any, Protocol, runtime_checkable

import numpy as np
from gymnasium import spaces

from uamfleet.config import ConfigError, EnvConfig, RewardConfig
from uamfleet.env.mixture import MixtureVectorEnv
from uamfleet.env.vector_env import VectorEnv
from uamfleet.env.workers import ShardedVectorEnv
from uamfleet.observe.legacy import observed_config
from uamfleet.observe.spec import ObserverSpec
from uamfleet.paths import table_for
from uamfleet.paths.distance_table import cache_dir
from uamfleet.sim.world import World

BACKENDS: tuple[str, ...] = ("auto", "inline", "mixture", "workers")
"""The names :func:`make_vector` takes (``auto``: chosen from the configs and the workers)."""


@runtime_checkable
class VectorBackend(Protocol):
    """What a collector reads of its training envs, whichever backend steps them.

    ``step(actions [E, A])`` returns obs (each field [E, A, ...]), rewards [E, A], terminated [E], truncated [E] and
    info with ``reward_terms`` [E, A, T] and, where an episode ended, ``_episode``, ``episode`` and ``final_obs``
    for every env (read them where ``_episode``). ``A`` is :attr:`num_taxis`, the largest fleet's; env e's own taxis
    are its first ``taxis_per_env[e]`` columns, the others padding (only when :attr:`mixed_sizes`)."""

    @property
    def num_envs(self) -> int: ...

    @property
    def num_taxis(self) -> int: ...

    @property
    def taxis_per_env(self) -> np.ndarray:
        """[E] each env's own fleet size."""
        ...

    @property
    def mixed_sizes(self) -> bool:
        """Whether some env flies a smaller fleet than :attr:`num_taxis` (its extra columns are padding)."""
        ...

    @property
    def envs(self) -> list[VectorEnv]:
        """The in-process envs whose tables a caller may fill (none where workers hold them)."""
        ...

    @property
    def cfg(self) -> EnvConfig: ...

    @property
    def single_observation_space(self) -> spaces.Dict: ...

    @property
    def single_action_space(self) -> spaces.Discrete: ...

    @property
    def state_space(self) -> spaces.Box | None: ...

    def reset(self, seed: int | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]: ...

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]: ...

    def global_state(self) -> np.ndarray: ...

    def set_reward_weights(self, weights: RewardConfig) -> None: ...

    def close(self) -> None: ...


class InlineVectorEnv(VectorEnv):
    """The inline backend: a :class:`~uamfleet.env.vector_env.VectorEnv` of one config, with the backend interface
    (every env flies the config's fleet; :attr:`envs` is itself; :meth:`close` has nothing to stop)."""

    @property
    def taxis_per_env(self) -> np.ndarray:
        return np.full(self.num_envs, self.num_taxis)

    @property
    def mixed_sizes(self) -> bool:
        return False

    @property
    def envs(self) -> list[VectorEnv]:
        return [self]

    def close(self) -> None:
        pass


def resolve_backend(backend: str, num_configs: int, workers: int) -> str:
    """The backend ``backend`` names for ``num_configs`` configs and ``workers`` worker processes (``auto``
    resolved); ConfigError in one line for an unknown name or one that contradicts the configs or the workers."""
    if backend not in BACKENDS:
        raise ConfigError(f"backend={backend!r} is unknown; use one of {list(BACKENDS)}.")
    if backend == "auto":
        return "workers" if workers else "mixture" if num_configs > 1 else "inline"
    if backend == "workers" and not workers:
        raise ConfigError("backend='workers' steps the envs in worker processes; give workers >= 1 (or backend auto).")
    if backend != "workers" and workers:
        raise ConfigError(
            f"backend={backend!r} steps the envs in this process, but workers={workers} asks for worker processes; "
            "use backend 'workers' (or auto), or workers=0."
        )
    if backend == "inline" and num_configs > 1:
        raise ConfigError(
            f"backend='inline' steps one config, not {num_configs}; use backend 'mixture' (or auto) for several."
        )
    return backend


def make_vector(
    cfgs: EnvConfig | Sequence[EnvConfig], num_envs: int, backend: str = "auto", *, workers: int = 0,
    global_state: bool = False, fill_tables: bool = False, copy: bool = True, observer: ObserverSpec | None = None,
) -> VectorBackend:  # fmt: skip
    """``num_envs`` envs over ``cfgs`` (one config or a list: one group of envs each), stepped by ``backend``
    (module docstring; ``workers`` processes for ``"workers"``), each observed by ``observer`` (an
    :class:`~uamfleet.observe.spec.ObserverSpec`; None: each config's own observer fields). The worlds are the
    configs' own: a spec that cannot read one raises :class:`~uamfleet.config.ConfigError` in one line.

    ``fill_tables``: every env's feasible-path distance tables computed now (or loaded from the disk cache) instead
    of a few Dijkstras per new episode; worker processes load them from the disk cache, filled here once.
    ``global_state`` and ``copy`` are the workers' (:class:`~uamfleet.env.workers.ShardedVectorEnv`); the in-process
    backends always keep a global state and return fresh observations."""
    cfgs = [cfgs] if isinstance(cfgs, EnvConfig) else list(cfgs)
    chosen = resolve_backend(backend, len(cfgs), workers)
    if chosen == "workers":
        if fill_tables and cache_dir() is not None:  # without a disk cache each worker fills its own
            for cfg in cfgs:
                table_for(World(observed_config(cfg, observer)[0])).fill()
        return ShardedVectorEnv(
            cfgs, num_envs, workers, global_state=global_state, fill_tables=fill_tables, copy=copy, observer=observer
        )
    venv: VectorBackend
    if chosen == "inline":
        venv = InlineVectorEnv(cfgs[0], num_envs=num_envs, observer=observer)
    else:
        venv = MixtureVectorEnv(cfgs, num_envs=num_envs, observer=observer)
    if fill_tables:
        for env in venv.envs:
            table_for(env.world).fill()
    return venv


__all__ = ["BACKENDS", "InlineVectorEnv", "VectorBackend", "make_vector", "resolve_backend"]
