"""Does the fleet around a taxi explain its value beyond the five linear features? Fly heading=onward (the chosen
dispatcher's options and shipped value) on training episodes, record each taxi's post-decision state at every batch
as the value fit does (uamfleet.cli.assignment_value) plus where every other taxi's route then ends and when, and
compare the held-out fit of the Monte-Carlo returns: the five features against the five plus the fleet context
(distance from the taxi's end to the nearest other taxi free before it, in units of the mean site distance, and
the count of other taxis ending within one such unit, each also times the open share). Fit on the first half of the
episodes, scored on the second half (R^2 and RMSE).

python reports/2026-12-05-fleet-onward-teacher/value_context.py [EPISODES_PER_SETTING]   (default 8)
"""

from __future__ import annotations

import sys

import numpy as np

from uamfleet.baselines.assignment_value import fit_linear_value, load_value, shipped_value_path
from uamfleet.baselines.batch_assignment import RecordingAssignment
from uamfleet.baselines.fleet_steering import shared_fields
from uamfleet.cli.assignment_value import episode_samples
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import FLEET_ARRIVAL_WINDOW_S, make_fleet_instance, split_seeds
from uamfleet.rollout import run_episode

SETTINGS = ((4, 48), (8, 96))
HORIZON_S = 300.0


class ContextRecording(RecordingAssignment):
    """The recorder, also keeping where and when every taxi's route ends at each batch (after the assignment)."""

    def reset(self, sim) -> None:  # type: ignore[no-untyped-def]
        super().reset(sim)
        self.ends: list[tuple[np.ndarray, np.ndarray]] = []  # per batch: [A, 2] end points, [A] free times

    def dispatch(self, released: list[int]) -> None:
        before = len(self.decisions)
        super().dispatch(released)
        if len(self.decisions) == before:
            return
        pos = self.sim.state.pos_m[0]
        ends = np.array([self.stop_point(r[-1]) if (r := self.routes[a]) else pos[a] for a in range(self.num_taxis)])
        free = np.array([row[2] for row in self.decisions[before:]])
        self.ends.append((ends, free))


def episode_rows(taxis: int, requests: int, seed: int) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    cfg = make_fleet_instance("berlin", seed, taxis, requests, separation="shield", hover_action=True)
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    shared_fields(env.sim, warm=True)
    policy = ContextRecording(value=load_value(shipped_value_path()), wait_weight=1.0, assign_on_release=True,
                              unassigned_price_s=1000.0, unassigned_guard_s=600.0, heading="onward")  # fmt: skip
    run_episode(env, policy, seed=0)
    base, returns = episode_samples(policy, HORIZON_S, FLEET_ARRIVAL_WINDOW_S)  # as the value fit reads them
    unit = policy._remoteness.scale_m
    context = []
    for ends, free in policy.ends:
        for a in range(len(ends)):
            others = [b for b in range(len(ends)) if b != a and free[b] <= free[a]]  # free before it: its rivals
            gaps = np.linalg.norm(ends[others] - ends[a], axis=-1) / unit if others else np.array([3.0])
            context.append((min(float(gaps.min()), 3.0), float((gaps < 1.0).sum())))
    ctx = np.array(context)
    open_share = base[:, 1:2]
    return np.hstack([base, ctx, ctx * open_share]), base, returns


def scores(x_fit, y_fit, x_test, y_test, constrained: bool = False) -> tuple[float, float]:
    """Held-out (R^2, RMSE) of a ridge least-squares fit: the value fit's own (its sign constraints) or plain."""
    if constrained:
        w = fit_linear_value(x_fit, y_fit, 1e-3)
    else:
        k = x_fit.shape[1]
        w = np.linalg.lstsq(np.vstack([x_fit, np.sqrt(1e-3) * np.eye(k)]), np.concatenate([y_fit, np.zeros(k)]),
                            rcond=None)[0]  # fmt: skip
    residual = y_test - x_test @ w
    return 1.0 - residual.var() / y_test.var(), float(np.sqrt(np.mean(residual**2)))


def main(count: int) -> None:
    seeds = split_seeds("train", count)
    parts = [episode_rows(t, r, s) for s in seeds for t, r in SETTINGS]
    half = len(parts) // 2
    full_fit, base_fit, y_fit = (np.concatenate(c) for c in zip(*parts[:half], strict=True))
    full_test, base_test, y_test = (np.concatenate(c) for c in zip(*parts[half:], strict=True))
    print(f"{len(parts)} episodes, {len(y_fit)} states fitted, {len(y_test)} held out")
    rows = (
        ("five features, the value fit's constraints", scores(base_fit, y_fit, base_test, y_test, constrained=True)),
        ("five features, plain ridge", scores(base_fit, y_fit, base_test, y_test)),
        ("plus fleet context, plain ridge", scores(full_fit, y_fit, full_test, y_test)),
    )
    for label, (r2, rmse) in rows:
        print(f"{label:<44} R2 {r2:.3f}, RMSE {rmse:.3f}")


if __name__ == "__main__":
    main(int(sys.argv[1]) if len(sys.argv) > 1 else 8)
