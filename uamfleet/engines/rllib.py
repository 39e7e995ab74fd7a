"""RLlib's PPO on a uamfleet scenario: every taxi one agent of a shared policy, actions masked.

    from uamfleet.engines.rllib import ppo_config

    algo = ppo_config("berlin_random", num_taxis=4).env_runners(num_env_runners=8).build_algo()
    result = algo.train()   # one PPO iteration

Why an adapter: RLlib's default encoders take a Box, not our Dict of fields, and its action-masking module reads
exactly two keys, ``observations`` and ``action_mask``. :class:`FlatMaskedParallelEnv` gives it that: every field
but the mask flattened (in the layout's order) into one float32 vector, and the mask as float32 0 / 1.
``ray[rllib]`` pins an older gymnasium than uamfleet's, so it lives in its own venv (``scripts/engines.sh``).
"""

from __future__ import annotations

from typing import Any, ClassVar

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from uamfleet.config import EnvConfig
from uamfleet.engines import require
from uamfleet.env.parallel_env import UAMFleetParallelEnv
from uamfleet.presets import make_config

ENV_NAME = "uamfleet"
"""The name :func:`ppo_config` registers the env under (``register_env``)."""
POLICY_ID = "shared"
"""The one policy every taxi maps to, as our own trainer shares one."""


class FlatMaskedParallelEnv(ParallelEnv):
    """A uamfleet ParallelEnv whose observations are ``{"observations": float32[D], "action_mask": float32[16]}``:
    D is the sum of the other fields' sizes, concatenated in the observation space's order (so a field's slice is
    the same every step). Rewards, terminations, infos and ``state()`` pass through unchanged."""

    metadata: ClassVar[dict[str, Any]] = {"name": "uamfleet_flat_masked_v0", "render_modes": []}

    def __init__(self, env: UAMFleetParallelEnv) -> None:
        self.env = env
        self.possible_agents = list(env.possible_agents)
        self.agents = list(env.agents) if hasattr(env, "agents") else list(self.possible_agents)
        inner = env.observation_space(self.possible_agents[0])
        assert isinstance(inner, spaces.Dict)
        self.fields = [name for name in inner.spaces if name != "action_mask"]
        size = sum(int(np.prod(inner.spaces[name].shape or ())) for name in self.fields)
        num_actions = int(np.prod(inner.spaces["action_mask"].shape or ()))
        self._space = spaces.Dict(
            {
                "observations": spaces.Box(-np.inf, np.inf, (size,), np.float32),
                "action_mask": spaces.Box(0.0, 1.0, (num_actions,), np.float32),
            }
        )

    def observation_space(self, agent: Any) -> spaces.Space:
        return self._space

    def action_space(self, agent: Any) -> spaces.Space:
        return self.env.action_space(agent)

    def flatten(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """One agent's Dict observation in the flat form."""
        flat = np.concatenate([np.asarray(obs[name], np.float32).ravel() for name in self.fields])
        return {"observations": flat, "action_mask": np.asarray(obs["action_mask"], np.float32)}

    def reset(self, seed: int | None = None, options: dict | None = None) -> tuple[dict, dict]:
        obs, infos = self.env.reset(seed=seed, options=options)
        self.agents = list(self.env.agents)
        return {a: self.flatten(o) for a, o in obs.items()}, infos

    def step(self, actions: dict) -> tuple[dict, dict, dict, dict, dict]:
        obs, rewards, terminated, truncated, infos = self.env.step(actions)
        self.agents = list(self.env.agents)
        return {a: self.flatten(o) for a, o in obs.items()}, rewards, terminated, truncated, infos

    def state(self) -> np.ndarray:
        return self.env.state()

    def close(self) -> None:
        self.env.close()


def flat_masked_env(scenario: str | EnvConfig = "berlin_random", **overrides: Any) -> FlatMaskedParallelEnv:
    """The flat, masked ParallelEnv of a scenario (any :func:`uamfleet.make_config` override)."""
    cfg = scenario if isinstance(scenario, EnvConfig) else make_config(scenario, **overrides)
    return FlatMaskedParallelEnv(UAMFleetParallelEnv(cfg))


def ppo_config(scenario: str | EnvConfig = "berlin_random", **overrides: Any) -> Any:
    """An RLlib ``PPOConfig`` for ``scenario``: the env registered as :data:`ENV_NAME` (RLlib's
    ``ParallelPettingZooEnv`` around :func:`flat_masked_env`), every taxi mapped to the one policy
    :data:`POLICY_ID`, whose module masks the logits with ``action_mask`` (RLlib's
    ``ActionMaskingTorchRLModule``). Chain any further settings (``.env_runners(...)``, ``.training(...)``)
    before ``.build_algo()``. :class:`~uamfleet.engines.EngineMissingError` without RLlib."""
    require("rllib", "ray", "ray.rllib")
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv
    from ray.rllib.examples.rl_modules.classes.action_masking_rlm import ActionMaskingTorchRLModule
    from ray.tune.registry import register_env

    cfg = scenario if isinstance(scenario, EnvConfig) else make_config(scenario, **overrides)
    register_env(ENV_NAME, lambda _: ParallelPettingZooEnv(flat_masked_env(cfg)))
    module = RLModuleSpec(module_class=ActionMaskingTorchRLModule)
    return (
        PPOConfig()
        .environment(ENV_NAME)
        .multi_agent(policies={POLICY_ID}, policy_mapping_fn=lambda agent_id, *args, **kwargs: POLICY_ID)
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs={POLICY_ID: module}))
    )


__all__ = ["ENV_NAME", "POLICY_ID", "FlatMaskedParallelEnv", "flat_masked_env", "ppo_config"]
