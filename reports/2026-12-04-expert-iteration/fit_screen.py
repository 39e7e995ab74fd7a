"""Screen the fit's learning rate and epochs on the labels of an expert-iteration run (validation seeds only).

    .venv/bin/python reports/2026-12-04-expert-iteration/fit_screen.py runs/exit_berlin_s6 --rounds 0 1

For each (learning rate, epochs, anchor): the fit from the run's start on those rounds' labels, the agreement with
the labels by source (hedge / finish), the share of hedge labels whose argmax is the hover action and the fitted
network's argmax there, and greedy TD on the run's validation block paired against the start.
"""

from __future__ import annotations

import argparse
import copy
import itertools
from pathlib import Path

import numpy as np
import torch

from uamfleet.instances import split_seeds
from uamfleet.rl.expert_iteration import ExItOptions, fit, label_set, paired, start_policy, validation_flights
from uamfleet.rl.labels import HEDGE, Labels
from uamfleet.rl.networks import obs_to_torch
from uamfleet.types import HOVER_ACTION


def main() -> None:
    parser = argparse.ArgumentParser()
    parser.add_argument("run", type=Path)
    parser.add_argument("--rounds", type=int, nargs="+", default=[0])
    parser.add_argument("--lrs", type=float, nargs="+", default=[1e-4, 1e-3])
    parser.add_argument("--epochs", type=int, nargs="+", default=[3, 10])
    parser.add_argument("--anchors", type=float, nargs="+", default=[1.0])
    parser.add_argument("--val", type=int, default=80)
    a = parser.parse_args()
    torch.set_num_threads(1)
    opts = ExItOptions()
    _, start = start_policy(opts)
    labels = Labels.concat(
        [Labels.load(p) for r in a.rounds for p in sorted((a.run / "labels" / str(r)).glob("*.npz"))]
    )
    data = label_set(start, labels, opts)
    hedge = labels.source == HEDGE
    hover = hedge & (labels.target.argmax(-1) == HOVER_ACTION)
    print(f"{labels.num_labels} labels: {hedge.sum()} hedge ({hover.sum()} with hover best), {(~hedge).sum()} finish")
    seeds = [int(s) for s in split_seeds("validation", a.val, opts.val_first)]
    base = validation_flights(start, opts.family, seeds, True)
    for lr, epochs, anchor in itertools.product(a.lrs, a.epochs, a.anchors):
        policy = copy.deepcopy(start)
        stats = fit(policy, start, data, ExItOptions(learning_rate=lr, epochs=epochs, kl_anchor=anchor),
                    np.random.default_rng(0))  # fmt: skip
        with torch.no_grad():
            logits = policy.net.masked_logits(obs_to_torch(data.obs, "cpu"))
        argmax = logits.argmax(-1).numpy()
        target = labels.target.argmax(-1)
        flights = validation_flights(policy, opts.family, seeds, True)
        d, ci = paired(flights[:, 1], base[:, 1])
        print(f"lr {lr:g} epochs {epochs} anchor {anchor:g}: fit {stats}; agreement hedge "
              f"{(argmax == target)[hedge].mean():.3f} finish {(argmax == target)[~hedge].mean():.3f}; hover labels "
              f"flown as hover {(argmax == HOVER_ACTION)[hover].mean():.3f}, hover elsewhere "
              f"{(argmax == HOVER_ACTION)[~hover].mean():.3f}; val PR {flights[:, 0].mean():.1f} TD "
              f"{flights[:, 1].mean():,.0f} vs start {d:+.0f} ± {ci:.0f} m", flush=True)  # fmt: skip


if __name__ == "__main__":
    main()
