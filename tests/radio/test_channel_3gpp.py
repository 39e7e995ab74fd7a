"""TR 36.777 UMi-AV: the check values of its Annex B at h = 100 m, f_c = 2 GHz, and the expected SINR of paper
Eq. 6 computed by hand."""

from __future__ import annotations

import math

import numpy as np
import pytest

from uamfleet.radio import BaseStation, expected_sinr_db, expected_sinr_map_3gpp
from uamfleet.radio.channel_3gpp import (
    expected_gain,
    los_breakpoints_m,
    los_probability,
    noise_power_dbm,
    pathloss_los_db,
    pathloss_nlos_db,
    shadowing_sigma_db,
)

H = 100.0
FC = 2.0


def test_los_breakpoints() -> None:
    p1, d1 = los_breakpoints_m(H)
    assert p1 == pytest.approx(467.0, abs=0.05)
    assert d1 == pytest.approx(155.2, abs=0.05)


def test_los_probability_check_values() -> None:
    np.testing.assert_allclose(los_probability([300.0, 500.0, 1000.0], H), [0.771, 0.547, 0.254], atol=5e-4)
    np.testing.assert_array_equal(los_probability([0.0, 100.0, 155.0], H), [1.0, 1.0, 1.0])
    assert los_probability(155.2, H) < 1.0


@pytest.mark.parametrize(("d2d", "los", "nlos"), [(500.0, 94.4, 114.2), (1000.0, 100.7, 122.5)])
def test_pathloss_check_values(d2d: float, los: float, nlos: float) -> None:
    # The SPEC's values are reproduced from the 3-D distance with a GBS 10 m high (UMi default) under the
    # UAV at 100 m; from the 2-D distance the NLoS values would be 114.0 / 122.4 dB.
    d3d = math.hypot(d2d, H - 10.0)
    assert float(pathloss_los_db(d3d, H, FC)) == pytest.approx(los, abs=0.05)
    assert float(pathloss_nlos_db(d3d, H, FC)) == pytest.approx(nlos, abs=0.05)
    assert float(pathloss_nlos_db(d2d, H, FC)) == pytest.approx(nlos, abs=0.25)
    assert round(float(pathloss_nlos_db(d2d, H, FC)), 1) != nlos


def test_pathloss_floors() -> None:
    # Very close in: free space is the binding LoS term (TR 36.777 Table B-2 max(...)).
    d = 1.0
    assert float(pathloss_los_db(d, H, FC)) == pytest.approx(20 * math.log10(FC) + 32.45)
    assert float(pathloss_nlos_db(d, H, FC)) >= float(pathloss_los_db(d, H, FC))


def test_shadowing_and_noise() -> None:
    assert shadowing_sigma_db(H, los=True) == 2.0  # max(5 e^-1 = 1.84, 2)
    assert shadowing_sigma_db(30.0, los=True) == pytest.approx(5 * math.exp(-0.3))
    assert shadowing_sigma_db(H, los=False) == 8.0
    assert noise_power_dbm() == pytest.approx(-95.0)  # -174 + 70 + 9
    assert noise_power_dbm(20.0, 7.0) == pytest.approx(-174 + 73.0103 + 7, abs=1e-4)


def test_shadowing_mean_factor() -> None:
    d2d = np.array([1000.0])
    plain = expected_gain(d2d, H, 20.0, FC)
    shadowed = expected_gain(d2d, H, 20.0, FC, include_shadowing_mean=True)
    p = los_probability(d2d, H)
    d3d = math.hypot(1000.0, 80.0)
    g_los = 10 ** (-pathloss_los_db(d3d, H, FC) / 10)
    g_nlos = 10 ** (-pathloss_nlos_db(d3d, H, FC) / 10)
    f_los = math.exp((2.0 * math.log(10) / 10) ** 2 / 2)
    f_nlos = math.exp((8.0 * math.log(10) / 10) ** 2 / 2)
    np.testing.assert_allclose(plain, p * g_los + (1 - p) * g_nlos, rtol=1e-12)
    np.testing.assert_allclose(shadowed, p * g_los * f_los + (1 - p) * g_nlos * f_nlos, rtol=1e-12)


def hand_gain(d2d: float, h_bs: float) -> float:
    """TR 36.777 UMi-AV expected gain at h = 100 m, f_c = 2 GHz, written out from the TR text."""
    d3d = math.sqrt(d2d**2 + (100.0 - h_bs) ** 2)
    fs = 20 * math.log10(d3d) + 20 * math.log10(2.0) + 32.45
    pl_los = max(fs, 30.9 + (22.25 - 0.5 * 2.0) * math.log10(d3d) + 20 * math.log10(2.0))
    pl_nlos = max(pl_los, 32.4 + (43.2 - 7.6 * 2.0) * math.log10(d3d) + 20 * math.log10(2.0))
    p1, d1 = 233.98 * 2.0 - 0.95, max(294.05 * 2.0 - 432.94, 18.0)
    p_los = 1.0 if d2d <= d1 else d1 / d2d + math.exp(-d2d / p1) * (1 - d1 / d2d)
    return p_los * 10 ** (-pl_los / 10) + (1 - p_los) * 10 ** (-pl_nlos / 10)


def test_two_gbs_sinr_by_hand() -> None:
    a = BaseStation(0.0, 0.0, 20.0, power_dbm=40.0, loading=1.0)
    b = BaseStation(1000.0, 0.0, 15.0, power_dbm=43.0, loading=0.5)
    point = (300.0, 400.0)  # 500 m from A, sqrt(700^2 + 400^2) from B
    s_a = 10 ** (40 / 10) * hand_gain(500.0, 20.0)  # mW
    s_b = 10 ** (43 / 10) * hand_gain(math.hypot(700.0, 400.0), 15.0)
    noise = 10 ** (-95.0 / 10)
    # paper Eq. 6: the serving GBS's own loading does not matter; the other's loading scales its interference.
    expected = max(s_a / (0.5 * s_b + noise), s_b / (1.0 * s_a + noise))
    got = expected_sinr_db(point, [a, b])
    assert float(got) == pytest.approx(10 * math.log10(expected), abs=1e-9)
    # A is the stronger one here, and it is interference-limited: B's loading matters, the noise hardly.
    assert s_a > s_b
    quieter = expected_sinr_db(point, [a, BaseStation(1000.0, 0.0, 15.0, power_dbm=43.0, loading=0.0)])
    assert float(quieter) == pytest.approx(10 * math.log10(s_a / noise), abs=1e-9)


def test_single_gbs_is_snr() -> None:
    bs = BaseStation(0.0, 0.0, 20.0)
    got = expected_sinr_db([[0.0, 300.0]], [bs], noise_dbm=-90.0)
    assert got.shape == (1,)
    assert float(got[0]) == pytest.approx(40 + 10 * math.log10(hand_gain(300.0, 20.0)) + 90, abs=1e-9)


def test_map_grid_and_values() -> None:
    stations = [BaseStation(100.0, 50.0, 20.0), BaseStation(300.0, 350.0, 20.0, loading=0.3)]
    radio = expected_sinr_map_3gpp(stations, side_m=395.0, resolution_m=20.0, name="toy")
    assert radio.shape == (21, 21)  # centres 0 ... 400 cover the 395 m square
    assert radio.side_m == 395.0 and radio.name == "toy" and radio.base_stations == tuple(stations)
    assert not radio.is_estimate and "3GPP" in radio.source
    pts = np.array([[0.0, 0.0], [100.0, 60.0], [240.0, 380.0]])
    np.testing.assert_allclose(radio.sinr_at(pts), expected_sinr_db(pts, stations), rtol=0, atol=1e-12)
    # The best cell is next to a station (within about a cell).
    ix, iy = np.unravel_index(np.argmax(radio.sinr_db), radio.shape)
    assert min(math.hypot(ix * 20.0 - b.x_m, iy * 20.0 - b.y_m) for b in stations) < 30.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"altitude_m": 20.0}, "22.5"),
        ({"altitude_m": 400.0}, "300"),
        ({"carrier_ghz": 0.0}, "carrier_ghz"),
    ],
)
def test_bad_model_inputs(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        expected_sinr_db([0.0, 0.0], [BaseStation(0.0, 0.0, 20.0)], **kwargs)


def test_bad_stations() -> None:
    with pytest.raises(ValueError, match="empty"):
        expected_sinr_db([0.0, 0.0], [])
    with pytest.raises(ValueError, match="not below the UAV altitude"):
        expected_sinr_db([0.0, 0.0], [BaseStation(0.0, 0.0, 120.0)])
    with pytest.raises(ValueError, match="side_m"):
        expected_sinr_map_3gpp([BaseStation(0.0, 0.0, 20.0)], side_m=0.0, resolution_m=10.0)
