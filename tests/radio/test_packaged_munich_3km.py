"""The packaged ``munich_3km`` map: Munich's scene ray-traced over a 3 km square by ``uamfleet-radio-map --scene munich
--altitude-m 100 --cell-m 10 --threads 1 --extent-m -1568 -1586 1432 1414`` (hashes and values taken from that
file, not recomputed here). Away from the city's buildings the map is free space, so its SINR there is checked
against Friis's law computed here from the GBS positions alone; the map's family keeps Berlin's thresholds, at
which the radio binds; and the map flies through the commands by name."""

from __future__ import annotations

import csv
import dataclasses
import hashlib
import math
from pathlib import Path

import numpy as np
import pytest

import uamfleet
from uamfleet.cli import benchmark, fleet_benchmark, render, rollout
from uamfleet.instances import (
    BERLIN_THRESHOLDS_DB,
    family_of,
    make_fleet_instance,
    map_family,
)
from uamfleet.radio import RADIO_MAPS, load_radio_map, packaged, raytrace
from uamfleet.sim.world import World

NAME = "munich_3km"
# The whole file as the command wrote it (copied into the package as is), and its arrays' C-ordered float64 bytes.
NPZ_SHA256 = "e2e274c48e426e9edd24cb46cc739e45afaeed3167e4cd9546747e62df7c0177"
SINR_SHA256 = "abad290a40fdf3441d7ed385bf8998a8ba00eabf1e7fc902c52a76bf8081c5f1"
BS_VALUES_SHA256 = "d3ae7c53d26cabef82e741deac7c7e7f97b2789fd8f7f76ecb5c991bebce309e"
# The 750 m grid over the 3,000 m square: 4 x 4 GBS at the grid cells' centres, (i + 0.5) * 750 - 5 m (the frame's
# origin is the first 10 m cell's centre).
GRID_M = (370.0, 1120.0, 1870.0, 2620.0)
# The scene's buildings in the map's frame: its bounding box (-805.6 ... 669.9, -688.6 ... 517.0) + (1563, 1581).
CITY_X_M, CITY_Y_M = (757.0, 2233.0), (892.0, 2098.0)


def _sha256(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array).tobytes()).hexdigest()


def test_the_package_holds_the_commands_output_and_stays_small() -> None:
    path = packaged.DATA_DIR / packaged.MUNICH_3KM_NPZ
    assert NAME in RADIO_MAPS and load_radio_map(NAME) is load_radio_map(NAME)
    assert path.stat().st_size < 1_000_000
    assert hashlib.sha256(path.read_bytes()).hexdigest() == NPZ_SHA256
    radio = load_radio_map(NAME)
    assert radio.sinr_db.dtype == np.float64 and _sha256(radio.sinr_db) == SINR_SHA256
    bs_values = [(b.x_m, b.y_m, b.height_m, b.power_dbm, b.frequency_mhz, b.loading) for b in radio.base_stations]
    assert _sha256(np.array(bs_values, dtype=np.float64)) == BS_VALUES_SHA256
    assert not np.isnan(radio.sinr_db).any()  # every cell reached
    assert np.nanmin(radio.sinr_db) == -6.992932268216709 and np.nanmax(radio.sinr_db) == 16.046637183507514


def test_frame_base_stations_and_provenance() -> None:
    radio = load_radio_map(NAME)
    assert radio.shape == (300, 300) and radio.resolution_m == 10.0 and radio.origin_m == (0.0, 0.0)
    assert radio.side_m == 2990.0 and radio.altitude_m == 100.0 and radio.label == NAME
    assert [(b.x_m, b.y_m) for b in radio.base_stations] == [(x, y) for y in GRID_M for x in GRID_M]
    # 20 m masts, except on the one roof taller than 17 m under a site (roof + 3 m), inside the city
    tall = [b for b in radio.base_stations if b.height_m != 20.0]
    assert [(b.x_m, b.y_m) for b in tall] == [(1120.0, 1870.0)] and 20.0 < tall[0].height_m < 40.0
    record = raytrace.provenance(radio)
    assert (record["scene"], record["sionna_rt_version"], record["seed"]) == ("munich", "2.2.0", 42)
    assert record["extent_m"] == [-1568.0, -1586.0, 1432.0, 1414.0] and record["scene_origin_m"] == [-1563.0, -1581.0]
    assert (record["altitude_m"], record["cell_m"], record["gbs_placement"]) == (100.0, 10.0, "grid")
    params = record["params"]
    assert (params["carrier_ghz"], params["power_dbm"], params["samples_per_tx"]) == (2.0, 40.0, 10_000_000)


def _free_space_sinr_db(radio: uamfleet.RadioMap, x_m: float, y_m: float) -> float:
    """Best server over the others plus thermal noise, every GBS seen in free space (Friis, isotropic antennas)."""
    wavelength = 299_792_458.0 / 2e9
    received_mw = [
        10 ** (b.power_dbm / 10)
        * (wavelength / (4 * math.pi * math.dist((x_m, y_m, 100.0), (b.x_m, b.y_m, b.height_m)))) ** 2
        for b in radio.base_stations
    ]
    best = max(received_mw)
    return 10 * math.log10(best / (sum(received_mw) - best + 10 ** (-95.0 / 10)))


@pytest.mark.parametrize(
    "point",
    [(370.0, 370.0), (2620.0, 2620.0), (370.0, 2620.0), (2620.0, 370.0),  # above a GBS: ~13.3 dB
     (745.0, 745.0), (2245.0, 2245.0),  # where four cells meet: ~-6.4 dB
     (745.0, 370.0), (370.0, 745.0), (2620.0, 1495.0), (1495.0, 370.0)],  # between two cells: ~-3 dB
)  # fmt: skip
def test_outside_the_city_the_map_is_free_space(point: tuple[float, float]) -> None:
    x, y = point
    assert not (CITY_X_M[0] <= x <= CITY_X_M[1] and CITY_Y_M[0] <= y <= CITY_Y_M[1])
    radio = load_radio_map(NAME)
    # 0.7 dB: the Monte-Carlo rays (10^7 per GBS) averaged over a 10 m cell, and rays the city reflects
    assert float(radio.sinr_at([x, y])) == pytest.approx(_free_space_sinr_db(radio, x, y), abs=0.7)


def test_its_family_keeps_berlins_thresholds_where_the_radio_binds() -> None:
    fam = map_family(NAME)
    assert fam.thresholds_db == BERLIN_THRESHOLDS_DB and fam.min_trip_m == round(500.0 * 2990.0 / 3260.0) == 459.0
    blocks = World(uamfleet.make_config("munich_3km_random")).blocks.sinr_db
    shares = [float(np.mean(blocks >= t)) for t in BERLIN_THRESHOLDS_DB]
    # every block flyable at -7 and -6 dB; at -3 dB 15 % are not (Berlin: 81.2 % flyable at -3 dB)
    assert shares == pytest.approx([1.0, 1.0, 0.9867, 0.9389, 0.85], abs=1e-4)
    # where four cells meet, the best GBS is one of four equally far ones: at most 1/3 of the rest, -4.8 dB
    assert float(load_radio_map(NAME).sinr_at([745.0, 745.0])) < -10 * math.log10(3) < BERLIN_THRESHOLDS_DB[-1]


def test_its_presets_are_berlins_on_the_map() -> None:
    for preset, berlin in (("munich_3km_random", "berlin_random"), ("munich_3km_instances", "berlin_instances")):
        cfg, like = uamfleet.make_config(preset), uamfleet.make_config(berlin)
        assert cfg.radio is load_radio_map(NAME) and cfg.scenario == preset
        same = cfg.replace(radio=like.radio, scenario=berlin)
        assert all(getattr(same, f.name) == getattr(like, f.name) for f in dataclasses.fields(like))
        assert family_of(preset) == NAME  # a policy trained on the preset validates on the map's family


def _rows(path: Path) -> list[dict[str, str]]:
    with path.open(encoding="utf-8") as f:
        return list(csv.DictReader(f))


@pytest.mark.slow  # 70 s on the shared machine: a 3 km map's instances, a fleet instance, a tour and a render
def test_the_commands_fly_it_by_name(tmp_path: Path, capsys) -> None:
    # the benchmark's rows on the test instances: tests/test_map_cli.py flies every packaged city there
    assert (
        benchmark.cli(["--map", NAME, "--count", "1", "--methods", "straight", "--out-csv", str(tmp_path / "b.csv")])
        == 0
    )
    out = tmp_path / "f.csv"
    argv = ["--map", NAME, "--count", "1", "--settings", "2x12", "--jobs", "1", "--dispatchers", "greedy",
            "--out-csv", str(out)]  # fmt: skip
    assert fleet_benchmark.cli(argv) == 0
    [row] = _rows(out)
    assert (row["family"], row["setting"], int(row["seed"])) == (NAME, "2x12", 2_000_000)
    assert float(row["threshold_db"]) == make_fleet_instance(NAME, 2_000_000, 2, 12).sinr_min_db
    [flown] = rollout.main(rollout.Args(map=NAME, policy="raster_opt", episodes=1))
    assert flown["pr_pct"] == 100.0
    written = render.main(render.Args(map=NAME, policy="straight", out=tmp_path / "city.html"))
    assert written["html"].is_file()
    printed = capsys.readouterr().out
    provenance = f"Map: packaged map '{NAME}': 300 x 300 cells of 10 m, operating square 2990 m, 16 base station(s)"
    assert printed.count(provenance) == 4
    assert f"berlin_instances on {NAME}: 1 taxi(s), γ_T = -3 dB" in printed  # the family's strictest threshold
