"""Fit the claims policy to the departures label.py measured: at each labelled point the better of the flown action
and the runner-up (by the episode's cost, when they differ by more than --min-delta) is the target of a
cross-entropy, the other rows keep the start's distribution (KL anchor). Held-out episodes (by seed) measure
whether the network predicts which departures help.

python reports/2026-12-05-fleet-departures/train.py --data /tmp/dep/*.npz --out departures.pt
"""

from __future__ import annotations

import argparse
import copy
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from uamfleet.rl.checkpoint import Checkpoint, checkpoint_source
from uamfleet.rl.fleet_imitation import fleet_policy, save_fleet_checkpoint
from uamfleet.rl.networks import obs_to_torch
from uamfleet.rl.ppo import categorical_kl

CHECKPOINT = "reports/2026-12-04-fleet-val50/claims_hover01_r3.pt"
SEED, STEP, TAXI, FLOWN, DEPARTURE, MARGIN, D_COST = range(7)
LABELS = {"total": D_COST, "h10": 12, "h30": 13, "h100": 14}


def label_delta(meta: np.ndarray, label: str) -> np.ndarray:
    """The departure's cost minus the flown action's, by ``label``: over the episode (``total``), the same minus
    its episode's median (``centered``: a flight that was unlucky makes most departures look better), or over
    the next 10 / 30 / 100 steps (``h10`` …)."""
    if label == "centered":
        out = meta[:, D_COST].copy()
        for s in np.unique(meta[:, SEED]):
            here = meta[:, SEED] == s
            out[here] -= np.median(out[here])
        return out
    return meta[:, LABELS[label]]


@dataclass
class DepartureArgs:
    data: list[str] = field(default_factory=list)
    init: str = CHECKPOINT
    min_delta: float = 100.0
    learning_rate: float = 1e-4
    epochs: int = 30
    kl_anchor: float = 1.0
    holdout: float = 0.25
    seed: int = 0


def load(paths: list[str]) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray], np.ndarray]:
    parts = [np.load(p) for p in paths]
    keys = [k[2:] for k in parts[0].files if k.startswith("x_")]
    x = {k: np.concatenate([p["x_" + k] for p in parts]) for k in keys}
    anchor = {k: np.concatenate([p["anchor_" + k] for p in parts]) for k in keys}
    width = max(p["meta"].shape[1] for p in parts)  # older files lack the horizon columns: NaN there
    meta = np.concatenate([np.pad(p["meta"], ((0, 0), (0, width - p["meta"].shape[1])), constant_values=np.nan)
                           for p in parts])  # fmt: skip
    return x, anchor, meta


def logits_of(net, rows: dict[str, np.ndarray], idx: np.ndarray) -> torch.Tensor:
    return net.masked_logits(obs_to_torch({k: v[idx] for k, v in rows.items()}, "cpu"))


def accuracy(net, x, meta, idx, targets, delta) -> dict[str, float]:
    """Among points ``idx``: how often the network prefers the better of (flown, departure); and how often the
    departure beats the flown action when the network prefers the departure."""
    with torch.no_grad():
        lg = logits_of(net, x, idx)
    flown, dep = meta[idx, FLOWN].astype(int), meta[idx, DEPARTURE].astype(int)
    rows = torch.arange(len(idx))
    prefers_dep = (lg[rows, dep] > lg[rows, flown]).numpy()
    better = targets[idx] == dep
    return {"agree": float(np.mean(prefers_dep == better)), "departs": float(np.mean(prefers_dep)),
            "departs_right": float(np.mean(better[prefers_dep])) if prefers_dep.any() else float("nan"),
            "base_rate_better": float(np.mean(better)),
            "taken_mean_delta": float(np.mean(delta[idx][prefers_dep])) if prefers_dep.any() else 0.0,
            "all_mean_delta": float(np.mean(delta[idx]))}  # fmt: skip


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--data", nargs="+", required=True)
    ap.add_argument("--min-delta", type=float, default=100.0)
    ap.add_argument("--label", default="total", choices=["total", "centered", "h10", "h30", "h100"])
    ap.add_argument("--learning-rate", type=float, default=1e-4)
    ap.add_argument("--epochs", type=int, default=30)
    ap.add_argument("--kl-anchor", type=float, default=1.0)
    ap.add_argument("--holdout", type=float, default=0.25, help="share of episodes (by seed) held out")
    ap.add_argument("--final", action="store_true", help="fit on every episode (no holdout) and save")
    ap.add_argument("--out", default=None)
    a = ap.parse_args()
    args = DepartureArgs(a.data, CHECKPOINT, a.min_delta, a.learning_rate, a.epochs, a.kl_anchor, a.holdout)
    torch.manual_seed(0)
    rng = np.random.default_rng(0)
    x, anchor, meta = load(a.data)
    delta = label_delta(meta, a.label)
    keep = np.abs(np.nan_to_num(delta)) > a.min_delta
    targets = np.where(delta < 0, meta[:, DEPARTURE], meta[:, FLOWN]).astype(np.int64)
    seeds = np.unique(meta[:, SEED])
    held = set(rng.choice(seeds, size=0 if a.final else max(1, int(len(seeds) * a.holdout)), replace=False))
    is_held = np.array([s in held for s in meta[:, SEED]])
    train_idx, test_idx = np.flatnonzero(keep & ~is_held), np.flatnonzero(keep & is_held)
    print(
        f"{len(meta)} points, {keep.sum()} with |delta| > {a.min_delta}: departure better on "
        f"{np.mean(delta[keep] < 0):.2f}; train {len(train_idx)}, held out {len(test_idx)} "
        f"({len(held)} of {len(seeds)} episodes)",
        flush=True,
    )
    policy = fleet_policy(CHECKPOINT, 24, dispatch_claims=True)
    net = policy.net
    reference = copy.deepcopy(net).eval().requires_grad_(False)
    opt = torch.optim.Adam(net.parameters(), lr=a.learning_rate, eps=1e-5)
    n_anchor = len(anchor["self"])
    with torch.no_grad():
        ref_anchor = logits_of(reference, anchor, np.arange(n_anchor))
    y = torch.as_tensor(targets)
    for epoch in range(a.epochs + 1):
        net.eval()
        if epoch % 5 == 0 or epoch == a.epochs:
            with torch.no_grad():
                moved = float((logits_of(net, anchor, np.arange(n_anchor)).argmax(-1) != ref_anchor.argmax(-1))
                              .float().mean())  # fmt: skip
            tr = accuracy(net, x, meta, train_idx, targets, delta)
            te = accuracy(net, x, meta, test_idx, targets, delta) if len(test_idx) else {}
            fmt = lambda d: " ".join(f"{k}={v:.3g}" for k, v in d.items())  # noqa: E731
            print(
                f"epoch {epoch}: train {fmt(tr)} | held out {fmt(te)} | anchor argmax changed {moved:.3f}", flush=True
            )
        if epoch == a.epochs:
            break
        net.train()
        for chunk in np.array_split(rng.permutation(train_idx), max(1, len(train_idx) // 256)):
            lg = logits_of(net, x, chunk)
            ce = torch.nn.functional.cross_entropy(lg, y[chunk])
            sample = rng.choice(n_anchor, size=min(512, n_anchor), replace=False)
            kl = categorical_kl(logits_of(net, anchor, sample), ref_anchor[sample]).mean()
            loss = ce + a.kl_anchor * kl
            opt.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 1.0)
            opt.step()
    net.eval()
    if a.out:
        row = {"points": float(len(train_idx)), "epochs": float(a.epochs)}
        save_fleet_checkpoint(Path(a.out), Checkpoint.load(checkpoint_source(CHECKPOINT)), net, args, row,
                              key="fleet_departures")  # fmt: skip
        print("wrote", a.out)


if __name__ == "__main__":
    main()
