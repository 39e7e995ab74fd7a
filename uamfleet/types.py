"""Typed containers of the batched simulator: state, per-step events. Shapes: E envs, A taxis, P passengers."""

from __future__ import annotations

from dataclasses import dataclass
from typing import NamedTuple

import numpy as np

# Passenger status codes (pax_status).
HIDDEN = 0  # request not released yet (or a padding row): invisible, cannot be picked up
WAITING = 1  # released, waiting at its origin
ON_BOARD = 2  # in taxi pax_taxi
DELIVERED = 3


@dataclass
class FleetState:
    """The whole simulator state. Arrays are updated in place by :func:`uamfleet.env.dynamics.step`
    (copying the visit counts every step would cost more than the step itself)."""

    t: np.ndarray  # [E] int64, steps since reset
    pos_m: np.ndarray  # [E, A, 2] float64, taxi positions (world frame)
    free_seats: np.ndarray  # [E, A] int64
    history_m: np.ndarray  # [E, A, H, 2] float64, positions at steps t-1 ... t-H (index 0 = most recent)
    history_seats: np.ndarray  # [E, A, H] int64, free seats at those steps
    visits: np.ndarray  # [E, A, nbx + k, nby + k] int32, per-taxi block visit counts, padded by the patch size k
    distance_m: np.ndarray  # [E, A] float64, distance flown this episode
    action_mask: np.ndarray  # [E, A, 16] bool, moves allowed from the current positions
    pax_exists: np.ndarray  # [E, P] bool, False for padding rows
    pax_release: np.ndarray  # [E, P] int64, release step
    pax_origin_m: np.ndarray  # [E, P, 2] float64
    pax_dest_m: np.ndarray  # [E, P, 2] float64
    pax_status: np.ndarray  # [E, P] int8: HIDDEN / WAITING / ON_BOARD / DELIVERED
    pax_taxi: np.ndarray  # [E, P] int64, taxi carrying / that carried the passenger, -1 if none
    pax_pickup_step: np.ndarray  # [E, P] int64, -1 until picked up
    pax_dropoff_step: np.ndarray  # [E, P] int64, -1 until delivered

    @property
    def num_envs(self) -> int:
        return int(self.pos_m.shape[0])

    @property
    def num_taxis(self) -> int:
        return int(self.pos_m.shape[1])

    def copy(self) -> FleetState:
        return FleetState(**{k: v.copy() for k, v in vars(self).items()})

    def take(self, envs: np.ndarray) -> FleetState:
        """A copy holding only the envs ``envs`` (an index array), in that order."""
        return FleetState(**{k: v[envs] for k, v in vars(self).items()})


class StepEvents(NamedTuple):
    """What happened in one transition. Reward, metrics and viewers consume these; none recomputes physics."""

    prev_pos_m: np.ndarray  # [E, A, 2] positions before the step
    pos_m: np.ndarray  # [E, A, 2] positions after the step
    actions: np.ndarray  # [E, A] int64 headings taken
    moved: np.ndarray  # [E, A] bool, the move was allowed and flown
    blocked: np.ndarray  # [E, A] bool, the move was not allowed: the taxi stayed in place
    first_visit: np.ndarray  # [E, A] bool, the taxi entered a block it had never visited
    block_visits: np.ndarray  # [E, A] int32, the taxi's visit count of its block after the step
    picked_up: np.ndarray  # [E, P] bool, boarded this step (by pax_taxi)
    dropped_off: np.ndarray  # [E, P] bool, delivered this step (by pax_taxi)
    released: np.ndarray  # [E, P] bool, request became visible at the new step
    pickups: np.ndarray  # [E, A] int64, passengers boarded by each taxi
    dropoffs: np.ndarray  # [E, A] int64, passengers delivered by each taxi
    separation_violation: np.ndarray  # [E, A] bool, another taxi is closer than min_separation_m
    segment_min_sinr_db: np.ndarray  # [E, A] min raster SINR along the flown segment (-inf: N.C./outside)
    all_delivered: np.ndarray  # [E] bool, every passenger of the instance has been delivered
    t: np.ndarray  # [E] int64 step index after the transition
