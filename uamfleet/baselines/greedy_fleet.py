"""A greedy fleet dispatcher: every taxi flies to its nearest actionable stop along feasible paths."""

from __future__ import annotations

import numpy as np

from uamfleet.baselines.fleet_steering import fleet_actions, shared_fields
from uamfleet.env.protocol import PolicyBase
from uamfleet.sim.core import Simulator
from uamfleet.types import ON_BOARD, WAITING


class GreedyFleetPolicy(PolicyBase):
    """A simple fleet dispatcher (not one of the paper's baselines): nearest stop first.

    Each taxi heads for its nearest stop: a drop-off of a passenger it carries, or, while it has a free seat, the
    origin of a waiting passenger no nearer taxi has claimed this step (taxi-passenger pairs are claimed nearest
    first). It steers along feasible paths (:class:`~uamfleet.paths.DistanceFields`), so taxis go round no-fly
    areas instead of getting stuck at their edges. A taxi with nothing to do hovers (the hover action, where the env
    has it) or zig-zags about the point where it became idle (as the other fleet dispatchers do:
    :func:`~uamfleet.baselines.fleet_steering.fleet_actions`, which also makes an idle taxi step out of a busy
    one's way under the shield), instead of chasing its own position.
    """

    def reset(self, sim: Simulator) -> None:
        if sim.num_envs != 1:
            raise ValueError(f"GreedyFleetPolicy drives a one-env core, got num_envs={sim.num_envs}")
        self.sim = sim
        self.fields = shared_fields(sim)
        self._idle_at: list[np.ndarray | None] = [None] * sim.num_taxis

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return fleet_actions(self.sim, self.fields, self._idle_at, self._targets())

    def _targets(self) -> list[np.ndarray | None]:
        s = self.sim.state
        pos, status, carrier, free = s.pos_m[0], s.pax_status[0], s.pax_taxi[0], s.free_seats[0]
        waiting = np.flatnonzero((status == WAITING) & s.pax_exists[0])
        d_wait = np.linalg.norm(pos[:, None] - s.pax_origin_m[0][waiting][None], axis=-1)  # [A, W]
        claims: dict[int, tuple[float, np.ndarray]] = {}
        taken: set[int] = set()
        for flat in np.argsort(d_wait, axis=None):
            a, w = np.unravel_index(flat, d_wait.shape)
            if free[a] > 0 and a not in claims and w not in taken:
                claims[int(a)] = (float(d_wait[a, w]), s.pax_origin_m[0, waiting[w]])
                taken.add(int(w))
        targets: list[np.ndarray | None] = []
        for a in range(len(pos)):
            best = claims.get(a)
            for p in np.flatnonzero((status == ON_BOARD) & (carrier == a)):
                d = float(np.linalg.norm(s.pax_dest_m[0, p] - pos[a]))
                if best is None or d < best[0]:
                    best = (d, s.pax_dest_m[0, p])
            targets.append(None if best is None else best[1])
        return targets
