"""The PPO loss (clipped surrogate, clipped value loss, entropy bonus), CleanRL's formulation, and the KL term
that keeps a fine-tuned policy near the one it started from (:func:`categorical_kl`)."""

from __future__ import annotations

from dataclasses import dataclass

import torch


@dataclass(frozen=True)
class PPOLossInfo:
    policy_loss: float
    value_loss: float
    entropy: float
    approx_kl: float
    old_approx_kl: float
    clipfrac: float
    kl_to_init: float = 0.0


def categorical_kl(logits: torch.Tensor, reference_logits: torch.Tensor) -> torch.Tensor:
    """KL(p || q) [B] between the categorical distributions of two rows of logits [B, K] (p: ``logits``, q:
    ``reference_logits``). Masked actions carry a large negative logit in both (the network's ``NOT_THIS``),
    so their probabilities are 0 and they add nothing; an action p takes but q excludes would make it infinite,
    so the log-probabilities are taken with ``log_softmax`` (finite) rather than ``log`` of probabilities."""
    log_p = torch.log_softmax(logits, dim=-1)  # [B, K]
    log_q = torch.log_softmax(reference_logits, dim=-1)  # [B, K]
    return (log_p.exp() * (log_p - log_q)).sum(-1)  # [B]


def ppo_loss(
    new_logprob: torch.Tensor,  # [B]
    old_logprob: torch.Tensor,  # [B]
    entropy: torch.Tensor,  # [B]
    new_value: torch.Tensor,  # [B]
    old_value: torch.Tensor,  # [B]
    advantages: torch.Tensor,  # [B]
    returns: torch.Tensor,  # [B]
    clip_coef: float,
    vf_coef: float,
    ent_coef: float,
    clip_vloss: bool = True,
    norm_adv: bool = True,
    adv_stats: tuple[torch.Tensor, torch.Tensor] | None = None,
    denominator: int | None = None,
) -> tuple[torch.Tensor, PPOLossInfo]:
    """CleanRL's PPO loss over a minibatch of B samples.

    Data-parallel use (one rank's share of a global minibatch): ``adv_stats`` = (mean, std) of the global
    minibatch's advantages, and ``denominator`` = the global minibatch size, so every mean becomes a sum over
    this rank's samples / the global size; summed over ranks, loss, gradient and info are the global ones."""

    def mean(x: torch.Tensor) -> torch.Tensor:
        return x.mean() if denominator is None else x.sum() / denominator

    log_ratio = new_logprob - old_logprob  # [B]
    ratio = log_ratio.exp()  # [B]
    with torch.no_grad():
        old_approx_kl = mean(-log_ratio)
        approx_kl = mean((ratio - 1) - log_ratio)  # Schulman's unbiased low-variance estimator
        clipfrac = mean(((ratio - 1.0).abs() > clip_coef).float())
    if norm_adv and adv_stats is not None:
        advantages = (advantages - adv_stats[0]) / (adv_stats[1] + 1e-8)  # [B]
    elif norm_adv and advantages.numel() > 1:
        advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)  # [B]
    pg_loss = mean(torch.max(-advantages * ratio, -advantages * ratio.clamp(1 - clip_coef, 1 + clip_coef)))
    if clip_vloss:
        v_clipped = old_value + (new_value - old_value).clamp(-clip_coef, clip_coef)  # [B]
        v_loss = 0.5 * mean(torch.max((new_value - returns) ** 2, (v_clipped - returns) ** 2))
    else:
        v_loss = 0.5 * mean((new_value - returns) ** 2)
    entropy_mean = mean(entropy)
    loss = pg_loss - ent_coef * entropy_mean + vf_coef * v_loss
    info = PPOLossInfo(
        policy_loss=float(pg_loss.detach()),
        value_loss=float(v_loss.detach()),
        entropy=float(entropy_mean.detach()),
        approx_kl=float(approx_kl),
        old_approx_kl=float(old_approx_kl),
        clipfrac=float(clipfrac),
    )
    return loss, info
