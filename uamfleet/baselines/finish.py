"""A policy while requests may still come, the step-level search once none can: ``FinishWithSearch``.

An instance family's demand model (:mod:`uamfleet.instances`) releases every request within its window (step 0 …
``window_steps``) and has at most ``max_requests``. From the first step at which the window is over, or the most
requests are released, nothing more can come: the rest of the episode is a deterministic problem over known
requests, which the step-level search (``replan``'s solver, :class:`~uamfleet.baselines.step_planner.StepSearch`)
solves nearly exactly, and a learned policy's one- or two-move look-ahead does not. :class:`FinishWithSearch`
flies any one-taxi policy until then, solves once at that step, and flies the plan to the end.

Why: the shipped policy flies as short as ``replan`` until the last release and loses its whole gap to it after
(reports/2026-12-03-results-history/README.md, "The two-move look-ahead policy"), while ``replan`` pays a search at
every release. Here the policy flies the uncertain part of the episode at its own cost (≤ 1 ms a decision) and one
search flies the known part. The switch reads only the clock, the count of released requests and the family's model:
never a hidden row.
"""

from __future__ import annotations

import time
from typing import Any

import numpy as np

from uamfleet.baselines.anticipation import world_family
from uamfleet.baselines.planner_policy import require_one_taxi_env
from uamfleet.baselines.step_planner import SearchSettings, StepSearch, released_only
from uamfleet.config import EnvConfig
from uamfleet.env.protocol import PolicyBase
from uamfleet.instances import FAMILIES, check_family
from uamfleet.sim.core import Simulator
from uamfleet.types import HIDDEN

FINISH_RANK_SLACK = 0.5
"""The search's rank slack (as ``replan_futures``' search over the known requests)."""


def no_request_can_come(released: int, t: int, window_steps: int, max_requests: int) -> bool:
    """Whether a family's demand model can release nothing after step ``t``: its window (steps 0 … ``window_steps``,
    a request released at step t is seen at step t) is over, or ``released`` is its largest count."""
    return t >= window_steps or released >= max_requests


class FinishWithSearch(PolicyBase):
    """``policy`` (any one-taxi policy: :class:`~uamfleet.rl.policy.GreedyPolicy`, guided search, a planner) until
    :func:`no_request_can_come`, then the plan of one step-level search of width ``beam`` over the requests, all
    known by then, flown to the end (module docstring). If the search finds no plan (none within the time limit),
    ``policy`` flies on. ``solves`` keeps (step, moves planned, thread CPU s, wall s) of the search."""

    def __init__(self, policy: Any, window_steps: int, max_requests: int, beam: int = 16) -> None:
        if beam < 1 or window_steps < 0 or max_requests < 1:
            raise ValueError(
                f"FinishWithSearch(window_steps={window_steps}, max_requests={max_requests}, beam={beam}): need "
                "window_steps >= 0, max_requests >= 1 and beam >= 1 (e.g. FinishWithSearch.of_family(policy, "
                "'berlin', cfg.slot_s, beam=16))."
            )
        self.policy, self.window_steps, self.max_requests, self.beam = policy, window_steps, max_requests, beam
        self.sim: Simulator | None = None
        self.plan: list[int] | None = None  # None: the policy still flies
        self.solves: list[tuple[int, int, float, float]] = []
        self.from_world = False  # True (of_world): window_steps and max_requests are read from each world at reset

    @property
    def spec(self) -> Any:
        """What it reads: its base policy's ``spec`` (None for a planner or a plain function)."""
        return getattr(self.policy, "spec", None)

    @classmethod
    def of_family(cls, policy: Any, family: str, slot_s: float, beam: int = 16) -> FinishWithSearch:
        """The finisher for instances of ``family`` (:data:`uamfleet.instances.FAMILIES`) flown with slots of
        ``slot_s`` seconds (the release window in steps, as :func:`uamfleet.instances.make_instance` draws it)."""
        check_family(family)
        fam = FAMILIES[family]
        return cls(policy, fam.window_steps(slot_s), fam.max_passengers, beam)

    @classmethod
    def of_world(cls, policy: Any, beam: int = 16) -> FinishWithSearch:
        """The finisher that reads, at each :meth:`reset`, the family of the simulator's world
        (:func:`~uamfleet.baselines.anticipation.world_family`) and its slot; a world no family draws (a fixed
        scenario) is refused there in one line."""
        finisher = cls(policy, 0, 1, beam)
        finisher.from_world = True
        return finisher

    @property
    def passenger_slots(self) -> int | None:
        """The wrapped policy's passenger axis (None: any)."""
        return getattr(self.policy, "passenger_slots", None)

    def layout(self, cfg: EnvConfig) -> EnvConfig:
        """``cfg`` laid out for the wrapped policy (unchanged for a policy without a layout)."""
        layout = getattr(self.policy, "layout", None)
        return layout(cfg) if layout is not None else cfg

    def reset(self, sim: Simulator) -> None:
        require_one_taxi_env(sim, "a policy finished by search", type(self).__name__)
        if self.from_world:
            fam = FAMILIES[world_family(sim.cfg, "finish")]
            self.window_steps, self.max_requests = fam.window_steps(sim.cfg.slot_s), fam.max_passengers
        self.sim, self.plan, self.solves = sim, None, []
        self.policy.reset(sim)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        assert self.sim is not None, "call reset(sim) first (uamfleet.rollout.fly does)"
        s = self.sim.state
        if self.plan is None:
            released = int(((s.pax_status[0] != HIDDEN) & s.pax_exists[0]).sum())
            if no_request_can_come(released, int(s.t[0]), self.window_steps, self.max_requests):
                self.plan = self._solve()
        if self.plan:
            return np.array([[self.plan.pop(0)]])
        return self.policy(obs)  # before the switch, or after a search that found nothing

    def _solve(self) -> list[int]:
        assert self.sim is not None
        start, start_cpu = time.perf_counter(), time.thread_time()
        found = StepSearch(self.sim.cfg).solve(
            released_only(self.sim.state), [SearchSettings(beam=self.beam, rank_slack=FINISH_RANK_SLACK)]
        )
        moves = found.moves if found is not None else -1
        self.solves.append(
            (int(self.sim.state.t[0]), moves, time.thread_time() - start_cpu, time.perf_counter() - start)
        )
        return list(found.actions) if found is not None else []


__all__ = ["FINISH_RANK_SLACK", "FinishWithSearch", "no_request_can_come"]
