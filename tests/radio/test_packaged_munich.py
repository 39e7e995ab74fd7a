"""The packaged ray-traced Munich map and its presets: the arrays are those of the map ``uamfleet-radio-map --scene
munich --altitude-m 100 --cell-m 10 --threads 1`` wrote (hashes and values taken from that file, not recomputed
here), its frame and provenance read without Sionna, and a dispatcher flies ``munich_random`` to the end."""

from __future__ import annotations

import dataclasses
import hashlib

import numpy as np

import uamfleet
from uamfleet.policies import make_flown
from uamfleet.radio import load_radio_map, packaged, raytrace
from uamfleet.rollout import fly

# sha256 of the C-ordered float64 bytes of the command's output arrays (sinr_db [148, 121], bs_values [4, 6]).
SINR_SHA256 = "f3e2d43f790c56f8f95b27f8c7825d7f349bde92d6e182c719d5ee28f9096354"
BS_VALUES_SHA256 = "14c3a1f839b031e0a92ca1c3ec17ebb2c7f05289416f94d905ba093d3f3f20fd"
# The whole file as the command wrote it (copied into the package as is).
NPZ_SHA256 = "b80384c4a60e342d307f727a1e4b1ace50c22c8787323f69071e583454acbb6c"
# GBS (x, y, height) in the map frame: the 750 m grid's 2 x 2 cell centres, on a roof plus 3 m where taller than 20 m.
GBS_XYH = [
    (365.0, 297.5, 26.0151309967041),
    (1105.0, 297.5, 20.0),
    (365.0, 902.5, 20.0),
    (1105.0, 902.5, 22.31031036376953),
]


def sha256(array: np.ndarray) -> str:
    return hashlib.sha256(np.ascontiguousarray(array).tobytes()).hexdigest()


def test_munich_is_a_packaged_name() -> None:
    assert "munich" in uamfleet.RADIO_MAPS
    radio = load_radio_map("munich")
    assert load_radio_map("munich") is radio  # built once, like the other packaged maps


def test_munich_arrays_are_the_commands_output_bit_for_bit() -> None:
    assert hashlib.sha256((packaged.DATA_DIR / packaged.MUNICH_NPZ).read_bytes()).hexdigest() == NPZ_SHA256
    radio = load_radio_map("munich")
    assert radio.sinr_db.dtype == np.float64 and sha256(radio.sinr_db) == SINR_SHA256
    bs_values = [(b.x_m, b.y_m, b.height_m, b.power_dbm, b.frequency_mhz, b.loading) for b in radio.base_stations]
    assert sha256(np.array(bs_values, dtype=np.float64)) == BS_VALUES_SHA256
    # A few cells by value: no NaN (every cell reached), extremes and corners as written.
    assert not np.isnan(radio.sinr_db).any()
    assert radio.sinr_db[0, 0] == 1.9411054768884373 and radio.sinr_db[-1, -1] == 5.065053553383663
    assert np.nanmin(radio.sinr_db) == -4.389312822720931 and np.nanmax(radio.sinr_db) == 16.866135060383765
    assert np.unravel_index(np.argmax(radio.sinr_db), radio.shape) == (112, 90)


def test_munich_frame_and_base_stations() -> None:
    radio = load_radio_map("munich")
    assert radio.shape == (148, 121) and radio.resolution_m == 10.0
    assert radio.origin_m == (0.0, 0.0) and radio.side_m == 1200.0 and radio.altitude_m == 100.0
    assert radio.label == "munich" and not radio.is_estimate
    assert [(b.x_m, b.y_m, b.height_m) for b in radio.base_stations] == GBS_XYH
    assert {(b.power_dbm, b.frequency_mhz, b.loading) for b in radio.base_stations} == {(40.0, 2000.0, 1.0)}
    # A point reads the cell whose centre is nearest: (5, 5) m is cell (0, 0)'s edge, (1195, 1195) m cell (119, 119).
    assert radio.sinr_at([4.9, 4.9]) == radio.sinr_db[0, 0]
    assert radio.sinr_at([1195.0, 1194.9]) == radio.sinr_db[120, 119]


def test_munich_provenance_is_readable_without_sionna() -> None:
    radio = load_radio_map("munich")
    assert radio.source.startswith("RAY-TRACED: Sionna RT 2.2.0, scene munich, 2 GHz")
    record = raytrace.provenance(radio)
    assert record["scene"] == "munich" and record["sionna_rt_version"] == "2.2.0" and record["seed"] == 42
    assert record["format"] == "uamfleet-radio-map/1" and record["gbs_placement"] == "grid"
    assert (record["altitude_m"], record["cell_m"]) == (100.0, 10.0)
    assert record["scene_origin_m"] == [-800.5836791992188, -683.6006469726562]
    params = record["params"]
    assert (params["carrier_ghz"], params["power_dbm"], params["samples_per_tx"]) == (2.0, 40.0, 10_000_000)


def test_munich_presets_are_berlins_on_the_munich_map() -> None:
    for munich, berlin in (("munich_random", "berlin_random"), ("munich_instances", "berlin_instances")):
        cfg, like = uamfleet.make_config(munich), uamfleet.make_config(berlin)
        assert munich in uamfleet.SCENARIOS and cfg.scenario == munich
        assert cfg.radio is load_radio_map("munich")
        same = cfg.replace(radio=like.radio, scenario=berlin)
        assert all(getattr(same, f.name) == getattr(like, f.name) for f in dataclasses.fields(like))
    assert uamfleet.make_config("munich_random", radio="berlin").radio.label == "berlin"  # radio= still wins


def test_greedy_delivers_everyone_on_munich_random() -> None:
    cfg = uamfleet.make_config("munich_random", num_taxis=2)
    traj = fly(cfg, make_flown("greedy", seed=0, num_taxis=2), seed=0)
    requests = int(traj.pax_exists.sum())
    assert requests >= 2
    assert traj.terminated and not traj.truncated
    assert traj.episode["delivered"] == requests
