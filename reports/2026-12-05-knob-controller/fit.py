"""Fit the knob controller to the hindsight labels and say, by episode-grouped cross-validation on the training
episodes, how much distance its choices would save at a decision (switch and hold to the end, in that episode's
true future) against keeping onward's knobs, beside a best fixed knob and the hindsight best.

usage: python reports/2026-12-05-knob-controller/fit.py LABELS.pkl ... [--save MODEL.npz] [--ridge 1.0] [--margin 0]
"""

from __future__ import annotations

import argparse
import csv
import sys
from pathlib import Path

import numpy as np
from scipy import stats

sys.path.insert(0, str(Path(__file__).resolve().parent))
from features import NAMES, features
from label import read_records

COST_COLUMNS = [f"cost_s_{k}" for k in range(5)]
WAIT_COLUMNS = [f"wait_s_{k}" for k in range(5)]  # empty in the first run's rows (distance alone recorded)


def export(paths: list[str], out: str) -> None:
    """The records of ``paths`` (label.py's files) as one CSV: map, episode, t, the features, the 5 costs."""
    with open(out, "w", encoding="utf-8", newline="") as f:
        w = csv.writer(f)
        w.writerow(["map", "episode", "t", *NAMES, *COST_COLUMNS, *WAIT_COLUMNS])
        for path in paths:
            for r in read_records(path):
                x = features(r["state"], r["routes"], r["time_limit_steps"], r["slot_s"], r["side_m"])
                waits = r.get("waits_s", ("",) * len(WAIT_COLUMNS))
                w.writerow([Path(path).stem.rstrip("0123456789"), r["episode"], r["t"], *(f"{v:.6g}" for v in x),
                            *r["costs_s"], *waits])  # fmt: skip


def table(
    paths: list[str], wait_cost: float = 0.0, first_run: bool = False
) -> tuple[np.ndarray, np.ndarray, np.ndarray, list[str]]:
    """X [N, F], deltas [N, K] (s of flight plus ``wait_cost`` times s of waiting, knob k minus knob 0), groups [N]
    (episode ids), maps [N], from the CSV of :func:`export` (rows without waits left out when ``wait_cost`` > 0,
    rows with them when ``first_run``) or label.py's files (distance alone)."""
    X, D, G, M = [], [], [], []
    for path in paths:
        if path.endswith(".csv"):
            for row in csv.DictReader(open(path, encoding="utf-8")):
                if (wait_cost and not row[WAIT_COLUMNS[0]]) or (first_run and row[WAIT_COLUMNS[0]]):
                    continue
                X.append([float(row[n]) for n in NAMES])
                c = np.array([float(row[k]) for k in COST_COLUMNS])
                if wait_cost:
                    c = c + wait_cost * np.array([float(row[k]) for k in WAIT_COLUMNS])
                D.append(c - c[0])
                G.append(f"{row['map']}:{row['episode']}")
                M.append(row["map"])
            continue
        for r in read_records(path):
            X.append(features(r["state"], r["routes"], r["time_limit_steps"], r["slot_s"], r["side_m"]))
            c = np.array(r["costs_s"])
            D.append(c - c[0])
            G.append(f"{path}:{r['episode']}")
            M.append(Path(path).stem)
    return np.array(X), np.array(D), np.array(G), M


def fit_ridge(X: np.ndarray, D: np.ndarray, lam: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Weights [F, K] on standardised features (the bias column left as it is), with their mean and scale."""
    mu, sd = X.mean(0), X.std(0) + 1e-9
    mu[0], sd[0] = 0.0, 1.0
    Z = (X - mu) / sd
    reg = lam * len(Z) * np.eye(Z.shape[1])
    reg[0, 0] = 0.0
    W = np.linalg.solve(Z.T @ Z + reg, Z.T @ D)
    return W, mu, sd


def expand(X: np.ndarray, interact: bool) -> np.ndarray:
    """[N, F] features, with ``interact`` also every one but the bias times the map flag (one model per map, in
    one weight matrix): [N, 2F - 1]."""
    if not interact:
        return X
    return np.concatenate([X, X[:, 1:] * X[:, [NAMES.index("detroit")]]], axis=1)


def predict(model: tuple[np.ndarray, np.ndarray, np.ndarray], X: np.ndarray) -> np.ndarray:
    W, mu, sd = model
    return ((X - mu) / sd) @ W


def choose(pred: np.ndarray, margin: float) -> np.ndarray:
    """Knob per row: the least predicted delta if it is below -margin, else knob 0 (onward's own)."""
    k = pred.argmin(1)
    return np.where(pred[np.arange(len(pred)), k] < -margin, k, 0)


def clustered(values: np.ndarray, groups: np.ndarray) -> str:
    per = np.array([values[groups == g].mean() for g in np.unique(groups)])
    half = stats.t.ppf(0.975, len(per) - 1) * per.std(ddof=1) / np.sqrt(len(per))
    return f"{per.mean():+7.1f} ± {half:5.1f}"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("labels", nargs="+")
    ap.add_argument("--ridge", type=float, default=1.0)
    ap.add_argument("--margin", type=float, default=0.0)
    ap.add_argument("--folds", type=int, default=5)
    ap.add_argument("--save")
    ap.add_argument("--first-run", action="store_true", help="the first run's rows alone (distance, no waits)")
    ap.add_argument("--wait-cost", type=float, default=0.0, help="s of flight a second of waiting costs in the label")
    ap.add_argument("--export", help="write the labels as one CSV (the committed labels.csv) and stop")
    ap.add_argument("--interact", action="store_true", help="one model per map (features times the map flag)")
    a = ap.parse_args()
    if a.export:
        export(a.labels, a.export)
        return
    X, D, G, M = table(a.labels, a.wait_cost, a.first_run)
    M = np.array(M)
    X = expand(X, a.interact)
    episodes = np.unique(G)
    rng = np.random.default_rng(0)
    fold_of = dict(zip(rng.permutation(episodes), np.arange(len(episodes)) % a.folds, strict=True))
    fold = np.array([fold_of[g] for g in G])
    picked = np.zeros(len(X), int)
    for f in range(a.folds):
        model = fit_ridge(X[fold != f], D[fold != f], a.ridge)
        picked[fold == f] = choose(predict(model, X[fold == f]), a.margin)
    realized = D[np.arange(len(D)), picked]
    print(
        f"{len(X)} decisions, {len(episodes)} episodes; s of flight per decision vs onward's knobs (95 % over episodes)"
    )
    for m in sorted(set(M)):
        s = M == m
        fixed = [clustered(D[s, k], G[s]) for k in range(D.shape[1])]
        print(
            f"  {m}: controller {clustered(realized[s], G[s])} (switches {np.mean(picked[s] > 0):.0%}); "
            f"hindsight best {clustered(D[s].min(1), G[s])}"
        )
        print(f"    fixed knobs: {' | '.join(fixed)}")
    if a.save:
        W, mu, sd = fit_ridge(X, D, a.ridge)
        np.savez(a.save, W=W, mu=mu, sd=sd, names=np.array(NAMES), margin=a.margin, interact=a.interact)
        print(f"saved {a.save}")


if __name__ == "__main__":
    main()
