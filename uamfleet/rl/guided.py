"""Search at decision time, guided by a trained policy (an option beside greedy decoding, not the default).

At the start and at every release, :class:`GuidedSearchPolicy` rolls several candidate flights forward in a
scratch copy of the env (the env's own step, so every rule is the core's) over the requests released so far:

- the policy's greedy flight after each of its ``top_k`` most likely first headings (the first of them is the
  greedy flight itself), and
- ``samples`` flights drawn from the policy (softmax of its logits at ``temperature``),

and flies the one that delivers every known passenger in the fewest moves (then the fewest steps) until the next
release, when it plans again. Between releases a decision costs a list pop. Because the greedy flight is always a
candidate and the scratch core reproduces the env exactly until a release, on an instance whose requests are all
known at the start it never flies longer than greedy decoding.

With ``horizon`` (an option for large maps, where a full rollout of every candidate takes seconds) each candidate is
rolled at most ``horizon`` steps and ranked by its moves plus the shortest tour through every known stop still to
serve from where it stands (``tour_via_stop`` of its observation; exact for the stops the tour DP covers, and in
centre-to-centre moves, so it counts no pick-up radius); a candidate that delivers everyone within the horizon
counts its moves alone. The chosen candidate is flown for its ``horizon`` steps and the search runs again (a
rolling horizon), so the cost of one search is bounded by ``(top_k + samples) x horizon`` steps on any map, and
the guarantee above holds only where the horizon reaches the end of every candidate.

With ``expert_beam`` > 0 the plan of ``replan``'s beam search of that width over the same known requests is one more
candidate (the policy's flights win ties): the search alone is then the yardstick the learned candidates must beat.
"""

from __future__ import annotations

import time
from collections.abc import Sequence
from typing import Any, NamedTuple

import numpy as np
import torch

from uamfleet.baselines.anticipation import DemandPrior, world_family
from uamfleet.baselines.demand_models import DemandModel, demand_model
from uamfleet.baselines.step_planner import SearchSettings, StepSearch, released_only
from uamfleet.checks import MAX_SEED, MAX_TIME_LIMIT_STEPS, check_flag, check_integer, check_number
from uamfleet.config import EnvConfig
from uamfleet.env.protocol import PolicyBase
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import FAMILIES, check_family
from uamfleet.observe.spec import ObserverSpec
from uamfleet.rl.loop_guard import LoopGuard
from uamfleet.rl.policy import GreedyPolicy
from uamfleet.rollout import Trajectory, fly
from uamfleet.sim.core import Simulator
from uamfleet.sim.generator import pad_passengers
from uamfleet.types import HIDDEN, HOVER_ACTION, NUM_HEADINGS, FleetState

MAX_SAMPLES = 1024
"""Upper bound of the sampled flights of one search (``samples``; ``uamfleet-benchmark --guided-samples`` and
``--hedge-samples``): each is a scratch env rolled to its end."""
MAX_EXPERT_BEAM = 4096
"""Upper bound of ``expert_beam``, the width of replan's beam search as one more candidate."""
MAX_FUTURES = 256
"""Upper bound of ``futures`` (``--hedge-futures``): one scratch env per future and candidate (up to 17 candidates)."""
MAX_STEPS = MAX_TIME_LIMIT_STEPS
"""Upper bound of the step counts ``horizon``, ``commit`` and ``tail``: an episode's longest."""

WAIT_ACTIONS: tuple[str, ...] = ("forbidden", "hover")
"""How the hedge's wait candidate keeps the taxi in place: a heading the rule forbids (where one is), or the hover
action (16) of a world that has it, at any step."""


class SearchScores(NamedTuple):
    """The hedge's candidates at one state scored over sampled futures (:meth:`AnticipatingGuidedSearch.scores_at`)."""

    actions: np.ndarray  # [C] int: each candidate's first action (a heading; the wait: HOVER_ACTION or the forbidden
    # heading it holds)
    mean_moves: np.ndarray  # [C] float: its moves averaged over the futures
    per_future: np.ndarray  # [C, F] float: its moves in each future (plus the tour bound where cut by the tail)
    waits: np.ndarray  # [C] bool: the candidate holds its first action `commit` steps (the wait)
    cpu_s: float  # thread CPU seconds of the scoring


def check_demand_spec(spec: str) -> str:
    """``spec`` if it names a demand model the hedge can read on a world: ``family`` (the true law of the world's
    instance family), a family's name, ``wrong`` (:func:`~uamfleet.baselines.demand_models.wrong_model` of the
    world's family) or a fitted model's ``.json`` file; ValueError naming them otherwise."""
    if spec in ("family", "wrong") or spec.endswith(".json"):
        return spec
    check_family(spec)
    return spec


def model_on_world(spec: str | None, cfg: EnvConfig, policy: str) -> DemandPrior | DemandModel:
    """The demand model ``spec`` names (None: ``family``) on ``cfg``'s world. The true law of a family without a
    declared law (``berlin``, ``detroit3gpp``) is :class:`DemandPrior`, as every recorded hedge row was flown; a
    family with a law (``berlin_stream``, ...) samples it (:class:`~uamfleet.baselines.demand_models.FamilyLaw`)."""
    if spec is None or spec == "family":
        spec = world_family(cfg, policy)
    if spec in FAMILIES and FAMILIES[spec].law is None:
        return DemandPrior.of_family(spec, cfg)
    return demand_model(spec, cfg)


class GuidedSearchPolicy(PolicyBase):
    """A one-taxi policy for :func:`uamfleet.rollout.fly`: ``policy`` improved by rollouts at each release
    (module docstring). ``plans`` keeps (release step, candidates, chosen moves, wall-clock seconds, thread CPU
    seconds) of every search. The defaults (8 first headings, 24 samples at temperature 2) flew the shortest of four
    settings on 25 validation instances (reports/2026-12-03-results-history/README.md, "Learning from the search").
    ``horizon`` (None: every candidate to its end) bounds a search's rollouts (module docstring)."""

    def __init__(
        self, policy: GreedyPolicy, top_k: int = 8, samples: int = 24, temperature: float = 2.0, seed: int = 0,
        expert_beam: int = 0, horizon: int | None = None, guard_rollouts: bool = False,
    ) -> None:  # fmt: skip
        top_k = check_integer("top_k", top_k, 1, NUM_HEADINGS, fix=" (the policy's likeliest first headings, e.g. 8)")
        samples = check_integer("samples", samples, 0, MAX_SAMPLES, fix=" (flights sampled per search, e.g. 24)")
        temperature = check_number("temperature", temperature, positive=True)
        seed = check_integer("seed", seed, 0, MAX_SEED)
        expert_beam = check_integer("expert_beam", expert_beam, 0, MAX_EXPERT_BEAM, fix=" (0: no beam search)")
        if horizon is not None:
            horizon = check_integer("horizon", horizon, 1, MAX_STEPS, fix=" or None (every candidate to its end)")
        guard_rollouts = check_flag("guard_rollouts", guard_rollouts)
        self.policy, self.top_k, self.samples, self.temperature = policy, top_k, samples, temperature
        self.expert_beam = expert_beam  # > 0: replan's beam search of this width is one more candidate
        # greedy steps of the rollouts decoded as the policy flies, loop guard included (False: the argmax alone,
        # as every committed learned_guided row was made)
        self.guard_rollouts = guard_rollouts
        self.horizon = horizon  # None: candidates rolled to their end; else at most this many steps, then the tour
        self._replan_when_flown = False  # with a horizon: the plan ran out before the episode's end
        self.search: StepSearch | None = None
        self.search_won: list[bool] = []  # per search: the step-level search's plan was shorter than every flight
        self.rng = np.random.default_rng(seed)
        self.sim: Simulator | None = None
        self.scratch: VectorEnv | None = None
        self.queue: list[int] = []
        self.plans: list[tuple[int, int, int, float, float]] = []

    @property
    def spec(self) -> ObserverSpec | None:
        """What it reads: its base policy's observer spec (:attr:`GreedyPolicy.spec`)."""
        return self.policy.spec

    @property
    def passenger_slots(self) -> int | None:
        """The policy's passenger axis (an instance with more requests cannot be flown)."""
        return self.policy.passenger_slots

    def fly(self, cfg: EnvConfig, seed: int | None = 0) -> Trajectory:
        """One recorded episode on the world ``cfg`` as given, observed by the policy's spec."""
        return fly(cfg, self, seed=seed)

    def reset(self, sim: Simulator) -> None:
        if sim.num_envs != 1 or sim.num_taxis != 1:
            raise ValueError(
                f"GuidedSearchPolicy flies one taxi in one env; got {sim.num_envs} env(s) x {sim.num_taxis} taxi(s)."
            )
        self.sim = sim
        self.policy.reset(sim)  # its loop guard, for the steps it flies after a plan
        if self.scratch is None or self.scratch.cfg is not sim.cfg:
            # observed as the policy reads (its spec), whatever the world's own observer fields
            self.scratch = VectorEnv(sim.cfg, num_envs=self.top_k + self.samples, autoreset=True, observer=self.spec)
            self.scratch.reset(seed=0)
            self.search = StepSearch(sim.cfg) if self.expert_beam else None
        self._trace_search_shapes()
        self.queue, self.plans, self.search_won = [], [], []
        self._released = self._released_rows()
        self.queue = self._search()

    def _trace_search_shapes(self) -> None:
        """With a traced actor, call it once at each batch shape a search feeds it, here at reset rather than in the
        first search: a trace is made at its shape's first call (about 1 s on one core), setup that would otherwise
        count as that search's time. Observes its scratch states and flies nothing, so no search changes."""
        if self.policy.traced and self.scratch is not None:
            self.policy.trace_for(self.policy.network_input(self.scratch.observer.observe(self.scratch.state)))

    def _released_rows(self) -> np.ndarray:
        assert self.sim is not None
        s = self.sim.state
        return (s.pax_status[0] != HIDDEN) & s.pax_exists[0]

    def _search(self) -> list[int]:
        """Roll the candidates forward from the env's state over the released requests; the best one's actions."""
        assert self.sim is not None and self.scratch is not None
        start, start_cpu = time.perf_counter(), time.thread_time()
        scratch = self.scratch
        self._replan_when_flown = False
        root = released_only(self.sim.state)  # the future is unknown
        if not root.pax_exists.any():
            return []
        for target, source in zip(scratch.state, root, strict=True):
            target[:] = source  # every scratch env starts as the env does, over the known requests
        limit = int(self.sim.cfg.time_limit_steps - self.sim.state.t[0])
        span = limit if self.horizon is None else min(limit, self.horizon)
        chosen_plan, best_key = self._rollouts(span, cut=span < limit)  # uncut: every candidate runs to its end
        search_won = False
        if self.search is not None:  # the search's own plan competes; the policy's flight wins ties
            plan = self.search.solve(root, [SearchSettings(beam=self.expert_beam, rank_slack=0.5)])
            if plan is not None and (best_key is None or (plan.moves, plan.steps) < best_key):
                chosen_plan, best_key, search_won = list(plan.actions), (plan.moves, plan.steps), True
                self._replan_when_flown = False  # the search's plan runs to the end
        self.search_won.append(search_won)
        wall, cpu = time.perf_counter() - start, time.thread_time() - start_cpu
        self.plans.append((int(self.sim.state.t[0]), scratch.num_envs, best_key[0] if best_key else -1, wall, cpu))
        return chosen_plan

    def _headings(
        self, logits: torch.Tensor, depth: int, obs: dict[str, np.ndarray], guard: LoopGuard | None = None
    ) -> np.ndarray:  # fmt: skip
        """[K] this step's heading of each candidate: its top_k first headings at depth 0 (the greedy one first),
        then greedy (with ``guard``: the policy's decoding, its loop guard included); the sampled candidates draw
        from the policy at ``temperature`` throughout."""
        chosen = self._greedy(logits, obs, guard)  # [K]
        if depth == 0:
            chosen[: self.top_k] = torch.topk(logits[0], self.top_k).indices.numpy()
        if self.samples:
            probs = torch.softmax(logits[self.top_k :] / self.temperature, -1).double().numpy()
            chosen[self.top_k :] = [self.rng.choice(len(p), p=p / p.sum()) for p in probs]
        return chosen

    def _rollouts(self, limit: int, cut: bool = False) -> tuple[list[int], tuple[int, int] | None]:
        """Every candidate flown in the scratch core (set to the root) for at most ``limit`` steps; the actions of
        the one that delivers every known passenger in the fewest moves (then steps), and its (moves, steps). With
        ``cut`` (``limit`` is the horizon), a candidate still flying at ``limit`` counts its moves plus its tour
        bound (:meth:`_tour_moves`), rounded to whole moves in the returned key."""
        assert self.scratch is not None and self.sim is not None
        scratch, K = self.scratch, self.scratch.num_envs
        obs = scratch.observer.observe(scratch.state)
        actions: list[list[int]] = [[] for _ in range(K)]
        moves, steps, finished = np.zeros(K, np.int64), np.full(K, -1), np.zeros(K, bool)
        guard = LoopGuard() if self.guard_rollouts and self.policy.loop_guard is not None else None
        for depth in range(limit):
            chosen = self._headings(self.policy.logits_of(self.policy.network_input(obs)), depth, obs, guard)  # [K]
            obs, _, terminated, truncated, info = scratch.step(chosen[:, None])
            live = ~finished
            moves[live] += info["events"].moved[live, 0]
            for k in np.flatnonzero(live):
                actions[k].append(int(chosen[k]))
            ended = live & (terminated | truncated)
            steps[ended & terminated] = depth + 1
            finished |= ended
            if finished.all():
                break
            if not cut and (steps >= 0).any() and (moves[~finished] >= moves[steps >= 0].min()).all():
                break  # no candidate still flying can win: its moves only grow, and it ends later (more steps)
        if cut and not finished.all():
            flying = ~finished  # cut at the horizon: ranked by moves + the tour still to fly
            estimate = moves.astype(float)
            estimate[flying] += self._tour_moves(obs)[flying]
            estimate[finished & (steps < 0)] = np.inf  # cut by the time limit: never chosen over one that delivers
            steps[flying] = depth + 1
            best = int(np.lexsort((steps, estimate))[0])
            self._replan_when_flown = bool(flying[best])
            return actions[best], (round(float(estimate[best])), int(steps[best]))
        done = np.flatnonzero(steps >= 0)
        if not len(done):
            return [], None
        best = int(done[np.lexsort((steps[done], moves[done]))[0]])
        return actions[best], (int(moves[best]), int(steps[best]))

    def _tour_moves(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        """[K] the shortest tour through every known stop left, from each scratch taxi's position, in moves: the
        least ``tour_via_stop`` over its actionable stops (0 where it has none)."""
        assert self.sim is not None
        cfg = self.sim.cfg
        tours = obs["stop_paths"][:, 0, :, 2].astype(float)  # [K, P] map sides
        actionable = obs["stop_heading_mask"][:, 0].any(-1)  # [K, P]
        least = np.where(actionable, tours, np.inf).min(-1)
        side_m = self.sim.world.side_m
        return np.where(np.isfinite(least), least * side_m / cfg.step_m, 0.0)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        assert self.sim is not None, "call reset(sim) first (uamfleet.rollout.fly does)"
        released = self._released_rows()
        if (released & ~self._released).any():
            self._released = released
            self.queue = self._search()
        elif self._search_due():
            self.queue = self._search()
        if self.queue:
            return np.array([[self.queue.pop(0)]])
        return self.policy(obs)

    def _search_due(self) -> bool:
        """Whether to search again at this step although nothing was released: a horizon's plan was flown."""
        return not self.queue and self._replan_when_flown

    @staticmethod
    def _greedy(logits: torch.Tensor, obs: dict[str, np.ndarray], guard: LoopGuard | None) -> np.ndarray:
        """[B] the greedy heading of each row: the argmax, or with ``guard`` the policy's decoding (its loop guard)."""
        return logits.argmax(-1).numpy() if guard is None else guard.choose(obs, logits.numpy())


class AnticipatingGuidedSearch(GuidedSearchPolicy):
    """Guided search that hedges for the requests still to come: a rollout algorithm over futures sampled from the
    instance family's demand model (an option beside greedy decoding and :class:`GuidedSearchPolicy`).

    While the demand model says a request may still come (:class:`uamfleet.baselines.anticipation.DemandPrior`),
    every ``commit`` steps and at every release the taxi draws ``futures`` futures given what is known (the same
    ones for every candidate, so candidates differ by their flights, not by their luck), and for each of the
    policy's ``first_headings`` most likely first headings flies the policy's greedy decoding (its loop guard
    included) from there in every future (the env's own step, so the sampled requests are released to it as they
    would be). It takes the first heading of
    least mean moves over the futures (ties to the policy's own), then flies the policy until the next search. With
    ``wait``, where a heading the rule forbids keeps the taxi in place, staying there ``commit`` steps (then the
    policy) is one more candidate: a wait flies no distance, and it is how ``replan_futures`` hedges most;
    ``wait_action="hover"`` waits with the hover action (16) instead, at any step of a world that has it.
    Until a sampled request is released the policy's flight in a future is its flight over the known requests, so
    what is scored is what the taxi does next; after, it is the policy's answer to that future. This is Bertsekas'
    rollout algorithm with the policy as its base and sample average approximation over the demand model
    (``replan_futures`` does the same with the step-level search as base, at a minute per instance).

    Once no request can come, it searches once as :class:`GuidedSearchPolicy` does (the known requests are then
    all the requests; ``top_k`` 8 and ``samples`` 8 here, so that search too fits a second of one core) and flies
    that plan. The defaults are the settings tried on 60 validation instances whose every search took at most a
    second of one core (reports/2026-12-03-results-history/README.md, "Hedging for the requests to come"). Like
    ``replan_futures`` it reads only released requests, the clock and the family's demand model: ``demand`` (a family's
    name, a :class:`~uamfleet.baselines.anticipation.DemandPrior`, or None: the family of the simulator's world at each
    :meth:`reset`, refused there for a world no family draws). ``plans`` keeps every search as
    :class:`GuidedSearchPolicy`'s does (the chosen candidate's mean moves, rounded, in place of its moves)."""

    def __init__(
        self, policy: GreedyPolicy, demand: str | DemandPrior | DemandModel | None, first_headings: int = 4,
        futures: int = 8,
        commit: int = 4, tail: int | None = 10, wait: bool = True, seed: int = 0, top_k: int = 8, samples: int = 8,
        wait_action: str = "forbidden", **known_search: Any,
    ) -> None:  # fmt: skip
        if isinstance(demand, str):
            check_demand_spec(demand)
        elif demand is not None and not callable(getattr(demand, "sample", None)):
            raise ValueError(
                f"demand={demand!r} is no demand model; pass a family's name, 'family', 'wrong', a fitted model's "
                ".json file or a DemandModel, e.g. 'berlin'."
            )
        first_headings = check_integer("first_headings", first_headings, 1, NUM_HEADINGS, fix=" (e.g. 4)")
        futures = check_integer("futures", futures, 1, MAX_FUTURES, fix=" (futures drawn per search, e.g. 8)")
        commit = check_integer("commit", commit, 1, MAX_STEPS, fix=" (steps between searches, e.g. 4)")
        if tail is not None:
            tail = check_integer("tail", tail, 0, MAX_STEPS, fix=" or None (every rollout to its end), e.g. 10")
        wait = check_flag("wait", wait)
        if wait_action not in WAIT_ACTIONS:
            raise ValueError(f"wait_action={wait_action!r} is unknown; choose one of {WAIT_ACTIONS}.")
        seed = check_integer("seed", seed, 0, MAX_SEED)
        known_search.setdefault("guard_rollouts", True)  # its flights are the policy's, loop guard included
        super().__init__(policy, top_k=top_k, samples=samples, seed=seed, **known_search)
        self.demand, self.first_headings, self.futures, self.commit = demand, first_headings, futures, commit
        self.tail = tail  # None: every rollout to its end
        self.wait = wait  # waiting in place `commit` steps is a candidate where a forbidden heading allows it
        self.wait_action = wait_action  # "hover": the wait is the hover action (16), at any step of a world with it
        self.seed = seed
        self._priors: dict[tuple[str, float, str], DemandPrior | DemandModel] = {}
        self._futures_envs: dict[int, VectorEnv] = {}
        self._futures_world: EnvConfig | None = None  # the world its futures envs were built for
        self.hedged: list[bool] = []  # per search over futures: a first heading other than the policy's won
        self.waited: list[bool] = []  # per search over futures: waiting in place won
        self.scores: list[tuple[np.ndarray, np.ndarray]] = []  # per search over futures: (first headings, mean moves)
        self.searched_at: list[int] = []  # per search over futures: the step it was made at

    def reset(self, sim: Simulator) -> None:
        if self.demand is not None and not isinstance(self.demand, str):
            self.prior = self.demand
        else:  # the named model on this map and threshold (its flyable sites), made once per pair
            key = (sim.cfg.scenario, float(sim.cfg.sinr_min_db), str(sim.cfg.feasibility))
            if key not in self._priors:
                self._priors[key] = model_on_world(self.demand, sim.cfg, "hedge")
            self.prior = self._priors[key]
        self._check_rows(sim.cfg)
        if self.wait and self.wait_action == "hover" and not sim.cfg.hover_action:
            raise ValueError(
                "wait_action='hover' waits with the hover action (16), which this world refuses: build it with "
                "hover_action=True (uamfleet bench --hover-action), or wait where a heading is forbidden "
                "(wait_action='forbidden')."
            )
        self.rng_futures = np.random.default_rng(self.seed)
        self.hedged, self.waited, self.scores, self.searched_at = [], [], [], []
        self._next_search_t = 0  # the step of the next search over futures, between releases
        self._known_search_done = False
        super().reset(sim)  # its search at the start runs through _search below

    def _trace_search_shapes(self) -> None:
        """As the base class's, and also at the root's one row and at the futures' batches (:meth:`scores_at`:
        ``first_headings`` candidates, one more with the wait, times ``futures``), building their scratch envs."""
        super()._trace_search_shapes()
        if not self.policy.traced:
            return
        assert self.sim is not None and self.scratch is not None
        self.policy.trace_for(self.policy.network_input(self.scratch.observer.observe(self.sim.state)))
        candidates = [self.first_headings + 1] if self.wait else []
        if not (self.wait and self.wait_action == "hover"):  # no wait, or a forbidden heading only some steps have
            candidates.append(self.first_headings)
        for count in candidates:
            env = self._futures_env(count * self.futures)
            self.policy.trace_for(self.policy.network_input(env.observer.observe(env.state)))

    def _future_rows(self, world_rows: int) -> int:
        """The passenger rows of its sampled futures: the world's, or the demand model's most requests if more."""
        return max(world_rows, self.prior.max_requests)

    def _check_rows(self, cfg: EnvConfig) -> None:
        """ValueError when its policy cannot read the futures it samples: up to the demand model's most requests."""
        rows = self._future_rows(cfg.num_passengers)
        spec = self.spec
        if spec is not None:
            reads = rows if spec.reads(cfg.replace(max_passengers=rows).world) is None else spec.rows(cfg.world)
        else:
            reads = self.policy.passenger_slots if self.policy.passenger_slots is not None else rows
        if reads < rows:
            raise ValueError(
                f"AnticipatingGuidedSearch samples up to {self.prior.max_requests} requests of its demand model, "
                f"but its policy reads {reads} passenger rows: give it a policy trained with max_passengers >= "
                f"{self.prior.max_requests} (or one that reads a passenger window)."
            )

    def _search(self) -> list[int]:
        assert self.sim is not None
        # the sampled requests need rows: the known state on a passenger axis the demand model's count fits in
        known = released_only(self.sim.state)
        if not known.pax_exists.any():
            return []
        futures = self.futures_at(self.rng_futures, self.futures)
        if futures is None:  # nothing can come any more: the known requests are all of them
            self._known_search_done = True
            return super()._search()
        self._next_search_t = int(self.sim.state.t[0]) + self.commit
        return self._hedge(futures)

    def futures_at(self, rng: np.random.Generator, count: int) -> list[FleetState] | None:
        """``count`` futures of the simulator's current state drawn from the demand model with ``rng``: the released
        requests, and sampled ones on the passenger axis the model's count fits in (a future where none is drawn is
        the known state); None where no request can come any more. Reads no hidden row."""
        assert self.sim is not None, "call reset(sim) first"
        known = released_only(self.sim.state)
        known = pad_passengers(known, self._future_rows(known.pax_exists.shape[1]))
        samples = [self.prior.sample(known, rng) for _ in range(count)]
        if all(f is None for f in samples):
            return None
        return [known if f is None else f for f in samples]

    def _hedge(self, futures: list[FleetState]) -> list[int]:
        """The candidate of least mean moves over ``futures`` (class docstring, :meth:`scores_at`): its first
        heading, or with ``wait`` its ``commit`` steps in place."""
        assert self.sim is not None
        start = time.perf_counter()
        scores = self.scores_at(futures)
        first, means = scores.actions, scores.mean_moves
        best = int(np.argmin(means))  # ties to the lowest index: the policy's own first heading
        hold = self.commit if scores.waits[best] else 1
        self.hedged.append(bool(best > 0 and first[best] != first[0]))
        self.waited.append(bool(scores.waits[best]))
        self.scores.append((first.copy(), means))
        t = int(self.sim.state.t[0])
        self.searched_at.append(t)
        self.plans.append((t, len(first) * len(futures), round(float(means[best])), time.perf_counter() - start,
                           scores.cpu_s))  # fmt: skip
        return [int(first[best])] * hold

    def scores_at(self, futures: Sequence[FleetState]) -> SearchScores:
        """The candidates at the simulator's current state scored over ``futures`` (:meth:`futures_at`), flying
        nothing in the simulator: the policy's ``first_headings`` likeliest first headings, and with ``wait`` the
        wait (the hover action, or the first forbidden heading, held ``commit`` steps), each followed by the
        policy's greedy decoding (its loop guard included) in a scratch env per candidate and future, to the end
        or ``tail`` steps past the demand model's window (then plus the tour through the stops left); a rollout
        cut by the time limit counts the limit's steps more."""
        assert self.sim is not None and self.scratch is not None, "call reset(sim) first"
        start_cpu = time.thread_time()
        K, F = self.first_headings, len(futures)
        root_obs = self.scratch.observer.observe(self.sim.state)  # it reads the world as the policy does (reset)
        root_logits = self.policy.logits_of(self.policy.network_input(root_obs))[0]
        finite = torch.isfinite(root_logits) & (root_logits > -1e8)
        order = torch.argsort(root_logits, descending=True)[: max(1, min(K, int(finite.sum())))].numpy()
        first = np.resize(order, K)  # fewer allowed headings than K: the last rows repeat candidates
        hold = np.ones(K, np.int64)  # steps a candidate keeps its first action before the policy flies
        blocked = np.flatnonzero(~self.sim.state.action_mask[0, 0, :NUM_HEADINGS])
        if self.wait and self.wait_action == "hover":  # the hover action keeps the taxi in place at any step
            first, hold = np.append(first, HOVER_ACTION), np.append(hold, self.commit)
        elif self.wait and len(blocked):  # a heading the rule forbids keeps the taxi in place: waiting flies nothing
            first, hold = np.append(first, blocked[0]), np.append(hold, self.commit)
        C = len(first)
        env = self._futures_env(C * F)
        for name in FleetState._fields:
            for f, future in enumerate(futures):  # env c * F + f: candidate c in future f
                getattr(env.state, name)[f::F] = getattr(future, name)[0]
        obs = env.observer.observe(env.state)
        t = int(self.sim.state.t[0])
        limit = int(self.sim.cfg.time_limit_steps - t)
        if self.tail is not None:  # every sampled request is released by the window's end: then a tour bound
            limit = min(limit, max(0, self.prior.window_steps - t) + self.tail)
        rows_first, rows_hold = np.repeat(first, F), np.repeat(hold, F)
        moves, finished, delivered = np.zeros(C * F), np.zeros(C * F, bool), np.zeros(C * F, bool)
        guard = None if self.policy.loop_guard is None else LoopGuard()  # the policy's decoding, loop guard included
        for depth in range(limit):
            chosen = rows_first.copy()
            if depth:
                greedy = self._greedy(self.policy.logits_of(self.policy.network_input(obs)), obs, guard)
                chosen = np.where(depth < rows_hold, rows_first, greedy)
            obs, _, terminated, truncated, info = env.step(chosen[:, None])
            live = ~finished
            moves[live] += info["events"].moved[live, 0]
            delivered |= live & terminated
            finished |= live & (terminated | truncated)
            if finished.all():
                break
        cut = ~finished  # still flying at the tail's end: its moves plus the tour through the stops it has left
        moves[cut] += self._tour_moves(obs)[cut]
        moves[finished & ~delivered] += self.sim.cfg.time_limit_steps  # cut by the time limit: never preferred
        per_future = moves.reshape(C, F)
        return SearchScores(first, per_future.mean(1), per_future, hold > 1, time.thread_time() - start_cpu)

    def _futures_env(self, num_envs: int) -> VectorEnv:
        """The scratch env of ``num_envs`` rows for one search (made once per size and config)."""
        assert self.sim is not None
        if self._futures_world is not self.sim.cfg:  # another world: its envs are built afresh
            self._futures_envs.clear()
            self._futures_world = self.sim.cfg
        env = self._futures_envs.get(num_envs)
        if env is None:  # the world's rules on the futures' passenger axis, observed as the policy reads
            futures_world = self.sim.cfg.replace(max_passengers=self._future_rows(self.sim.cfg.num_passengers))
            env = self._futures_envs[num_envs] = VectorEnv(futures_world, num_envs, autoreset=True, observer=self.spec)
            env.reset(seed=0)
        return env

    def _search_due(self) -> bool:
        """`commit` steps flown since the last search over futures, while a request may come (or a horizon's plan
        flown, once nothing can)."""
        assert self.sim is not None
        due = not self._known_search_done and int(self.sim.state.t[0]) >= self._next_search_t
        return due or super()._search_due()


__all__ = [
    "WAIT_ACTIONS",
    "AnticipatingGuidedSearch",
    "GuidedSearchPolicy",
    "SearchScores",
    "check_demand_spec",
    "model_on_world",
]
