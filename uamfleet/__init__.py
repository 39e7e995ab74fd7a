"""uamfleet: communication-aware ride-sharing route planning for Urban Air Mobility fleets.

Public surface::

    uamfleet.SCENARIOS                                   # scenario names
    env = uamfleet.parallel_env("berlin_p4", sinr_min_db=-3.0, num_taxis=1)   # PettingZoo ParallelEnv
    venv = uamfleet.vector_env("berlin_p4", num_envs=64, num_taxis=4)          # the batched core
    radio = uamfleet.load_radio_map("berlin")                                  # RadioMap
    planner = uamfleet.pretrained("berlin")      # a learned planner for your own Berlin instance: planner.fly(cfg)
"""

from __future__ import annotations

from typing import Any

from uamfleet.config import REWARD_TERMS, ConfigError, DemandConfig, EnvConfig, Request, RewardConfig, WorldConfig
from uamfleet.env.parallel_env import Renderer, UAMFleetParallelEnv, face_config, parallel_env
from uamfleet.env.vector_env import VectorEnv
from uamfleet.observe.spec import LookaheadSpec, ObserverSpec, StopsSpec
from uamfleet.presets import SCENARIOS, make_config
from uamfleet.radio import RADIO_MAPS, RadioMap, load_radio_map

__version__ = "0.1.0"


def _viz_renderer(render_mode: str, env: UAMFleetParallelEnv) -> Renderer:
    """uamfleet.viz's renderer, imported on the first ``render()`` (``import uamfleet`` stays light)."""
    from uamfleet.viz.render import make_renderer

    return make_renderer(render_mode, env)


# The env draws through uamfleet.viz without importing it (layers point down; this face sits above both).
UAMFleetParallelEnv.default_renderer = _viz_renderer


def vector_env(
    scenario: str | WorldConfig = "berlin_p4",
    num_envs: int = 1,
    autoreset: bool = True,
    observer: ObserverSpec | None = None,
    **overrides: Any,
) -> VectorEnv:
    """The batched core: ``num_envs`` envs of a scenario with config overrides (any EnvConfig field), observed by
    ``observer`` (None: the scenario's observer)."""
    return VectorEnv(face_config(scenario, overrides), num_envs=num_envs, autoreset=autoreset, observer=observer)


def pretrained(name: str = "berlin", device: str = "cpu") -> Any:
    """A pretrained planner shipped with the package (:mod:`uamfleet.policies.learned`):
    ``uamfleet.pretrained("berlin")`` plans one taxi on the Berlin map at any threshold -7 ... -3 dB;
    ``.fly(cfg)`` flies a config of yours."""
    from uamfleet.policies.learned import pretrained as load  # torch is imported only when asked for

    return load(name, device=device)


__all__ = [
    "RADIO_MAPS",
    "REWARD_TERMS",
    "SCENARIOS",
    "ConfigError",
    "DemandConfig",
    "EnvConfig",
    "LookaheadSpec",
    "ObserverSpec",
    "RadioMap",
    "Request",
    "RewardConfig",
    "StopsSpec",
    "UAMFleetParallelEnv",
    "VectorEnv",
    "WorldConfig",
    "load_radio_map",
    "make_config",
    "parallel_env",
    "pretrained",
    "vector_env",
]
