"""The planners and fleet dispatchers of :mod:`uamfleet.baselines` in the registry, with their typed options.

The classes stay in :mod:`uamfleet.baselines`; this module only builds them. The defaults are those the benchmarks
fly (``replan`` at beam 64, rank slack 1: ``uamfleet-benchmark --replan-beam``; ``best_known`` at beam 256, rank
slack 1 then 0: ``--best-known-beams``).
"""

from __future__ import annotations

import functools
import re
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from uamfleet.baselines import (
    FLEET_DISPATCHERS,
    PLANNERS,
    POLICIES,
    STEP_PLANNERS,
    GreedyFleetPolicy,
    PlannerPolicy,
)
from uamfleet.baselines.anticipation import AnticipatingReplan, DemandPrior, world_family
from uamfleet.baselines.assignment_value import VALUE_DISPATCHER, value_for_dispatcher
from uamfleet.baselines.batch_assignment import BatchAssignmentPolicy, InsertionPolicy, check_seconds
from uamfleet.baselines.fleet_dispatch import check_wait_weight
from uamfleet.baselines.fleet_steering import check_heading
from uamfleet.baselines.random_policy import RandomPolicy
from uamfleet.baselines.step_planner import SearchSettings, StepPlannerPolicy
from uamfleet.checks import MAX_SEED, MAX_TAXIS, ConfigError, check_integer, check_number
from uamfleet.env.protocol import PolicyBase
from uamfleet.policies.names import parse
from uamfleet.policies.registry import NoOptions, available, make, register
from uamfleet.sim.core import Simulator

REFIT_VALUES = Path("docs/results/assignment_value_refit")
"""Where a valued dispatcher's ``value=<stem>`` file lies (``<stem>.json``, from the repository root)."""


def _seconds(name: str, value: float | None) -> float | None:
    """``value`` as seconds in ``[0, MAX_SECONDS]`` (None stays None)."""
    return None if value is None else check_seconds(name, value)


@dataclass(frozen=True)
class ReplanOptions:
    """``replan``: one beam search of width ``beam`` over the known requests at each release."""

    beam: int = 64
    rank_slack: float = 1.0

    def __post_init__(self) -> None:
        SearchSettings(check_integer("beam", self.beam, 1, fix=" (e.g. 64)"), rank_slack=self.rank_slack)


@dataclass(frozen=True)
class BestKnownOptions:
    """``best_known``: the shortest of beam searches of widths ``beams`` over every request, their rank slacks
    taken from ``rank_slack`` in turn."""

    beams: tuple[int, ...] = (256,)
    rank_slack: tuple[float, ...] = (1.0, 0.0)

    def __post_init__(self) -> None:
        if not self.beams or not self.rank_slack:
            raise ConfigError(f"beams={self.beams!r}, rank_slack={self.rank_slack!r}: give at least one of each.")
        for i, beam in enumerate(self.beams):
            check_integer("beams", beam, 1, fix=" (e.g. 256)")
            SearchSettings(beam, rank_slack=self.rank_slack[i % len(self.rank_slack)])


@dataclass(frozen=True)
class RandomOptions:
    """``random``: uniform over the allowed headings, drawn from ``seed``."""

    seed: int = 0

    def __post_init__(self) -> None:
        check_integer("seed", self.seed, 0, MAX_SEED)


@dataclass(frozen=True)
class InsertionOptions:
    """``insertion``: schedules cost their total ride time plus ``wait`` (β) times their total wait; ``heading``: how
    a taxi heads for its stop, ``field``, ``table`` or ``onward``
    (:data:`~uamfleet.baselines.fleet_steering.HEADING_RULES`)."""

    wait: float = 0.0
    heading: str = "field"

    def __post_init__(self) -> None:
        check_wait_weight("wait", self.wait)
        check_heading(self.heading)


@dataclass(frozen=True)
class BatchOptions:
    """``batch_assignment``: ``wait`` as :class:`InsertionOptions`; ``release``: also re-assign at each release;
    ``unassigned_price_s``: what a request left out costs (plus (1 + β) times its wait; none: 10^6 s), up to
    ``unassigned_guard_s`` of wait (needs a price); ``heading`` as :class:`InsertionOptions`."""

    wait: float = 0.0
    release: bool = False
    unassigned_price_s: float | None = None
    unassigned_guard_s: float | None = None
    heading: str = "field"

    def __post_init__(self) -> None:
        check_wait_weight("wait", self.wait)
        check_heading(self.heading)
        _seconds("unassigned_price_s", self.unassigned_price_s)
        _seconds("unassigned_guard_s", self.unassigned_guard_s)
        if self.unassigned_guard_s is not None and self.unassigned_price_s is None:
            raise ConfigError(
                "unassigned_guard_s bounds how long unassigned_price_s may leave a request out; give both."
            )


@dataclass(frozen=True)
class ValueBatchOptions(BatchOptions):
    """``batch_assignment_value``: :class:`BatchOptions` with a learned value of where each trip leaves its taxi:
    ``value`` (a file, or the stem of one in :data:`REFIT_VALUES`; none: the shipped one) priced at
    ``value_price_s`` seconds per unit (none: the file's price), for a service of ``arrival_window_s``."""

    value_price_s: float | None = None
    value: str | None = None
    arrival_window_s: float | None = None

    def __post_init__(self) -> None:
        super().__post_init__()
        _seconds("value_price_s", self.value_price_s)
        if self.arrival_window_s is not None:
            check_number("arrival_window_s", self.arrival_window_s, positive=True)


def value_path(value: str | None) -> Path | None:
    """The value file of ``value``: a path as given (one with a folder or a suffix), else a stem in
    :data:`REFIT_VALUES`; None for the shipped one."""
    if value is None:
        return None
    if Path(value).is_file() or Path(value).suffix or len(Path(value).parts) > 1:  # a file: its reader says if missing
        return Path(value)
    stem = REFIT_VALUES / f"{value}.json"
    if not stem.is_file():
        raise FileNotFoundError(f"value={value!r} is neither a file nor a stem of {REFIT_VALUES}; give one.")
    return stem


class FamilyReplan(PolicyBase):
    """``replan_futures`` on the demand model of the simulator's world: at each :meth:`reset` the family is read
    from the world (:func:`~uamfleet.baselines.anticipation.world_family`; a fixed scenario is refused in one line)
    and its model made on the episode's map and threshold, then
    :class:`~uamfleet.baselines.anticipation.AnticipatingReplan` flies."""

    def __init__(self) -> None:
        self.inner: AnticipatingReplan | None = None

    def reset(self, sim: Simulator) -> None:
        family = world_family(sim.cfg, "replan_futures")
        self.inner = AnticipatingReplan(DemandPrior.of_family(family, sim.cfg))
        self.inner.reset(sim)

    def act(self, obs: Any) -> Any:
        assert self.inner is not None, "reset(sim) first"
        return self.inner.act(obs)


ONE_FLIGHT_OPTIONS: dict[str, dict[str, Any]] = {
    "replan": {"beam": 128, "rank_slack": 0.5},
    "best_known": {"beams": (256, 256, 1024), "rank_slack": (1.0, 0.0, 0.5)},
}
"""The options :func:`make_flown` gives a bare step-planner name: the wider searches one flight affords
(``uamfleet rollout`` / ``render``, a planner in the fleet benchmark), where the benchmarks' defaults (the
registry's) are sized for hundreds of instances. An option the name gives replaces the whole entry."""


def make_flown(
    name: str, seed: int = 0, num_taxis: int = 1, assignment_value: Path | None = None,
    arrival_window_s: float | None = None,
) -> Any:  # fmt: skip
    """The planner or dispatcher ``name`` (the grammar or a recorded alias) for one flight of ``num_taxis`` taxis,
    built by the registry: a bare step planner with :data:`ONE_FLIGHT_OPTIONS`, ``random`` drawn from ``seed``,
    ``batch_assignment_value`` with the value of ``assignment_value`` (None: the shipped one) for a service of
    ``arrival_window_s``. ValueError for another kind of policy, an unknown name, or a single-taxi planner for a
    fleet."""
    if not isinstance(name, str):
        raise ConfigError(f"--policy {name!r} is a {type(name).__name__}; name a policy, one of {POLICIES}.")
    seed = check_integer("seed", seed, 0, MAX_SEED)
    num_taxis = check_integer("num_taxis", num_taxis, 1, MAX_TAXIS)
    if arrival_window_s is not None:
        arrival_window_s = check_number("arrival_window_s", arrival_window_s, positive=True)
    call, options = _flown_call(name)
    if available()[call][0] == "planner" and call != "random" and num_taxis != 1:
        raise ConfigError(
            f"--policy {name} is a single-taxi planner but the fleet has {num_taxis} taxis; use a fleet "
            f"dispatcher ({', '.join(FLEET_DISPATCHERS)}) or random for a fleet, or --num-taxis 1."
        )
    if not options:
        options = dict(ONE_FLIGHT_OPTIONS.get(call, {}))
    if call == "random":
        options.setdefault("seed", seed)
    if call == VALUE_DISPATCHER:
        if assignment_value is not None:
            options.setdefault("value", str(assignment_value))
        if arrival_window_s is not None:
            options.setdefault("arrival_window_s", arrival_window_s)
    return make(call, **options)


def _flown_call(name: str) -> tuple[str, dict[str, Any]]:
    """``(call, options)`` of ``name`` for :func:`make_flown`: a planner or a dispatcher; a name the registry
    does not know, or another kind, is refused naming the policies a flight takes."""
    head = re.split(r"[:+@(]", name, maxsplit=1)[0]
    if head not in available():
        raise ConfigError(
            f"unknown --policy {name!r}; choose one of {POLICIES} (options after ':', e.g. replan:beam=64)."
        )
    kind = available()[head][0]
    if kind not in ("planner", "dispatcher"):
        raise ConfigError(f"--policy {name!r} is a {kind} policy; a flight by name takes a planner or a dispatcher, "
                          f"one of {POLICIES}.")  # fmt: skip
    call, options = parse(name)
    return call, dict(options)


def _batch(options: BatchOptions, value: Any = None) -> BatchAssignmentPolicy:
    return BatchAssignmentPolicy(
        value=value,
        wait_weight=options.wait,
        assign_on_release=options.release,
        unassigned_price_s=options.unassigned_price_s,
        unassigned_guard_s=options.unassigned_guard_s,
        heading=options.heading,
    )


def _valued(options: ValueBatchOptions) -> BatchAssignmentPolicy:
    price = "" if options.value_price_s is None else f":{options.value_price_s!r}"
    value = value_for_dispatcher(f"{VALUE_DISPATCHER}{price}", value_path(options.value), options.arrival_window_s)
    return _batch(options, value)


def _best_known(options: BestKnownOptions) -> StepPlannerPolicy:
    slack = options.rank_slack
    settings = [SearchSettings(b, rank_slack=slack[i % len(slack)]) for i, b in enumerate(options.beams)]
    return StepPlannerPolicy("best_known", settings)


def _planner(name: str, _options: NoOptions, _base: None) -> PlannerPolicy:
    return PlannerPolicy(name)


def _register() -> None:
    for name in PLANNERS:
        register(name, "planner", NoOptions, functools.partial(_planner, name))
    register("replan", "planner", ReplanOptions,
             lambda o, _b: StepPlannerPolicy("replan", [SearchSettings(o.beam, rank_slack=o.rank_slack)]))  # fmt: skip
    register("best_known", "planner", BestKnownOptions, lambda o, _b: _best_known(o))
    register("replan_futures", "planner", NoOptions, lambda _o, _b: FamilyReplan())
    register("random", "planner", RandomOptions, lambda o, _b: RandomPolicy(seed=o.seed))
    register("greedy", "dispatcher", NoOptions, lambda _o, _b: GreedyFleetPolicy())
    register("insertion", "dispatcher", InsertionOptions,
             lambda o, _b: InsertionPolicy(wait_weight=o.wait, heading=o.heading))  # fmt: skip
    register("batch_assignment", "dispatcher", BatchOptions, lambda o, _b: _batch(o))
    register(VALUE_DISPATCHER, "dispatcher", ValueBatchOptions, lambda o, _b: _valued(o))


_register()
assert set(STEP_PLANNERS) == {"replan", "best_known"} and FLEET_DISPATCHERS == ("greedy", "insertion",
                                                                                 "batch_assignment")  # fmt: skip

__all__ = [
    "ONE_FLIGHT_OPTIONS",
    "REFIT_VALUES",
    "BatchOptions",
    "BestKnownOptions",
    "FamilyReplan",
    "InsertionOptions",
    "RandomOptions",
    "ReplanOptions",
    "ValueBatchOptions",
    "make_flown",
    "value_path",
]
