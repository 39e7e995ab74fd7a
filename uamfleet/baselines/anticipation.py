"""Online search that anticipates releases (``replan_futures``): ``replan`` scored on futures sampled from the demand.

``replan`` plans over the requests released so far as if no other request were ever to come; the clairvoyant
``best_known`` is 12 % shorter on the Berlin test set because it knows where and when the next requests appear. An
online planner cannot know that, but it may know the *distribution* the instances are drawn from
(:mod:`uamfleet.instances`): how many requests an instance has, when they are released, where they go. This planner
uses it as the online stochastic optimisation literature does (sample average approximation over sampled scenarios,
Bent & Van Hentenryck, Operations Research 2004):

1. At the start and at every release, ``replan``'s plan over the known requests is one candidate.
2. :attr:`AnticipatingReplan.futures` futures are sampled from :class:`DemandPrior` given what is known (the
   number of requests still to come from its posterior, their release steps and trips from the family's model);
   each future's clairvoyant plan (the search over the known and the sampled requests together) is another.
3. Each candidate is scored on :attr:`AnticipatingReplan.scored` *fresh* futures (not those that made the
   candidates, which would favour each one's own): its moves until that future's next release, flown in a scratch
   core, plus the moves of a clairvoyant search from there over everything that future holds. The candidate of
   least mean is flown until the next real release, when it all starts again; a future's plan only until the step
   its future expected the next release (past it, that plan serves requests that may never come: the first try
   flew it on, and flew imagined trips), when the decision is made again with what is known then.

It reads only released requests (never a hidden row of the env), the clock, and the family's demand model. It is a
yardstick, not a real-time method: each release costs one search per candidate and one per candidate and scored
future (seconds on one core). Where the prior says no request can come any more, it flies ``replan``'s plan.
"""

from __future__ import annotations

import math
import time
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from uamfleet.baselines.demand_models import (
    DemandModel,
    EstimatedDemand,
    FamilyLaw,
    NoDemandModelError,
    demand_model,
    world_family,
    wrong_model,
)
from uamfleet.baselines.planner_policy import require_one_taxi_env
from uamfleet.baselines.step_planner import (
    SEARCH_STATE_FIELDS,
    SearchSettings,
    StepPlan,
    StepPlannerPolicy,
    StepSearch,
    released_only,
)
from uamfleet.config import EnvConfig
from uamfleet.env.protocol import PolicyBase
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import FAMILIES, check_family, draw_trip
from uamfleet.sim.core import Simulator
from uamfleet.sim.generator import allocate_state, flyable_sites
from uamfleet.sim.world import World
from uamfleet.types import HIDDEN, FleetState


@dataclass(frozen=True)
class DemandPrior:
    """What an online planner may know of an instance family's demand (:mod:`uamfleet.instances`): an instance has
    ``min_requests`` … ``max_requests`` requests (uniformly), the first released at step 0 and each other at a step
    drawn uniformly from 0 … ``window_steps``; each is a trip between two of the flyable ``sites`` [S, 2] at least
    ``min_trip_m`` apart (origin uniform, destination uniform among the sites that far)."""

    min_requests: int
    max_requests: int
    window_steps: int
    min_trip_m: float
    sites: np.ndarray

    @classmethod
    def of_family(cls, family: str, cfg: EnvConfig) -> DemandPrior:
        """The prior of ``family``'s instances on ``cfg``'s map and threshold (its flyable sites)."""
        check_family(family)
        fam = FAMILIES[family]
        return cls(fam.min_passengers, fam.max_passengers, fam.window_steps(cfg.slot_s), fam.min_trip_m,
                   flyable_sites(World(cfg)))  # fmt: skip

    def count_posterior(self, known: int, t: int) -> tuple[np.ndarray, np.ndarray]:
        """(counts, probabilities): the instance's number of requests given that ``known`` are released by step
        ``t``. Each of the N − 1 requests after the first is released by then with p = (t + 1) / (window + 1), so
        P(N | known) ∝ C(N − 1, known − 1) p^(known − 1) (1 − p)^(N − known) over N = max(min, known) … max."""
        counts = np.arange(max(self.min_requests, known), self.max_requests + 1)
        p = min(1.0, (t + 1) / (self.window_steps + 1))
        if p >= 1.0 or len(counts) <= 1:
            return counts[:1], np.ones(min(1, len(counts)))
        weight = np.array([math.comb(n - 1, known - 1) * p ** (known - 1) * (1 - p) ** (n - known) for n in counts])
        return counts, weight / weight.sum()

    def sample(self, known: FleetState, rng: np.random.Generator) -> FleetState | None:
        """A future of env 0 of ``known`` (released requests only, on a passenger axis of ``max_requests`` or more):
        a copy with the requests still to come added as hidden rows, with their release steps and trips; None when
        no request can come any more (the window is over, or the count is already the most)."""
        t = int(known.t[0])
        exists = known.pax_exists[0]
        counts, probs = self.count_posterior(int(exists.sum()), t)
        more = int(rng.choice(counts, p=probs)) - int(exists.sum())
        if more <= 0 or t >= self.window_steps:
            return None
        free = np.flatnonzero(~exists)
        if len(free) < more:
            raise ValueError(f"the state has {len(free)} free passenger rows for {more} sampled requests: lay it out "
                             f"with max_passengers >= {self.max_requests}.")  # fmt: skip
        future = known.copy()
        for row in free[:more]:
            origin, dest = draw_trip(rng, self.sites, self.min_trip_m)
            if dest is None:  # no site that far from this origin: the next one
                dest = (origin + 1) % len(self.sites)
            future.pax_exists[0, row] = True
            future.pax_release[0, row] = int(rng.integers(t + 1, self.window_steps + 1))
            future.pax_origin_m[0, row] = self.sites[origin]
            future.pax_dest_m[0, row] = self.sites[dest]
            future.pax_status[0, row] = HIDDEN
            future.pax_taxi[0, row] = -1
            future.pax_pickup_step[0, row] = -1
            future.pax_dropoff_step[0, row] = -1
        return future


@dataclass
class Decision:
    """One decision of :class:`AnticipatingReplan`: the ``actions`` committed to; ``cut``: a sampled future's plan
    cut at that future's next release (decide again when it runs out, or at a real release before); ``basis``: the
    state the chosen plan was made over (the known requests, or that future); ``plan``: the whole plan chosen
    (None when no plan was found)."""

    actions: list[int]
    cut: bool
    basis: FleetState
    plan: StepPlan | None


REPLAN_FUTURES_SEARCH = SearchSettings(beam=64, rank_slack=0.5)
"""The search over the known requests: beam 64, rank slack 0.5 (the benchmark's ``replan`` uses rank slack 1.0)."""


class AnticipatingReplan(PolicyBase):
    """``replan_futures`` (module docstring) as a policy for a one-taxi, one-env core. ``plans`` keeps (step,
    number of candidates, index of the chosen one (0: ``replan``'s), its mean scored moves, actions committed to,
    wall seconds) of every decision. The defaults are not tuned (how they were chosen:
    reports/2026-12-03-results-history/README.md, "Anticipating releases")."""

    def __init__(
        self, prior: DemandPrior | DemandModel, futures: int = 4, scored: int = 8,
        replan: SearchSettings = REPLAN_FUTURES_SEARCH, future_beam: int = 16, score_beam: int = 8, seed: int = 0,
    ) -> None:  # fmt: skip
        if futures < 1 or scored < 1 or future_beam < 1 or score_beam < 1:
            raise ValueError(f"AnticipatingReplan(futures={futures}, scored={scored}, future_beam={future_beam}, "
                             f"score_beam={score_beam}): each must be >= 1 (e.g. 4, 8, 16, 8).")  # fmt: skip
        self.prior, self.futures, self.scored, self.seed = prior, futures, scored, seed
        self.replan_settings = (replan,)
        self.future_settings = (SearchSettings(future_beam, replan.cell_m, replan.rank_slack),)
        self.score_settings = (SearchSettings(score_beam, replan.cell_m, replan.rank_slack),)
        self.plans: list[tuple[int, int, int, float, int, float]] = []

    def prepare(self, cfg: EnvConfig) -> None:
        """Build the search for ``cfg``'s rules (done by :meth:`reset`; call it once before :meth:`decide` when
        the planner labels states of another env, as ``uamfleet.rl.imitation``'s teacher does)."""
        # the sampled requests need rows: plan on the env's rules with a passenger axis the prior's count fits in
        rows = max(cfg.num_passengers, self.prior.max_requests)
        self.padded = cfg.replace(max_passengers=rows) if rows > cfg.num_passengers else cfg
        self.search = StepSearch(self.padded)
        self.scratch = VectorEnv(self.search.scratch_cfg, 1, autoreset=True)
        self.scratch.reset(seed=0)
        # the known requests, on the padded axis (the search reads only SEARCH_STATE_FIELDS): rows past the env's
        # own stay as allocated, empty, for the sampled requests of each future's copy
        self.known = allocate_state(self.scratch.world, 1)

    def reset(self, sim: Simulator) -> None:
        require_one_taxi_env(sim, "replan_futures", type(self).__name__)
        self.sim = sim
        self.prepare(sim.cfg)
        self.rng = np.random.default_rng(self.seed)
        self.plans = []
        self._seen = sim.state.pax_status[0] != HIDDEN
        self.redecide = False  # whether the queue is a future's plan cut at that future's next release
        self.queue = self._decide()

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        s = self.sim.state
        newly = (s.pax_status[0] != HIDDEN) & ~self._seen
        if newly.any():
            self._seen |= newly
            self.queue = self._decide()
        elif not self.queue and self.redecide:  # a future's plan ran to its expected release, and none came
            self.queue = self._decide()
        if self.queue:
            return np.array([[self.queue.pop(0)]])
        return np.array([[StepPlannerPolicy._wait_action(s.action_mask[0, 0], int(s.t[0]))]])

    def known_state(self, state: FleetState, env_index: int = 0) -> FleetState:
        """Env ``env_index`` of ``state`` with only its released requests, on the padded passenger axis."""
        known = released_only(state.take(np.array([env_index])))
        P = known.pax_exists.shape[1]
        for name in SEARCH_STATE_FIELDS:
            target, source = getattr(self.known, name), getattr(known, name)
            if name.startswith("pax_"):
                target[:, :P] = source[:1]
            else:
                target[:] = source[:1]
        return self.known.copy()

    def _decide(self) -> list[int]:
        decision = self.decide(self.known_state(self.sim.state), self.rng)
        self.redecide = decision.cut
        return decision.actions

    def decide(self, known: FleetState, rng: np.random.Generator) -> Decision:
        """The decision from ``known`` (:meth:`known_state`), futures drawn from ``rng``; its record is appended
        to :attr:`plans`."""
        start = time.perf_counter()
        t = int(known.t[0])
        base = self._base_plan(known)
        if base is None:
            return Decision([], False, known, None)
        candidates: list[StepPlan] = [base]
        bases = [known]  # the state each candidate was planned over
        horizons = [len(base.actions)]  # how far each candidate is flown before deciding again
        makers = self._draw_futures(known, rng, self.futures)
        for future in makers:
            plan = self.search.solve(future, self.future_settings)
            if plan is not None:
                candidates.append(plan)
                bases.append(future)
                horizons.append(_next_release(future) - t)
        if len(candidates) == 1:
            self.plans.append((t, 1, 0, float(base.moves), len(base.actions), time.perf_counter() - start))
            return Decision(list(base.actions), False, known, base)
        scored = self._draw_futures(known, rng, self.scored)
        if not scored:
            scored = makers
        means = np.array([np.mean([self._score(c.actions, f, t) for f in scored]) for c in candidates])
        best = int(np.argmin(means))  # ties to the lowest index: replan's plan first
        committed = list(candidates[best].actions[: horizons[best]])
        self.plans.append((t, len(candidates), best, float(means[best]), len(committed), time.perf_counter() - start))
        return Decision(committed, best > 0, bases[best], candidates[best])

    def _base_plan(self, known: FleetState) -> StepPlan | None:
        """Replan's plan over ``known``, or None when even its wider fallback search finds none."""
        base = self.search.solve(known, self.replan_settings)
        if base is None:  # as replan: a wider, slack-free search before giving up
            wider = [SearchSettings(4 * s.beam, s.cell_m, 0.0) for s in self.replan_settings]
            base = self.search.solve(known, wider)
        return base

    def _draw_futures(self, known: FleetState, rng: np.random.Generator, count: int) -> list[FleetState]:
        """``count`` futures of ``known`` drawn from the prior in turn, the draws that return None left out."""
        return [f for f in (self.prior.sample(known, rng) for _ in range(count)) if f is not None]

    def _score(self, actions: Sequence[int], future: FleetState, t: int) -> float:
        """Moves of ``actions`` in ``future`` until its next release, plus a clairvoyant search's moves from there."""
        release = _next_release(future)
        horizon = release - t if release >= 0 else len(actions)
        for name in SEARCH_STATE_FIELDS:
            getattr(self.scratch.state, name)[:] = getattr(future, name)[:1]
        moves = 0
        for action in actions[:horizon]:
            _, _, terminated, _, info = self.scratch.step(np.array([[action]]))
            moves += int(info["events"].moved[0, 0])
            if terminated[0]:
                return float(moves)
        plan = self.search.solve(self.scratch.state, self.score_settings)
        return float(moves + (plan.moves if plan is not None else self.padded.time_limit_steps))


def _next_release(future: FleetState) -> int:
    """The release step of env 0's next hidden request, -1 when none is hidden."""
    coming = future.pax_exists[0] & (future.pax_status[0] == HIDDEN)
    return int(future.pax_release[0, coming].min()) if coming.any() else -1


__all__ = [
    "AnticipatingReplan",
    "Decision",
    "DemandModel",
    "DemandPrior",
    "EstimatedDemand",
    "FamilyLaw",
    "NoDemandModelError",
    "demand_model",
    "world_family",
    "wrong_model",
]
