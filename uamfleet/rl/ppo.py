"""The PPO loss (clipped surrogate, clipped value loss, entropy bonus), CleanRL's formulation."""

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
) -> tuple[torch.Tensor, PPOLossInfo]:
    log_ratio = new_logprob - old_logprob  # [B]
    ratio = log_ratio.exp()  # [B]
    with torch.no_grad():
        old_approx_kl = (-log_ratio).mean()
        approx_kl = ((ratio - 1) - log_ratio).mean()  # Schulman's unbiased low-variance estimator
        clipfrac = ((ratio - 1.0).abs() > clip_coef).float().mean()
    if norm_adv and advantages.numel() > 1:
        advantages = (advantages - advantages.mean()) / (advantages.std() + 1e-8)  # [B]
    pg_loss = torch.max(-advantages * ratio, -advantages * ratio.clamp(1 - clip_coef, 1 + clip_coef)).mean()
    if clip_vloss:
        v_clipped = old_value + (new_value - old_value).clamp(-clip_coef, clip_coef)  # [B]
        v_loss = 0.5 * torch.max((new_value - returns) ** 2, (v_clipped - returns) ** 2).mean()
    else:
        v_loss = 0.5 * ((new_value - returns) ** 2).mean()
    entropy_mean = entropy.mean()
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
