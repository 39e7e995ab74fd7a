"""Yardstick policies: raster and step-level planners (one taxi) and the fleet dispatchers (built by name through
:mod:`uamfleet.policies`)."""

from __future__ import annotations

from uamfleet.baselines.assignment_value import VALUE_DISPATCHER
from uamfleet.baselines.batch_assignment import BatchAssignmentPolicy, InsertionPolicy
from uamfleet.baselines.fleet_dispatch import OPTION_SEPARATOR, SCHEDULE_DISPATCHERS
from uamfleet.baselines.greedy_fleet import GreedyFleetPolicy
from uamfleet.baselines.planner_policy import PLANNERS, PlannerPolicy, planner_configs, planner_env_overrides
from uamfleet.baselines.random_policy import RandomPolicy
from uamfleet.baselines.step_planner import STEP_PLANNERS, StepPlannerPolicy

FLEET_DISPATCHERS: tuple[str, ...] = ("greedy", *SCHEDULE_DISPATCHERS)
"""The fleet dispatchers that need no learned value: ``greedy`` and the schedule dispatchers
(:data:`~uamfleet.baselines.fleet_dispatch.SCHEDULE_DISPATCHERS`). The fleet benchmark flies these by default;
``batch_assignment_value[:<price_s>]`` (:data:`VALUE_DISPATCHER`) is flown where named."""
POLICIES: tuple[str, ...] = (*PLANNERS, *STEP_PLANNERS, *FLEET_DISPATCHERS, "random")
"""The names a flight by name takes (:func:`uamfleet.policies.make_flown`, the ``--policy`` option of the eval
commands)."""

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
    "planner_configs",
    "planner_env_overrides",
]
