"""Can the claims network learn the onward dispatcher's heading? Label TRAIN+HELD training episodes of Berlin 4x48
and 8x96 flown by the onward dispatcher (beta 1) with its headings, fit the claims policy A' round 3 (with a zero
heading residual, or without) on the first TRAIN for EPOCHS epochs, and print the agreement with the teacher on the
held-out ones: overall, where the start disagreed (the labels it has to learn), and on the moves where the onward
rule flies another heading than the field rule (the move that makes a stop, aimed at the next: where the onward
dispatcher's gain is).

python reports/2026-12-05-fleet-onward-teacher/capacity.py [EPOCHS] [RESIDUAL_LR] [TRAIN] [HELD] [all|residual]
"""

from __future__ import annotations

import sys

import numpy as np
import torch

from uamfleet.baselines.fleet_steering import fleet_action
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.rl.fleet_imitation import (
    MASKED_LOG_PROB, FleetImitationArgs, fleet_policy, label_episode, make_teacher, parameter_groups,
)  # fmt: skip
from uamfleet.rl.imitation import Dataset, fit
from uamfleet.rl.networks import obs_to_torch

START = "reports/2026-12-04-fleet-val50/claims_hover01_r3.pt"
ONWARD = ("batch_assignment_value:value_price_s=100,wait=1,release=true,unassigned_price_s=1000,"
          "unassigned_guard_s=600,heading=onward")  # fmt: skip


def episodes(policy, count: int, first: int) -> tuple[list, np.ndarray]:
    """The labelled episodes and, per labelled row, whether onward's heading there is not the field rule's."""
    seeds = split_seeds("train", first + count)[first:]
    out, onward_moves = [], []

    def watch(env, obs, teacher, actions, log_probs) -> None:
        idle = [None] * len(actions)
        for a in range(len(actions)):
            target, after = teacher.target(a), teacher.stop_after(a)
            onward_moves.append(
                target is not None and after is not None
                and fleet_action(teacher.sim, teacher.fields, idle, a, target)
                != fleet_action(teacher.sim, teacher.fields, idle, a, target, onward=after)
            )  # fmt: skip

    for i, seed in enumerate(seeds):
        taxis, requests = (4, 48) if i % 2 == 0 else (8, 96)
        cfg = make_fleet_instance("berlin", seed, taxis, requests, separation="shield", hover_action=True)
        episode = label_episode(cfg, policy, make_teacher(ONWARD, taxis), 1.0, np.random.default_rng(i),
                                fit_floor=MASKED_LOG_PROB, watch=watch)  # fmt: skip
        assert episode.ruled_out == 0  # with the residual every label is fitted: rows align with the watch
        out.append(episode)
    return out, np.array(onward_moves)


def greedy(policy, obs: dict[str, np.ndarray]) -> np.ndarray:
    with torch.no_grad():
        return policy.net.masked_logits(obs_to_torch(obs, "cpu")).argmax(-1).numpy()


def main(epochs: int, residual_lr: float, train: int, held: int, which: str) -> None:
    torch.manual_seed(0)
    torch.set_num_threads(1)
    policy = fleet_policy(START, 24, heading_residual=True)
    args = FleetImitationArgs(heading_residual=True, fit_improbable=True, epochs=epochs,
                              residual_learning_rate=residual_lr)  # fmt: skip
    fitted, _ = episodes(policy, train, 0)
    test, onward_move = episodes(policy, held, 500)
    data = Dataset()
    for e in fitted:
        data.add(e.obs, e.labels, e.corrected)
    held_obs = {k: np.concatenate([e.obs[k] for e in test]) for k in test[0].obs}
    held_labels = np.concatenate([e.labels for e in test])
    before = greedy(policy, held_obs)
    wrong = before != held_labels
    groups = parameter_groups(policy.net, args)
    if which == "residual":
        groups = groups[1:]
    stats = fit(policy.net, data, args.fit_args(), torch.optim.Adam(groups), np.random.default_rng(0))
    after = greedy(policy, held_obs)
    print(f"epochs={epochs} residual_lr={residual_lr} fitted={which} train_rows={len(data.arrays()[1])} "
          f"held_rows={len(held_labels)} start_agreement={1 - wrong.mean():.3f} after={np.mean(after == held_labels):.3f} "
          f"on_start_wrong={np.mean(after[wrong] == held_labels[wrong]):.3f} "
          f"broke_right={np.mean(after[~wrong] != held_labels[~wrong]):.3f} onward_moves={onward_move.sum()} "
          f"start_on_them={np.mean(before[onward_move] == held_labels[onward_move]):.3f} "
          f"after_on_them={np.mean(after[onward_move] == held_labels[onward_move]):.3f} fit={stats}")  # fmt: skip


if __name__ == "__main__":
    a = sys.argv[1:]
    main(int(a[0]) if a else 10, float(a[1]) if len(a) > 1 else 0.01, int(a[2]) if len(a) > 2 else 8,
         int(a[3]) if len(a) > 3 else 4, a[4] if len(a) > 4 else "all")  # fmt: skip
