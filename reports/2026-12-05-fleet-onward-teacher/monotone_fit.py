"""The learned value refit on heading=onward's episodes with the monotonicity the value fit's sign constraints stand
for, and no more: dV/d(open share) >= 0 over the whole box of open share [0, 1] x the remoteness seen (four corner
constraints, V being quadratic in the open share and linear in remoteness), instead of each of the three open-share
weights >= 0 (which forces the square's weight to 0). The same states as refit_onward.json (8 training episodes of
2x24, 4x48, 6x72, 8x96 flown by onward with the shipped value); the held-out R^2 of both fits on the second half of
those episodes when fitted on the first; writes refit_onward_monotone.json (price 100 s) fitted on all of them.

python reports/2026-12-05-fleet-onward-teacher/monotone_fit.py OUT.json
"""

from __future__ import annotations

import sys

import numpy as np
from scipy.optimize import minimize

from uamfleet.baselines.assignment_value import (
    LinearValue, fit_linear_value, load_value, save_value, shipped_value_path,
)  # fmt: skip
from uamfleet.cli.assignment_value import episode_samples, fly_recorded, parse_options
from uamfleet.instances import FLEET_ARRIVAL_WINDOW_S, split_seeds

SETTINGS = ("2x24", "4x48", "6x72", "8x96")
RIDGE = 1e-3


def monotone_fit(x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Ridge least squares of ``y`` on ``x`` (the five features) with dV/do >= 0 at the box's four corners."""
    r_lo, r_hi = x[:, 4].min(), x[:, 4].max()
    corners = [(o, r) for o in (0.0, 1.0) for r in (r_lo, r_hi)]
    n = len(y)  # scaled by the count: a well-conditioned objective for SLSQP
    gram, rhs = (x.T @ x + RIDGE * np.eye(5)) / n, x.T @ y / n
    cons = [{"type": "ineq", "fun": lambda w, o=o, r=r: w[1] + 2 * w[2] * o + w[3] * r} for o, r in corners]
    start = fit_linear_value(x, y, RIDGE)  # feasible: every term >= 0
    out = minimize(lambda w: w @ gram @ w - 2 * rhs @ w, start, jac=lambda w: 2 * (gram @ w - rhs),
                   constraints=cons, method="SLSQP", options={"ftol": 1e-12, "maxiter": 500})  # fmt: skip
    assert out.success, out.message
    return out.x


def r2(w: np.ndarray, x: np.ndarray, y: np.ndarray) -> float:
    return 1.0 - float(np.var(y - x @ w) / np.var(y))


def main(out: str) -> None:
    options = parse_options("+wait=1+release+price=1000+guard=600")
    shipped = load_value(shipped_value_path())
    parts = []
    for seed in split_seeds("train", 8):
        for setting in SETTINGS:
            policy = fly_recorded("berlin", setting, seed, shipped, options, "onward")
            parts.append(episode_samples(policy, 300.0, FLEET_ARRIVAL_WINDOW_S))
    half = len(parts) // 2
    x_fit, y_fit = (np.concatenate(c) for c in zip(*parts[:half], strict=True))
    x_test, y_test = (np.concatenate(c) for c in zip(*parts[half:], strict=True))
    for label, fit in (("sign constraints", fit_linear_value), ("monotone in open share", monotone_fit)):
        w = fit(x_fit, y_fit) if fit is monotone_fit else fit(x_fit, y_fit, RIDGE)
        print(f"{label:<24} held-out R2 {r2(w, x_test, y_test):.3f}, weights {np.round(w, 3)}")
    x, y = (np.concatenate(c) for c in zip(*parts, strict=True))
    w = monotone_fit(x, y)
    meta = {"fit": "monotone in open share (reports/2026-12-05-fleet-onward-teacher/monotone_fit.py)",
            "flown_with": "shipped value", "options": "+wait=1+release+price=1000+guard=600", "heading": "onward",
            "settings": list(SETTINGS), "split": "train", "episodes": len(parts), "states": len(y),
            "r2": r2(w, x, y)}  # fmt: skip
    save_value(out, LinearValue(w, 100.0, 300.0, FLEET_ARRIVAL_WINDOW_S, meta))
    print(f"wrote {out}: weights {np.round(w, 3)}, R2 {meta['r2']:.3f} on {len(y)} states")


if __name__ == "__main__":
    main(sys.argv[1])
