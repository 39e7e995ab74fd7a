"""Fit the learned value of ``batch_assignment_value`` from the dispatcher's own experience (train split only).

    .venv/bin/python -m train.assignment_value --settings 2x24 4x48 6x72 8x96 --count 8 \\
        --out uamfleet/data/pretrained/assignment_value.json

Flies ``batch_assignment`` (or, with ``--fly-value FILE``, the dispatcher with that value: one step of policy
iteration; with ``--options``, e.g. ``+wait=1+release``, the options a dispatcher's name carries; with
``--heading onward``, its taxis steered as ``heading=onward`` steers them) on the first
``--count`` episodes of the **train** split of each setting (``4x48``, or ``detroit3gpp:4x24`` for another family:
one fit over all), under the shield with the hover action as the loaded benchmark rows, and records at every batch
that runs each taxi's post-decision state (when and where its route leaves it free) and who is on its plan, and
every pick-up. Each state's return is the discounted count of
the taxi's later pick-ups of passengers not on that plan (:mod:`uamfleet.baselines.assignment_value`); the linear
value is the ridge least-squares fit of those returns (LSTD(1), Monte-Carlo returns). The result is deterministic
(the train seeds and the dispatcher are), and written atomically as JSON with
``--price-s`` (seconds of ride time per unit of value; choose it on the validation split with
``uamfleet.cli.fleet_benchmark --split validation --dispatchers batch_assignment batch_assignment_value:<price>``).
"""

from __future__ import annotations

import resource
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from uamfleet.baselines.assignment_value import (
    FEATURES,
    LinearValue,
    discounted_future_pickups,
    fit_linear_value,
    load_value,
    post_state_features,
    save_value,
)
from uamfleet.baselines.batch_assignment import RecordingAssignment
from uamfleet.baselines.fleet_dispatch import DispatchOptions, split_options
from uamfleet.baselines.fleet_steering import check_heading, shared_fields
from uamfleet.checks import check_number
from uamfleet.cli._common import UsageError, check_outputs, output_paths, run
from uamfleet.cli.fleet_benchmark import setting_size
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import FAMILIES, FLEET_ARRIVAL_WINDOW_S, make_fleet_instance, split_seeds
from uamfleet.rollout import run_episode


@dataclass
class Args:
    family: str = "berlin"
    """instance family (uamfleet.instances.FAMILIES) of the settings that name none"""
    settings: tuple[str, ...] = ("2x24", "4x48", "6x72", "8x96")
    """fleet settings (taxis x requests) whose train episodes are flown; [<family>:]<taxis>x<requests>, e.g.
    detroit3gpp:4x24 (one fit over the episodes of every setting named)"""
    count: int = 8
    """train episodes per setting"""
    first: int = 0
    """index of the first seed in the train split"""
    horizon_s: float = 300.0
    """a pick-up t seconds after the decision counts exp(-t / horizon_s)"""
    ridge: float = 1e-3
    price_s: float = 0.0
    """seconds of ride time per unit of value written with the fit (0: the value is off until one is chosen)"""
    fly_value: Path | None = None
    """fly the dispatcher with this value instead of plain batch_assignment (policy iteration)"""
    options: str = ""
    """the flown dispatcher's options, as after a dispatcher's name (fleet_dispatch.split_options), e.g.
    "+wait=1+release": schedules cost ride time + 1 · wait, and a batch also runs at every release"""
    heading: str = "field"
    """how the flown dispatcher's taxis head for their stops (its heading option: field, table or onward;
    uamfleet.baselines.fleet_steering)"""
    out: Path = Path("uamfleet/data/pretrained/assignment_value.json")
    overwrite: bool = False
    """replace an existing --out"""


def episode_samples(
    policy: RecordingAssignment, horizon_s: float, arrival_window_s: float
) -> tuple[np.ndarray, np.ndarray]:
    """(features, Monte-Carlo returns) of one recorded episode, one row per (taxi, assignment)."""
    rows = policy.decisions
    columns = np.array([r[2:4] for r in rows], dtype=float).reshape(-1, 2)  # free, far
    feats = post_state_features(columns[:, 0], columns[:, 1], arrival_window_s)
    by_taxi: dict[int, list[tuple[int, float]]] = {}
    for p, taxi, t in policy.pickups:
        by_taxi.setdefault(taxi, []).append((p, t))
    returns = [discounted_future_pickups(now, plan, by_taxi.get(a, []), horizon_s) for a, now, _, _, plan in rows]
    return feats, np.array(returns, dtype=float)


def family_setting(setting: str, family: str) -> tuple[str, str]:
    """(family, setting) of a ``--settings`` entry: ``detroit3gpp:4x24``, or ``4x48`` in ``family``."""
    named, sep, size = setting.rpartition(":")
    if sep and named not in FAMILIES:
        raise UsageError(f"--settings {setting}: unknown family {named!r}; choose one of {tuple(FAMILIES)}.")
    setting_size(size)
    return (named if sep else family), size


def parse_options(text: str) -> DispatchOptions:
    """``--options`` (e.g. ``+wait=1+release``) read as after a dispatcher's name; "" is the plain dispatcher."""
    if text and not text.startswith("+"):
        raise UsageError(f"--options {text!r}: give options as after a dispatcher's name, e.g. +wait=1+release.")
    return split_options(f"batch_assignment{text}")[1]


def fly_recorded(
    family: str,
    setting: str,
    seed: int,
    value: LinearValue | None,
    options: DispatchOptions = DispatchOptions(),  # noqa: B008 (frozen)
    heading: str = "field",
) -> RecordingAssignment:
    """One train episode flown and recorded (shield and hover action, as the loaded benchmark rows)."""
    taxis, requests = setting_size(setting)
    cfg = make_fleet_instance(family, seed, taxis, requests, separation="shield", hover_action=True)
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    shared_fields(env.sim, warm=True)
    policy = RecordingAssignment(
        value=value,
        wait_weight=options.wait_weight,
        assign_on_release=options.assign_on_release,
        unassigned_price_s=options.unassigned_price_s,
        unassigned_guard_s=options.unassigned_guard_s,
        heading=heading,
    )
    run_episode(env, policy, seed=0)
    return policy


def main(args: Args) -> dict[str, Any]:
    flown_settings = [family_setting(setting, args.family) for setting in args.settings]
    options = parse_options(args.options)
    check_heading(args.heading, "--heading")
    seeds = split_seeds("train", args.count, args.first)
    check_number("--horizon-s", args.horizon_s, positive=True)
    check_number("--price-s", args.price_s, minimum=0.0)
    check_number("--ridge", args.ridge, minimum=0.0)
    if not args.settings:
        raise UsageError("--settings is empty: give at least one <taxis>x<requests> setting.")
    output_paths({"--out": args.out})
    check_outputs(args.overwrite, [args.out])
    flown = load_value(args.fly_value) if args.fly_value is not None else None
    start, cpu0 = time.perf_counter(), time.process_time()
    parts: list[tuple[np.ndarray, np.ndarray]] = []
    for seed in seeds:
        for family, setting in flown_settings:
            policy = fly_recorded(family, setting, seed, flown, options, args.heading)
            parts.append(episode_samples(policy, args.horizon_s, FLEET_ARRIVAL_WINDOW_S))
            print(
                f"{family} {setting} seed {seed}: {len(policy.decisions)} states, {len(policy.pickups)} pick-ups",
                flush=True,
            )
    feats, returns = (np.concatenate(column) for column in zip(*parts, strict=True))
    weights = fit_linear_value(feats, returns, args.ridge)
    wall, cpu = time.perf_counter() - start, time.process_time() - cpu0
    residual = float(np.sqrt(np.mean((feats @ weights - returns) ** 2)))
    meta = {
        "family": args.family, "settings": list(args.settings), "split": "train", "seeds": seeds,
        "episodes": len(parts), "states": len(returns), "mean_return": float(returns.mean()),
        "rmse": residual, "r2": 1.0 - residual**2 / max(float(returns.var()), 1e-12), "ridge": args.ridge,
"flown_with": str(args.fly_value) if args.fly_value else None,
        "options": {"wait_weight": options.wait_weight, "assign_on_release": options.assign_on_release}
        | ({} if options.unassigned_price_s is None else {"unassigned_price_s": options.unassigned_price_s})
        | ({} if options.unassigned_guard_s is None else {"unassigned_guard_s": options.unassigned_guard_s})
        | ({} if args.heading == "field" else {"heading": args.heading}),
        "wall_s": round(wall, 1), "cpu_s": round(cpu, 1),
        "peak_rss_mb": round(resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024, 1),
    }  # fmt: skip
    value = LinearValue(weights, args.price_s, args.horizon_s, FLEET_ARRIVAL_WINDOW_S, meta)
    save_value(args.out, value)
    print("weights: " + ", ".join(f"{n} {w:+.3f}" for n, w in zip(FEATURES, weights, strict=True)))
    print(f"wrote {args.out}: {len(returns)} states from {len(parts)} episodes, return mean {returns.mean():.2f}, "
          f"R² {meta['r2']:.3f}; {wall:.0f} s wall, {cpu:.0f} s CPU")  # fmt: skip
    return meta


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-assignment-value") -> int:
    """The ``python -m train.assignment_value`` command."""
    return run(main, Args, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.assignment_value"))
