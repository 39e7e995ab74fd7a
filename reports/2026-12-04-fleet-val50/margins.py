"""The logit margin of the hover over the best heading at each hover the claims policy A′ chooses, on training
episodes (seeds 0 and 1 of Berlin 4x48 and 8x96): reports/2026-12-04-fleet-val50/README.md.

python reports/2026-12-04-fleet-val50/margins.py
"""

from __future__ import annotations

import numpy as np
import torch

from uamfleet.instances import make_fleet_instance
from uamfleet.policies import make_flown
from uamfleet.rollout import fly
from uamfleet.types import HOVER_ACTION

CHECKPOINT = "reports/2026-12-04-fleet-val50/claims_hover01_r3.pt"


def main() -> None:
    margins: list[float] = []
    flown = make_flown(f"fleet_claims:source={CHECKPOINT}")
    choose = flown.policy.choose

    def recording_choose(obs: dict[str, np.ndarray], logits: torch.Tensor) -> np.ndarray:
        rows = logits.detach().numpy()
        best_heading = rows[:, :HOVER_ACTION].max(axis=1)
        margins.extend(float(h - b) for h, b in zip(rows[:, HOVER_ACTION], best_heading, strict=True) if np.isfinite(b))
        return choose(obs, logits)

    flown.policy.choose = recording_choose
    for taxis, requests in ((4, 48), (8, 96)):
        for seed in (0, 1):  # training seeds
            fly(make_fleet_instance("berlin", seed, taxis, requests, separation="shield", hover_action=True), flown)
    margin = np.array(margins)
    hovers = margin[margin > 0]
    print(f"{len(margin)} taxi-steps with a heading open, {len(hovers)} hovers chosen")
    for below in (0.1, 0.25, 0.5, 1, 2, 4):
        print(f"share of the hovers with a margin below {below}: {float((hovers < below).mean()):.3f}")


if __name__ == "__main__":
    main()
