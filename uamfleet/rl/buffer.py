"""Rollout storage, GAE with truncation bootstrapping, running normalisers, and the sums over finished episodes.

Agents are flattened: one rollout row per (env, taxi), N = E * A, so every taxi of every env is a sample of
the one shared policy.
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass, field

import numpy as np
import torch

from uamfleet.observe.spec import field_kind, field_row_mask
from uamfleet.rl.distributed import Ranks


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
        self.update_from_moments(batch.mean(0), batch.var(0), batch.shape[0])

    def update_from_moments(self, b_mean: np.ndarray, b_var: np.ndarray, b_count: float) -> None:
        delta = b_mean - self.mean
        total = self.count + b_count
        self.mean = self.mean + delta * b_count / total
        m2 = self.var * self.count + b_var * b_count + delta**2 * self.count * b_count / total
        self.var = m2 / total
        self.count = total

    def state_dict(self) -> dict[str, torch.Tensor | float]:
        """Tensors and a float: loadable with ``torch.load(weights_only=True)``."""
        return {"mean": torch.tensor(self.mean), "var": torch.tensor(self.var), "count": float(self.count)}

    def load_state_dict(self, state: dict[str, torch.Tensor | np.ndarray | float]) -> None:
        self.mean, self.var = _float64(state["mean"]), _float64(state["var"])
        self.count = float(state["count"])


def _float64(x: torch.Tensor | np.ndarray | float) -> np.ndarray:
    if isinstance(x, torch.Tensor):
        x = x.detach().cpu().numpy()
    return np.array(x, dtype=np.float64)


def global_moments(
    batches: list[np.ndarray], shifts: list[np.ndarray], ranks: Ranks
) -> list[tuple[np.ndarray, np.ndarray, float]]:
    """(mean, var, count) of each batch [n, *shape] pooled over all ranks, in one all-reduce.

    Sums are taken around ``shift`` (the running mean, equal on every rank) so that var = E[d^2] - E[d]^2
    does not cancel catastrophically."""
    parts = []
    for x, shift in zip(batches, shifts, strict=True):
        d = x - shift  # [n, *shape]
        parts += [np.array([x.shape[0]], np.float64), d.sum(0).ravel(), (d * d).sum(0).ravel()]
    total = ranks.all_sum(np.concatenate(parts))
    out, start = [], 0
    for x, shift in zip(batches, shifts, strict=True):
        size = int(np.prod(x.shape[1:]))
        n = total[start]
        s1 = total[start + 1 : start + 1 + size].reshape(x.shape[1:]) / n
        s2 = total[start + 1 + size : start + 1 + 2 * size].reshape(x.shape[1:]) / n
        out.append((shift + s1, np.maximum(s2 - s1 * s1, 0.0), float(n)))
        start += 1 + 2 * size
    return out


class ObservationNormalizer:
    """Normalises the observation fields of kind ``"feature"`` and ``"set"`` (:data:`uamfleet.observe.spec.FIELD_KINDS`)
    with running statistics, keeping the masked rows of a set at zero; ``"mask"`` and ``"raw"`` fields pass through
    unchanged. ``shapes``: one agent's shape of each field, by name (ValueError for a name that is no field)."""

    def __init__(self, shapes: dict[str, tuple[int, ...]], clip: float = 10.0) -> None:
        normalised = [k for k in shapes if field_kind(k) in ("feature", "set")]
        self.fields = {k: RunningMeanStd(shapes[k]) for k in normalised}
        self.row_masks = {k: mask for k in normalised if (mask := field_row_mask(k)) is not None}
        self.clip = clip

    def update(self, obs: dict[str, np.ndarray], ranks: Ranks | None = None) -> None:
        """Fold a batch [N, ...] into the statistics; with a joined ``ranks``, the batch of all ranks."""
        if ranks is None or not ranks.active:
            for key, rms in self.fields.items():
                rms.update(obs[key])
            return
        batches = [obs[key].reshape(-1, *rms.shape) for key, rms in self.fields.items()]
        moments = global_moments(batches, [rms.mean for rms in self.fields.values()], ranks)
        for rms, (mean, var, count) in zip(self.fields.values(), moments, strict=True):
            rms.update_from_moments(mean, var, count)

    def __call__(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        out = dict(obs)
        for key, rms in self.fields.items():
            x = (obs[key] - rms.mean) / np.sqrt(rms.var + 1e-8)
            if key in self.row_masks:  # masked rows (unreleased passengers, absent taxis) stay exactly zero
                x = x * obs[self.row_masks[key]][..., None]
            out[key] = np.clip(x, -self.clip, self.clip).astype(np.float32)
        return out

    def state_dict(self) -> dict[str, dict[str, torch.Tensor | float]]:
        return {k: v.state_dict() for k, v in self.fields.items()}

    def resized(self, shapes: dict[str, tuple[int, ...]]) -> ObservationNormalizer:
        """These statistics for another layout of the same fields (another fleet size): a field of kind ``"set"``
        (passenger rows, other taxis) with another number of rows gets the statistics pooled over its rows, the
        same for every row; every other field keeps its own. Raises ValueError when a field changes otherwise."""
        out = ObservationNormalizer(shapes, self.clip)
        for key, rms in self.fields.items():
            new = out.fields.get(key)
            if new is None:
                raise ValueError(f"field {key!r} is not in the new layout {sorted(shapes)}.")
            if new.shape == rms.shape:
                mean, var = rms.mean, rms.var
            elif key in self.row_masks and len(new.shape) >= 2 and new.shape[1:] == rms.shape[1:]:
                pooled = rms.mean.mean(0)  # the moments of all rows together
                mean = np.broadcast_to(pooled, new.shape)
                var = np.broadcast_to((rms.var + rms.mean**2).mean(0) - pooled**2, new.shape)
            else:
                raise ValueError(f"field {key!r} has shape {new.shape} here and {rms.shape} in the statistics.")
            new.mean, new.var, new.count = mean.copy(), np.maximum(var, 0.0), rms.count
        return out

    def load_state_dict(self, state: dict[str, dict[str, torch.Tensor | np.ndarray | float]]) -> None:
        for key, value in state.items():
            self.fields[key].load_state_dict(value)


class RewardScaler:
    """Divides rewards by the running std of the discounted return (Gymnasium's NormalizeReward), per agent."""

    def __init__(self, num_agents: int, gamma: float) -> None:
        self.rms = RunningMeanStd(())
        self.returns = np.zeros(num_agents)
        self.gamma = gamma

    def __call__(self, rewards: np.ndarray, done: np.ndarray) -> np.ndarray:
        """One step's rewards [N] scaled; ``done`` [N] ends the agents' returns."""
        self.returns = self.returns * self.gamma + rewards
        self.rms.update(self.returns)
        self.returns[done] = 0.0
        return rewards / np.sqrt(self.rms.var + 1e-8)

    def scale_rollout(self, rewards: np.ndarray, done: np.ndarray, ranks: Ranks) -> np.ndarray:
        """A rollout's rewards [T, N] scaled as T calls would, with the statistics of all ranks' returns.

        The scaled rewards are needed only after the rollout, so the T steps' return moments travel in one
        all-reduce instead of one per step; the statistics then take the T updates in order."""
        batches = []
        for t in range(rewards.shape[0]):
            self.returns = self.returns * self.gamma + rewards[t]
            batches.append(self.returns.copy())  # [N]
            self.returns[done[t]] = 0.0
        scaled = np.empty_like(rewards)
        moments = global_moments(batches, [self.rms.mean] * len(batches), ranks)
        for t, (mean, var, count) in enumerate(moments):
            self.rms.update_from_moments(mean, var, count)
            scaled[t] = rewards[t] / np.sqrt(self.rms.var + 1e-8)
        return scaled


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


@dataclass
class EpisodeSums:
    """Sums over the episodes that finished during a rollout (of this rank until pooled: :meth:`pooled`)."""

    episode_return: float = 0.0  # of the mean taxi
    length: float = 0.0
    service_rate: float = 0.0
    distance_m: float = 0.0  # of the whole fleet
    count: float = 0.0

    def add(self, episode: dict[str, np.ndarray], e: int) -> None:
        """Add env ``e``'s finished episode (``info["episode"]`` of the core)."""
        self.episode_return += float(episode["return"][e].mean())
        self.length += float(episode["length"][e])
        self.service_rate += float(episode["service_rate"][e])
        self.distance_m += float(episode["distance_m"][e].sum())
        self.count += 1.0

    def pooled(self, ranks: Ranks) -> EpisodeSums:
        """The sums over all ranks."""
        return EpisodeSums(*ranks.all_sum(np.array(dataclasses.astuple(self), dtype=np.float64)))
