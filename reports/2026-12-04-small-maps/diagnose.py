"""Where a learned policy's extra metres come from on a map's validation instances, against ``replan``.

Each step of an episode is classed by what the taxi knows after the previous step: ``idle`` (nobody on board and
no released request waiting: nothing to fly to) or ``busy``. Metres flown in each class, per method; and the
range (min, max) of every observation field the policy reads, so that a map's inputs can be set against Berlin's.

    PYTHONPATH=$PWD python reports/2026-12-04-small-maps/diagnose.py --map berlin --count 30
"""

from __future__ import annotations

import argparse

import numpy as np

from uamfleet.instances import make_instance, split_seeds
from uamfleet.policies import make_named
from uamfleet.rollout import Trajectory, fly


def idle_before_step(traj: Trajectory) -> np.ndarray:
    """[T] bool: before step t, nobody is on board and every released request is delivered."""
    exists = traj.pax_exists
    released = traj.release_step[None, :] <= np.arange(traj.num_steps)[:, None]  # released at step t's start
    delivered = np.zeros(len(exists), bool)
    picked = np.zeros(len(exists), bool)
    idle = []
    for t, ev in enumerate(traj.events):
        on_board = picked & ~delivered
        waiting = exists & released[t] & ~picked
        idle.append(not on_board.any() and not waiting.any())
        picked |= ev.picked_up[0]
        delivered |= ev.dropped_off[0]
    return np.array(idle)


def split_metres(traj: Trajectory) -> tuple[float, float, int, int]:
    """Metres flown while idle and while busy, and the steps of each."""
    idle = idle_before_step(traj)
    flown = np.linalg.norm(np.diff(traj.positions_m[0], axis=0), axis=-1)
    return float(flown[idle].sum()), float(flown[~idle].sum()), int(idle.sum()), int((~idle).sum())


class Recorder:
    """Wraps a policy and keeps the min and max of every observation field it is given."""

    def __init__(self, policy: object) -> None:
        self.policy, self.low, self.high = policy, {}, {}

    def reset(self, sim: object) -> None:
        self.policy.reset(sim)  # type: ignore[attr-defined]

    @property
    def spec(self) -> object:
        return self.policy.spec  # type: ignore[attr-defined]

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        for key, value in obs.items():
            if np.issubdtype(np.asarray(value).dtype, np.number) and np.size(value):
                self.low[key] = min(self.low.get(key, np.inf), float(np.min(value)))
                self.high[key] = max(self.high.get(key, -np.inf), float(np.max(value)))
        return self.policy.act(obs)  # type: ignore[attr-defined]


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("--map", default="berlin")
    parser.add_argument("--count", type=int, default=30)
    parser.add_argument("--policy", default="learned:source=berlin", help="a learned policy's name")
    args = parser.parse_args()
    learned = Recorder(make_named(args.policy))
    replan = make_named("replan")
    totals = {"learned": np.zeros(4), "replan": np.zeros(4)}
    for seed in split_seeds("validation", args.count):
        cfg = make_instance(args.map, seed, max_passengers=6)
        for name, policy in (("learned", learned), ("replan", replan)):
            totals[name] += split_metres(fly(cfg, policy))
    for name, (idle_m, busy_m, idle_steps, busy_steps) in totals.items():
        n = args.count
        print(
            f"{args.map} {name}: idle {idle_m / n:,.0f} m over {idle_steps / n:.1f} steps, "
            f"busy {busy_m / n:,.0f} m over {busy_steps / n:.1f} steps (means over {n} validation instances)"
        )
    for key in sorted(learned.low):
        print(f"  {key}: {learned.low[key]:.3g} .. {learned.high[key]:.3g}")


if __name__ == "__main__":
    main()
