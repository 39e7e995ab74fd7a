"""Yardstick policies: raster and step-level planners (one taxi), a greedy fleet dispatcher, and a policy factory."""

from __future__ import annotations

from pathlib import Path
from typing import Any

from uamfleet.baselines.assignment_value import VALUE_DISPATCHER, value_for_dispatcher
from uamfleet.baselines.fleet_dispatch import (
    DISPATCHERS,
    WAIT_WEIGHT_SUFFIX,
    BatchAssignmentPolicy,
    InsertionPolicy,
    split_wait_weight,
)
from uamfleet.baselines.greedy_fleet import GreedyFleetPolicy
from uamfleet.baselines.planner_policy import PLANNERS, PlannerPolicy, planner_configs, planner_env_overrides
from uamfleet.baselines.random_policy import RandomPolicy
from uamfleet.baselines.step_planner import STEP_PLANNERS, StepPlannerPolicy

POLICIES: tuple[str, ...] = (*PLANNERS, *STEP_PLANNERS, "greedy", *DISPATCHERS, "random")
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
    with an optional ``+wait=<β>``: schedules cost ride time + β · wait), or random.

    Fly a planner under the ``flown`` config of :func:`planner_configs` (one seat for CPTSP, SINR ignored for the
    straight line) and score it against the ``scored`` one."""
    if name in PLANNERS or name in STEP_PLANNERS:
        if num_taxis != 1:
            raise ValueError(
                f"--policy {name} is a single-taxi planner but the fleet has {num_taxis} taxis; use a fleet "
                f"dispatcher (greedy, {', '.join(DISPATCHERS)}) or random for a fleet, or --num-taxis 1."
            )
        return PlannerPolicy(name) if name in PLANNERS else StepPlannerPolicy(name)
    base, wait_weight = split_wait_weight(name)
    if base != name and base not in DISPATCHERS and base.partition(":")[0] != VALUE_DISPATCHER:
        raise ValueError(
            f"--policy {name!r}: {WAIT_WEIGHT_SUFFIX}<β> weighs waits in a schedule dispatcher's costs; "
            f"{base!r} has none: use it with {', '.join(DISPATCHERS)} or {VALUE_DISPATCHER}[:<price_s>]."
        )
    if name == "greedy":
        return GreedyFleetPolicy()
    if base == "insertion":
        return InsertionPolicy(wait_weight=wait_weight)
    if base == "batch_assignment":
        return BatchAssignmentPolicy(wait_weight=wait_weight)
    if (value := value_for_dispatcher(base, assignment_value, arrival_window_s)) is not None:
        return BatchAssignmentPolicy(value=value, wait_weight=wait_weight)
    if name == "random":
        return RandomPolicy(seed=seed)
    raise ValueError(f"unknown --policy {name!r}; choose one of {POLICIES}.")


__all__ = [
    "DISPATCHERS",
    "PLANNERS",
    "POLICIES",
    "STEP_PLANNERS",
    "VALUE_DISPATCHER",
    "WAIT_WEIGHT_SUFFIX",
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
