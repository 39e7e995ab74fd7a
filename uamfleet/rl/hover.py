"""A trained stop-head policy that can take the hover action (16) at every step: :func:`with_hover_anytime`, and
its checkpoint (:func:`hover_checkpoint`).

The conversion keeps every weight and adds the hover logit of ``NetConfig.hover_anytime`` (a bias at
:data:`~uamfleet.rl.heads.HOVER_START`, a zero linear map of the features): the converted policy hovers with
probability below 1e-5 and flies the same greedy actions, until it is trained to wait where a search waits.
"""

from __future__ import annotations

import dataclasses
from typing import TYPE_CHECKING

from uamfleet.checks import ConfigError
from uamfleet.rl.checkpoint import CHECKPOINT_FORMAT, Checkpoint, trained_spec
from uamfleet.rl.networks import MSHAActorCritic

if TYPE_CHECKING:
    from uamfleet.rl.policy import GreedyPolicy

NEW_PARAMETERS = "stop_head.anytime_hover."
"""The prefix of the parameters :func:`with_hover_anytime` adds (the hover logit's weight and bias)."""


def with_hover_anytime(policy: GreedyPolicy) -> GreedyPolicy:
    """A copy of ``policy`` whose network also takes the hover action (16) at every step (``NetConfig.hover_anytime``):
    the same weights and normaliser plus the new hover logit, zero weight and bias :data:`~uamfleet.rl.heads.
    HOVER_START`, so each heading keeps its probability times 1 - 6.1e-6 and the greedy actions stay the same. Its
    spec says ``hover=True``: it flies worlds made with ``hover_action=True`` and refuses others (one line at
    ``reset``). ``trained_on`` stays the config its weights were evaluated on. A policy that already takes the
    hover at every step is returned as it is; one with ``hover_logit`` (action 16 open where no stop is, the shipped
    fleet policy) keeps that hover and adds this one's probability to it. ValueError for one without a stop head,
    ConfigError for one without an observer spec (load it with ``load_policy``)."""
    if policy.spec is None:
        raise ConfigError("this policy has no observer spec to give the hover action: load it with load_policy.")
    if policy.net.cfg.hover_anytime:
        return policy
    cfg = dataclasses.replace(policy.net.cfg, hover_anytime=True)  # ValueError without a stop head

    def carry_over(new: MSHAActorCritic) -> None:  # the new hover parameters keep their initial values
        missing, unexpected = new.load_state_dict(policy.net.state_dict(), strict=False)
        if unexpected or any(not k.startswith(NEW_PARAMETERS) for k in missing):
            raise ValueError(f"the policy's network does not carry over: missing {missing}, unexpected {unexpected}.")

    return policy.with_network(cfg, carry_over, dataclasses.replace(policy.spec, hover=True))


def hover_checkpoint(source: Checkpoint, policy: GreedyPolicy) -> Checkpoint:
    """``source``, the checkpoint ``policy`` was converted from (:func:`with_hover_anytime` of its ``load_policy``),
    with ``policy``'s weights, its ``net_config`` (``hover_anytime`` stored) and what it reads (its spec, hover
    action included), in the current format: :meth:`Checkpoint.save` writes it atomically and ``load_policy`` reads
    it back (``torch.load(weights_only=True)``). What only training needs (optimiser moments, RNG states, the reward
    scaler) is dropped, as :func:`uamfleet.policies.learned.export_policy` does: the new parameters have no moments."""
    if policy.spec is None or policy.trained_on is None:
        raise ConfigError("this policy has no observer spec or training config: load it with load_policy.")
    net_config = dataclasses.asdict(policy.net.cfg)
    return dataclasses.replace(
        source,
        model={k: v.detach().clone() for k, v in policy.net.state_dict().items()},
        net_config=net_config,
        observer=trained_spec(policy.trained_on, net_config, observer=policy.spec).to_dict(),
        format=CHECKPOINT_FORMAT,
        optimizer={}, reward_scaler=None, cuda_rng=None, numpy_rng={},
    )  # fmt: skip


__all__ = ["NEW_PARAMETERS", "hover_checkpoint", "with_hover_anytime"]
