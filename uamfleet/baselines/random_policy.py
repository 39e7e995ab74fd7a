"""The random yardstick: uniform over the allowed headings."""

from __future__ import annotations

import numpy as np

from uamfleet.env.protocol import PolicyBase


class RandomPolicy(PolicyBase):
    """Uniform over the allowed headings of each taxi (uniform over all 16 when none is allowed)."""

    def __init__(self, seed: int | None = None) -> None:
        self.rng = np.random.default_rng(seed)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        mask = obs["action_mask"].astype(bool)  # [E, A, 16]
        mask = np.where(mask.any(-1, keepdims=True), mask, True)
        scores = self.rng.random(mask.shape) * mask  # the max over allowed entries is uniform among them
        return np.argmax(scores, axis=-1)
