"""A learned value of a taxi's post-decision state for ``batch_assignment`` (approximate dynamic programming).

In the style of NeurADP (Shah, Lowalekar, Varakantham, AAAI 2020), the trip assignment of
:class:`~uamfleet.baselines.batch_assignment.BatchAssignmentPolicy` may score each (taxi, trip) by its immediate cost
(the increase of the taxi's total ride time, seconds) **minus** ``price_s`` times the learned value of the state
the taxi is left in, relative to taking no new trip:

    cost'(taxi, trip) = cost(taxi, trip) - price_s * (V(after trip) - V(after no trip))

Taking no trip costs 0 in the programme, so subtracting the no-trip value keeps it the reference (the programme
picks at most one trip per taxi, so this equals adding ``-price_s * V`` to every choice, the no-trip one included).

**The post-decision state** of a taxi is where and when its planned route leaves it free: the point of its last
stop (its position if the route is empty) and the time it gets there (:class:`PostState`).
**The value** counts future work: the expected number of passengers the taxi will pick up later that are not on
its plan now, discounted by ``exp(-(pick-up time - decision time) / horizon_s)``. This is NeurADP's reward (one
per request served), with pick-ups as the events because ``batch_assignment`` re-assigns waiting requests until
someone picks them up. ``price_s`` converts a future passenger into seconds of ride time; it is a knob, chosen on
validation episodes.

**The approximator** is linear in a few dimensionless features (:func:`post_state_features`): the share of the
arrival window (the operator's service period, known to a dispatcher) still open when the taxi is free, its square,
and the mean distance from where it ends to the map's flyable sites (where requests are drawn) in units of the mean
distance between two sites, alone and times the open share. The weights are fitted by least squares to the
Monte-Carlo returns of the dispatcher's own episodes (:func:`fit_linear_value`, i.e. LSTD(1) with a ridge), those
of the open-share columns kept >= 0 so that the value never grows with the time the taxi is free
(:data:`INCREASING`). A TD(0) fit needs a reward that depends only on a transition, and this one does not: whether a
pick-up is new depends on the plans at both ends, which later re-assignments change. Files are JSON
(:func:`save_value`, :func:`load_value`).
"""

from __future__ import annotations

import dataclasses
import json
import math
from importlib import resources
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.optimize import lsq_linear

from uamfleet.checks import ConfigError, is_number
from uamfleet.io import write_text_atomic

FEATURES: tuple[str, ...] = ("bias", "open_share", "open_share_sq", "remoteness_x_open_share", "remoteness")
"""The names of :func:`post_state_features`' columns, in order."""

INCREASING: tuple[int, ...] = (1, 2, 3)
"""The columns whose weights the fit keeps >= 0. Each grows with the open share (remoteness is positive), so a
taxi's value never grows with the time it is free at the same place: a taxi free earlier can always hover until
the later time. A first fit without this rule, with a column of the time until the taxi is free, rewarded longer
routes: priced at 400 s, riders waited until the time limit (reports/2026-12-03-results-history/README.md,
"A learned value inside `batch_assignment`")."""

MAX_SECONDS = 1e9
"""Upper bound of every time and price in seconds of the dispatchers (``price_s``, ``penalty_s``, ``+price=<s>``,
``+guard=<s>``; 32 years): costs stay far from float overflow, so an assignment never compares infinities."""
VALUE_DISPATCHER = "batch_assignment_value"
"""The dispatcher name of ``batch_assignment`` with a learned value; ``batch_assignment_value:<price_s>`` prices it
other than its file does (:func:`value_for_dispatcher`)."""
CHOSEN_DISPATCHER = f"{VALUE_DISPATCHER}:100+wait=1+release+price=1000+guard=600"
"""The fleet dispatcher chosen on validation episodes, the yardstick of the fleet tables (docs/results.md): the
learned value priced at 100 s, a 1-step wait before releasing a batch, the price of a release and the guard."""


@dataclass(frozen=True)
class PostState:
    """A taxi after a decision: it is free at ``free_s`` (episode seconds) at ``end_m`` [2]."""

    end_m: np.ndarray
    free_s: float


class SiteRemoteness:
    """Mean straight-line distance from a point to every flyable site, in units of the mean distance between two
    sites (about 1 at a typical site; lower is central). Requests are drawn uniformly over these sites, so this is a
    demand-free measure of how far a taxi that ends at the point is from where the next requests will appear."""

    def __init__(self, sites_m: np.ndarray, max_pairs: int = 512) -> None:
        sites = np.asarray(sites_m, dtype=float)
        if sites.ndim != 2 or sites.shape[1] != 2 or len(sites) < 2:
            raise ValueError(f"sites_m must be [S, 2] with S >= 2 sites, got shape {sites.shape}.")
        step = max(1, len(sites) // max_pairs)  # an even subsample keeps the pairwise mean cheap on big maps
        sample = sites[::step]
        pair = np.linalg.norm(sample[:, None] - sample[None], axis=-1)
        self.sites_m = sites
        self.scale_m = float(pair.sum() / (len(sample) * (len(sample) - 1)))

    def __call__(self, points_m: np.ndarray) -> np.ndarray:
        """[N] remoteness of ``points_m`` [N, 2]."""
        pts = np.atleast_2d(np.asarray(points_m, dtype=float))
        return np.linalg.norm(pts[:, None] - self.sites_m[None], axis=-1).mean(axis=1) / self.scale_m


def post_state_features(free_s: np.ndarray, remoteness: np.ndarray, arrival_window_s: float) -> np.ndarray:
    """[N, len(FEATURES)] features of N post-decision states (module docstring): free at ``free_s`` [N] seconds
    (episode time), ending at points of ``remoteness`` [N]."""
    free = np.asarray(free_s, dtype=float)
    far = np.asarray(remoteness, dtype=float)
    open_share = np.clip((arrival_window_s - free) / arrival_window_s, 0.0, 1.0)
    return np.stack([np.ones_like(free), open_share, open_share**2, far * open_share, far], axis=1)


@dataclass
class LinearValue:
    """V(state) = features · weights; ``price_s`` seconds of ride time per unit of value in the assignment."""

    weights: np.ndarray
    price_s: float = 0.0
    horizon_s: float = 300.0
    arrival_window_s: float = 600.0
    meta: dict | None = None

    def __post_init__(self) -> None:
        self.weights = np.asarray(self.weights, dtype=float)
        if self.weights.shape != (len(FEATURES),):
            raise ValueError(
                f"weights must have {len(FEATURES)} entries ({', '.join(FEATURES)}), got {self.weights.shape}."
            )
        for name in ("price_s", "horizon_s", "arrival_window_s"):
            value = getattr(self, name)
            if not is_number(value) or not math.isfinite(value) or value < 0 or (name != "price_s" and value == 0):
                raise ValueError(f"{name}={value!r} must be finite and {'>= 0' if name == 'price_s' else '> 0'}.")
            if value > MAX_SECONDS:
                raise ConfigError(f"{name}={value!r} is too large: at most {MAX_SECONDS:g} s.")

    def with_price(self, price_s: float) -> LinearValue:
        return LinearValue(self.weights, price_s, self.horizon_s, self.arrival_window_s, self.meta)

    def values(self, free_s: np.ndarray, remoteness: np.ndarray) -> np.ndarray:
        """[N] V of N post-decision states."""
        return post_state_features(free_s, remoteness, self.arrival_window_s) @ self.weights


def discounted_future_pickups(
    decision_s: float, plan: Sequence[int], pickups: Sequence[tuple[int, float]], horizon_s: float
) -> float:
    """The return of one post-decision state: the sum over the taxi's pick-ups after ``decision_s`` of passengers
    not on its ``plan`` then of exp(-(pick-up time - decision_s) / horizon_s); ``pickups``: (passenger, time s)."""
    planned = set(plan)
    return float(
        sum(math.exp(-(t - decision_s) / horizon_s) for p, t in pickups if t > decision_s and p not in planned)
    )


def fit_linear_value(
    features: np.ndarray, returns: np.ndarray, ridge: float = 1e-3, nonnegative: Sequence[int] = INCREASING
) -> np.ndarray:
    """Weights w minimising |features · w - returns|² + ridge · n · |w|² with w[i] >= 0 for i in ``nonnegative``
    (ridge scaled by the sample count n; ``scipy.optimize.lsq_linear`` on the stacked system)."""
    x, y = np.asarray(features, dtype=float), np.asarray(returns, dtype=float)
    if x.ndim != 2 or y.shape != (len(x),) or not len(x):
        raise ValueError(f"features [N, F] and returns [N] with N >= 1 expected, got {x.shape} and {y.shape}.")
    if not (np.isfinite(x).all() and np.isfinite(y).all()):
        raise ValueError("features and returns must be finite; a NaN or inf came from the recorded episodes.")
    lower = np.full(x.shape[1], -np.inf)
    lower[list(nonnegative)] = 0.0
    a = np.vstack([x, math.sqrt(ridge * len(x)) * np.eye(x.shape[1])])
    b = np.concatenate([y, np.zeros(x.shape[1])])
    return np.asarray(lsq_linear(a, b, bounds=(lower, np.inf), method="bvls", tol=1e-12).x)


def save_value(path: Path, value: LinearValue) -> None:
    """Write the value as JSON atomically (a temporary file renamed over ``path``)."""
    body = {
        "features": list(FEATURES),
        "weights": [float(w) for w in value.weights],
        "price_s": value.price_s,
        "horizon_s": value.horizon_s,
        "arrival_window_s": value.arrival_window_s,
        "meta": value.meta or {},
    }
    write_text_atomic(path, json.dumps(body, indent=2) + "\n")


def load_value(path: Path) -> LinearValue:
    """The value written by :func:`save_value`; refuses a file of other features."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"no assignment value at {path}; train one with `python -m train.assignment_value`.")
    body = json.loads(path.read_text(encoding="utf-8"))
    if tuple(body.get("features", ())) != FEATURES:
        raise ValueError(f"{path} holds features {body.get('features')}, this code reads {list(FEATURES)}; refit it.")
    return LinearValue(
        np.array(body["weights"]), body["price_s"], body["horizon_s"], body["arrival_window_s"], body.get("meta")
    )


def shipped_value_path() -> Path:
    """The value shipped with the package (``uamfleet/data/pretrained/assignment_value.json``)."""
    return Path(str(resources.files("uamfleet") / "data" / "pretrained" / "assignment_value.json"))


def value_for_dispatcher(
    name: str, path: Path | None = None, arrival_window_s: float | None = None
) -> LinearValue | None:
    """The value a dispatcher name flies: None unless ``name`` is :data:`VALUE_DISPATCHER` (the file's price) or
    ``batch_assignment_value:<price_s>``; read from ``path`` (default :func:`shipped_value_path`), with the
    service's ``arrival_window_s`` when given."""
    head, sep, price = name.partition(":")
    if head != VALUE_DISPATCHER:
        return None
    value = load_value(path if path is not None else shipped_value_path())
    if sep:
        try:
            value = value.with_price(float(price))
        except ValueError as err:
            raise ConfigError(
                f"dispatcher {name!r}: give {VALUE_DISPATCHER}:<price_s> with a finite price in [0, {MAX_SECONDS:g}] "
                f"in seconds of ride time per unit of value (e.g. {VALUE_DISPATCHER}:60); {err}"
            ) from None
    if arrival_window_s is not None:
        value = dataclasses.replace(value, arrival_window_s=arrival_window_s)
    return value


__all__ = [
    "CHOSEN_DISPATCHER",
    "FEATURES",
    "INCREASING",
    "MAX_SECONDS",
    "VALUE_DISPATCHER",
    "LinearValue",
    "PostState",
    "SiteRemoteness",
    "discounted_future_pickups",
    "fit_linear_value",
    "load_value",
    "post_state_features",
    "save_value",
    "shipped_value_path",
    "value_for_dispatcher",
]
