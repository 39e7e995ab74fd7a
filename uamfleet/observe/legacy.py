"""The legacy constructor split in two, and joined again: an :class:`~uamfleet.config.EnvConfig` (a world and the
observer fields in one config) as its :class:`~uamfleet.config.WorldConfig` and
:class:`~uamfleet.observe.spec.ObserverSpec`, and the config a simulator is built from for a world and a spec."""

from __future__ import annotations

import dataclasses

from uamfleet.config import ConfigError, EnvConfig, WorldConfig
from uamfleet.observe.spec import LookaheadSpec, ObserverSpec, StopsSpec


def split_env_config(cfg: EnvConfig) -> tuple[WorldConfig, ObserverSpec]:
    """The world of ``cfg`` and the spec of what it observes, so that ``spec.layout(world)`` is
    ``observation_layout(cfg)`` field for field.

    Without a passenger window the spec pins the rows and the time scale ``cfg`` observes: ``slots_per_taxi`` is
    ``cfg.num_passengers / cfg.num_taxis`` and ``time_scale_steps`` is ``cfg.time_limit_steps`` (a policy trained
    on it then reads that many rows, and its time feature keeps its scale, in a world of another size). ``hover``
    follows the world's action set (``cfg.hover_action``); ``fleet_rows`` is None (the others are a set)."""
    windowed = cfg.passenger_window is not None
    stops = StopsSpec(rivals=cfg.stop_rivals, claims=cfg.stop_claims) if cfg.stop_features else None
    lookahead = LookaheadSpec(depth=cfg.lookahead_depth) if cfg.stop_features and cfg.heading_lookahead else None
    spec = ObserverSpec(
        history_len=cfg.history_len,
        patch_size=cfg.patch_size,
        passenger_window=cfg.passenger_window,
        slots_per_taxi=None if windowed else cfg.num_passengers / cfg.num_taxis,
        time_scale_steps=None if windowed else cfg.time_limit_steps,
        stops=stops,
        lookahead=lookahead,
        hover=cfg.hover_action,
    )
    return cfg.world, spec


def check_observable(world: WorldConfig, spec: ObserverSpec) -> None:
    """:class:`ConfigError` with :meth:`ObserverSpec.reads`'s line when ``spec`` cannot read ``world``. A spec that
    reads more passenger rows than the world has is observable: the observer pads them (masked, zero)."""
    refusal = spec.reads(world)
    if refusal is not None:
        raise ConfigError(refusal + ".")


def observed_config(cfg: WorldConfig, observer: ObserverSpec | None = None) -> tuple[EnvConfig, ObserverSpec]:
    """The config a face builds its simulator from, and the spec its observer reads, for ``cfg`` observed by
    ``observer``.

    ``observer=None``: an :class:`EnvConfig` is kept as it is and observed by its own split; a bare
    :class:`WorldConfig` is observed by ``ObserverSpec()``. A spec given is checked against the world
    (:meth:`ObserverSpec.reads`; :class:`ConfigError` with its line) and the world is joined with it: the
    simulator keeps the history, the patch margin and the tour caches the observer reads (``history_len``,
    ``patch_size``, the stop fields). A spec without a window that reads more passenger rows than the world has
    is padded by the observer (the world is not resized)."""
    if observer is None:
        if isinstance(cfg, EnvConfig):
            return cfg, split_env_config(cfg)[1]
        observer = ObserverSpec()
    if not isinstance(observer, ObserverSpec):
        raise ConfigError(f"observer={observer!r} must be an ObserverSpec or None (the config's own observer).")
    world = cfg.world if isinstance(cfg, EnvConfig) else cfg
    check_observable(world, observer)
    stops, lookahead = observer.stops, observer.lookahead
    joined = EnvConfig(
        **{f.name: getattr(world, f.name) for f in dataclasses.fields(WorldConfig)},
        passenger_window=observer.passenger_window,
        history_len=observer.history_len,
        patch_size=observer.patch_size,
        stop_features=stops is not None,
        stop_rivals=stops is not None and stops.rivals,
        stop_claims=stops is not None and stops.claims,
        heading_lookahead=lookahead is not None,
        lookahead_depth=1 if lookahead is None else lookahead.depth,
    )
    return joined, observer


__all__ = ["check_observable", "observed_config", "split_env_config"]
