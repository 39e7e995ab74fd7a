"""The packaged maps: SPEC §2 facts, equality with the source files, the Detroit estimate's conventions."""

from __future__ import annotations

import csv
import io
import time
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
    assert RADIO_MAPS == ("berlin", "detroit_estimate", "detroit_3gpp")


def test_unknown_name() -> None:
    with pytest.raises(ValueError, match=r"'paris'.*'berlin'.*'detroit_estimate'.*'detroit_3gpp'.*WinProp"):
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


def test_berlin_loads_fast() -> None:
    start = time.perf_counter()
    radio = packaged._berlin()  # uncached
    assert time.perf_counter() - start < 0.5
    assert radio.shape == (328, 327)


@pytest.mark.skipif(not BERLIN_TXT.is_file(), reason="shared WinProp source file not available")
def test_berlin_equals_the_winprop_file() -> None:
    start = time.perf_counter()
    source = read_winprop(BERLIN_TXT)
    assert time.perf_counter() - start < 1.5
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
        else:  # unknown: not computed
            assert np.isnan(mean.sinr_db[ix, iy])
            assert global_min.sinr_db[ix, iy] == DETROIT_BELOW_FLOOR_DB  # the global minimum
            assert not mean.feasible(centre, -30.0)
    assert {r["status"] for r in rows} == {"est", "below_-17", "unknown"}


def test_detroit_3gpp() -> None:
    start = time.perf_counter()
    radio = packaged._detroit_3gpp()  # uncached
    assert time.perf_counter() - start < 3.0
    assert isinstance(radio, RadioMap)
    assert radio.name == "detroit_3gpp" and not radio.is_estimate and "SYNTHETIC" in radio.source
    assert radio.resolution_m == 10.0 and radio.side_m == 11130.0 and radio.shape == (1114, 1114)
    assert len(radio.base_stations) == 10
    assert not np.isnan(radio.sinr_db).any()
    # Calibrated to the estimate (packaged.DETROIT_3GPP_NOISE_DBM): about a quarter of the 320 m blocks
    # below -17 dB, median block in the low -10s.
    blocks = radio.block_map(320.0).sinr_db
    assert 0.2 < (blocks < -17).mean() < 0.35
    assert -16 < np.median(blocks) < -10
    # The peaks sit at the GBS sites.
    for bs in radio.base_stations:
        assert radio.sinr_at([bs.x_m, bs.y_m]) > 10.0


def test_berlin_heading_table_is_fast() -> None:
    radio = load_radio_map("berlin")
    fresh = RadioMap(radio.sinr_db, resolution_m=radio.resolution_m)
    start = time.perf_counter()
    table = fresh.heading_segment_min_sinr(100.0, 16)
    assert time.perf_counter() - start < 1.0
    assert table.shape == (16, 328, 327)
