"""The planners and fleet dispatchers of :mod:`uamfleet.baselines` in the registry, with their typed options.

The classes stay in :mod:`uamfleet.baselines`; this module only builds them. The defaults are those the benchmarks
fly (``replan`` at beam 64, rank slack 1: ``uamfleet-benchmark --replan-beam``; ``best_known`` at beam 256, rank
slack 1 then 0: ``--best-known-beams``).
"""

from __future__ import annotations

import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any

from uamfleet.baselines import FLEET_DISPATCHERS, PLANNERS, STEP_PLANNERS, GreedyFleetPolicy, PlannerPolicy
from uamfleet.baselines.anticipation import AnticipatingReplan, DemandPrior
from uamfleet.baselines.assignment_value import MAX_SECONDS, VALUE_DISPATCHER, value_for_dispatcher
from uamfleet.baselines.batch_assignment import BatchAssignmentPolicy, InsertionPolicy
from uamfleet.baselines.fleet_dispatch import check_wait_weight
from uamfleet.baselines.random_policy import RandomPolicy
from uamfleet.baselines.step_planner import SearchSettings, StepPlannerPolicy
from uamfleet.checks import MAX_SEED, ConfigError, check_integer, check_number
from uamfleet.instances import check_family
from uamfleet.policies.registry import NoOptions, register

REFIT_VALUES = Path("docs/results/assignment_value_refit")
"""Where a valued dispatcher's ``value=<stem>`` file lies (``<stem>.json``, from the repository root)."""


def _seconds(name: str, value: float | None) -> float | None:
    """``value`` as seconds in ``[0, MAX_SECONDS]`` (None stays None)."""
    if value is None:
        return None
    value = check_number(name, value, minimum=0.0)
    if value > MAX_SECONDS:
        raise ConfigError(f"{name}={value:g} is too large: at most {MAX_SECONDS:g} s.")
    return value


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
class FuturesOptions:
    """``replan_futures``: replan scored on futures sampled from ``family``'s demand model."""

    family: str = "berlin"

    def __post_init__(self) -> None:
        check_family(self.family)


@dataclass(frozen=True)
class RandomOptions:
    """``random``: uniform over the allowed headings, drawn from ``seed``."""

    seed: int = 0

    def __post_init__(self) -> None:
        check_integer("seed", self.seed, 0, MAX_SEED)


@dataclass(frozen=True)
class InsertionOptions:
    """``insertion``: schedules cost their total ride time plus ``wait`` (β) times their total wait."""

    wait: float = 0.0

    def __post_init__(self) -> None:
        check_wait_weight("wait", self.wait)


@dataclass(frozen=True)
class BatchOptions:
    """``batch_assignment``: ``wait`` as :class:`InsertionOptions`; ``release``: also re-assign at each release;
    ``unassigned_price_s``: what a request left out costs (plus (1 + β) times its wait; none: 10^6 s), up to
    ``unassigned_guard_s`` of wait (needs a price)."""

    wait: float = 0.0
    release: bool = False
    unassigned_price_s: float | None = None
    unassigned_guard_s: float | None = None

    def __post_init__(self) -> None:
        check_wait_weight("wait", self.wait)
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


class FamilyReplan:
    """``replan_futures`` for ``family``'s instances: the demand model is made on each episode's map and threshold
    (:meth:`reset`), then :class:`~uamfleet.baselines.anticipation.AnticipatingReplan` flies."""

    def __init__(self, family: str) -> None:
        check_family(family)
        self.family = family
        self.inner: AnticipatingReplan | None = None

    def reset(self, env: Any) -> None:
        self.inner = AnticipatingReplan(DemandPrior.of_family(self.family, env.cfg))
        self.inner.reset(env)

    def __call__(self, obs: Any) -> Any:
        assert self.inner is not None, "reset(env) first"
        return self.inner(obs)


def _batch(options: BatchOptions, value: Any = None) -> BatchAssignmentPolicy:
    return BatchAssignmentPolicy(
        value=value,
        wait_weight=options.wait,
        assign_on_release=options.release,
        unassigned_price_s=options.unassigned_price_s,
        unassigned_guard_s=options.unassigned_guard_s,
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
    register("replan_futures", "planner", FuturesOptions, lambda o, _b: FamilyReplan(o.family))
    register("random", "planner", RandomOptions, lambda o, _b: RandomPolicy(seed=o.seed))
    register("greedy", "dispatcher", NoOptions, lambda _o, _b: GreedyFleetPolicy())
    register("insertion", "dispatcher", InsertionOptions, lambda o, _b: InsertionPolicy(wait_weight=o.wait))
    register("batch_assignment", "dispatcher", BatchOptions, lambda o, _b: _batch(o))
    register(VALUE_DISPATCHER, "dispatcher", ValueBatchOptions, lambda o, _b: _valued(o))


_register()
assert set(STEP_PLANNERS) == {"replan", "best_known"} and FLEET_DISPATCHERS == ("greedy", "insertion",
                                                                                 "batch_assignment")  # fmt: skip

__all__ = [
    "REFIT_VALUES",
    "BatchOptions",
    "BestKnownOptions",
    "FamilyReplan",
    "FuturesOptions",
    "InsertionOptions",
    "RandomOptions",
    "ReplanOptions",
    "ValueBatchOptions",
    "value_path",
]
