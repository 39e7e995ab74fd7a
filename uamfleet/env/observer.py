"""Per-taxi observations and the global state, computed for all envs and taxis at once.

Positions are relative to the observing taxi and divided by the map side, so they lie in [-1, 1]; SINR is in
dB relative to the threshold (>= 0 means flyable), clipped to [-30, 30]; visit ratios are the taxi's visits
of a block divided by the steps flown so far (the paper's "uncertainty map"). Every field, with shape, dtype and
unit: ``docs/rules.md`` ("Observation", "State"); feature names and indices: :mod:`uamfleet.types`.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from uamfleet.env import kernels
from uamfleet.env.world import PATCH_CLIP_DB, PATCH_PAD_DB, World
from uamfleet.paths import table_for
from uamfleet.types import (
    DELIVERED,
    HIDDEN,
    HISTORY_FEATURES,
    NUM_HEADINGS,
    ON_BOARD,
    OTHER_FEATURES,
    PASSENGER_FEATURES,
    SELF_FEATURES,
    STATE_PASSENGER_FEATURES,
    STATE_TAXI_FEATURES,
    STOP_CLAIM_FEATURES,
    STOP_PATH_FEATURES,
    STOP_RIVAL_FEATURES,
    WAITING,
    FleetState,
)

__all__ = [
    "HISTORY_FEATURES",
    "OTHER_FEATURES",
    "PASSENGER_FEATURES",
    "SELF_FEATURES",
    "ObservationShapeError",
    "Observer",
    "check_observation",
]


class Observer:
    """Builds the observation dict ``{name: [E, A, ...] array}`` and the global ``state`` [E, S]."""

    def __init__(self, world: World) -> None:
        cfg = world.cfg
        self.world = world
        self.cfg = cfg
        self.num_taxis = cfg.num_taxis
        self.num_others = max(cfg.num_taxis - 1, 1)  # keep one masked row for a single taxi (no 0-size spaces)
        self.observation_space = self._observation_space()
        taxi_size, pax_size = len(STATE_TAXI_FEATURES), len(STATE_PASSENGER_FEATURES)
        self.state_size = cfg.num_taxis * taxi_size + cfg.num_passengers * pax_size + 1  # + time
        self.state_space = spaces.Box(-np.inf, np.inf, (self.state_size,), np.float32)
        # feasible-path distances for the stop features (cached per map and threshold; rows filled per new stop)
        self.table = table_for(world) if cfg.stop_features else None

    def _observation_space(self) -> spaces.Dict:
        cfg = self.cfg
        k, P, H = cfg.patch_size, cfg.num_passengers, cfg.history_len
        f32 = np.float32
        stop_fields: dict[str, spaces.Space] = {}
        if cfg.stop_features:
            stop_fields = {
                "stop_paths": spaces.Box(0.0, kernels.STOP_PATH_CLIP, (P, len(STOP_PATH_FEATURES)), f32),
                "stop_heading_mask": spaces.Box(0, 1, (P, NUM_HEADINGS), np.int8),
            }
            if cfg.num_taxis > 1 or cfg.stop_claims:  # claims: also a fleet of one (one layout for every size)
                stop_fields["stop_rivals"] = spaces.Box(0.0, kernels.STOP_PATH_CLIP, (P, len(STOP_RIVAL_FEATURES)), f32)
                if cfg.stop_claims:
                    stop_fields["stop_claims"] = spaces.Box(0, 1, (P, len(STOP_CLAIM_FEATURES)), np.int8)
                    stop_fields["hover_heading_mask"] = spaces.Box(0, 1, (NUM_HEADINGS,), np.int8)
        return spaces.Dict(
            {
                **stop_fields,
                "self": spaces.Box(-1.0, 1.0, (len(SELF_FEATURES),), f32),
                "history": spaces.Box(-2.0, 2.0, (H, len(HISTORY_FEATURES)), f32),
                "passengers": spaces.Box(-2.0, 2.0, (P, len(PASSENGER_FEATURES)), f32),
                "passenger_mask": spaces.Box(0, 1, (P,), np.int8),
                "sinr_patch": spaces.Box(PATCH_PAD_DB, PATCH_CLIP_DB, (k, k), f32),
                "visit_patch": spaces.Box(0.0, 1.0, (k, k), f32),
                "others": spaces.Box(-2.0, 2.0, (self.num_others, len(OTHER_FEATURES)), f32),
                "others_mask": spaces.Box(0, 1, (self.num_others,), np.int8),
                "action_mask": spaces.Box(0, 1, (NUM_HEADINGS,), np.int8),
            }
        )

    def observe(self, state: FleetState) -> dict[str, np.ndarray]:
        """The observation of every taxi: ``{name: [E, A, ...]}`` (fresh arrays, safe to keep)."""
        cfg = self.cfg
        E, A = state.num_envs, state.num_taxis
        P, H, k, n_others = cfg.num_passengers, cfg.history_len, cfg.patch_size, self.num_others
        f32 = np.float32
        obs: dict[str, np.ndarray] = {
            "self": np.empty((E, A, len(SELF_FEATURES)), f32),
            "history": np.empty((E, A, H, len(HISTORY_FEATURES)), f32),
            "passengers": np.empty((E, A, P, len(PASSENGER_FEATURES)), f32),
            "passenger_mask": np.empty((E, A, P), np.int8),
            "sinr_patch": np.empty((E, A, k, k), f32),
            "visit_patch": np.empty((E, A, k, k), f32),
            "others": np.empty((E, A, n_others, len(OTHER_FEATURES)), f32),
            "others_mask": np.empty((E, A, n_others), np.int8),
            "action_mask": np.empty((E, A, NUM_HEADINGS), np.int8),
        }
        kernels.observe(
            state, self.world.arrays, obs["self"], obs["history"], obs["passengers"], obs["passenger_mask"],
            obs["sinr_patch"], obs["visit_patch"], obs["others"], obs["others_mask"], obs["action_mask"],
        )  # fmt: skip
        if self.table is not None:
            obs["stop_paths"] = np.empty((E, A, P, len(STOP_PATH_FEATURES)), f32)
            obs["stop_heading_mask"] = np.empty((E, A, P, NUM_HEADINGS), np.int8)
            table, (nbx, nby) = self.table, self.table.shape
            args = (state, self.world.arrays, table.distance_m, nbx, nby, obs["stop_paths"], obs["stop_heading_mask"])
            rivals = None
            if A > 1 or cfg.stop_claims:
                obs["stop_rivals"] = np.empty((E, A, P, len(STOP_RIVAL_FEATURES)), f32)
                claims_shape = (E, A, P, len(STOP_CLAIM_FEATURES)) if cfg.stop_claims else (0, 0, 0, 0)
                claims = np.zeros(claims_shape, np.int8)
                if cfg.stop_claims:
                    obs["stop_claims"] = claims
                    obs["hover_heading_mask"] = np.empty((E, A, NUM_HEADINGS), np.int8)
                    kernels.hover_headings(state, self.world.arrays, obs["hover_heading_mask"])
                rivals = (state, self.world.arrays, table.distance_m, nbx, nby, obs["stop_rivals"], claims)
            if not kernels.stop_features(*args) or (rivals is not None and not kernels.stop_rivals(*rivals)):
                # a stop whose table rows are not computed yet (a new instance): compute them, then again
                exists = state.pax_exists
                table.ensure(np.concatenate([state.pax_origin_m[exists], state.pax_dest_m[exists]]))
                kernels.stop_features(*args)
                if rivals is not None:
                    kernels.stop_rivals(*rivals)
        return obs

    def state(self, state: FleetState) -> np.ndarray:
        """[E, S] float32 global state for centralised critics: taxis (x, y, seats, time in episode) and the
        released passengers (origin, destination, status one-hot, carrier); unreleased rows are zero."""
        side, cfg = self.world.side_m, self.cfg
        E, A = state.num_envs, state.num_taxis
        taxis = np.concatenate(
            [state.pos_m / side, (state.free_seats / cfg.seats)[..., None], np.zeros((E, A, 1))], axis=-1
        )  # [E, A, STATE_TAXI_FEATURES]; last column: taxi index / A tells the taxis apart
        taxis[..., 3] = np.arange(A) / A
        status = state.pax_status
        visible = ((status != HIDDEN) & state.pax_exists)[..., None]
        pax = (
            np.concatenate(
                [
                    state.pax_origin_m / side,
                    state.pax_dest_m / side,
                    status[..., None] == np.array([WAITING, ON_BOARD, DELIVERED]),
                    ((state.pax_taxi + 1) / A)[..., None],
                    ((state.t[:, None] - state.pax_release) / cfg.time_limit_steps)[..., None],
                ],
                axis=-1,
            )
            * visible
        )  # [E, P, STATE_PASSENGER_FEATURES]
        time = np.minimum(state.t / cfg.time_limit_steps, 1.0)[:, None]
        return np.concatenate([taxis.reshape(E, -1), pax.reshape(E, -1), time], axis=-1).astype(np.float32)


class ObservationShapeError(ValueError):
    """An observation does not match the observation space of the env config it is used with."""


def check_observation(obs: dict[str, np.ndarray], space: spaces.Dict, batch_dims: int = 0) -> None:
    """Raise :class:`ObservationShapeError` naming the field, its shape and the expected one.

    ``batch_dims`` leading axes are allowed before each field's shape (2 for the core's ``[E, A, ...]``).
    Policies call this on their input so that an observation from another config (another number of
    passengers, patch size or fleet size) fails loudly instead of being silently broadcast.
    """
    if not isinstance(obs, dict):
        raise ObservationShapeError(f"observation must be a dict of arrays, got {type(obs).__name__}.")
    missing = sorted(set(space.spaces) - set(obs))
    if missing:
        raise ObservationShapeError(f"observation lacks field(s) {missing}; expected fields {sorted(space.spaces)}.")
    batch_shape: tuple[int, ...] | None = None
    for key, sub in space.spaces.items():
        value = np.asarray(obs[key])
        expected = tuple(sub.shape or ())
        shape = value.shape
        if len(shape) != batch_dims + len(expected) or shape[batch_dims:] != expected:
            raise ObservationShapeError(
                f"observation field {key!r} has shape {shape}, expected {('*',) * batch_dims + expected} "
                f"({batch_dims} batch axes); build observations with an env of the same config "
                "(num_passengers, patch_size, history_len, num_taxis)."
            )
        if batch_shape is None:
            batch_shape = shape[:batch_dims]
        elif shape[:batch_dims] != batch_shape:
            raise ObservationShapeError(
                f"observation field {key!r} has batch shape {shape[:batch_dims]}, other fields {batch_shape}."
            )
