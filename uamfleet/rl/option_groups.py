"""Options in groups: a dataclass whose fields are option groups (each a frozen dataclass), its flags flat on the
command line (:data:`Flat`) and stored flat in checkpoints (:func:`flat_options`, :func:`grouped_from_flat`).
The training options (:class:`uamfleet.rl.options.TrainArgs`) and the imitation options are built this way."""

from __future__ import annotations

import dataclasses
from collections.abc import Mapping
from typing import Any, TypeVar

import tyro

from uamfleet.config import ConfigError

G = TypeVar("G")

Flat = tyro.conf.OmitArgPrefixes
"""A group's flags keep their own names (``--learning-rate``, not ``--ppo.learning-rate``); ``--help`` shows the
group as a section."""


def flat_options(grouped: Any) -> dict[str, Any]:
    """Every option of a dataclass of option groups (each a dataclass), by name, in the groups' order."""
    return {
        f.name: getattr(group, f.name)
        for group in (getattr(grouped, g.name) for g in dataclasses.fields(grouped))
        for f in dataclasses.fields(group)
    }


def option_groups(cls: type) -> dict[str, type]:
    """The group classes of a dataclass of option groups, by attribute (each group's default factory)."""
    return {g.name: g.default_factory for g in dataclasses.fields(cls)}  # type: ignore[misc]


def grouped_from_flat(cls: type[G], flat: Mapping[str, Any]) -> G:
    """A dataclass of option groups built from the flat dict ``flat`` (option name -> value; options it lacks take
    their defaults); ConfigError naming any key that is no option of ``cls``."""
    groups = option_groups(cls)
    group_of = {f.name: name for name, group in groups.items() for f in dataclasses.fields(group)}
    unknown = sorted(set(flat) - set(group_of))
    if unknown:
        raise ConfigError(f"{unknown} are no options of {cls.__name__}; give only its options (e.g. seed), by name.")
    grouped: dict[str, dict[str, Any]] = {name: {} for name in groups}
    for name, value in flat.items():
        grouped[group_of[name]][name] = value
    return cls(**{name: groups[name](**values) for name, values in grouped.items()})
