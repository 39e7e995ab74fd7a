"""The checks every config uses: :class:`ConfigError` and ``check_number`` / ``check_integer`` / ``check_flag`` /
``check_point`` / ``check_sequence`` (a bad value fails with a message naming the field, the value and the fix),
and the upper bounds of the sizes. The base of :mod:`uamfleet.config` and :mod:`uamfleet.demand`, importing nothing
of the package.
"""

from __future__ import annotations

import math
import os
from collections.abc import Sequence
from typing import Any

import numpy as np

# Upper bounds of the sizes that set the memory of every observation (documented on EnvConfig): a 3,000 x 3,000
# patch would be 72 MB per taxi and step, so a typo there fails at once instead of exhausting memory later.
MAX_PATCH_SIZE = 64
MAX_HISTORY_LEN = 256
MAX_TAXIS = 1024
MAX_PASSENGERS = 1024
MAX_COUNT = 2**31 - 1
"""Upper bound of every other count (steps, seats, visits): it must fit the simulator's integer arrays."""
MAX_TIME_LIMIT_STEPS = 2**24 - 1
"""Upper bound of an episode's steps: step counts must stay exact in float32 (the observation's visit ratios)."""
MAX_ENVS = 65_536
"""Upper bound of ``num_envs`` of the batched core (:class:`uamfleet.VectorEnv`): its state and observations are
allocated up front, about 10 KB per env of one taxi on ``berlin_p4`` and 60 KB per env of a 4-taxi ``berlin_fleet``
(4 GB at this bound), so a typo such as ``num_envs=10**12`` fails at once instead of exhausting memory."""
MAX_SEED = 2**63 - 1
"""Largest seed of an instance or a reset (NumPy's SeedSequence takes any non-negative integer; this keeps seeds
plain int64)."""


class ConfigError(ValueError):
    """A config value of the wrong type or out of range; the message names the field, the value and the fix.

    A ``ValueError`` (also for values of the wrong type, e.g. ``sinr_min_db='-3'``), so one ``except
    ValueError`` catches every bad input of the package: this, :class:`~uamfleet.sim.generator.
    InfeasibleInstanceError`, :class:`~uamfleet.sim.dynamics.InvalidActionError` and
    :class:`~uamfleet.radio.WinPropFormatError`.
    """


def is_number(value: Any) -> bool:
    """A real number: an int or float of Python or NumPy, not a bool, not a string."""
    # bool is an int to Python, but True is no step count or distance; strings are not parsed on the user's behalf.
    return isinstance(value, (int, float, np.integer, np.floating)) and not isinstance(value, (bool, np.bool_))


def _not_a_number(name: str, value: Any, kind: str, integer: bool = False) -> ConfigError:
    hint = ""
    if isinstance(value, str):
        try:
            number = float(value)
            hint = f", e.g. {name.split(' ')[0]}={int(number) if integer and number.is_integer() else number!r}"
        except ValueError:
            pass
    return ConfigError(f"{name}={value!r} is a {type(value).__name__}, not a number; pass {kind}{hint}.")


def check_number(name: str, value: Any, *, minimum: float | None = None, positive: bool = False) -> float:
    """``value`` as a finite float; :class:`ConfigError` naming ``name`` if it is not a finite real number
    (NaN, inf, a string, a bool) or is below ``minimum`` / not positive."""
    if not is_number(value):
        raise _not_a_number(name, value, "an int or float")
    if not math.isfinite(value):
        raise ConfigError(f"{name}={value!r} must be a finite number.")
    if positive and not value > 0:
        raise ConfigError(f"{name}={value!r} must be a positive number.")
    if minimum is not None and value < minimum:
        raise ConfigError(f"{name}={value!r} must be >= {minimum:g}.")
    return float(value)


def check_integer(name: str, value: Any, minimum: int, maximum: int | None = None, fix: str = "") -> int:
    """``value`` as an int in ``[minimum, maximum]`` (default maximum :data:`MAX_COUNT`); :class:`ConfigError`
    naming ``name`` otherwise. A float with an integral value (``500.0``) is accepted; ``1.5``, NaN, strings and
    bools are not (never truncated)."""
    bound = f"in [{minimum}, {maximum}]" if maximum is not None else f">= {minimum}"
    maximum = MAX_COUNT if maximum is None else maximum
    if not is_number(value):
        raise _not_a_number(name, value, f"an integer {bound}", integer=True)
    if not math.isfinite(value) or int(value) != value:
        raise ConfigError(f"{name}={value!r} must be a whole number {bound}{fix}; it is never rounded.")
    if value < minimum:
        raise ConfigError(f"{name}={value!r} must be an integer {bound}{fix}.")
    if value > maximum:
        raise ConfigError(f"{name}={value!r} is too large: at most {maximum}{fix}.")
    return int(value)


def check_flag(name: str, value: Any) -> bool:
    """``value`` as a bool; :class:`ConfigError` naming ``name`` for anything but ``True`` / ``False`` (also NumPy's):
    a string such as ``'no'`` is truthy, so taking it as a flag would silently mean the opposite."""
    if not isinstance(value, (bool, np.bool_)):
        raise ConfigError(f"{name}={value!r} must be True or False.")
    return bool(value)


def check_point(name: str, value: Any) -> tuple[float, float]:
    """``value`` as a finite ``(x, y)`` pair of floats in metres; :class:`ConfigError` naming ``name`` otherwise
    (three coordinates, a string, NaN, ...)."""
    try:
        n = len(value)
    except TypeError:
        n = -1
    if isinstance(value, str) or n != 2 or not all(is_number(v) and math.isfinite(v) for v in value):
        raise ConfigError(
            f"{name}={value!r} must be a finite (x, y) pair of numbers in metres (world frame); "
            "the altitude is EnvConfig.altitude_m, not a third coordinate."
        )
    return (float(value[0]), float(value[1]))


def check_sequence(name: str, value: Any) -> Any:
    """``value`` if it is a sequence (tuple, list or array; not a string); :class:`ConfigError` otherwise."""
    if isinstance(value, (str, bytes)) or not isinstance(value, (Sequence, np.ndarray)):
        raise ConfigError(f"{name}={value!r} must be a sequence (tuple or list), not {type(value).__name__}.")
    return value


# -- Size limits of what the package reads (docs/inputs.md) --------------------------------------------------------
# A file declares its size before anything is allocated for it; past a limit the reader refuses with the size it
# would need and the environment variable that raises the limit. The defaults are generous for a city (a 4,000 x
# 4,000 raster is 40 km at 10 m cells) and far below what a 24 GB machine would die of.

SIZE_LIMITS: dict[str, tuple[int, str]] = {
    "map_cells": (16_000_000, "cells of a radio map's raster (or of a ray-traced map's measurement plane)"),
    "scene_bytes": (512 * 2**20, "bytes of a scene's XML plus every mesh file it names"),
    "scene_shapes": (100_000, "shapes (plus included files) of one scene"),
    "scene_extent_m": (50_000, "side of a scene's or a map's area, in metres"),
}
"""``name: (default, what it bounds)``; each is overridden by the environment variable ``UAMFLEET_MAX_<NAME>``."""


def size_limit(name: str) -> int:
    """The limit ``name`` of :data:`SIZE_LIMITS`, or the positive integer in ``UAMFLEET_MAX_<NAME>`` when set."""
    default, _ = SIZE_LIMITS[name]
    variable = f"UAMFLEET_MAX_{name.upper()}"
    raw = os.environ.get(variable)
    if raw is None or raw == "":
        return default
    try:
        value = int(raw)
    except ValueError:
        value = 0
    if value < 1:
        raise ConfigError(f"{variable}={raw!r} must be a positive integer (the limit on {SIZE_LIMITS[name][1]}).")
    return value


def check_size(name: str, needed: float, what: str, unit_bytes: float = 0.0) -> None:
    """Refuse ``needed`` (a count of :data:`SIZE_LIMITS` ``name``) for ``what`` when it is over the limit: the message
    names the size, the memory it would need when ``unit_bytes`` (bytes per unit) is given, and how to raise the
    limit."""
    limit = size_limit(name)
    if not math.isfinite(needed) or needed > limit:
        memory = f" ({needed * unit_bytes / 2**30:.1f} GiB)" if unit_bytes and math.isfinite(needed) else ""
        raise ConfigError(
            f"{what} needs {needed:,.0f} {SIZE_LIMITS[name][1]}{memory}, over the limit of {limit:,}; "
            f"if it is meant, raise it with UAMFLEET_MAX_{name.upper()}=<n>."
        )
