"""The stop head: the policy as a mixture over the taxi's actionable stops and a free move.

:class:`StopHead` turns the torso's features and passenger tokens into one categorical distribution over the 16
headings (17 with the hover action): each actionable stop puts its weight on the heading that makes most progress
along its feasible path (``stop_heading_mask``), a free component spreads its own over the actor's logits. The
constants below set its prior and its initial weights; :class:`uamfleet.rl.networks.MSHAActorCritic` builds it
for ``NetConfig(action_head="stops")``.
"""

from __future__ import annotations

import math

import torch
import torch.nn.functional as F
from torch import nn

from uamfleet.rl.encoders import as_bool, layer_init
from uamfleet.types import DISPATCH_CLAIM_FEATURES, NUM_HEADINGS, STOP_CLAIM_FEATURES, STOP_PATH_FEATURES

TOUR_VIA_STOP = STOP_PATH_FEATURES.index("tour_via_stop")
PATH_TO_STOP = STOP_PATH_FEATURES.index("path_to_stop")
CLAIMED_BY_OTHER = STOP_CLAIM_FEATURES.index("claimed_by_other")

NOT_THIS = -1e4  # log-weight of "no": exp() is 0 in float32, yet finite, so no NaN reaches a gradient
NEARNESS_INIT = 20.0
"""Initial weight of the stop head's prior, per map side of tour: on Berlin (3.3 km) a stop whose tour is 330 m
shorter starts with 2 more logits (e^2 = 7.4 times the probability)."""
HOVER_LEAD = 2.0
"""Initial lead, in logits, of the stop head's hover component over its free move: an idle taxi starts by
hovering (7.4 times as likely as moving freely)."""
PRIOR_FLOOR = -12.0
"""With ``heading_residual``, the stop mixture's log-probabilities are floored here before the learned residual
is added: a heading the prior rules out (log-probability -1e4) stays within reach of a residual of a dozen logits,
and with zero residuals the policy keeps the prior's greedy choice and all but e^-12 of its probabilities."""
LOOKAHEAD_HIDDEN = 16
"""Width of the stop head's look-ahead correction (one input, the heading's look-ahead in moves)."""
LOOKAHEAD_GAIN = -PRIOR_FLOOR
"""Logits per unit of the look-ahead correction's output: a correction of about 1 outweighs the prior's lead over
the floor, so a few hundred gradient steps can teach a heading the prior rules out (at a unit gain the output layer
had to grow a dozen-fold, and DAgger's rounds stopped far short of it)."""
LOOKAHEAD_RULE = 100.0
"""A :attr:`NetConfig.lookahead_rule` at which the least look-ahead heading decides: a heading 0.12 move (12 m)
worse than the best loses by more than the prior's whole range (:data:`PRIOR_FLOOR`), so the prior only breaks
near-ties, and a learned correction must grow to a dozen logits to turn the taxi off the rule's heading."""
HOVER_START = -12.0
"""Initial logit of the hover action (16) with ``NetConfig.hover_anytime``: its probability starts at
sigmoid(-12) = 6.1e-6 at every step, so a converted policy hovers with probability below 1e-5 and never by argmax
(the likeliest heading's log-probability is at least log(1/16) = -2.8, the hover's -12)."""
CLAIM_INIT = 8.0
"""Initial logits taken from a stop that the nearest-first matching gives to another taxi (``stop_claims``): about
the tour prior of 1.3 km more (Berlin), and enough that a taxi whose every stop is claimed starts by waiting."""


class StopHead(nn.Module):
    """``action_head="stops"``: the policy as a mixture over the taxi's actionable stops and a free move.

    The env marks, per actionable stop, the heading that makes most progress along its feasible path
    (``stop_heading_mask``, one-hot). Each stop p gets a score from its passenger token and the taxi's features;
    a "free" component gets one from the features alone and spreads its weight over the allowed headings by the
    actor's logits. Then ``pi(h) = sum_p w_p [h = heading_p] + w_free * pi_free(h)`` with ``w = softmax(scores)``:
    still one categorical distribution over the 16 headings (the env and PPO are unchanged), but choosing a stop
    is one decision instead of learning the path to it.

    Each stop's score starts from a prior, ``-nearness * (measure - the best stop's)``. With
    ``NetConfig.stop_prior="tour"`` the measure is ``tour_via_stop`` (``stop_paths[..., 2]``, map sides, passed
    to the network unnormalised): the shortest tour through every known stop that flies to this one first. So
    the untrained policy already flies that tour and keeps flying to the stop it chose; ``nearness`` (initially
    :data:`NEARNESS_INIT`, learned) and the learned part of the score then move it off that order where the
    return says so. With ``stop_prior="nearest"`` the measure is ``path_to_stop``: the fleet's choice, since one
    taxi's tour through every waiting passenger of a fleet is not its tour.

    In a fleet whose observation has ``stop_claims`` (``claims=True``), a waiting passenger that the nearest-first
    matching of free taxis gives to *another* taxi starts :data:`CLAIM_INIT` logits lower (``claim_weight``,
    learned), and the free component is also open when every actionable stop of the taxi is claimed by others
    (it carries nobody and no passenger is left for it): the taxi may then wait instead of chasing another
    taxi's passenger. With ``hover=True`` (the observation has ``hover_heading_mask``, the heading back to where
    the taxi was a step ago) a hover component opens with the free move and starts :data:`HOVER_LEAD` logits ahead
    of it: an idle taxi then hovers about a point, as the dispatchers' idle taxis do. With ``hover_logit=True``
    (``NetConfig.hover_logit``, for an env with the hover action) that component's log-weight is instead the
    log-probability of action 16 (stay in place), open whenever no stop is (it needs no hover heading): the output
    has 17 columns, and the stop and free components keep their headings' log-probabilities unchanged.

    ``hover_anytime=True`` (``NetConfig.hover_anytime``, for an env with the hover action) opens action 16 at every
    step, stops open or not: :meth:`with_anytime_hover` turns the masked heading logits into 17 log-probabilities,
    the headings' old probabilities times 1 - p and action 16's p = sigmoid(b + w . features), with ``b`` learned
    from :data:`HOVER_START` and ``w`` from zero (with ``hover_logit``, p is added to the hover component's
    probability). The search's "wait here", or a dispatcher's, is then a decision the policy can imitate wherever it
    is taken.

    ``dispatch=True`` (``NetConfig.dispatch_claim_inputs``) adds to each stop's score a learned linear term of a
    dispatcher's claims on it (``DISPATCH_CLAIM_FEATURES``: on my schedule, on another taxi's, my next stop, my
    schedule's order; :mod:`uamfleet.rl.fleet_claims`), zero at first.

    ``free_move=False`` (the default) gives the free component weight only when the taxi has no actionable
    stop (nothing released, or everyone delivered): the policy then chooses stops only. With ``free_move=True``
    it is always a component (starting at ``free_bias``), so the policy may wait or reposition.

    ``residual=True`` (``NetConfig.heading_residual``) lets the policy choose its flight: learned per-heading
    logits (each stop's from its hidden row, weighted by that stop's mixture weight, plus one from the features)
    are added to the mixture's log-probabilities floored at :data:`PRIOR_FLOOR`. They start at zero, so the
    untrained head flies as the prior; the order of the known stops still comes from the exact tour prior.

    ``lookahead=True`` (``NetConfig.lookahead_inputs``) adds a learned function of each heading's look-ahead
    (``heading_lookahead``: its move plus the shortest tour after it, in moves above the best heading's) to the
    floored log-probabilities: one small network shared by the 16 headings, zero at first. It can learn to enter a
    stop's pick-up radius on the side of the next stop, which the prior leaves to heading order.
    ``lookahead_rule`` (``NetConfig.lookahead_rule``) also takes that many logits per move of look-ahead from each
    heading, a fixed term: at :data:`LOOKAHEAD_RULE` the untrained head flies the least look-ahead heading (the rule
    of ``reports/2026-12-03-one-off-benchmarks/lookahead_rule.py``), the prior breaking near-ties, and what is learned
    corrects the rule.

    Why each part is there (the runs without it): ``reports/2026-12-03-results-history/README.md``, "What fell short,
    what was tried" (the prior, the free move) and "A learned fleet" (claims, hover).
    """

    def __init__(
        self, features: int, d_model: int, hidden: int, free_bias: float = -2.0, free_move: bool = False,
        claims: bool = False, hover: bool = False, residual: bool = False, lookahead: bool = False,
        hover_logit: bool = False, lookahead_rule: float = 0.0, hover_anytime: bool = False, dispatch: bool = False,
    ) -> None:  # fmt: skip
        super().__init__()
        self.lookahead_rule = lookahead_rule  # fixed logits per move of look-ahead (NetConfig.lookahead_rule)
        self.free_move, self.claims, self.hovers, self.residual = free_move, claims, hover, residual
        self.hover_logit = hover_logit  # the hover component is action 16's logit (no parameters of its own)
        self.lookahead = lookahead
        if lookahead:  # g(look-ahead of heading h) added to heading h's logit; zero at first
            self.residual_lookahead = nn.Sequential(
                nn.Linear(1, LOOKAHEAD_HIDDEN), nn.Tanh(), layer_init(nn.Linear(LOOKAHEAD_HIDDEN, 1), std=0.0)
            )
        if residual:  # the flight beyond the prior: per-heading logits, zero at first (the prior unchanged)
            self.residual_per_stop = layer_init(nn.Linear(hidden, NUM_HEADINGS), std=0.0)
            self.residual_free = layer_init(nn.Linear(features, NUM_HEADINGS), std=0.0)
        if claims:  # only then: checkpoints of heads without claims keep their exact parameter set
            self.log_claim_weight = nn.Parameter(torch.tensor(math.log(CLAIM_INIT)))
        if hover:  # a "hover" component beside the free move, HOVER_LEAD logits ahead of it at first
            self.hover = layer_init(nn.Linear(features, 1), std=0.01, bias=free_bias + HOVER_LEAD)
        self.from_features = nn.Linear(features, hidden)
        self.from_token = nn.Linear(d_model, hidden, bias=False)
        self.score = layer_init(nn.Linear(hidden, 1), std=0.01)
        self.free = layer_init(nn.Linear(features, 1), std=0.01, bias=free_bias)
        self.log_nearness = nn.Parameter(torch.tensor(math.log(NEARNESS_INIT)))
        self.hover_anytime = hover_anytime
        if hover_anytime:  # made last and drawing no random numbers: every other initial weight stays as without it
            self.anytime_hover = nn.Linear(features, 1)
            nn.init.zeros_(self.anytime_hover.weight)
            nn.init.constant_(self.anytime_hover.bias, HOVER_START)
        self.dispatch = dispatch
        if dispatch:  # a dispatcher's claims on each stop, a linear term of its score: zero at first, made last
            self.dispatch_score = nn.Linear(len(DISPATCH_CLAIM_FEATURES), 1, bias=False)
            nn.init.zeros_(self.dispatch_score.weight)

    def forward(
        self, features: torch.Tensor, tokens: torch.Tensor, heading_mask: torch.Tensor, free_logits: torch.Tensor,
        path_to_stop: torch.Tensor | None = None, claimed_by_other: torch.Tensor | None = None,
        hover_mask: torch.Tensor | None = None, with_residual: bool = True, lookahead: torch.Tensor | None = None,
        dispatch_claims: torch.Tensor | None = None,
    ) -> torch.Tensor:  # fmt: skip
        """features [B, F], tokens [B, P, D], heading_mask [B, P, 16], free_logits [B, 16] (masked), path_to_stop
        [B, P] (map sides; None: no prior), claimed_by_other [B, P] bool (with ``claims``), hover_mask [B, 16]
        one-hot (with ``hover``), lookahead [B, 16] (with ``lookahead``), dispatch_claims [B, P, 4] (with
        ``dispatch``) → log pi [B, 16]; with ``residual`` or
        ``lookahead`` (and ``with_residual``) unnormalised logits: the mixture's log-probabilities floored at
        :data:`PRIOR_FLOOR` plus the learned per-heading corrections."""
        onehot = as_bool(heading_mask)  # [B, P, 16]
        actionable = onehot.any(-1)  # [B, P]
        hidden, scores, open_stop = self._stop_scores(features, tokens, actionable, path_to_stop, claimed_by_other)
        if self.dispatch:
            if dispatch_claims is None:
                raise ValueError("this stop head reads a dispatcher's claims: pass dispatch_claims [B, P, 4].")
            scores = scores + self.dispatch_score(dispatch_claims.to(scores.dtype)).squeeze(-1) * actionable
        idle, hover_at = self._idle_scores(features, open_stop, hover_mask)
        weights = torch.log_softmax(torch.cat([scores, *idle], dim=-1), dim=-1)  # [B, P + 1 (+ 1)]
        logp = self._mixture(weights, onehot, free_logits, hover_at)  # [B, 16 (+ 1)]
        if not ((self.residual or self.lookahead) and with_residual):
            return logp
        return self._corrected(logp, weights, hidden, features, lookahead)

    def with_anytime_hover(self, logits: torch.Tensor, features: torch.Tensor) -> torch.Tensor:
        """``hover_anytime``: masked logits [B, 16] (or [B, 17] with ``hover_logit``) and the torso's features [B, F]
        → log pi [B, 17]: each old action's log-probability plus log(1 - p), and in column 16 (the hover action) p
        added, p = sigmoid(b + w . features): with ``hover_logit`` pi(16) = (1 - p) pi_old(16) + p, the hover
        component's where no stop is open plus this one's at every step. The old actions keep their order, so the
        greedy action stays the same while p is small, and a masked heading stays at the masked value
        (probability 0)."""
        z = self.anytime_hover(features)  # [B, 1] the hover's log-odds
        kept = torch.log_softmax(logits, dim=-1) + F.logsigmoid(-z)  # [B, 16 (+ 1)] log(pi_old (1 - p))
        if logits.shape[-1] == NUM_HEADINGS:
            return torch.cat([kept, F.logsigmoid(z)], dim=-1)  # [B, 17]
        hover = torch.logaddexp(kept[:, NUM_HEADINGS:], F.logsigmoid(z))  # [B, 1] log((1 - p) pi_old(16) + p)
        return torch.cat([kept[:, :NUM_HEADINGS], hover], dim=-1)  # [B, 17]

    def _stop_scores(
        self, features: torch.Tensor, tokens: torch.Tensor, actionable: torch.Tensor,
        path_to_stop: torch.Tensor | None, claimed_by_other: torch.Tensor | None,
    ) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:  # fmt: skip
        """(hidden [B, P, H], each stop's score [B, P] with its prior and claim, :data:`NOT_THIS` where it is not
        actionable, open_stop [B, P]: the actionable stops that keep the free component closed)."""
        hidden = torch.tanh(self.from_features(features).unsqueeze(1) + self.from_token(tokens))  # [B, P, H]
        scores = self.score(hidden).squeeze(-1)  # [B, P]
        if path_to_stop is not None:  # relative to the nearest stop: only the free move's weight sees the shift
            nearest = path_to_stop.masked_fill(~actionable, math.inf).amin(-1, keepdim=True)  # [B, 1]
            extra = torch.where(actionable, path_to_stop - nearest, 0.0)  # [B, P] >= 0
            scores = scores - self.log_nearness.exp() * extra
        open_stop = actionable  # [B, P] the stops that keep the free component closed
        if self.claims:
            if claimed_by_other is None:
                raise ValueError("this stop head reads claims: pass claimed_by_other [B, P] (obs 'stop_claims').")
            scores = scores - self.log_claim_weight.exp() * claimed_by_other.to(scores.dtype)
            open_stop = actionable & ~claimed_by_other
        return hidden, scores.masked_fill(~actionable, NOT_THIS), open_stop

    def _idle_scores(
        self, features: torch.Tensor, open_stop: torch.Tensor, hover_mask: torch.Tensor | None
    ) -> tuple[list[torch.Tensor], torch.Tensor | None]:
        """(the free component's score [B, 1] and, with ``hover``, the hover component's; the hover heading one-hot
        [B, 16] with ``hover``, else None)."""
        free_score = self.free(features)  # [B, 1]
        if not self.free_move:  # only when there is no stop to fly to (that no other taxi is matched with)
            free_score = free_score.masked_fill(open_stop.any(-1, keepdim=True), NOT_THIS)
        if not self.hovers:
            return [free_score], None
        if hover_mask is None:
            raise ValueError("this stop head hovers: pass hover_mask [B, 16] (obs 'hover_heading_mask').")
        hover_at = as_bool(hover_mask)  # [B, 16] one-hot (all zero: no move allowed)
        closed = open_stop.any(-1, keepdim=True)  # [B, 1] a stop to fly to: no hovering
        if not self.hover_logit:  # the hover heading is needed to hover by it; the hover action needs none
            closed = closed | ~hover_at.any(-1, keepdim=True)
        return [free_score, self.hover(features).masked_fill(closed, NOT_THIS)], hover_at

    def _mixture(
        self, weights: torch.Tensor, onehot: torch.Tensor, free_logits: torch.Tensor, hover_at: torch.Tensor | None
    ) -> torch.Tensor:
        """log pi [B, 16] of the mixture of the stops' headings, the free move and the hover heading; with
        ``hover_logit`` the hover action's log-probability appended [B, 17]."""
        P = onehot.shape[1]
        per_stop = weights[:, :P, None] + torch.where(onehot, 0.0, NOT_THIS)  # [B, P, 16]
        free = weights[:, P : P + 1, None] + torch.log_softmax(free_logits, dim=-1).unsqueeze(1)  # [B, 1, 16]
        parts = [per_stop, free]
        if hover_at is not None and not self.hover_logit:
            parts.append(weights[:, P + 1 :, None] + torch.where(hover_at, 0.0, NOT_THIS).unsqueeze(1))  # [B, 1, 16]
        logp = torch.logsumexp(torch.cat(parts, dim=1), dim=1)  # [B, 16] log-probabilities
        if self.hover_logit:  # the hover's log-weight is the hover action's log-probability (+ logp's: 1 in all)
            logp = torch.cat([logp, weights[:, P + 1 :]], dim=-1)  # [B, 17]
        return logp

    def _corrected(
        self, logp: torch.Tensor, weights: torch.Tensor, hidden: torch.Tensor, features: torch.Tensor,
        lookahead: torch.Tensor | None,
    ) -> torch.Tensor:  # fmt: skip
        """The mixture's log-probabilities floored at :data:`PRIOR_FLOOR` plus the learned residual and look-ahead
        corrections of the headings [B, 16 (+ 1)]."""
        P = hidden.shape[1]
        logits = logp.clamp(min=PRIOR_FLOOR)  # [B, 16 (+ 1)] the corrections below are the headings' only
        headings = logits[:, :NUM_HEADINGS]  # [B, 16]
        if self.residual:  # each stop's own flight correction (from its hidden row), weighted by its mixture weight
            per_stop = torch.einsum("bp,bph->bh", weights[:, :P].exp(), self.residual_per_stop(hidden))  # [B, 16]
            headings = headings + per_stop + self.residual_free(features)
        if self.lookahead:
            if lookahead is None:
                raise ValueError(
                    "this stop head reads the look-ahead: pass lookahead [B, 16] (obs 'heading_lookahead')."
                )
            correction = self.residual_lookahead(lookahead.unsqueeze(-1)).squeeze(-1)  # [B, 16]
            headings = headings + LOOKAHEAD_GAIN * correction - self.lookahead_rule * lookahead
        return torch.cat([headings, logits[:, NUM_HEADINGS:]], dim=-1)  # [B, 16 (+ 1)]


__all__ = [
    "CLAIMED_BY_OTHER", "CLAIM_INIT", "HOVER_LEAD", "HOVER_START", "LOOKAHEAD_GAIN", "LOOKAHEAD_HIDDEN",
    "LOOKAHEAD_RULE", "NEARNESS_INIT", "NOT_THIS", "PATH_TO_STOP", "PRIOR_FLOOR", "TOUR_VIA_STOP", "StopHead",
]  # fmt: skip
