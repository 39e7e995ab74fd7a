"""A fleet policy that reads a dispatcher's commitments: the dispatcher runs alongside, the network decides.

The chosen fleet dispatcher keeps commitments the fleet policy's observation does not show: which taxi serves which
request and in what order (its stop schedules). :class:`ClaimsFleetPolicy` runs such a dispatcher beside the
network, watching every step exactly as when it flies (its ``act`` is called on the simulator at every step, so its
schedules advance, as in :func:`uamfleet.rl.fleet_imitation.label_episode`), and gives each passenger row of each
taxi's window the dispatcher's claim on that row's stop from this taxi's point of view
(:data:`~uamfleet.types.DISPATCH_CLAIM_FEATURES`, :func:`dispatch_claims`): on my schedule, on another taxi's, my
next stop, my schedule's order. The network (``NetConfig.dispatch_claim_inputs``) reads them as four more columns
of each passenger row and as a linear term of each stop's score; :func:`with_dispatch_claims` converts a trained
stop-head policy with both at zero, so the converted policy flies exactly as before until it is trained
(``uamfleet fleet-imitate --dispatch-claims``). One set of weights for every taxi and fleet size, as before.

The claims are the dispatcher's, so they read what it reads: released requests only (a row of the window is a
released request, and a dispatcher assigns a request at its release).
"""

from __future__ import annotations

import dataclasses

import numpy as np
import torch

from uamfleet.baselines.fleet_dispatch import ScheduleFleetPolicy
from uamfleet.baselines.fleet_steering import make_way, onward_heading
from uamfleet.baselines.sequencing import PICKUP
from uamfleet.checks import ConfigError
from uamfleet.env.protocol import PolicyBase
from uamfleet.observe.observer import Observer
from uamfleet.rl.networks import MSHAActorCritic
from uamfleet.rl.policy import GreedyPolicy
from uamfleet.sim.core import Simulator
from uamfleet.rl.heads import NOT_THIS
from uamfleet.types import DISPATCH_CLAIM_FEATURES, DISPATCH_CLAIMS_FIELD, HOVER_ACTION, ON_BOARD, WAITING

PASSENGER_EMBED = "torso.passengers.embed.weight"
"""The parameter :func:`with_dispatch_claims` widens: the passenger rows' embedding gets four zero columns, last."""
CLAIM_SCORE = "stop_head.dispatch_score.weight"
"""The parameter it adds: the claims' linear term in each stop's score, zero."""
SCHEDULED_TO_ME, SCHEDULED_TO_OTHER, MY_NEXT_STOP, MY_SCHEDULE_RANK = range(len(DISPATCH_CLAIM_FEATURES))


def open_stops(dispatcher: ScheduleFleetPolicy, taxi: int) -> list[int]:
    """The passengers of the stops still open on ``taxi``'s schedule, in its order: the pick-up of a passenger who
    waits, the drop-off of one this taxi carries (a waiting passenger's drop-off is not a stop it can fly to yet)."""
    assert dispatcher.sim is not None
    s = dispatcher.sim.state
    status, carrier = s.pax_status[0], s.pax_taxi[0]
    out = []
    for p, kind in dispatcher.routes[taxi]:
        if (kind == PICKUP and status[p] == WAITING) or (status[p] == ON_BOARD and carrier[p] == taxi):
            out.append(int(p))
    return out


def dispatch_claims(rows: np.ndarray, dispatcher: ScheduleFleetPolicy) -> np.ndarray:
    """[A, K, 4] float32: the claims (:data:`~uamfleet.types.DISPATCH_CLAIM_FEATURES`) of ``dispatcher``'s schedules
    on each taxi's window rows ``rows`` [A, K] (the state's passenger in each slot, -1 where empty; each row stands
    for its passenger's next stop: the pick-up while they wait, else the drop-off). Zero for an empty slot."""
    A, K = rows.shape
    out = np.zeros((A, K, len(DISPATCH_CLAIM_FEATURES)), np.float32)
    owner: dict[int, tuple[int, int]] = {}  # passenger -> (taxi, position among its open stops)
    for a in range(A):
        for rank, p in enumerate(open_stops(dispatcher, a)):
            owner.setdefault(p, (a, rank))
    for a in range(A):
        following = dispatcher.next_stop(a)
        for k in range(K):
            p = int(rows[a, k])
            if p < 0 or p not in owner:
                continue
            taxi, rank = owner[p]
            if taxi != a:
                out[a, k, SCHEDULED_TO_OTHER] = 1.0
                continue
            out[a, k, SCHEDULED_TO_ME] = 1.0
            out[a, k, MY_SCHEDULE_RANK] = 1.0 / (1 + rank)
            out[a, k, MY_NEXT_STOP] = float(following is not None and following[0] == p)
    return out


CLAIMS_HEADINGS = ("table", "onward")
"""Which heading a claims policy's stop head flies to its next stop (:func:`onward_marks`): the observation's
``stop_heading_mask`` as the env writes it, or, on the move that makes the stop, the dispatcher's onward rule."""


def check_claims_heading(value: object) -> str:
    """``value`` if it is one of :data:`CLAIMS_HEADINGS`; ConfigError naming it otherwise."""
    if value not in CLAIMS_HEADINGS:
        raise ConfigError(f"heading={value!r}: choose one of {', '.join(CLAIMS_HEADINGS)} (uamfleet.rl.fleet_claims).")
    return str(value)


def onward_marks(heading_mask: np.ndarray, claims: np.ndarray, dispatcher: ScheduleFleetPolicy) -> np.ndarray:
    """A copy of env 0's ``stop_heading_mask`` [1, A, K, 16] in which each taxi's next stop on ``dispatcher``'s
    schedule (its row with :data:`MY_NEXT_STOP` in ``claims`` [A, K, 4]) marks, where one of the taxi's allowed moves
    makes that stop (ends within the pick-up radius) and a stop follows it on the schedule, the move the dispatcher's
    ``heading=onward`` flies there (:func:`~uamfleet.baselines.fleet_steering.onward_heading`: of the moves that make
    the stop, the one ending nearest the stop after it). Every other row keeps the env's mark, so a stop head that
    flies the marks flies onward's heading on exactly the moves where that rule differs from the table's. A row the
    env marks nothing on (not actionable) stays unmarked."""
    assert dispatcher.sim is not None, "the dispatcher watches the simulator: call its reset(sim) first"
    marks = heading_mask.copy()
    for a, k in zip(*np.nonzero(claims[:, :, MY_NEXT_STOP]), strict=True):
        if not marks[0, a, k].any():
            continue
        target, after = dispatcher.target_and_after(int(a))
        if target is None or after is None:
            continue
        heading = onward_heading(dispatcher.sim, dispatcher.fields, int(a), target, after)
        if heading >= 0:
            marks[0, a, k] = 0
            marks[0, a, k, heading] = 1
    return marks


def with_dispatch_claims(policy: GreedyPolicy) -> GreedyPolicy:
    """A copy of ``policy`` whose network also reads a dispatcher's claims (``NetConfig.dispatch_claim_inputs``): the
    same weights and normaliser, the passenger rows' embedding widened by four zero columns and a zero linear term
    of the claims in each stop's score, so the copy flies the same greedy actions whatever the claims. A policy
    that reads them already is returned as it is. ConfigError for one without a stop head or an observer spec."""
    if policy.spec is None or policy.net.cfg.action_head != "stops":
        raise ConfigError("only a stop-head fleet policy loaded with load_policy reads a dispatcher's claims.")
    if policy.net.cfg.dispatch_claim_inputs:
        return policy
    cfg = dataclasses.replace(policy.net.cfg, dispatch_claim_inputs=True)

    def carry_over(new: MSHAActorCritic) -> None:
        old, state = policy.net.state_dict(), new.state_dict()
        for key, value in old.items():
            if key == PASSENGER_EMBED:  # [D, F] -> [D, F + 4]: the claims' columns come last, at zero
                state[key] = torch.cat([value, value.new_zeros(value.shape[0], len(DISPATCH_CLAIM_FEATURES))], dim=1)
            else:
                state[key] = value
        state[CLAIM_SCORE] = torch.zeros_like(state[CLAIM_SCORE])
        if set(state) != set(old) | {CLAIM_SCORE}:
            raise ValueError(f"the policy's network does not carry over: {sorted(set(state) ^ set(old))}.")
        new.load_state_dict(state)

    return policy.with_network(cfg, carry_over)


def with_claims(inputs: dict[str, np.ndarray], claims: np.ndarray) -> dict[str, np.ndarray]:
    """The network's rows ``inputs`` (:meth:`GreedyPolicy.network_input`, ``[A, ...]`` for one env) with the
    claims [A, K, 4] added as :data:`~uamfleet.types.DISPATCH_CLAIMS_FIELD`."""
    return {**inputs, DISPATCH_CLAIMS_FIELD: claims.reshape(-1, *claims.shape[-2:]).astype(np.float32)}


def claims_view(
    policy: GreedyPolicy, obs: dict[str, np.ndarray], claims: np.ndarray, dispatcher: ScheduleFleetPolicy,
    heading: str = "table",
) -> tuple[dict[str, np.ndarray], dict[str, np.ndarray]]:  # fmt: skip
    """What a claims policy's network reads of env 0's observation ``obs``, in flight and in training alike: (the
    observation, with ``heading="onward"`` its next stops' marks set by :func:`onward_marks`; the network's rows of
    it with the ``dispatcher``'s ``claims`` [A, K, 4] added, :func:`with_claims`)."""
    if heading == "onward":
        obs = {**obs, "stop_heading_mask": onward_marks(obs["stop_heading_mask"], claims, dispatcher)}
    return obs, with_claims(policy.network_input(obs), claims)


class ClaimsFleetPolicy(PolicyBase):
    """A fleet policy whose network reads ``dispatcher``'s claims (module docstring), acting greedily through its
    loop guard as :class:`GreedyPolicy` does; ``dispatcher`` (a schedule dispatcher, fresh or reused) watches every
    step. Its :attr:`spec` is the network policy's: the env is built to what the network reads.

    ``hover_when_idle`` (a decoding rule, for a network that may hover at any step, ``NetConfig.hover_anytime``):
    a taxi with an open stop on the dispatcher's schedule (:func:`open_stops`) does not hover; its most likely
    heading flies instead. The dispatcher itself hovers only with an empty schedule. ``heading="onward"``: the
    network reads its next stop's heading mark as :func:`onward_marks` sets it (the mark it was trained on with
    ``uamfleet fleet-imitate --claims-heading onward``). ``make_way`` (under the separation shield): a hovering taxi,
    or one with no open stop on the dispatcher's schedule, steps out of the way of a taxi whose next move would pass
    within the separation of it, by the dispatchers' own rule
    (:func:`~uamfleet.baselines.fleet_steering.make_way`): the shield keeps a hover and turns the other taxi aside,
    so without it a taxi hovering in a passage can hold a taxi with a rider back until the time limit."""

    def __init__(
        self, policy: GreedyPolicy, dispatcher: ScheduleFleetPolicy, hover_when_idle: bool = False,
        heading: str = "table", make_way: bool = False,
    ) -> None:  # fmt: skip
        if not policy.net.cfg.dispatch_claim_inputs:
            raise ConfigError(
                "this policy's network reads no dispatcher claims: convert it with with_dispatch_claims (and train "
                "it with uamfleet fleet-imitate --dispatch-claims), or fly it as 'learned'."
            )
        if not isinstance(dispatcher, ScheduleFleetPolicy):
            raise ConfigError(f"the claims are a schedule dispatcher's; {type(dispatcher).__name__} keeps none.")
        self.policy, self.dispatcher = policy, dispatcher
        self.hover_when_idle = hover_when_idle
        self.heading = check_claims_heading(heading)
        self.make_way = make_way
        self.spec = policy.spec
        self._observer: Observer | None = None

    def reset(self, sim: Simulator | None = None) -> None:
        if sim is None:
            raise ConfigError("ClaimsFleetPolicy.reset needs the simulator: its dispatcher watches it.")
        self.policy.reset(sim)
        self.dispatcher.reset(sim)
        if self._observer is None or self._observer.world is not sim.world:
            self._observer = Observer(sim.world, self.spec)  # only for the window's rows (its stop table is cached)

    def claims(self) -> np.ndarray:
        """[A, K, 4] the dispatcher's claims on each taxi's window rows now (call after its ``act`` this step)."""
        assert self._observer is not None and self.dispatcher.sim is not None, "call reset(sim) first"
        return dispatch_claims(self._observer.window_rows(self.dispatcher.sim.state)[0], self.dispatcher)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        if obs["action_mask"].shape[0] != 1:
            raise ConfigError("a ClaimsFleetPolicy flies one env at a time (its dispatcher watches env 0).")
        self.dispatcher.act(obs)  # its schedules advance by this step, as when it flies
        obs, inputs = claims_view(self.policy, obs, self.claims(), self.dispatcher, self.heading)
        logits = self.policy.logits_of(inputs)
        if self.hover_when_idle and logits.shape[-1] > HOVER_ACTION:
            busy = [a for a in range(logits.shape[0]) if open_stops(self.dispatcher, a)]
            if busy:
                logits = logits.clone()  # an inference tensor: a copy takes the change
                logits[busy, HOVER_ACTION] = NOT_THIS
        actions = np.array(self.policy.choose(obs, logits))  # a copy make_way may change
        sim = self.dispatcher.sim
        assert sim is not None  # reset(sim) gave it the simulator
        if self.make_way and sim.cfg.separation == "shield":
            idle = [bool(k == HOVER_ACTION or not open_stops(self.dispatcher, a)) for a, k in enumerate(actions[0])]
            make_way(sim, actions[0], idle, [None] * len(idle))
        return actions


__all__ = [
    "CLAIMS_HEADINGS",
    "CLAIM_SCORE",
    "PASSENGER_EMBED",
    "ClaimsFleetPolicy",
    "check_claims_heading",
    "claims_view",
    "dispatch_claims",
    "onward_marks",
    "open_stops",
    "with_claims",
    "with_dispatch_claims",
]
