"""Where the claims policy A′ round 3 flies another move than the dispatcher beside it, sorted by kind, on 8
training episodes of Berlin 4x48 (seeds 0-7): reports/2026-12-05-fleet-headings/README.md. With a prior (logits
added to the weight of the claim "my next stop" in each stop's score, a decoding rule tried here), the network
follows the dispatcher's choice of stop more strongly still.

python reports/2026-12-05-fleet-headings/kinds.py [prior ...]    (default: 0 3)
"""

from __future__ import annotations

import sys
from collections import Counter

import numpy as np

from uamfleet.instances import make_fleet_instance
from uamfleet.policies import make_flown
from uamfleet.baselines.fleet_steering import fleet_action
from uamfleet.rl.fleet_claims import CLAIM_SCORE, MY_NEXT_STOP, ClaimsFleetPolicy
from uamfleet.rl.networks import MSHAActorCritic
from uamfleet.rl.policy import GreedyPolicy
from uamfleet.rollout import fly
from uamfleet.types import HOVER_ACTION

CHECKPOINT = "reports/2026-12-04-fleet-val50/claims_hover01_r3.pt"


def with_next_stop_prior(policy: GreedyPolicy, prior: float) -> GreedyPolicy:
    """A copy of the claims-reading ``policy`` whose stop scores favour the dispatcher's next stop by ``prior``
    more logits."""

    def carry_over(new: MSHAActorCritic) -> None:
        state = {k: v.clone() for k, v in policy.net.state_dict().items()}
        state[CLAIM_SCORE][0, MY_NEXT_STOP] += prior
        new.load_state_dict(state)

    return policy.with_network(policy.net.cfg, carry_over)


def kinds(prior: float) -> Counter[str]:
    policy = make_flown(f"fleet_claims:source={CHECKPOINT}")
    assert isinstance(policy, ClaimsFleetPolicy)
    policy.policy = with_next_stop_prior(policy.policy, prior)  # a copy: the cached network policy is left as it is
    counts: Counter[str] = Counter()
    act = ClaimsFleetPolicy.act

    def recording_act(obs: dict[str, np.ndarray]) -> np.ndarray:
        chosen = act(policy, obs)[0]  # the dispatcher acted inside: its schedules are this step's
        disp = policy.dispatcher
        assert disp.sim is not None and policy._observer is not None
        rows = policy._observer.window_rows(disp.sim.state)[0]  # [A, K] passenger per window slot
        heading_of_row = obs["stop_heading_mask"][0]  # [A, K, 16] one-hot per actionable stop
        for a, k in enumerate(chosen):
            target = disp.target(a)
            mine = fleet_action(disp.sim, disp.fields, [None] * len(chosen), a, target)  # the dispatcher's rule
            if k == mine:
                counts["same move"] += 1
                continue
            if target is None:
                counts["dispatcher idle (hovers), network flies"] += 1
                continue
            if k == HOVER_ACTION:
                counts["network hovers, dispatcher flies to a stop"] += 1
                continue
            stop = disp.next_stop(a)
            slots = np.flatnonzero(rows[a] == stop[0]) if stop is not None else []
            stop_heading = [int(heading_of_row[a, j].argmax()) for j in slots if heading_of_row[a, j].any()]
            if not stop_heading:
                counts["dispatcher's stop not actionable in the window"] += 1
            elif k in stop_heading:
                counts["same stop, another heading"] += 1
            else:
                counts["another stop (or a free move)"] += 1
        return np.asarray(chosen)[None]

    policy.act = recording_act  # type: ignore[method-assign]
    for seed in range(8):  # training seeds
        fly(make_fleet_instance("berlin", seed, 4, 48, separation="shield", hover_action=True), policy)
    return counts


def main() -> None:
    for prior in [float(x) for x in sys.argv[1:]] or [0.0, 3.0]:
        counts = kinds(prior)
        total = sum(counts.values())
        print(f"prior={prior:g}: {total} taxi-steps")
        for kind, n in counts.most_common():
            print(f"  {kind}: {n} ({n / total:.3f})")


if __name__ == "__main__":
    main()
