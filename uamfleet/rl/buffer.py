"""Rollout storage, GAE with truncation bootstrapping, and running normalisers.

Agents are flattened: one rollout row per (env, taxi), N = E * A, so every taxi of every env is a sample of
the one shared policy.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import torch


def compute_gae(
    rewards: np.ndarray,  # [T, N]
    values: np.ndarray,  # [T, N] V(s_t)
    terminated: np.ndarray,  # [T, N] bool: s_{t+1} is terminal
    truncated: np.ndarray,  # [T, N] bool: the episode was cut after step t (s_{t+1} not terminal)
    final_values: np.ndarray,  # [T, N] V(final observation) where truncated, anything elsewhere
    next_value: np.ndarray,  # [N] V(s_T), the observation after the last stored step
    gamma: float,
    lam: float,
) -> tuple[np.ndarray, np.ndarray]:
    """Generalised advantage estimation (Schulman et al. 2016) with correct episode ends.

    With same-step autoreset the observation after a finished step t is already the next episode's first, so:
    a terminated step bootstraps from 0, a truncated one from the value of its real final observation (a
    time limit is not part of the task: never treat it as terminal), and no advantage flows across the end.
    Returns (advantages [T, N], returns [T, N] = advantages + values).
    """
    num_steps = rewards.shape[0]
    advantages = np.zeros_like(rewards, dtype=np.float64)
    last = np.zeros(rewards.shape[1])
    for t in reversed(range(num_steps)):
        following = next_value if t == num_steps - 1 else values[t + 1]
        bootstrap = np.where(truncated[t], final_values[t], following)
        bootstrap = np.where(terminated[t], 0.0, bootstrap)
        delta = rewards[t] + gamma * bootstrap - values[t]
        episode_continues = ~(terminated[t] | truncated[t])
        last = delta + gamma * lam * episode_continues * last
        advantages[t] = last
    return advantages, advantages + values


@dataclass
class RunningMeanStd:
    """Running mean / variance (Chan et al. parallel update), as Gymnasium's normalisation wrappers."""

    shape: tuple[int, ...] = ()
    mean: np.ndarray = field(init=False)
    var: np.ndarray = field(init=False)
    count: float = 1e-4

    def __post_init__(self) -> None:
        self.mean = np.zeros(self.shape)
        self.var = np.ones(self.shape)

    def update(self, x: np.ndarray) -> None:
        batch = x.reshape(-1, *self.shape)
        b_mean, b_var, b_count = batch.mean(0), batch.var(0), batch.shape[0]
        delta = b_mean - self.mean
        total = self.count + b_count
        self.mean = self.mean + delta * b_count / total
        m2 = self.var * self.count + b_var * b_count + delta**2 * self.count * b_count / total
        self.var = m2 / total
        self.count = total

    def state_dict(self) -> dict[str, np.ndarray | float]:
        return {"mean": self.mean.copy(), "var": self.var.copy(), "count": self.count}

    def load_state_dict(self, state: dict[str, np.ndarray | float]) -> None:
        self.mean = np.asarray(state["mean"], dtype=np.float64).copy()
        self.var = np.asarray(state["var"], dtype=np.float64).copy()
        self.count = float(np.asarray(state["count"]))


class ObservationNormalizer:
    """Normalises the continuous observation fields with running statistics; masks pass through unchanged."""

    def __init__(self, shapes: dict[str, tuple[int, ...]], clip: float = 10.0) -> None:
        self.fields = {k: RunningMeanStd(s) for k, s in shapes.items() if not k.endswith("mask")}
        self.clip = clip

    def update(self, obs: dict[str, np.ndarray]) -> None:
        for key, rms in self.fields.items():
            rms.update(obs[key])

    def __call__(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        out = dict(obs)
        for key, rms in self.fields.items():
            x = (obs[key] - rms.mean) / np.sqrt(rms.var + 1e-8)
            if key == "passengers":  # keep unreleased rows exactly zero: the network must not see them at all
                x = x * obs["passenger_mask"][..., None]
            if key == "others":
                x = x * obs["others_mask"][..., None]
            out[key] = np.clip(x, -self.clip, self.clip).astype(np.float32)
        return out

    def state_dict(self) -> dict[str, dict[str, np.ndarray | float]]:
        return {k: v.state_dict() for k, v in self.fields.items()}

    def load_state_dict(self, state: dict[str, dict[str, np.ndarray | float]]) -> None:
        for key, value in state.items():
            self.fields[key].load_state_dict(value)


class RewardScaler:
    """Divides rewards by the running std of the discounted return (Gymnasium's NormalizeReward), per agent."""

    def __init__(self, num_agents: int, gamma: float) -> None:
        self.rms = RunningMeanStd(())
        self.returns = np.zeros(num_agents)
        self.gamma = gamma

    def __call__(self, rewards: np.ndarray, done: np.ndarray) -> np.ndarray:
        self.returns = self.returns * self.gamma + rewards
        self.rms.update(self.returns)
        self.returns[done] = 0.0
        return rewards / np.sqrt(self.rms.var + 1e-8)


class RolloutBuffer:
    """Fixed-size storage of T steps of N agents; observations stay numpy until a minibatch is drawn."""

    def __init__(self, num_steps: int, num_agents: int, obs_shapes: dict[str, tuple[int, ...]], state_dim: int = 0):
        T, N = num_steps, num_agents
        self.obs = {k: np.zeros((T, N, *s), np.float32) for k, s in obs_shapes.items()}
        self.state = np.zeros((T, N, state_dim), np.float32) if state_dim else None
        self.actions = np.zeros((T, N), np.int64)
        self.logprobs = np.zeros((T, N), np.float32)
        self.rewards = np.zeros((T, N))
        self.values = np.zeros((T, N))
        self.terminated = np.zeros((T, N), bool)
        self.truncated = np.zeros((T, N), bool)
        self.final_values = np.zeros((T, N))

    def minibatch(
        self, index: np.ndarray, device: torch.device
    ) -> tuple[dict[str, torch.Tensor], torch.Tensor | None, torch.Tensor, torch.Tensor]:
        """Flat indices into [T * N] -> (obs, state, actions, old log-probs) tensors."""
        obs = {k: torch.as_tensor(v.reshape(-1, *v.shape[2:])[index], device=device) for k, v in self.obs.items()}
        state = None
        if self.state is not None:
            state = torch.as_tensor(self.state.reshape(-1, self.state.shape[-1])[index], device=device)
        actions = torch.as_tensor(self.actions.reshape(-1)[index], device=device)
        logprobs = torch.as_tensor(self.logprobs.reshape(-1)[index], device=device)
        return obs, state, actions, logprobs
