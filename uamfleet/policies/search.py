"""Search at decision time as wrappers over a base policy: ``argmax`` (the base itself), ``guided``, ``hedge`` and
``finish``, built from :mod:`uamfleet.rl.guided` and :mod:`uamfleet.baselines.finish` (their constructors as they
are). ``guided(BASE)``, ``hedge(BASE)`` need a learned base (a :class:`~uamfleet.rl.policy.GreedyPolicy`);
``finish(BASE)`` takes any one-taxi policy. ``hedge`` and ``finish`` read the instance family's demand model from
the simulator's world at ``reset(sim)`` and refuse, in one line, a world no family draws (a fixed scenario).

    from uamfleet import policies
    search = policies.make("hedge", base=("learned", {"traced": True}))
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

from uamfleet.baselines.finish import FinishWithSearch
from uamfleet.baselines.fleet_dispatch import ScheduleFleetPolicy, check_wait_weight
from uamfleet.baselines.fleet_search import DEMANDS, MAX_CANDIDATES, MAX_SITES, FleetSearch
from uamfleet.baselines.fleet_search import MAX_FUTURES as MAX_FLEET_FUTURES
from uamfleet.checks import MAX_SEED, check_integer, check_number
from uamfleet.config import FLEET_ARRIVAL_WINDOW_S
from uamfleet.policies.registry import NoOptions, PolicyNameError, register
from uamfleet.rl.guided import (
    MAX_EXPERT_BEAM,
    MAX_FUTURES,
    MAX_SAMPLES,
    MAX_STEPS,
    WAIT_ACTIONS,
    check_demand_spec,
    AnticipatingGuidedSearch,
    GuidedSearchPolicy,
)
from uamfleet.rl.policy import GreedyPolicy
from uamfleet.types import NUM_HEADINGS


FLEET_SEARCH = "fleet_search"
"""The search at decision time over a fleet dispatcher: ``fleet_search:OPTIONS(DISPATCHER)``, a fleet method the
fleet benchmark flies like a dispatcher."""
CHOSEN_DISPATCHER: tuple[str, dict[str, Any]] = ("batch_assignment_value", {
    "wait": 1.0, "release": True, "unassigned_price_s": 1000.0, "unassigned_guard_s": 600.0, "value_price_s": 100.0,
})  # fmt: skip
"""The fleet search's base when given none: the chosen loaded dispatcher,
``batch_assignment_value:100+wait=1+release+price=1000+guard=600`` (docs/results.md "Fleets")."""


@dataclass(frozen=True)
class GuidedOptions:
    """``guided``: at each release, the base's greedy flights after its ``top_k`` likeliest first headings and
    ``samples`` flights sampled at ``temperature`` (and, ``expert_beam`` > 0, replan's beam search of that width),
    rolled forward over the known requests (``horizon`` steps at most, none: to the end); the shortest is flown."""

    top_k: int = 8
    samples: int = 24
    temperature: float = 2.0
    expert_beam: int = 0
    horizon: int | None = None

    def __post_init__(self) -> None:
        check_integer("top_k", self.top_k, 1, NUM_HEADINGS, fix=" (e.g. 8)")
        check_integer("samples", self.samples, 0, MAX_SAMPLES, fix=" (e.g. 24)")
        check_number("temperature", self.temperature, positive=True)
        check_integer("expert_beam", self.expert_beam, 0, MAX_EXPERT_BEAM, fix=" (0: none)")
        if self.horizon is not None:
            check_integer("horizon", self.horizon, 1, MAX_STEPS, fix=" or none (to the end), e.g. 40")


@dataclass(frozen=True)
class HedgeOptions:
    """``hedge``: while a request of the demand model of the world's instance family may come, every ``commit``
    steps and at each release, the base's ``first_headings`` likeliest first headings flown in ``futures`` sampled
    futures (rollouts end ``tail`` steps after the last possible release, -1: at the end); then guided search with
    ``top_k`` and ``samples``. ``wait_action``: the wait candidate is a forbidden heading where one is
    (``forbidden``) or the hover action at any step of a world with it (``hover``). ``demand``: the model its
    futures are drawn from: ``family`` (the true law of the world's instance family), a family's name, ``wrong`` or
    a fitted model's ``.json`` file (``uamfleet demand fit``)."""

    first_headings: int = 4
    futures: int = 8
    commit: int = 4
    tail: int = 10
    samples: int = 8
    top_k: int = 8
    temperature: float = 2.0
    expert_beam: int = 0
    horizon: int | None = None
    wait_action: str = "forbidden"
    demand: str = "family"

    def __post_init__(self) -> None:
        try:
            check_demand_spec(self.demand)
        except ValueError as err:
            raise PolicyNameError(f"demand={self.demand!r}: {err}") from None
        if self.wait_action not in WAIT_ACTIONS:
            raise PolicyNameError(f"wait_action={self.wait_action!r} is unknown; choose one of {WAIT_ACTIONS}.")
        check_integer("first_headings", self.first_headings, 1, NUM_HEADINGS, fix=" (e.g. 4)")
        check_integer("futures", self.futures, 1, MAX_FUTURES, fix=" (e.g. 8)")
        check_integer("commit", self.commit, 1, MAX_STEPS, fix=" (e.g. 4)")
        check_integer("tail", self.tail, -1, MAX_STEPS, fix=" (-1: every rollout to its end), e.g. 10")
        GuidedOptions(self.top_k, self.samples, self.temperature, self.expert_beam, self.horizon)


@dataclass(frozen=True)
class FinishOptions:
    """``finish``: the base until the demand model of the world's instance family says no request can come, then
    one step-level search of width ``beam`` over the requests, flown to the end."""

    beam: int = 16

    def __post_init__(self) -> None:
        check_integer("beam", self.beam, 1, fix=" (e.g. 16)")


@dataclass(frozen=True)
class FleetSearchOptions:
    """``fleet_search``: every ``every`` steps, the schedule dispatcher BASE with its own wait weight and with each
    of ``waits`` rolled ``horizon`` steps (0: to the end) in ``futures`` futures sampled from the fleet demand of a
    service of ``arrival_window_s`` (draws from ``seed``; trips among ``sites`` of the map's flyable sites); the
    least mean of distance flown plus ``wait_cost`` times the passengers' waiting, both in seconds, is flown
    (:mod:`uamfleet.baselines.fleet_search`). ``demand``: the futures' model, ``true`` (the instances' law) or
    ``estimated`` (from the requests released so far); ``end_wait`` > 0 adds that weight times the waits so far of
    the passengers still waiting at the horizon; ``cpu_budget_s`` > 0 stops adding futures once one more would likely
    overrun that many CPU seconds (decisions then depend on the machine's speed)."""

    waits: tuple[float, ...] = (0.0, 3.0)
    futures: int = 3
    horizon: int = 10
    every: int = 5
    wait_cost: float = 1.0
    arrival_window_s: float = FLEET_ARRIVAL_WINDOW_S
    seed: int = 0
    sites: int = 48
    demand: str = "true"
    end_wait: float = 0.0
    cpu_budget_s: float = 0.0

    def __post_init__(self) -> None:
        if self.demand not in DEMANDS:
            raise PolicyNameError(f"demand={self.demand!r} is unknown; choose one of {DEMANDS}.")
        check_number("end_wait", self.end_wait, minimum=0.0)
        check_number("cpu_budget_s", self.cpu_budget_s, minimum=0.0)
        check_integer("sites", self.sites, 2, MAX_SITES, fix=" (sites the futures' trips are drawn among, e.g. 48)")
        for weight in self.waits:
            check_wait_weight("waits", weight)
        if len(self.waits) + 1 > MAX_CANDIDATES:
            raise PolicyNameError(f"waits={self.waits!r}: at most {MAX_CANDIDATES - 1} (e.g. waits=0;3).")
        check_integer("futures", self.futures, 1, MAX_FLEET_FUTURES, fix=" (e.g. 3)")
        check_integer("horizon", self.horizon, 0, MAX_STEPS, fix=" (0: to the end), e.g. 10")
        check_integer("every", self.every, 1, MAX_STEPS, fix=" (steps between searches, e.g. 5)")
        check_number("wait_cost", self.wait_cost, minimum=0.0)
        check_number("arrival_window_s", self.arrival_window_s, positive=True)
        check_integer("seed", self.seed, 0, MAX_SEED)


def _fleet_search(o: FleetSearchOptions, base: Any) -> FleetSearch:
    if not isinstance(base, ScheduleFleetPolicy):
        raise PolicyNameError(
            f"fleet_search rolls a schedule dispatcher forward; give one as its base, e.g. "
            f"fleet_search(batch_assignment_value:100+wait=1+release+price=1000+guard=600), not {base!r}."
        )
    return FleetSearch(
        base, o.waits, futures=o.futures, horizon=o.horizon or None, every=o.every, wait_cost=o.wait_cost,
        arrival_window_s=o.arrival_window_s, seed=o.seed, sites=o.sites, demand=o.demand, end_wait=o.end_wait,
        cpu_budget_s=o.cpu_budget_s or None,
    )  # fmt: skip


def _learned_base(name: str, base: Any) -> GreedyPolicy:
    if not isinstance(base, GreedyPolicy):
        raise PolicyNameError(f"{name} searches over a learned policy's logits; give base=learned:…, not {base!r}.")
    return base


def _guided(o: GuidedOptions, base: Any) -> GuidedSearchPolicy:
    return GuidedSearchPolicy(
        _learned_base("guided", base), top_k=o.top_k, samples=o.samples, temperature=o.temperature,
        expert_beam=o.expert_beam, horizon=o.horizon,
    )  # fmt: skip


def _hedge(o: HedgeOptions, base: Any) -> AnticipatingGuidedSearch:
    return AnticipatingGuidedSearch(
        _learned_base("hedge", base), o.demand, first_headings=o.first_headings, futures=o.futures, commit=o.commit,
        tail=None if o.tail < 0 else o.tail, top_k=o.top_k, samples=o.samples, temperature=o.temperature,
        expert_beam=o.expert_beam, horizon=o.horizon, wait_action=o.wait_action,
    )  # fmt: skip


register("argmax", "search", NoOptions, lambda _o, base: base)
register("guided", "search", GuidedOptions, _guided)
register("hedge", "search", HedgeOptions, _hedge)
register("finish", "search", FinishOptions, lambda o, base: FinishWithSearch.of_world(base, o.beam))
register(FLEET_SEARCH, "search", FleetSearchOptions, _fleet_search, default_base=CHOSEN_DISPATCHER)

__all__ = ["CHOSEN_DISPATCHER", "FLEET_SEARCH", "FinishOptions", "FleetSearchOptions", "GuidedOptions", "HedgeOptions"]
