"""TorchRL on a uamfleet scenario: one group of taxis, one masked categorical policy shared over them.

    from torchrl.collectors import Collector
    from uamfleet.engines.torchrl import masked_policy, torchrl_env

    env = torchrl_env("berlin_random", num_taxis=4)
    policy = masked_policy(env)
    collector = Collector(lambda: torchrl_env("berlin_random", num_taxis=4), policy, frames_per_batch=256,
                          total_frames=10_000)
    for batch in collector:   # batch["uam", "action"]: [256, 4], always an allowed heading
        ...

TorchRL's ``PettingZooWrapper`` puts all taxis in one group (``"uam"``: the agent axis), moves each taxi's
``action_mask`` to ``("uam", "action_mask")`` and the other fields under ``("uam", "observation", name)``.
:func:`masked_policy` flattens those fields per taxi, runs one MLP on every taxi (the weights are shared, as in our
own trainer) and samples from ``MaskedCategorical``, so a masked heading is never drawn. Many-machine collection:
``torchrl.collectors.distributed.DistributedCollector`` / ``RPCCollector`` with the same env factory and policy.
"""

from __future__ import annotations

from typing import Any

from uamfleet.config import EnvConfig
from uamfleet.engines import require
from uamfleet.env.parallel_env import UAMFleetParallelEnv
from uamfleet.presets import make_config

GROUP = "uam"
"""The one agent group TorchRL makes of the taxis (their names' prefix)."""


def torchrl_env(scenario: str | EnvConfig = "berlin_random", **overrides: Any) -> Any:
    """TorchRL's ``PettingZooWrapper`` around the scenario's ParallelEnv (any :func:`uamfleet.make_config`
    override); the action mask is read from the observation. :class:`~uamfleet.engines.EngineMissingError`
    without TorchRL."""
    require("torchrl", "torchrl")
    from torchrl.envs import PettingZooWrapper

    cfg = scenario if isinstance(scenario, EnvConfig) else make_config(scenario, **overrides)
    return PettingZooWrapper(env=UAMFleetParallelEnv(cfg), use_mask=False)


def observation_fields(env: Any) -> list[str]:
    """The observation fields of the group, in the spec's order (the action mask is not among them)."""
    return list(env.observation_spec[GROUP, "observation"].keys())


def masked_policy(env: Any, hidden: int = 64, seed: int | None = 0) -> Any:
    """A ``ProbabilisticActor`` for ``env`` (:func:`torchrl_env`): every observation field flattened and
    concatenated per taxi, a two-layer MLP shared by all taxis, logits masked by ``("uam", "action_mask")``
    (``MaskedCategorical``); writes ``("uam", "action")`` and its log-probability."""
    require("torchrl", "tensordict", "torchrl")
    import torch
    from tensordict.nn import TensorDictModule
    from torchrl.modules import MaskedCategorical, ProbabilisticActor

    fields = observation_fields(env)
    spec = env.observation_spec[GROUP, "observation"]
    size = sum(int(torch.Size(spec[name].shape[1:]).numel()) for name in fields)  # shape[0]: the taxis
    num_actions = int(env.full_action_spec[GROUP, "action"].space.n)
    if seed is not None:
        torch.manual_seed(seed)

    class FlatMLP(torch.nn.Module):
        """Logits [..., taxis, actions] from the fields [..., taxis, *shape]: the same weights for every taxi."""

        def __init__(self) -> None:
            super().__init__()
            self.net = torch.nn.Sequential(
                torch.nn.Linear(size, hidden), torch.nn.Tanh(), torch.nn.Linear(hidden, num_actions)
            )

        def forward(self, *tensors: torch.Tensor) -> torch.Tensor:
            taxis_dims = tensors[0].shape[: tensors[0].dim() - len(spec[fields[0]].shape[1:])]
            flat = [t.reshape(*taxis_dims, -1).float() for t in tensors]
            return self.net(torch.cat(flat, dim=-1))

    logits = TensorDictModule(
        FlatMLP(), in_keys=[(GROUP, "observation", name) for name in fields], out_keys=[(GROUP, "logits")]
    )
    return ProbabilisticActor(
        module=logits,
        spec=env.full_action_spec[GROUP, "action"],
        in_keys={"logits": (GROUP, "logits"), "mask": (GROUP, "action_mask")},
        out_keys=[(GROUP, "action")],
        distribution_class=MaskedCategorical,
        return_log_prob=True,
        log_prob_key=(GROUP, "sample_log_prob"),
    )


__all__ = ["GROUP", "masked_policy", "observation_fields", "torchrl_env"]
