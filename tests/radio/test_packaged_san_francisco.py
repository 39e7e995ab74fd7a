"""The packaged ``san_francisco`` map: Sionna RT's San Francisco scene ray-traced by ``uamfleet-radio-map --scene
san_francisco --altitude-m 100 --cell-m 10 --threads 1`` (reports/2026-12-04-big-city/; hashes and values taken
from that file, not recomputed here). Its instances by name are those flown from the file's path in the
map-mixture session (reports/2026-12-04-map-mixture/san_francisco.npz, the same bytes), so the recorded San
Francisco tables and ``uamfleet bench --map san_francisco`` fly one test set."""

from __future__ import annotations

import hashlib
from pathlib import Path

import numpy as np
import pytest

from uamfleet.cli import benchmark
from uamfleet.instances import make_instance, map_family, split_seeds
from uamfleet.map_rules import map_provenance
from uamfleet.radio import RADIO_MAPS, load_radio_map, packaged, raytrace

NAME = "san_francisco"
ROOT = Path(__file__).resolve().parents[2]
REPORT_NPZ = ROOT / "reports" / "2026-12-04-map-mixture" / "san_francisco.npz"
# The whole file as the command wrote it (copied into the package as is), and its arrays' C-ordered float64 bytes.
NPZ_SHA256 = "90276f16573767c660a58bc5ebb0c95a9d245e8df93765799fcc1f3a442fe0f2"
SINR_SHA256 = "f29d045361b0f46d66a92baf8ffcb129857a48bfc35d43ab4ec1ce2fdc45ec37"
BS_VALUES_SHA256 = "3433e1621ecb764c549efd04f12a4b8a80a7926456a5907232b2439d6e6e5fd9"


def _sha256(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array).tobytes()).hexdigest()


def test_the_package_holds_the_commands_output_and_stays_small() -> None:
    path = packaged.DATA_DIR / packaged.SAN_FRANCISCO_NPZ
    assert NAME in RADIO_MAPS and load_radio_map(NAME) is load_radio_map(NAME)
    assert path.stat().st_size < 200_000
    assert hashlib.sha256(path.read_bytes()).hexdigest() == NPZ_SHA256
    assert path.read_bytes() == REPORT_NPZ.read_bytes()  # the file the recorded San Francisco tables flew
    radio = load_radio_map(NAME)
    assert radio.sinr_db.dtype == np.float64 and _sha256(radio.sinr_db) == SINR_SHA256
    bs_values = [(b.x_m, b.y_m, b.height_m, b.power_dbm, b.frequency_mhz, b.loading) for b in radio.base_stations]
    assert _sha256(np.array(bs_values, dtype=np.float64)) == BS_VALUES_SHA256
    assert int(np.isnan(radio.sinr_db).sum()) == 670  # 5.9 % of the cells reached by no ray (the big-city report)
    assert np.nanmin(radio.sinr_db) == 0.00023120630892129468 and np.nanmax(radio.sinr_db) == 54.000917769899615


def test_frame_base_stations_and_provenance() -> None:
    radio = load_radio_map(NAME)
    assert radio.shape == (123, 93) and radio.resolution_m == 10.0 and radio.origin_m == (0.0, 0.0)
    assert radio.side_m == 920.0 and radio.altitude_m == 100.0 and radio.label == NAME
    assert [(b.x_m, b.y_m) for b in radio.base_stations] == [(302.5, 460.0), (917.5, 460.0)]
    record = raytrace.provenance(radio)
    assert (record["scene"], record["sionna_rt_version"], record["seed"]) == (NAME, "2.2.0", 42)
    assert (record["altitude_m"], record["cell_m"], record["gbs_placement"]) == (100.0, 10.0, "grid")
    # the scene's bounding box, 1,222 m x 928 m, and the frame's origin 5 m (half a cell) inside it
    x0, y0, x1, y1 = record["extent_m"]
    assert (round(x1 - x0), round(y1 - y0)) == (1222, 928)
    assert record["scene_origin_m"] == pytest.approx([x0 + 5.0, y0 + 5.0])
    assert map_provenance(NAME).startswith(
        f"packaged map '{NAME}': 123 x 93 cells of 10 m, operating square 920 m, 2 base station(s), altitude 100 m; "
        "source: RAY-TRACED: Sionna RT 2.2.0, scene san_francisco"
    )


def test_its_family_has_the_maps_own_thresholds_and_berlins_shortest_trip_scaled() -> None:
    fam = map_family(NAME)
    assert fam.thresholds_db == (1.4, 1.6, 2.3, 3.4, 4.0)  # its quantiles: Berlin's -7 ... -3 dB never bind here
    assert fam.min_trip_m == round(500.0 * 920.0 / 3260.0) == 141.0


@pytest.mark.parametrize("seed", [*split_seeds("test", 3), 2_000_049, *split_seeds("validation", 2)])
def test_its_instances_by_name_are_those_of_the_report_file(seed: int) -> None:
    by_name, by_path = make_instance(NAME, seed), make_instance(str(REPORT_NPZ), seed)
    assert by_name.scenario == by_path.scenario == f"{NAME}_seed{seed}"
    assert (by_name.sinr_min_db, by_name.starts_m, by_name.requests) == (
        by_path.sinr_min_db,
        by_path.starts_m,
        by_path.requests,
    )


def test_the_benchmark_flies_it_by_name_and_prints_its_provenance(tmp_path: Path, capsys) -> None:
    argv = ["--map", NAME, "--count", "1", "--jobs", "1", "--methods", "straight", "--out-csv", str(tmp_path / "b.csv")]
    assert benchmark.cli(argv) == 0
    assert f"Map: {map_provenance(NAME)}" in capsys.readouterr().out
