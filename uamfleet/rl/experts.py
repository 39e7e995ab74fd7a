"""The experts that label DAgger's states: ``replan``'s step-level search and ``replan_futures``' decisions.

Each expert keeps one plan per env of a group and answers :meth:`labels` (the heading it would fly in each env's
current state, :data:`NO_LABEL` where it only waits) and :meth:`advance` (after a step: a plan whose first heading
was flown moves on by one, any other is solved again at the next label). Where the policy proposes another heading,
the expert keeps it when that heading and a search from where it leads is not longer than its own plan, so a label
corrects the policy only where the search is strictly shorter. :mod:`uamfleet.rl.imitation` rolls out, aggregates
and fits on these labels.
"""

from __future__ import annotations

import time

import numpy as np

from uamfleet.baselines.anticipation import AnticipatingReplan
from uamfleet.baselines.step_planner import SEARCH_STATE_FIELDS, SearchSettings, StepSearch, released_only
from uamfleet.config import EnvConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.types import HIDDEN, FleetState

NO_LABEL = -1


class ReplanExpert:
    """``replan``'s solver as a labeller for one group of envs (one config).

    Each env keeps its plan and is re-solved only when the plan no longer holds: after a release, a new episode,
    or an executed heading other than the plan's. A plan's remaining moves are its length (the search keeps no
    move that stays in place once every known request is released).

    Many headings are often equally good (the plan's first heading is one of several ties), and a label that picks
    one of them at random teaches noise. So where the policy proposes another heading than the plan's, the expert
    also solves from where that heading leads; if the policy's heading is not longer, it becomes the label and the
    plan (the policy is corrected only where the search is strictly shorter)."""

    def __init__(self, cfg: EnvConfig, num_envs: int, beam: int) -> None:
        self.search = StepSearch(cfg)
        self.settings = (SearchSettings(beam=beam, rank_slack=0.5),)
        self.plans: list[list[int]] = [[] for _ in range(num_envs)]
        self.valid = np.zeros(num_envs, bool)
        self.solves = 0
        self.solve_s = 0.0
        self.corrections = 0  # labels that differ from the proposal because the search was strictly shorter
        self._child_env = VectorEnv(self.search.scratch_cfg, 1, autoreset=True)
        self._child_env.reset(seed=0)

    def _solve(self, state: FleetState, e: int) -> list[int]:
        start = time.perf_counter()
        plan = self.search.solve(state, self.settings, env_index=e)
        self.solve_s += time.perf_counter() - start
        self.solves += 1
        return list(plan.actions) if plan is not None else []

    def _after(self, known: FleetState, e: int, heading: int) -> list[int] | None:
        """The plan that starts with ``heading`` from env ``e`` of ``known``: the heading, then the search from
        where it leads; None if that heading does not move or no plan is found from there."""
        after, moved, done = _one_step(self._child_env, known, e, heading)
        if not moved:
            return None
        if done:
            return [heading]
        rest = self._solve(after, 0)
        return [heading, *rest] if rest else None

    def labels(self, venv: VectorEnv, proposals: np.ndarray | None = None) -> np.ndarray:
        """[E] the expert's heading in each env's current state (:data:`NO_LABEL` where it has no plan);
        ``proposals`` [E] (the policy's headings) are kept where they are as short as the plan."""
        stale = ~self.valid
        challenged = np.zeros_like(stale)
        if proposals is not None:
            first = np.array([p[0] if p else NO_LABEL for p in self.plans])
            challenged = self.valid & (first != NO_LABEL) & (first != proposals)
        if not (stale | challenged).any():
            return np.array([p[0] if p else NO_LABEL for p in self.plans], np.int64)
        known = released_only(venv.state)  # the search sees the released requests only, as replan does
        for e in np.flatnonzero(stale):
            self.plans[e] = self._solve(known, int(e))
            self.valid[e] = True
            challenged[e] = proposals is not None and bool(self.plans[e]) and self.plans[e][0] != proposals[e]
        for e in np.flatnonzero(challenged):
            alternative = self._after(known, int(e), int(proposals[e]))  # type: ignore[index]
            if alternative is not None and len(alternative) <= len(self.plans[e]):
                self.plans[e] = alternative
            else:
                self.corrections += 1
        return np.array([p[0] if p else NO_LABEL for p in self.plans], np.int64)

    def advance(self, executed: np.ndarray, released: np.ndarray, ended: np.ndarray) -> None:
        """After a step: a plan whose first heading was flown, with no release and no episode end, moves on by one;
        every other plan is re-solved at the next :meth:`labels`."""
        _advance_plans(self.plans, self.valid, executed, released, ended)


def _one_step(env: VectorEnv, state: FleetState, e: int, heading: int) -> tuple[FleetState, bool, bool]:
    """Env ``e`` of ``state`` flown one ``heading`` in the one-env core ``env``: (the state after it, whether the
    taxi moved, whether everyone is delivered; the state is the core's next episode then, and is not to be read)."""
    for name in SEARCH_STATE_FIELDS:
        getattr(env.state, name)[:] = getattr(state, name)[e : e + 1]
    _, _, terminated, _, info = env.step(np.array([[heading]]))
    return env.state.take(np.array([0])), bool(info["events"].moved[0, 0]), bool(terminated[0])


def _advance_plans(
    plans: list[list[int]], valid: np.ndarray, executed: np.ndarray, released: np.ndarray, ended: np.ndarray
) -> list[int]:
    """After a step: each valid plan whose first heading was flown, with no release and no episode end, moves on
    by one; every other is marked invalid (``valid`` in place). Returns the envs whose plan moved on."""
    moved_on = []
    for e, plan in enumerate(plans):
        if not valid[e]:
            continue
        followed = not plan or int(executed[e]) == plan[0]
        if released[e] or ended[e] or not followed:
            valid[e] = False
        elif plan:
            plan.pop(0)
            moved_on.append(e)
    return moved_on


class AnticipatingExpert:
    """``replan_futures``' decisions (:class:`~uamfleet.baselines.anticipation.AnticipatingReplan`: ``replan``'s
    plan and the plans of sampled futures, scored on other sampled futures) as the labeller of one group of envs.

    A decision holds until the next release, the episode's end, an executed heading other than its plan's, or,
    for a sampled future's plan, the step that future expected its next release. Every decision between the same
    two releases of an episode draws the same futures (its generator is seeded by the env, the episode and the
    number released), so a state reached again after a deviation is labelled against the same sampled demand,
    not a fresh draw. As in :class:`ReplanExpert`, a proposal other than the plan's first heading is kept when
    that heading and a search from where it leads, over the state the plan was made for (the known requests or
    the chosen future), is not longer than the rest of the plan. It never reads a hidden row of the env: only the
    released requests, the clock and the instance family's demand model."""

    def __init__(self, cfg: EnvConfig, num_envs: int, planner: AnticipatingReplan, seed: int = 0) -> None:
        self.planner = planner
        planner.prepare(cfg)
        self.seed = seed
        self.plans: list[list[int]] = [[] for _ in range(num_envs)]
        self.valid = np.zeros(num_envs, bool)
        self.cut = np.zeros(num_envs, bool)  # a sampled future's plan (or a kept proposal): decide again after it
        self.basis: list[FleetState | None] = [None] * num_envs  # the state the plan flies over, kept in step
        self.rest_moves = np.zeros(num_envs, np.int64)  # moves of the whole plan's rest over its basis
        self.episode = np.zeros(num_envs, np.int64)
        self.solves = 0  # decisions taken
        self.solve_s = 0.0
        self.corrections = 0
        self._child_env = VectorEnv(planner.search.scratch_cfg, 1, autoreset=True)
        self._child_env.reset(seed=0)

    def _decide(self, venv: VectorEnv, e: int) -> None:
        start = time.perf_counter()
        released = int(released_count(venv)[e])
        rng = np.random.default_rng([self.seed, e, int(self.episode[e]), released])
        decision = self.planner.decide(self.planner.known_state(venv.state, e), rng)
        self.planner.plans.clear()  # the benchmark's record of decisions; not kept here
        self.solve_s += time.perf_counter() - start
        self.solves += 1
        self.plans[e], self.cut[e], self.valid[e] = list(decision.actions), decision.cut, True
        self.basis[e] = decision.basis if decision.plan is not None else None
        self.rest_moves[e] = decision.plan.moves if decision.plan is not None else 0

    def labels(self, venv: VectorEnv, proposals: np.ndarray | None = None) -> np.ndarray:
        """[E] the teacher's heading in each env's current state (:data:`NO_LABEL` where it only waits);
        ``proposals`` [E] (the policy's headings) are kept where they are as short as the plan."""
        ran_out = self.cut & np.array([not p for p in self.plans])
        for stale in np.flatnonzero(~self.valid | ran_out):
            self._decide(venv, int(stale))
        for e in range(len(self.plans) if proposals is not None else 0):
            plan, basis = self.plans[e], self.basis[e]
            if not plan or basis is None or plan[0] == proposals[e]:  # type: ignore[index]
                continue
            self._weigh_proposal(e, basis, int(proposals[e]))  # type: ignore[index]
        return np.array([p[0] if p else NO_LABEL for p in self.plans], np.int64)

    def _weigh_proposal(self, e: int, basis: FleetState, heading: int) -> None:
        """Env ``e``'s plan starts with the policy's ``heading`` where flying it from ``basis`` then searching takes
        no more moves than the plan's rest (cut to the plan's length after a sampled future); else a correction."""
        plan = self.plans[e]
        after, moved, done = _one_step(self._child_env, basis, 0, heading)
        rest = None if done or not moved else self.planner.search.solve(after, self._settings(e))
        moves = 1 if done and moved else (1 + rest.moves if rest is not None else None)
        if moves is not None and moves <= self.rest_moves[e]:
            actions = [heading, *(rest.actions if rest is not None else [])]
            self.plans[e] = actions[: len(plan)] if self.cut[e] else actions
            self.rest_moves[e] = moves
        else:
            self.corrections += 1

    def _settings(self, e: int) -> tuple[SearchSettings, ...]:
        return self.planner.future_settings if self.cut[e] else self.planner.replan_settings

    def advance(self, executed: np.ndarray, released: np.ndarray, ended: np.ndarray) -> None:
        """After a step: a plan whose first heading was flown, with no release and no episode end, moves on by one
        (its basis state with it); every other plan is decided again at the next :meth:`labels`."""
        self.episode += ended
        for e in _advance_plans(self.plans, self.valid, executed, released, ended):
            basis = self.basis[e]
            if basis is not None:
                self.basis[e], moved, _ = _one_step(self._child_env, basis, 0, int(executed[e]))
                self.rest_moves[e] -= int(moved)


def released_count(venv: VectorEnv) -> np.ndarray:
    """[E] the requests released so far in each env of ``venv``."""
    s = venv.state
    return ((s.pax_status != HIDDEN) & s.pax_exists).sum(-1)  # [E]


__all__ = ["NO_LABEL", "AnticipatingExpert", "ReplanExpert", "released_count"]
