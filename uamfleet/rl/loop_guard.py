"""Greedy decoding that never flies a taxi in a circle: :class:`LoopGuard`.

Why: a greedy policy is a function of its observation. Between two events (a pick-up, a drop-off, a release, a
request taken by another taxi) a taxi's world changes only by its own position and the clock, so a taxi that
comes back to a point it stood on since its last event is likely to repeat what it did from there, forever. Under
``segment_raster`` this happens: the distance table, interpolated between block centres, can make a point look
closer to a stop than any move from it can get (the moves towards the stop cross outage cells), and the shipped
policy flew two headings back and forth until the time limit on 32 of the 200 Berlin test instances
(reports/2026-12-03-results-history/README.md, "Under `segment_raster`"). With a consistent distance a return without an
event only adds two moves, so forbidding it costs nothing where the policy is right.

The rule (docs/rules.md "Greedy decoding of a trained policy"): while a taxi has somewhere to go (a rider on board,
a request the fleet's matching gives it (``stop_claims``), or, flying alone, a waiting request and a free seat), a
heading whose move ends within a tenth of a move of a point it stood on since its last event (at most
:data:`MEMORY` points back) is taken only when every allowed heading does so; otherwise the taxi flies the most
likely heading that does not. Nothing else changes: a taxi with nowhere to go may circle on purpose (an idle taxi
without the hover action zig-zags about a point to wait), a hover (action 16) is never replaced, and a taxi that
has not moved yet (its step length unknown) flies the argmax.

Everything is read from the observation, so the guard works for any batch of envs and taxis: ``self`` (the
position ÷ side_m, the free seats, the clock), ``history`` (the last move's length, i.e. step_m ÷ side_m, unknown
until the taxi has moved), the status columns of ``passengers`` under ``passenger_mask`` and ``stop_claims`` when
observed (both counted, so a passenger window that reorders its rows is no event), and ``others_mask``.
"""

from __future__ import annotations

import numpy as np

from uamfleet.config import heading_vectors
from uamfleet.types import NUM_HEADINGS, PASSENGER_FEATURES

MEMORY = 64
"""Points remembered per taxi since its last event (a ring: older ones are forgotten)."""

_STATUS_COLUMNS = [PASSENGER_FEATURES.index(k) for k in ("waiting", "on_board_self", "on_board_other", "delivered")]
_UNIT = heading_vectors()  # [16, 2]: the moves' directions, as the world's moves_m = step_m * heading_vectors()


class LoopGuard:
    """The decoding rule of the module docstring, with one memory per row of the batch (env × taxi)."""

    def __init__(self, memory: int = MEMORY) -> None:
        self.memory = memory
        self.reset()

    def reset(self, env: object = None) -> None:
        """Forget every taxi's points (a new episode; ``env`` is ignored: the signature of ``Policy.reset``)."""
        self._rows = -1
        self.interventions = 0  # decisions whose argmax the guard replaced, since the last reset

    def _start(self, rows: int) -> None:
        self._rows = rows
        self._points = np.zeros((rows, self.memory, 2))
        self._count = np.zeros(rows, np.int64)  # points kept (<= memory), the newest at (count - 1) % memory
        self._key = np.full((rows, 7), -1.0)
        self._clock = np.full(rows, np.inf)
        self._step = np.zeros(rows)  # step_m / side_m once seen, 0 before

    def choose(self, obs: dict[str, np.ndarray], logits: np.ndarray) -> np.ndarray:
        """Actions [B] from masked ``logits`` [B, 16 or 17] for the observation ``obs`` ({name: [E, A, ...]},
        B = E * A rows)."""
        rows = logits.shape[0]
        if rows != self._rows:
            self._start(rows)
        me = obs["self"].reshape(rows, -1).astype(np.float64)
        here, seats, clock = me[:, :2], me[:, 2], me[:, 3]
        status = obs["passengers"].reshape(rows, -1, len(PASSENGER_FEATURES))[:, :, _STATUS_COLUMNS]
        counted = (status * obs["passenger_mask"].reshape(rows, -1, 1)).sum(1)  # [B, 4] requests by status
        claims = obs.get("stop_claims")
        claimed = claims.reshape(rows, -1, 2).sum(1) if claims is not None else np.zeros((rows, 2))
        key = np.concatenate([counted, claimed, seats[:, None]], axis=1)
        lone = obs["others_mask"].reshape(rows, -1).sum(1) == 0 if "others_mask" in obs else np.ones(rows, bool)
        has_goal = (counted[:, 1] > 0) | (claimed[:, 0] > 0) | (lone & (counted[:, 0] > 0) & (seats > 0))
        last_move = obs["history"].reshape(rows, -1, 3)[:, 0, :2].astype(np.float64)
        moved = np.hypot(last_move[:, 0], last_move[:, 1])
        self._step = np.where(moved > 0, moved, self._step)
        new_leg = (clock < self._clock) | np.any(np.abs(key - self._key) > 1e-6, axis=1)
        self._count[new_leg] = 0
        self._key, self._clock = key, clock
        slot = self._count % self.memory
        self._points[np.arange(rows), slot] = here
        self._count += 1

        choice = logits.argmax(-1)
        heading = np.minimum(choice, NUM_HEADINGS - 1)
        flagged = self._revisits(here, _UNIT[heading][:, None, :])[:, 0] & (choice < NUM_HEADINGS) & has_goal
        if not flagged.any():  # the common case: one look-up per taxi, not sixteen
            return choice
        revisit = self._revisits(here, _UNIT[None])  # [B, 16]
        fresh = obs["action_mask"].reshape(rows, NUM_HEADINGS).astype(bool) & ~revisit
        switch = flagged & fresh.any(-1)
        if switch.any():
            guarded = np.where(fresh, logits[:, :NUM_HEADINGS], -np.inf)
            choice = np.where(switch, guarded.argmax(-1), choice)
            self.interventions += int(switch.sum())
        return choice

    def _revisits(self, here: np.ndarray, units: np.ndarray) -> np.ndarray:
        """[B, H] whether the move from ``here`` [B, 2] along each of ``units`` [B or 1, H, 2] ends within a tenth
        of a move of a point the row remembers (False while its step length is unknown)."""
        ends = here[:, None, :] + self._step[:, None, None] * units  # [B, H, 2]
        kept = np.arange(self.memory)[None, :] < np.minimum(self._count, self.memory)[:, None]  # [B, M]
        gap = np.linalg.norm(ends[:, :, None, :] - self._points[:, None, :, :], axis=-1)  # [B, H, M]
        near = (gap < 0.1 * self._step[:, None, None]) & kept[:, None, :]
        return near.any(-1) & (self._step > 0)[:, None]
