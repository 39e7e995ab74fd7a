"""3GPP TR 36.777 Annex B UMi-AV channel for aerial UEs, and the expected SINR map of paper Eq. 4/6.

Model (TR 36.777 Tables B-1, B-2; aerial UE 22.5 m < h <= 300 m; f_c in GHz, distances in m):

- LoS:  PL = max(PL_fs, 30.9 + (22.25 - 0.5 log10 h) log10 d3D + 20 log10 f_c)
- NLoS: PL = max(PL_LoS, 32.4 + (43.2 - 7.6 log10 h) log10 d3D + 20 log10 f_c)
- P_LoS = 1 if d2D <= d1 else d1/d2D + exp(-d2D/p1) (1 - d1/d2D),
  p1 = 233.98 log10 h - 0.95, d1 = max(294.05 log10 h - 432.94, 18)
- shadowing sigma: LoS max(5 exp(-0.01 h), 2) dB, NLoS 8 dB

The path loss uses the 3-D distance ``d3D = sqrt(d2D^2 + (h - h_BS)^2)``, as the TR does, and P_LoS the 2-D
distance. The check values P_LoS = 0.771 / 0.547 / 0.254 at d2D = 300 / 500 / 1000 m and PL_LoS / PL_NLoS =
94.4 / 114.2 dB at 500 m, 100.7 / 122.5 dB at 1 km (h = 100 m, f_c = 2 GHz) imply exactly that with a height
difference of 81 ... 99 m, e.g. h_BS = 10 m, the UMi default: from d2D, PL_NLoS would be 114.0 / 122.4 dB
instead of 114.2 / 122.5 dB, and with h_BS = 20 m PL_NLoS(500 m) = 114.15 dB. The formulas are also used beyond
d2D = 4 km (the TR's range) for city-sized maps; the values there are an extrapolation.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from typing import Any

import numpy as np

from uamfleet.radio.radio_map import BaseStation, RadioMap, base_station_tuple, check_map_size

THERMAL_NOISE_DBM_PER_HZ = -174.0  # kT at 290 K
DEFAULT_BANDWIDTH_MHZ = 10.0
DEFAULT_NOISE_FIGURE_DB = 9.0  # a typical UE noise figure (TR 36.777 evaluation assumptions)
SHADOWING_SIGMA_NLOS_DB = 8.0  # TR 36.777 Table B-2, UMi-AV NLoS
MIN_AERIAL_HEIGHT_M = 22.5  # TR 36.777 Table B-1/B-2: UMi-AV applies for 22.5 m < h <= 300 m
MAX_AERIAL_HEIGHT_M = 300.0
_CHUNK_POINTS = 1 << 17  # points per vectorised batch: keeps the per-station temporaries in cache-sized pieces


def _check_height(h_ut_m: float) -> float:
    h = float(h_ut_m)
    if not MIN_AERIAL_HEIGHT_M < h <= MAX_AERIAL_HEIGHT_M:
        raise ValueError(
            f"UAV height {h} m is outside the TR 36.777 UMi-AV range "
            f"({MIN_AERIAL_HEIGHT_M}, {MAX_AERIAL_HEIGHT_M}] m; choose an altitude in that range"
        )
    return h


def _check_carrier(carrier_ghz: float) -> float:
    fc = float(carrier_ghz)
    if not (math.isfinite(fc) and fc > 0):
        raise ValueError(f"carrier_ghz must be > 0 (e.g. 2.0), got {carrier_ghz!r}")
    return fc


def los_probability(d2d_m: Any, h_ut_m: float) -> np.ndarray:
    """P_LoS of TR 36.777 Table B-1 (UMi-AV, 22.5 m < h <= 300 m)."""
    h = _check_height(h_ut_m)
    d = np.asarray(d2d_m, dtype=np.float64)
    p1 = 233.98 * math.log10(h) - 0.95
    d1 = max(294.05 * math.log10(h) - 432.94, 18.0)
    with np.errstate(divide="ignore", invalid="ignore"):
        far = d1 / d + np.exp(-d / p1) * (1.0 - d1 / d)
    return np.where(d <= d1, 1.0, far)


def los_breakpoints_m(h_ut_m: float) -> tuple[float, float]:
    """``(p1, d1)`` of the P_LoS formula, in metres."""
    h = _check_height(h_ut_m)
    return 233.98 * math.log10(h) - 0.95, max(294.05 * math.log10(h) - 432.94, 18.0)


def _pathloss_from_log_db(log10_d3d: np.ndarray, h: float, fc: float) -> tuple[np.ndarray, np.ndarray]:
    """(PL_LoS, PL_NLoS) in dB from log10(d3D): one logarithm shared by the three formulas."""
    log_fc = 20.0 * math.log10(fc)
    free_space = 20.0 * log10_d3d + log_fc + 32.45  # 20 log10(4 pi d f / c), d in m, f in GHz
    los = np.maximum(free_space, 30.9 + (22.25 - 0.5 * math.log10(h)) * log10_d3d + log_fc)
    nlos = np.maximum(los, 32.4 + (43.2 - 7.6 * math.log10(h)) * log10_d3d + log_fc)
    return los, nlos


def pathloss_los_db(d3d_m: Any, h_ut_m: float, carrier_ghz: float) -> np.ndarray:
    """UMi-AV LoS path loss (TR 36.777 Table B-2): max(free space, 30.9 + ...)."""
    log_d = np.log10(np.asarray(d3d_m, dtype=np.float64))
    return _pathloss_from_log_db(log_d, _check_height(h_ut_m), _check_carrier(carrier_ghz))[0]


def pathloss_nlos_db(d3d_m: Any, h_ut_m: float, carrier_ghz: float) -> np.ndarray:
    """UMi-AV NLoS path loss (TR 36.777 Table B-2); never below the LoS loss."""
    log_d = np.log10(np.asarray(d3d_m, dtype=np.float64))
    return _pathloss_from_log_db(log_d, _check_height(h_ut_m), _check_carrier(carrier_ghz))[1]


def shadowing_sigma_db(h_ut_m: float, los: bool) -> float:
    """Log-normal shadowing standard deviation (TR 36.777 Table B-2, UMi-AV)."""
    h = _check_height(h_ut_m)
    return max(5.0 * math.exp(-0.01 * h), 2.0) if los else SHADOWING_SIGMA_NLOS_DB


def _lognormal_mean_factor(sigma_db: float) -> float:
    # E[10^(X/10)] for X ~ N(0, sigma^2) in dB.
    return math.exp((sigma_db * math.log(10.0) / 10.0) ** 2 / 2.0)


def expected_gain(
    d2d_m: Any,
    h_ut_m: float,
    h_bs_m: float,
    carrier_ghz: float = 2.0,
    *,
    include_shadowing_mean: bool = False,
) -> np.ndarray:
    """Expected large-scale power gain (linear) ``P_LoS g_LoS + (1 - P_LoS) g_NLoS`` with ``g = 10^(-PL/10)``.

    With ``include_shadowing_mean`` each state's gain is multiplied by the mean of its log-normal shadowing,
    ``exp((sigma ln10 / 10)^2 / 2)`` (LoS ~2 dB -> x1.11, NLoS 8 dB -> x5.5); by default shadowing is taken as
    zero-mean in dB and left out, i.e. the gain uses the median path loss.
    """
    h = _check_height(h_ut_m)
    d2d = np.asarray(d2d_m, dtype=np.float64)
    # log10(d3D) = 0.5 log10(d2D^2 + dh^2): saves the square root
    log_d3d = 0.5 * np.log10(d2d * d2d + (h - float(h_bs_m)) ** 2)
    pl_los, pl_nlos = _pathloss_from_log_db(log_d3d, h, _check_carrier(carrier_ghz))
    g_los = 10.0 ** (-pl_los / 10.0)
    g_nlos = 10.0 ** (-pl_nlos / 10.0)
    if include_shadowing_mean:
        g_los = g_los * _lognormal_mean_factor(shadowing_sigma_db(h, los=True))
        g_nlos = g_nlos * _lognormal_mean_factor(shadowing_sigma_db(h, los=False))
    p_los = los_probability(d2d, h)
    return p_los * g_los + (1.0 - p_los) * g_nlos


def noise_power_dbm(
    bandwidth_mhz: float = DEFAULT_BANDWIDTH_MHZ, noise_figure_db: float = DEFAULT_NOISE_FIGURE_DB
) -> float:
    """Thermal noise -174 dBm/Hz + 10 log10(bandwidth) + noise figure (10 MHz, 9 dB -> -95.0 dBm)."""
    if not bandwidth_mhz > 0:
        raise ValueError(f"bandwidth_mhz must be > 0, got {bandwidth_mhz!r}")
    return THERMAL_NOISE_DBM_PER_HZ + 10.0 * math.log10(bandwidth_mhz * 1e6) + float(noise_figure_db)


def _check_stations(base_stations: Sequence[BaseStation], altitude_m: float) -> tuple[BaseStation, ...]:
    stations = base_station_tuple(base_stations)
    for bs in stations:
        if bs.height_m >= altitude_m:
            raise ValueError(
                f"base station {bs.name or (bs.x_m, bs.y_m)} is {bs.height_m} m tall, not below the UAV "
                f"altitude {altitude_m} m; the UMi-AV model is for aerial UEs above the GBS"
            )
    return stations


def expected_sinr_db(
    points: Any,
    base_stations: Sequence[BaseStation],
    *,
    altitude_m: float = 100.0,
    carrier_ghz: float = 2.0,
    noise_dbm: float | None = None,
    bandwidth_mhz: float = DEFAULT_BANDWIDTH_MHZ,
    noise_figure_db: float = DEFAULT_NOISE_FIGURE_DB,
    include_shadowing_mean: bool = False,
) -> np.ndarray:
    """Expected SINR [...] in dB at world points ``[..., 2]`` at ``altitude_m`` (paper Eq. 4/6).

    ``max_m P_m g_m / (sum_{m' != m} l_m' P_m' g_m' + sigma^2)`` with ``g`` from :func:`expected_gain`, each
    station's ``power_dbm`` and ``loading`` l, and noise ``noise_dbm`` (default: thermal noise over
    ``bandwidth_mhz`` plus ``noise_figure_db``). All stations share the carrier ``carrier_ghz`` (co-channel
    interference); ``BaseStation.frequency_mhz`` is not used.
    """
    h = _check_height(altitude_m)
    stations = _check_stations(base_stations, h)
    pts = np.asarray(points, dtype=np.float64)
    if pts.ndim == 0 or pts.shape[-1] != 2:
        raise ValueError(f"points must have shape [..., 2] (x_m, y_m), got shape {pts.shape}")
    noise_mw = 10.0 ** ((noise_power_dbm(bandwidth_mhz, noise_figure_db) if noise_dbm is None else noise_dbm) / 10)
    flat = pts.reshape(-1, 2)
    out = np.empty(flat.shape[0])
    for start in range(0, flat.shape[0], _CHUNK_POINTS):
        chunk = flat[start : start + _CHUNK_POINTS]
        signal_mw = np.stack(
            [
                10.0 ** (bs.power_dbm / 10.0)
                * expected_gain(
                    np.hypot(chunk[:, 0] - bs.x_m, chunk[:, 1] - bs.y_m),
                    h,
                    bs.height_m,
                    carrier_ghz,
                    include_shadowing_mean=include_shadowing_mean,
                )
                for bs in stations
            ]
        )  # [M, chunk]
        loading = np.array([bs.loading for bs in stations])[:, None]  # [M, 1]
        interference_mw = (loading * signal_mw).sum(axis=0)  # [chunk], all stations
        # Remove the serving station's own term; the round-off (~1e-16 of the total) is far below the noise.
        others_mw = np.maximum(interference_mw[None, :] - loading * signal_mw, 0.0)
        out[start : start + chunk.shape[0]] = (signal_mw / (others_mw + noise_mw)).max(axis=0)
    return (10.0 * np.log10(out)).reshape(pts.shape[:-1])


def expected_sinr_map_3gpp(
    base_stations: Sequence[BaseStation],
    *,
    side_m: float,
    resolution_m: float,
    altitude_m: float = 100.0,
    carrier_ghz: float = 2.0,
    noise_dbm: float | None = None,
    name: str = "3gpp",
    bandwidth_mhz: float = DEFAULT_BANDWIDTH_MHZ,
    noise_figure_db: float = DEFAULT_NOISE_FIGURE_DB,
    include_shadowing_mean: bool = False,
    source: str = "",
) -> RadioMap:
    """Expected-SINR :class:`RadioMap` over ``[0, side_m]^2`` (see :func:`expected_sinr_db`).

    Cell centres lie at ``0, resolution_m, ...`` up to the first multiple ``>= side_m`` on each axis, so the
    raster covers the whole operating square.
    """
    stations = tuple(base_stations)
    side_m, resolution_m = float(side_m), float(resolution_m)
    if not (math.isfinite(side_m) and side_m > 0 and math.isfinite(resolution_m) and resolution_m > 0):
        raise ValueError(f"side_m and resolution_m must be > 0, got side_m={side_m}, resolution_m={resolution_m}")
    n = math.ceil(side_m / resolution_m - 1e-9) + 1
    check_map_size(f"radio map {name!r}", (n, n), resolution_m, side_m, (0.0, 0.0))  # before the n x n grid
    axis = np.arange(n) * resolution_m
    xx, yy = np.meshgrid(axis, axis, indexing="ij")  # [ix, iy]
    sinr = expected_sinr_db(
        np.stack([xx, yy], axis=-1),
        stations,
        altitude_m=altitude_m,
        carrier_ghz=carrier_ghz,
        noise_dbm=noise_dbm,
        bandwidth_mhz=bandwidth_mhz,
        noise_figure_db=noise_figure_db,
        include_shadowing_mean=include_shadowing_mean,
    )
    return RadioMap(
        sinr_db=sinr,
        resolution_m=resolution_m,
        side_m=side_m,
        name=name,
        altitude_m=altitude_m,
        base_stations=stations,
        source=source or f"synthetic: 3GPP TR 36.777 UMi-AV expected SINR, {len(stations)} GBS",
    )
