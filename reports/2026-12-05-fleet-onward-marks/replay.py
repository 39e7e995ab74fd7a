"""Replay Berlin 8 x 96 test seed 2000026, the first test flight's short episode, with and without make_way.

python reports/2026-12-05-fleet-onward-marks/replay.py   (about 30 s on one core)

Prints, for each, the steps flown and who was not delivered; without make_way it also prints, every 25 steps from
step 300, each taxi's action and its distance from the taxi carrying the undelivered rider (taxi 4 flies toward
taxi 1, hovering 52 m ahead, and back).
"""

from __future__ import annotations

import numpy as np

from uamfleet import policies
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import make_fleet_instance
from uamfleet.rollout import observer_of
from uamfleet.types import DELIVERED

NAME = "fleet_claims:source=reports/2026-12-04-fleet-val50/claims_hover01_r3.pt,heading=onward"


def replay(name: str) -> None:
    cfg = make_fleet_instance("berlin", 2000026, 8, 96, separation="shield", hover_action=True)
    policy = policies.make_named(name)
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy))
    obs, _ = env.reset(seed=0)
    policy.reset(env.sim)
    log = []
    step = 0
    while True:
        actions = policy.act(obs)
        log.append((step, actions[0].copy(), env.sim.state.pos_m[0].copy()))
        obs, _, terminated, truncated, _ = env.step(actions)
        if terminated[0] or truncated[0]:
            break
        step += 1
    s = env.sim.state
    short = np.flatnonzero(s.pax_exists[0] & (s.pax_status[0] != DELIVERED))
    print(
        f"{name}: {step + 1} steps, not delivered: {short.tolist()} (carried by taxi {s.pax_taxi[0, short].tolist()})"
    )
    for p in short:
        carrier = int(s.pax_taxi[0, p])
        for step, actions, pos in log[300::25]:
            gaps = np.linalg.norm(pos - pos[carrier], axis=1).round().astype(int)
            print(f"  step {step}: actions {actions.tolist()}, metres from taxi {carrier}: {gaps.tolist()}")


if __name__ == "__main__":
    replay(NAME)
    replay(NAME + ",make_way=true")
