"""The one ``Policy`` protocol: what rollout, the benchmarks, the viewer and the PettingZoo examples call.

A policy is reset with the simulator it acts in at the start of every episode, then acts on a batch of
observations::

    policy.reset(env.sim)            # the Simulator: state, cfg, world, num_envs, num_taxis
    actions = policy.act(obs)        # {name: [E, A, ...]} -> [E, A] int64 headings

``policy(obs)`` is ``policy.act(obs)``. Every policy :func:`uamfleet.policies.make` builds satisfies it
(``isinstance(policy, Policy)``). A search that rolls forward builds its own environment from ``sim.cfg``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any, Protocol, runtime_checkable

import numpy as np

from uamfleet.observe.spec import ObserverSpec

if TYPE_CHECKING:
    from uamfleet.sim.core import Simulator


@runtime_checkable
class Policy(Protocol):
    """Maps a batch of observations ``{name: [E, A, ...]}`` to headings [E, A] (int64).

    ``spec`` says what of the observation it reads (a learned policy: the
    :class:`~uamfleet.observe.spec.ObserverSpec` its checkpoint stores, to build its env with ``observer=spec``; a
    search wrapper: its base's); None for a policy that reads the simulator's state (planners, dispatchers) or
    nothing beyond the action mask every observation has."""

    spec: Any

    def reset(self, sim: Simulator) -> None:
        """A new episode in ``sim`` (already reset: its ``state`` holds the episode's start)."""
        ...

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """[E, A] int64 actions for the batch ``obs``."""
        ...

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray: ...


class PolicyBase:
    """What most policies share of :class:`Policy`: no ``spec`` (it reads the simulator's state), a ``reset`` that
    keeps nothing, and ``policy(obs)`` calling :meth:`act` (so a subclass overrides ``act`` alone)."""

    spec: Any = None

    def reset(self, sim: Simulator) -> None:
        """A new episode: nothing to forget."""

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        raise NotImplementedError(f"{type(self).__name__} must define act(obs).")

    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return self.act(obs)


def observer_of(policy: object) -> ObserverSpec | None:
    """The observer ``policy`` reads (its :attr:`Policy.spec` when that is an
    :class:`~uamfleet.observe.spec.ObserverSpec`), to build its env with ``observer=``; None: the world's own (a
    planner, a dispatcher or a plain function of the observation)."""
    spec = getattr(policy, "spec", None)
    return spec if isinstance(spec, ObserverSpec) else None


__all__ = ["Policy", "PolicyBase", "observer_of"]
