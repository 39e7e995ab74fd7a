"""Per-taxi observations, computed for all envs and taxis at once (the global state for centralised critics is
the simulator's: :func:`uamfleet.sim.core.global_state`).

Positions are relative to the observing taxi and divided by the map side, so they lie in [-1, 1]; SINR is in
dB relative to the threshold (>= 0 means flyable), clipped to [-30, 30]; visit ratios are the taxi's visits
of a block divided by the steps flown so far (the paper's "uncertainty map"). Every field, with shape, dtype and
unit: ``docs/rules.md`` ("Observation", "State"); feature names and indices: :mod:`uamfleet.types`.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces

from uamfleet.config import ConfigError
from uamfleet.observe import basic, window
from uamfleet.observe.lookahead import LookaheadComponent
from uamfleet.observe.legacy import check_observable, split_env_config
from uamfleet.observe.stops import StopsComponent
from uamfleet.observe.spec import PASSENGER_AXIS_FIELDS, ObserverSpec, observation_space
from uamfleet.paths import table_for
from uamfleet.sim.pretyped import PreTyped
from uamfleet.sim.world import World
from uamfleet.types import HISTORY_FEATURES, OTHER_FEATURES, PASSENGER_FEATURES, SELF_FEATURES, FleetState

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
    """Builds the observation dict ``{name: [E, A, ...] array}`` of what ``spec`` reads of ``world``; its fields,
    shapes and dtypes are :meth:`ObserverSpec.layout`'s (``self.layout``). ``spec=None``: the split of the world's
    config (:func:`uamfleet.observe.legacy.split_env_config`). With a passenger window (``spec.passenger_window``)
    every field is computed for every passenger of the state (``self.computed``), then each taxi's window of the
    passenger-axis fields is taken (:mod:`uamfleet.observe.window`); without one, a spec that reads more passenger
    rows than the world has gets them padded (masked and zero). The time features divide by
    ``spec.time_scale_steps`` (None: the world's time limit)."""

    def __init__(self, world: World, spec: ObserverSpec | None = None) -> None:
        cfg = world.cfg
        if spec is None:
            spec = split_env_config(cfg)[1]
        else:
            check_observable(cfg, spec)
            kept = (cfg.history_len, cfg.patch_size, cfg.stop_features or spec.stops is None)
            if kept != (spec.history_len, spec.patch_size, True):
                raise ConfigError(
                    f"the simulator keeps history_len={cfg.history_len}, patch_size={cfg.patch_size} and "
                    f"stop_features={cfg.stop_features}, which the observer {spec} cannot read; build the simulator "
                    "from uamfleet.observe.legacy.observed_config(world, spec)."
                )
        self.spec = spec
        self.world = world
        self.cfg = cfg
        self.num_taxis = cfg.num_taxis
        self.layout = self.spec.layout(cfg)
        self.computed = self.spec.computed_layout(cfg)  # the layout itself without a window
        self.window = self.spec.passenger_window
        self.depth = 0 if self.spec.lookahead is None else self.spec.lookahead.depth
        self.observation_space = observation_space(self.layout)
        # feasible-path distances for the stop features (cached per map and threshold; rows filled per new stop)
        self.table = table_for(world) if self.spec.stops is not None else None
        # the planner-derived fields, each prepared (table rows filled) before any kernel runs, then written
        self.components: list[StopsComponent | LookaheadComponent] = []
        if self.table is not None:
            self.components.append(StopsComponent(world, self.table, "stop_rivals" in self.layout))
            if self.depth:
                self.components.append(LookaheadComponent(world, self.table, self.depth))
        self._window = None
        if self.window is not None:
            self._window = window.WindowComponent(self.window, cfg.num_passengers, self.table)
        # without a window the spec may read more rows than the world has: those are padded, masked and zero, as
        # the rows of passengers a larger state holds but has not drawn
        self._padded = [
            name for name in PASSENGER_AXIS_FIELDS
            if name in self.layout and self.layout[name].shape[0] > self.computed[name].shape[0]
        ]  # fmt: skip
        # the always-on fields read the time limit from the world's arrays: the spec's scale replaces it there
        scale = self.spec.time_scale_steps
        arrays = world.arrays
        if scale is not None and scale != arrays.time_limit_steps:
            arrays = arrays._replace(time_limit_steps=float(scale))
        self._basic_arrays = arrays
        # the kernels without numba typing the state and the world's arrays on every call (uamfleet.sim.pretyped)
        self._observe, self._hover = PreTyped(basic.observe), PreTyped(basic.hover_headings)

    def observe(self, state: FleetState) -> dict[str, np.ndarray]:
        """The observation of every taxi: ``{name: [E, A, ...]}`` (fresh arrays, safe to keep)."""
        E, A = state.num_envs, state.num_taxis
        for component in self.components:
            component.prepare(state)
        obs = {name: np.empty((E, A, *spec.shape), spec.dtype) for name, spec in self.computed.items()}
        self._observe(
            state, self._basic_arrays, obs["self"], obs["history"], obs["passengers"], obs["passenger_mask"],
            obs["sinr_patch"], obs["visit_patch"], obs["others"], obs["others_mask"], obs["action_mask"],
        )  # fmt: skip
        if "hover_heading_mask" in obs:
            self._hover(state, self.world.arrays, obs["hover_heading_mask"])
        for component in self.components:
            component.write(state, obs)
        if self._window is None:
            return self._pad(obs) if self._padded else obs
        rows = self._window.rows(state)
        picked = window.take_rows(obs, rows, [name for name in PASSENGER_AXIS_FIELDS if name in obs])
        return {name: picked.get(name, obs[name]) for name in self.layout}

    def _pad(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """``obs`` with the passenger-axis fields grown to the rows the spec reads (the rows past the world's zero)."""
        for name in self._padded:
            value = obs[name]
            grown = np.zeros((*value.shape[:2], *self.layout[name].shape), value.dtype)
            grown[:, :, : value.shape[2]] = value
            obs[name] = grown
        return obs

    def window_rows(self, state: FleetState) -> np.ndarray:
        """[E, A, K] int64: the state's passenger row in each slot of each taxi's window, -1 for an empty slot
        (:mod:`uamfleet.observe.window`; needs ``passenger_window``)."""
        assert self._window is not None
        for component in self.components:
            component.prepare(state)
        return self._window.rows(state)


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
