"""Greedy decoding in which a taxi with nothing to do stays where it is: :class:`IdleWait`.

Why: the network picks among the allowed headings only (its logits are masked), so a lone taxi without the hover
action can never stay in place, and with nothing to do it zig-zags about a point at one move per step. ``replan``
waits instead, by asking for a heading the rule forbids (the taxi stays:
``StepPlannerPolicy._wait_action``). On Berlin's instances a taxi is hardly ever idle (its trips outlast the
release window), but on a small map it often is, and the moves it then flies are most of what it flies beyond
``replan`` (measured in reports/2026-12-04-small-maps/README.md).

The rule (docs/rules.md "Greedy decoding of a trained policy"): a taxi with no rider on board, no released request
waiting and no request the fleet's matching gives it (``stop_claims``, when observed) takes the hover action where
the network has it, else the first heading its action mask forbids, as ``replan`` waits; where every heading is
allowed it flies the greedy choice as before. Everything is read from the observation. Off by default
(``learned:idle_wait=true``), so every recorded flight of a learned policy is unchanged.
"""

from __future__ import annotations

import numpy as np

from uamfleet.rl.loop_guard import LoopGuard
from uamfleet.types import (
    HOVER_ACTION,
    NUM_HEADINGS,
    NUM_PASSENGER_FEATURES,
    PAX_ON_BOARD_SELF,
    PAX_WAITING,
    STOP_CLAIMED_BY_ME,
)


def idle_rows(obs: dict[str, np.ndarray], rows: int) -> np.ndarray:
    """[B] bool: the taxi of each row has nobody on board, no released request waits and none is claimed for it."""
    status = obs["passengers"].reshape(rows, -1, NUM_PASSENGER_FEATURES)
    shown = obs["passenger_mask"].reshape(rows, -1) > 0
    busy = ((status[..., PAX_ON_BOARD_SELF] > 0) | (status[..., PAX_WAITING] > 0)) & shown
    claims = obs.get("stop_claims")
    if claims is not None:
        busy |= claims.reshape(rows, -1, claims.shape[-1])[..., STOP_CLAIMED_BY_ME] > 0
    return np.asarray(~busy.any(-1))


class IdleWait(LoopGuard):
    """The decoding rule of the module docstring on top of the loop guard (``guarded`` False: on top of the argmax
    alone), in the place of :class:`~uamfleet.rl.policy.GreedyPolicy`'s ``loop_guard``."""

    def __init__(self, guarded: bool = True) -> None:
        self.guarded = guarded
        super().__init__()

    def reset(self, env: object = None) -> None:
        """A new episode: the guard forgets its points and the count of waits restarts."""
        super().reset(env)
        self.waits = 0  # decisions the rule turned into a wait, since the last reset

    def choose(self, obs: dict[str, np.ndarray], logits: np.ndarray) -> np.ndarray:
        """Actions [B] from masked ``logits`` [B, 16 or 17] for the observation ``obs`` ({name: [E, A, ...]})."""
        rows = logits.shape[0]
        choice = super().choose(obs, logits) if self.guarded else logits.argmax(-1)
        idle = idle_rows(obs, rows)
        if not idle.any():
            return choice
        forbidden = ~obs["action_mask"].reshape(rows, NUM_HEADINGS).astype(bool)
        wait, can_wait = forbidden.argmax(-1), forbidden.any(-1)  # the first forbidden heading, as replan's
        if logits.shape[-1] > NUM_HEADINGS:  # the network has the hover action: it is the wait, at any step
            wait, can_wait = np.full(rows, HOVER_ACTION), np.ones(rows, bool)
        waiting = idle & can_wait
        self.waits += int(waiting.sum())
        return np.where(waiting, wait, choice)
