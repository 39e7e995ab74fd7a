"""Typed containers of the batched simulator and the layouts they share: state, per-step events, headings,
passenger status codes and observation feature indices (each defined here once). Shapes: E envs, A taxis,
P passengers, H history steps, k patch size. The rules behind them: ``docs/rules.md``.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

NUM_HEADINGS = 16
"""Flight directions, also the size of the action space: heading k points 22.5° * k counter-clockwise from east
(paper §IV-A, k = 0..15)."""
HOVER_ACTION = NUM_HEADINGS
"""Action 16, only with ``EnvConfig.hover_action``: stay in place for the slot (time passes, no distance flown;
always allowed, never in the heading mask). docs/rules.md "Motion"."""

# Passenger status codes (pax_status); docs/rules.md "Release and pick-up".
HIDDEN = 0  # request not released yet (or a padding row): invisible, cannot be picked up
WAITING = 1  # released, waiting at its origin
ON_BOARD = 2  # in taxi pax_taxi
DELIVERED = 3

# ---- observation columns (docs/rules.md "Observation"): the names of each field's last axis, and the indices the
# kernels write through, derived from them. Which fields a config observes, with shapes, bounds and kinds:
# uamfleet.observe.spec.observation_layout (the one spec; it names these tuples as the fields' columns).
SELF_FEATURES: tuple[str, ...] = ("x", "y", "free_seats", "time")  # x, y / side; seats / capacity; t / limit
SELF_X = SELF_FEATURES.index("x")
SELF_Y = SELF_FEATURES.index("y")
SELF_FREE_SEATS = SELF_FEATURES.index("free_seats")
SELF_TIME = SELF_FEATURES.index("time")
HISTORY_FEATURES: tuple[str, ...] = ("dx", "dy", "free_seats")  # (position then - now) / side; seats then / capacity
HIST_DX = HISTORY_FEATURES.index("dx")
HIST_DY = HISTORY_FEATURES.index("dy")
HIST_FREE_SEATS = HISTORY_FEATURES.index("free_seats")
OTHER_FEATURES: tuple[str, ...] = ("dx", "dy", "free_seats")  # (other taxi - this one) / side; its seats / capacity
OTHER_DX = OTHER_FEATURES.index("dx")
OTHER_DY = OTHER_FEATURES.index("dy")
OTHER_FREE_SEATS = OTHER_FEATURES.index("free_seats")
PASSENGER_FEATURES: tuple[str, ...] = (
    "origin_dx",  # (origin - taxi) / side
    "origin_dy",
    "dest_dx",  # (destination - taxi) / side
    "dest_dy",
    "dist_to_origin",  # |origin - taxi| / side
    "dist_to_dest",  # |destination - taxi| / side
    "trip_length",  # |destination - origin| / side
    "waiting",  # released, not yet picked up
    "on_board_self",  # on board this taxi
    "on_board_other",  # on board another taxi
    "delivered",
    "age",  # (t - release step) / time limit
)
PAX_ORIGIN_DX = PASSENGER_FEATURES.index("origin_dx")
PAX_ORIGIN_DY = PASSENGER_FEATURES.index("origin_dy")
PAX_DEST_DX = PASSENGER_FEATURES.index("dest_dx")
PAX_DEST_DY = PASSENGER_FEATURES.index("dest_dy")
PAX_DIST_TO_ORIGIN = PASSENGER_FEATURES.index("dist_to_origin")
PAX_DIST_TO_DEST = PASSENGER_FEATURES.index("dist_to_dest")
PAX_TRIP_LENGTH = PASSENGER_FEATURES.index("trip_length")
PAX_WAITING = PASSENGER_FEATURES.index("waiting")
PAX_ON_BOARD_SELF = PASSENGER_FEATURES.index("on_board_self")
PAX_ON_BOARD_OTHER = PASSENGER_FEATURES.index("on_board_other")
PAX_DELIVERED = PASSENGER_FEATURES.index("delivered")
PAX_AGE = PASSENGER_FEATURES.index("age")
NUM_PASSENGER_FEATURES = len(PASSENGER_FEATURES)
STOP_PATH_FEATURES: tuple[str, ...] = (
    "path_to_stop",  # feasible-path distance from the taxi to the row's stop / side (0: no actionable stop)
    "ride_path",  # feasible-path distance from the row's origin to its destination / side
    "tour_via_stop",  # the shortest tour through every known stop that flies to this one first / side
)  # the "stop_paths" field, with EnvConfig.stop_features
STOP_PATH_TO_STOP = STOP_PATH_FEATURES.index("path_to_stop")
STOP_RIDE_PATH = STOP_PATH_FEATURES.index("ride_path")
STOP_TOUR_VIA_STOP = STOP_PATH_FEATURES.index("tour_via_stop")
STOP_RIVAL_FEATURES: tuple[str, ...] = (
    "rival_path",  # feasible-path distance from a waiting row's origin to the nearest other taxi with a seat / side
    "rivals_nearer",  # share of the other taxis with a seat that are nearer to it than this taxi
)  # the "stop_rivals" field, with EnvConfig.stop_features and stop_rivals (or stop_claims), for any fleet size
STOP_RIVAL_PATH = STOP_RIVAL_FEATURES.index("rival_path")
STOP_RIVALS_NEARER = STOP_RIVAL_FEATURES.index("rivals_nearer")
STOP_CLAIM_FEATURES: tuple[str, ...] = (
    "claimed_by_me",  # 1: the nearest-first matching of free taxis to waiting rows gives this row to this taxi
    "claimed_by_other",  # 1: ... to another taxi
)  # the "stop_claims" field (int8), with EnvConfig.stop_claims, for any fleet size
DISPATCH_CLAIM_FEATURES: tuple[str, ...] = (
    "scheduled_to_me",  # 1: the stop of this row is on this taxi's schedule in a dispatcher the policy runs alongside
    "scheduled_to_other",  # 1: ... on another taxi's schedule
    "my_next_stop",  # 1: it is the first stop of this taxi's schedule that the taxi can act on now
    "my_schedule_rank",  # 1 / (1 + its position among this taxi's open stops), 0 when not on its schedule
)  # the "dispatch_claims" rows a fleet policy reads beside its observation (uamfleet.rl.fleet_claims), any fleet
DISPATCH_CLAIMS_FIELD = "dispatch_claims"
"""The network input [P, len(DISPATCH_CLAIM_FEATURES)] of a dispatcher's claims (``NetConfig.dispatch_claim_inputs``):
not an observation field; the policy that runs the dispatcher alongside adds it to the network's rows."""
STOP_CLAIMED_BY_ME = STOP_CLAIM_FEATURES.index("claimed_by_me")
STOP_CLAIMED_BY_OTHER = STOP_CLAIM_FEATURES.index("claimed_by_other")
STOP_PATH_CLIP = 16.0
"""Upper bound of the ``stop_paths`` and ``stop_rivals`` distances (map sides): an unreachable stop (``inf``) reads
as this."""
LOOKAHEAD_CLIP = 4.0
"""Upper bound of the ``heading_lookahead`` field (moves): a heading not allowed, or this many moves worse than the
best one or more, reads as this."""
STATE_TAXI_FEATURES: tuple[str, ...] = ("x", "y", "free_seats", "index")  # rows of state(), per taxi
STATE_TAXI_INDEX = STATE_TAXI_FEATURES.index("index")
STATE_PASSENGER_FEATURES: tuple[str, ...] = (
    "origin_x",
    "origin_y",
    "dest_x",
    "dest_y",
    "waiting",
    "on_board",
    "delivered",
    "carrier",
    "age",
)


class FleetState(NamedTuple):
    """The whole simulator state. Arrays are updated in place by :func:`uamfleet.sim.dynamics.step`
    (copying the visit counts every step would cost more than the step itself). A NamedTuple of arrays, so
    the compiled kernels (:mod:`uamfleet.sim.motion`, :mod:`uamfleet.observe`) take it whole."""

    t: np.ndarray  # [E] int64, steps since reset
    pos_m: np.ndarray  # [E, A, 2] float64, taxi positions (world frame)
    free_seats: np.ndarray  # [E, A] int64
    history_m: np.ndarray  # [E, A, H, 2] float64, positions at steps t-1 ... t-H (index 0 = most recent)
    history_seats: np.ndarray  # [E, A, H] int64, free seats at those steps
    visits: np.ndarray  # [E, A, nbx + k, nby + k] int32, per-taxi block visit counts, padded by the patch size k
    distance_m: np.ndarray  # [E, A] float64, distance flown this episode
    action_mask: np.ndarray  # [E, A, NUM_HEADINGS] bool, moves allowed from the current positions
    pax_exists: np.ndarray  # [E, P] bool, False for padding rows
    pax_release: np.ndarray  # [E, P] int64, release step
    pax_origin_m: np.ndarray  # [E, P, 2] float64
    pax_dest_m: np.ndarray  # [E, P, 2] float64
    pax_status: np.ndarray  # [E, P] int8: HIDDEN / WAITING / ON_BOARD / DELIVERED
    pax_taxi: np.ndarray  # [E, P] int64, taxi carrying / that carried the passenger, -1 if none
    pax_pickup_step: np.ndarray  # [E, P] int64, -1 until picked up
    pax_dropoff_step: np.ndarray  # [E, P] int64, -1 until delivered
    # [E, 2P, 2P] float64, feasible-path distances between the instance's stops (row/column 2p: p's origin, 2p + 1:
    # her destination), looked up by the stop features on first use (NaN: not yet) and kept for the episode, as the
    # stops never move; [E, 0, 0] without stop features
    stop_pair_m: np.ndarray
    # [E, A] int64 and [E, A, 2P] float64: each taxi's shortest tour rests after each first stop (the stop features'
    # exact tours) and the key of the stops and seats they were computed for (-1: none); [E, A, 0] without them
    stop_tour_key: np.ndarray
    stop_tour_m: np.ndarray

    @property
    def num_envs(self) -> int:
        return int(self.pos_m.shape[0])

    @property
    def num_taxis(self) -> int:
        return int(self.pos_m.shape[1])

    def copy(self) -> FleetState:
        return FleetState(*(v.copy() for v in self))

    def take(self, envs: np.ndarray) -> FleetState:
        """A copy holding only the envs ``envs`` (an index array), in that order."""
        return FleetState(*(v[envs] for v in self))


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
    heading_flown: np.ndarray  # [E, A] int64, the heading flown (the shield may change it), -1: stayed in place
    shield_intervened: np.ndarray  # [E, A] bool, the shield replaced the move asked for or moved the taxi apart
    hovered: np.ndarray  # [E, A] bool, the taxi hovered: it took HOVER_ACTION, or the shield held its allowed move
