"""Yardstick policies: raster and step-level planners (one taxi), a greedy fleet dispatcher, and a policy factory."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from uamfleet.baselines.assignment_value import VALUE_DISPATCHER, value_for_dispatcher
from uamfleet.baselines.batch_assignment import BatchAssignmentPolicy, InsertionPolicy
from uamfleet.baselines.fleet_dispatch import OPTION_SEPARATOR, SCHEDULE_DISPATCHERS, split_options
from uamfleet.baselines.greedy_fleet import GreedyFleetPolicy
from uamfleet.baselines.planner_policy import PLANNERS, PlannerPolicy, planner_configs, planner_env_overrides
from uamfleet.baselines.random_policy import RandomPolicy
from uamfleet.baselines.step_planner import STEP_PLANNERS, StepPlannerPolicy
from uamfleet.checks import MAX_SEED, MAX_TAXIS, ConfigError, check_integer, check_number

FLEET_DISPATCHERS: tuple[str, ...] = ("greedy", *SCHEDULE_DISPATCHERS)
"""The fleet dispatchers that need no learned value: ``greedy`` and the schedule dispatchers
(:data:`~uamfleet.baselines.fleet_dispatch.SCHEDULE_DISPATCHERS`). The fleet benchmark flies these by default;
``batch_assignment_value[:<price_s>]`` (:data:`VALUE_DISPATCHER`) is flown where named."""
POLICIES: tuple[str, ...] = (*PLANNERS, *STEP_PLANNERS, *FLEET_DISPATCHERS, "random")
"""Names accepted by :func:`make_policy` (and the ``--policy`` option of the eval commands)."""


def make_policy(
    name: str,
    seed: int = 0,
    num_taxis: int = 1,
    assignment_value: Path | None = None,
    arrival_window_s: float | None = None,
) -> Any:
    """A policy by name: a single-taxi planner (:data:`PLANNERS`, :data:`STEP_PLANNERS`), a fleet dispatcher
    (``greedy``, ``insertion``, ``batch_assignment``; ``batch_assignment_value[:<price_s>]`` with the learned value
    of ``assignment_value``, default the shipped file, for a service of ``arrival_window_s``; each of these three
    with the options of :func:`~uamfleet.baselines.fleet_dispatch.split_options`, e.g. ``+wait=1+release``), or
    random.

    Fly a planner under the ``flown`` config of :func:`planner_configs` (one seat for CPTSP, SINR ignored for the
    straight line) and score it against the ``scored`` one."""
    if not isinstance(name, str):
        raise ConfigError(f"--policy {name!r} is a {type(name).__name__}; name a policy, one of {POLICIES}.")
    seed = check_integer("seed", seed, 0, MAX_SEED)
    num_taxis = check_integer("num_taxis", num_taxis, 1, MAX_TAXIS)
    if arrival_window_s is not None:
        arrival_window_s = check_number("arrival_window_s", arrival_window_s, positive=True)
    if name in PLANNERS or name in STEP_PLANNERS:
        return _planner(name, num_taxis)
    if name == "random":
        return RandomPolicy(seed=seed)
    return _dispatcher(name, assignment_value, arrival_window_s)


def _planner(name: str, num_taxis: int) -> Any:
    """The single-taxi planner ``name``; ValueError for a fleet."""
    if num_taxis != 1:
        raise ValueError(
            f"--policy {name} is a single-taxi planner but the fleet has {num_taxis} taxis; use a fleet "
            f"dispatcher ({', '.join(FLEET_DISPATCHERS)}) or random for a fleet, or --num-taxis 1."
        )
    return PlannerPolicy(name) if name in PLANNERS else StepPlannerPolicy(name)


def _dispatcher(name: str, assignment_value: Path | None, arrival_window_s: float | None) -> Any:
    """The fleet dispatcher ``name`` with the options it carries (:func:`make_policy`)."""
    base, options = split_options(name)
    batch = base == "batch_assignment" or base.partition(":")[0] == VALUE_DISPATCHER
    if base != name and not (batch or base == "insertion"):
        raise ValueError(
            f"--policy {name!r}: options after {OPTION_SEPARATOR!r} belong to the schedule dispatchers "
            f"({', '.join(SCHEDULE_DISPATCHERS)}, {VALUE_DISPATCHER}[:<price_s>]), not to {base!r}."
        )
    if options.assign_on_release and not batch:
        raise ValueError(f"--policy {name!r}: +release times a batch assignment; {base!r} assigns each release.")
    if options.unassigned_price_s is not None and not batch:
        raise ValueError(f"--policy {name!r}: +price prices what a batch assignment leaves out; {base!r} has none.")
    if name == "greedy":
        return GreedyFleetPolicy()
    if base == "insertion":
        return InsertionPolicy(wait_weight=options.wait_weight)
    if batch:
        return BatchAssignmentPolicy(
            value=value_for_dispatcher(base, assignment_value, arrival_window_s),
            wait_weight=options.wait_weight,
            assign_on_release=options.assign_on_release,
            unassigned_price_s=options.unassigned_price_s,
            unassigned_guard_s=options.unassigned_guard_s,
        )
    raise ValueError(f"unknown --policy {name!r}; choose one of {POLICIES}.")


__all__ = [
    "FLEET_DISPATCHERS",
    "OPTION_SEPARATOR",
    "PLANNERS",
    "POLICIES",
    "SCHEDULE_DISPATCHERS",
    "STEP_PLANNERS",
    "VALUE_DISPATCHER",
    "BatchAssignmentPolicy",
    "GreedyFleetPolicy",
    "InsertionPolicy",
    "PlannerPolicy",
    "RandomPolicy",
    "StepPlannerPolicy",
    "make_policy",
    "planner_configs",
    "planner_env_overrides",
]
