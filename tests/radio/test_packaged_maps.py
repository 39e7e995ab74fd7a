"""The packaged maps: facts of the Berlin WinProp file (size, antennas, N.C. cells), equality with the source
files, the Detroit estimate's conventions."""

from __future__ import annotations

import csv
import io
from pathlib import Path

import numpy as np
import pytest

from uamfleet.radio import (
    DETROIT_BELOW_FLOOR_DB,
    RADIO_MAPS,
    RadioMap,
    load_radio_map,
    read_winprop,
)
from uamfleet.radio import packaged

SHARED = Path("/work/shared/data")
BERLIN_TXT = SHARED / "berlin" / "berlin_UAM_SNIR_100.txt"


def test_names() -> None:
    assert RADIO_MAPS == ("berlin", "detroit_estimate", "detroit_3gpp", "munich", "munich_3km", "san_francisco")


def test_unknown_name() -> None:
    names = r"'paris'.*'berlin'.*'detroit_estimate'.*'detroit_3gpp'.*'munich'.*'munich_3km'.*'san_francisco'.*WinProp"
    with pytest.raises(ValueError, match=names):
        load_radio_map("paris")


def test_cached_and_passthrough() -> None:
    radio = load_radio_map("berlin")
    assert load_radio_map("berlin") is radio
    assert load_radio_map(radio) is radio


def test_berlin_facts() -> None:
    radio = load_radio_map("berlin")
    sinr = radio.sinr_db
    assert radio.shape == (328, 327)
    assert radio.resolution_m == 10.0 and radio.side_m == 3260.0 and radio.altitude_m == 100.0
    assert radio.origin_m == (0.0, 0.0) and radio.utm_origin_m == (392260.0, 5816868.0)
    assert not radio.is_estimate and radio.label == "berlin"
    assert "Traffic-Alpha" in radio.source and "MIT" in radio.source
    assert round(float(np.nanmin(sinr)), 2) == -15.97
    assert round(float(np.nanmax(sinr)), 2) == 17.63
    assert round(float(np.nanmedian(sinr)), 2) == 1.57
    nc = np.isnan(sinr)
    assert nc.sum() == 1041
    # The whole west and east columns and the north row, plus 61 interior cells.
    assert nc[0, :].all() and nc[-1, :].all() and nc[:, -1].all()
    assert nc[1:-1, :-1].sum() == 61
    stations = radio.base_stations
    assert len(stations) == 19
    assert sorted(b.height_m for b in stations) == [15.0] + [20.0] * 18
    assert {b.power_dbm for b in stations} == {40.0}
    assert min(b.frequency_mhz for b in stations) == 2115.0 and max(b.frequency_mhz for b in stations) == 2165.0


def test_berlin_loads_uncached() -> None:
    radio = packaged._berlin()  # uncached (load times: benchmarks/radio_load.py)
    assert radio.shape == (328, 327)


@pytest.mark.skipif(not BERLIN_TXT.is_file(), reason="shared WinProp source file not available")
def test_berlin_equals_the_winprop_file() -> None:
    source = read_winprop(BERLIN_TXT)
    radio = load_radio_map("berlin")
    np.testing.assert_array_equal(np.isnan(radio.sinr_db), np.isnan(source.sinr_db))
    np.testing.assert_allclose(radio.sinr_db, source.sinr_db, rtol=0, atol=1e-4, equal_nan=True)
    assert radio.base_stations == source.base_stations
    assert (radio.resolution_m, radio.side_m, radio.altitude_m, radio.utm_origin_m) == (
        source.resolution_m,
        source.side_m,
        source.altitude_m,
        source.utm_origin_m,
    )
    # A path works too.
    assert load_radio_map(str(BERLIN_TXT)).shape == (328, 327)


def test_berlin_licence_is_packaged() -> None:
    text = (packaged.DATA_DIR / packaged.BERLIN_LICENSE).read_text()
    first = text.splitlines()[0]
    assert packaged.BERLIN_NPZ in first and "Traffic-Alpha/UAM-Path-Planning" in first
    assert "MIT License" in text and "Copyright (c) 2025 Traffic-Alpha" in text


def detroit_rows() -> list[dict[str, str]]:
    text = (packaged.DATA_DIR / packaged.DETROIT_CSV).read_text()
    return list(csv.DictReader(line for line in io.StringIO(text) if not line.startswith("#")))


def test_detroit_estimate_frame() -> None:
    radio = load_radio_map("detroit_estimate")
    assert radio.is_estimate and radio.label == "detroit_estimate (estimate)"
    assert "ESTIMATE" in radio.source and "-17" in radio.source
    assert radio.shape == (35, 35)
    assert radio.resolution_m == 320.0 and radio.origin_m == (160.0, 160.0) and radio.side_m == 11130.0
    # CSV row 0 = south, columns = x: (row 0, col 3) is -16.4 dB and lies at x in [960, 1280), y in [0, 320).
    assert radio.sinr_db[3, 0] == -16.4
    assert radio.sinr_at([1000.0, 10.0]) == -16.4
    assert radio.sinr_at([11130.0, 11130.0]) == DETROIT_BELOW_FLOOR_DB  # last (250 m) block, row 34 col 34


def test_detroit_estimate_blocks_reproduce_the_csv() -> None:
    radio = load_radio_map("detroit_estimate")
    mean = radio.block_map(320.0, nc_rule="nanmean")
    global_min = radio.block_map(320.0)
    assert mean.shape == (35, 35)
    rows = detroit_rows()
    assert len(rows) == 35 * 35
    estimated = {(int(r["col"]), int(r["row"])): float(r["sinr_db_est"]) for r in rows if r["status"] == "est"}
    for r in rows:
        ix, iy = int(r["col"]), int(r["row"])
        centre = [(float(r["x0"]) + float(r["x1"])) / 2, (float(r["y0"]) + float(r["y1"])) / 2]
        if r["status"] == "est":
            assert mean.sinr_db[ix, iy] == float(r["sinr_db_est"])
            assert global_min.sinr_db[ix, iy] == float(r["sinr_db_est"])
            assert mean.feasible(centre, -17.0) == (float(r["sinr_db_est"]) >= -17.0)
        elif r["status"] == "below_-17":
            assert mean.sinr_db[ix, iy] == DETROIT_BELOW_FLOOR_DB
            assert not mean.feasible(centre, -17.0) and not radio.feasible(centre, -17.0)
        else:  # unknown (hidden in the figure): mean of the estimated 4-neighbours, N.C. if there is none
            near = [estimated[n] for n in ((ix - 1, iy), (ix + 1, iy), (ix, iy - 1), (ix, iy + 1)) if n in estimated]
            if near:
                assert mean.sinr_db[ix, iy] == pytest.approx(sum(near) / len(near))
            else:
                assert np.isnan(mean.sinr_db[ix, iy])
                assert global_min.sinr_db[ix, iy] == DETROIT_BELOW_FLOOR_DB  # the global minimum
    assert {r["status"] for r in rows} == {"est", "below_-17", "unknown"}
    # The Detroit P5 start (6290, 9450) lies in a hidden block: neighbours -16.4, -14.6, -14.6 (and one below -17).
    assert global_min.sinr_at([6290.0, 9450.0]) == pytest.approx((-16.4 - 14.6 - 14.6) / 3)


def test_detroit_3gpp() -> None:
    radio = packaged._detroit_3gpp()  # uncached
    assert isinstance(radio, RadioMap)
    assert radio.name == "detroit_3gpp" and not radio.is_estimate and "SYNTHETIC" in radio.source
    assert radio.resolution_m == 10.0 and radio.side_m == 11130.0 and radio.shape == (1114, 1114)
    assert len(radio.base_stations) == 10
    assert not np.isnan(radio.sinr_db).any()
    # Calibrated (packaged.DETROIT_3GPP_NOISE_DBM): every Detroit P5 stop flyable at -17 dB, 10-35 % of the
    # 320 m blocks below -17 dB (estimate: 26.6 %), median block in the low -10s (estimate: -12.3 dB).
    blocks = radio.block_map(320.0)
    p5_stops = [(6290, 9450), (6594, 7563), (9570, 7210), (7494, 5855), (1375, 6530), (3500, 5220), (5100, 2500),
                (2175, 6906), (2234, 3850), (3781, 3438), (7830, 2430)]  # fmt: skip
    assert blocks.feasible(np.array(p5_stops, float), -17.0).all()
    assert 0.1 < (blocks.sinr_db < -17).mean() < 0.35
    assert -16 < np.median(blocks.sinr_db) < -10
    # The peaks sit at the GBS sites.
    for bs in radio.base_stations:
        assert radio.sinr_at([bs.x_m, bs.y_m]) > 10.0


def test_berlin_heading_table() -> None:
    radio = load_radio_map("berlin")
    fresh = RadioMap(radio.sinr_db, resolution_m=radio.resolution_m)
    table = fresh.heading_segment_min_sinr(100.0, 16)
    assert table.shape == (16, 328, 327)
