"""Berlin's instance rules scaled to any radio map: the steps, the thresholds and the names of a map's family.

:mod:`uamfleet.instances` draws the instances of any map (a packaged map's name or a map file) with Berlin's rules;
this module holds what those rules read from the map alone: its steps (:func:`map_step_m`), its thresholds
(:func:`map_thresholds`: Berlin's where they bind on the map, else the map's own quantiles at Berlin's shares of
flyable blocks), its family's name (:func:`map_family_name`) and the one-line provenance printed with every table
flown on it (:func:`map_provenance`).
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from uamfleet.config import ConfigError
from uamfleet.presets import make_config
from uamfleet.radio import RadioMap, load_radio_map
from uamfleet.radio.packaged import RADIO_MAPS

BERLIN_THRESHOLDS_DB = (-7.0, -6.0, -5.0, -4.0, -3.0)
"""Berlin's thresholds (dB), the ``berlin`` family's and any map's where they bind on it."""
BERLIN_STEP_M = 100.0
"""Berlin's steps (and SINR blocks), of 3 s."""
BERLIN_SIDE_M = 3260.0
"""The side of the Berlin map's operating square, the extent Berlin's rules are scaled from."""
BERLIN_FEASIBLE_SHARES = (0.9568, 0.9421, 0.9063, 0.8650, 0.8118)
"""The share of the Berlin map's 100 m blocks flyable at each of :data:`BERLIN_THRESHOLDS_DB` (-7 ... -3 dB):
the shares a map's own thresholds reproduce when Berlin's do not bind on it (:func:`map_thresholds`)."""
MIN_FEASIBLE_SHARE = 0.10
"""Berlin's thresholds are kept on a map only if at least this share of its blocks is flyable at -7 dB ..."""
MIN_INFEASIBLE_SHARE = 0.01
"""... and at least this share is not flyable at -3 dB (else the radio would not bind there)."""

MAP_SUFFIXES = (".npz", ".txt")
"""The map files a family is derived from by path: a ``.npz`` of ``uamfleet-radio-map``, a WinProp ASCII ``.txt``."""


def scaled_steps(scenario: str, step_m: float | None) -> dict[str, float]:
    """``step_m`` and ``slot_s`` overrides of ``scenario``'s preset for steps of ``step_m`` at its speed (none: {})."""
    if step_m is None:
        return {}
    base = make_config(scenario)
    return {"step_m": step_m, "slot_s": base.slot_s * step_m / base.step_m}


def map_step_m(radio: RadioMap) -> float | None:
    """The steps of a map's family: Berlin's 100 m, or one raster cell where the map's cells are coarser (blocks
    hold at least one raster value); None: Berlin's."""
    return float(radio.resolution_m) if radio.resolution_m > BERLIN_STEP_M else None


def map_thresholds(radio: RadioMap) -> tuple[float, ...]:
    """The thresholds of a map's family: Berlin's (-7 ... -3 dB) where they bind on the map (at -7 dB at least
    :data:`MIN_FEASIBLE_SHARE` of its 100 m blocks flyable, at -3 dB at least :data:`MIN_INFEASIBLE_SHARE` not);
    else the map's own quantiles: the five thresholds (rounded down to 0.1 dB) at which the map has Berlin's
    shares of flyable blocks at -7 ... -3 dB (:data:`BERLIN_FEASIBLE_SHARES`), so that the radio binds on it as
    much as on Berlin. Blocks with no value (N.C.) are never flyable."""
    base = make_config("berlin_random", radio=radio, **scaled_steps("berlin_random", map_step_m(radio)))
    sinr = np.asarray(radio.block_map(base.block_size_m, nc_rule=base.nc_rule).sinr_db, float).ravel()
    sinr = np.where(np.isnan(sinr), -np.inf, sinr)
    loosest, strictest = BERLIN_THRESHOLDS_DB[0], BERLIN_THRESHOLDS_DB[-1]
    if np.mean(sinr >= loosest) >= MIN_FEASIBLE_SHARE and np.mean(sinr < strictest) >= MIN_INFEASIBLE_SHARE:
        return BERLIN_THRESHOLDS_DB
    # the share flyable at t is mean(sinr >= t): t = the (1 - share) quantile, rounded down keeps at least the share
    quantiles = np.quantile(sinr, [1.0 - share for share in BERLIN_FEASIBLE_SHARES], method="lower")
    if not np.all(np.isfinite(quantiles)):
        raise ConfigError(
            f"radio map {radio.label!r} has a value in fewer than {BERLIN_FEASIBLE_SHARES[0]:.0%} of its "
            f"{base.block_size_m:g} m blocks: too few to draw instances on; give a map with values over its square."
        )
    return tuple(float(np.floor(q * 10.0 + 1e-9) / 10.0) for q in quantiles)  # 1e-9: 1.3 * 10 may be 12.999...


def map_family_name(name_or_path: str | os.PathLike[str]) -> str:
    """The name of a map's family: a packaged map's name, or a file's stem (``maps/paris.npz`` -> ``paris``)."""
    if isinstance(name_or_path, str) and name_or_path in RADIO_MAPS:
        return name_or_path
    return Path(name_or_path).stem


def map_provenance(name_or_path: str | os.PathLike[str] | RadioMap) -> str:
    """One line on a map a table was flown on: where it comes from (a packaged name or a file's path), its raster
    (cells and cell size), its operating square and base stations, and the map's own recorded source and
    provenance (e.g. a ray-traced ``.npz``'s scene, parameters and versions)."""
    radio = load_radio_map(name_or_path)
    if isinstance(name_or_path, RadioMap):
        where = f"map {radio.label!r}"
    elif isinstance(name_or_path, str) and name_or_path in RADIO_MAPS:
        where = f"packaged map {name_or_path!r}"
    else:
        where = f"map file {os.fspath(name_or_path)}"
    nx, ny = radio.sinr_db.shape
    line = (
        f"{where}: {nx} x {ny} cells of {radio.resolution_m:g} m, operating square {radio.side_m:g} m, "
        f"{len(radio.base_stations)} base station(s), altitude {radio.altitude_m:g} m"
    )
    source = " ".join(str(radio.source).split())
    return line + (f"; source: {source}" if source else "")


__all__ = [
    "BERLIN_FEASIBLE_SHARES",
    "BERLIN_SIDE_M",
    "BERLIN_STEP_M",
    "BERLIN_THRESHOLDS_DB",
    "MAP_SUFFIXES",
    "MIN_FEASIBLE_SHARE",
    "MIN_INFEASIBLE_SHARE",
    "map_family_name",
    "map_provenance",
    "map_step_m",
    "map_thresholds",
    "scaled_steps",
]
