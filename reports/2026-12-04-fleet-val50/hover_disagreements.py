"""Where the claims policy A′ (hover at any step) and the dispatcher beside it disagree about hovering, on training
episodes (seeds 0 and 1 of Berlin 4x48 and 8x96): per taxi-step, the policy hovers where the dispatcher flies, or
flies where it hovers, split by what the dispatcher's next stop is (a pick-up, a drop-off, none).
reports/2026-12-04-fleet-val50/README.md.

python reports/2026-12-04-fleet-val50/hover_disagreements.py
"""

from __future__ import annotations

from collections import Counter

import numpy as np

from uamfleet.baselines.sequencing import PICKUP
from uamfleet.instances import make_fleet_instance
from uamfleet.policies import make_flown
from uamfleet.rollout import fly
from uamfleet.types import HOVER_ACTION

CHECKPOINT = "reports/2026-12-04-fleet-val50/claims_hover01_r3.pt"


def main() -> None:
    flown = make_flown(f"fleet_claims:source={CHECKPOINT}")
    dispatcher = flown.dispatcher
    counts: Counter[tuple[str, str]] = Counter()
    teacher_actions: list[np.ndarray] = []
    teacher_act = dispatcher.act

    def recording_act(obs: dict[str, np.ndarray]) -> np.ndarray:
        actions = teacher_act(obs)
        teacher_actions.append(np.asarray(actions).reshape(-1))
        return actions

    dispatcher.act = recording_act
    policy_act = flown.act

    def comparing_act(obs: dict[str, np.ndarray]) -> np.ndarray:
        actions = policy_act(obs)
        mine, theirs = np.asarray(actions).reshape(-1), teacher_actions[-1]
        for taxi, (a, b) in enumerate(zip(mine, theirs, strict=True)):
            following = dispatcher.next_stop(taxi)
            kind = "none" if following is None else ("pick-up" if following[1] == PICKUP else "drop-off")
            if (a == HOVER_ACTION) != (b == HOVER_ACTION):
                counts[("policy hovers, dispatcher flies" if a == HOVER_ACTION else "policy flies, dispatcher hovers",
                        kind)] += 1  # fmt: skip
            counts[("taxi-steps", "all")] += 1
        return actions

    flown.act = comparing_act
    for taxis, requests in ((4, 48), (8, 96)):
        for seed in (0, 1):  # training seeds
            fly(make_fleet_instance("berlin", seed, taxis, requests, separation="shield", hover_action=True), flown)
    for (what, kind), n in sorted(counts.items()):
        print(f"{what:>34} | next stop {kind:>8} | {n}")


if __name__ == "__main__":
    main()
