"""Instance families of any map (uamfleet.instances.map_family): by a packaged map's name or a map file's path,
Berlin's rules scaled to the map, thresholds from its SINR quantiles where Berlin's do not bind, rebuilt from the
name or path alone in a spawned process; the named families untouched."""

from __future__ import annotations

import multiprocessing as mp
import shutil
from pathlib import Path

import numpy as np
import pytest

from uamfleet.instances import (
    BERLIN_FEASIBLE_SHARES,
    BERLIN_THRESHOLDS_DB,
    FAMILIES,
    family_of,
    make_fleet_instance,
    make_instance,
    map_family,
    map_provenance,
    map_thresholds,
)
from uamfleet.presets import make_config
from uamfleet.radio import BaseStation, RadioMap, load_radio_map, save_radio_map_npz
from uamfleet.sim.world import World


def _block_map(values: np.ndarray) -> RadioMap:
    """A 1,000 m map of 10 m cells whose 100 m block (bx, by) holds ``values[bx, by]`` in every cell."""
    index = np.minimum(np.arange(101) // 10, 9)  # cell centre i * 10 m lies in block i // 10 (x = 1000: the last)
    sinr = values[index[:, None], index[None, :]]
    return RadioMap(sinr_db=sinr, resolution_m=10.0, side_m=1000.0, name="blocks",
                    base_stations=(BaseStation(500.0, 500.0, 20.0),))  # fmt: skip


def test_thresholds_are_the_map_quantiles_at_berlins_shares_where_berlin_thresholds_do_not_bind() -> None:
    # 100 blocks at 0.0, 0.1, ..., 9.9 dB: every block is flyable at -3 dB, so Berlin's thresholds would not bind.
    # Berlin's flyable shares 95.68 / 94.21 / 90.63 / 86.50 / 81.18 % need 96 / 95 / 91 / 87 / 82 of the 100
    # blocks: the thresholds that keep the top 96, ... blocks are 0.4, 0.5, 0.9, 1.3 and 1.8 dB.
    radio = _block_map((np.arange(100) / 10.0).reshape(10, 10))
    thresholds = map_thresholds(radio)
    assert thresholds == (0.4, 0.5, 0.9, 1.3, 1.8)
    blocks = np.arange(100) / 10.0
    for threshold, share in zip(thresholds, BERLIN_FEASIBLE_SHARES, strict=True):
        assert np.mean(blocks >= threshold) >= share  # at least Berlin's share flyable
        assert np.mean(blocks >= threshold + 0.1) < share  # and the next 0.1 dB step would be below it


def test_berlin_thresholds_are_kept_where_they_bind() -> None:
    # blocks at -10.0, -9.8, ..., 9.8 dB: 85 % flyable at -7 dB and 35 % not at -3 dB
    assert map_thresholds(_block_map((np.arange(100) / 5.0 - 10.0).reshape(10, 10))) == BERLIN_THRESHOLDS_DB


def test_berlin_shares_are_the_berlin_maps_and_its_own_thresholds_are_kept() -> None:
    cfg = make_config("berlin_random")
    blocks = cfg.radio.block_map(cfg.block_size_m, nc_rule=cfg.nc_rule).sinr_db
    shares = [float(np.mean(np.nan_to_num(blocks, nan=-np.inf) >= t)) for t in BERLIN_THRESHOLDS_DB]
    assert shares == pytest.approx(BERLIN_FEASIBLE_SHARES, abs=5e-5)
    assert map_thresholds(load_radio_map("berlin")) == BERLIN_THRESHOLDS_DB


def test_munich_family_scales_berlins_rules_to_its_extent() -> None:
    fam = map_family("munich")
    assert FAMILIES["munich"] == fam and "munich" in FAMILIES and "munich" not in list(FAMILIES)
    assert fam.min_trip_m == round(500.0 * 1200.0 / 3260.0) == 184.0  # Berlin's 500 m of 3,260 m, of 1,200 m
    assert (fam.min_passengers, fam.max_passengers, fam.release_window_s) == (2, 6, 120.0)
    # Munich is flyable everywhere at -7 ... -3 dB: its thresholds are its own quantiles, each binding
    blocks = World(make_config("munich_random")).blocks.sinr_db
    assert fam.thresholds_db != BERLIN_THRESHOLDS_DB and np.all(blocks >= -3.0)
    for threshold, share in zip(fam.thresholds_db, BERLIN_FEASIBLE_SHARES, strict=True):
        assert share <= np.mean(blocks >= threshold) < 1.0


def test_munich_instances_follow_the_rules_and_the_seed() -> None:
    fam = map_family("munich")
    for seed in (0, 1_000_000, 2_000_000, 2_000_001):
        cfg = make_instance("munich", seed)
        assert cfg.scenario == f"munich_seed{seed}" and cfg.radio is load_radio_map("munich")
        assert cfg.sinr_min_db in fam.thresholds_db and cfg.num_taxis == 1
        assert 2 <= len(cfg.requests) <= 6 and cfg.requests[0].release_step == 0
        assert all(r.release_step <= 40 for r in cfg.requests)  # 2 minutes of 3 s steps
        for r in cfg.requests:
            assert np.hypot(*np.subtract(r.origin_m, r.destination_m)) >= fam.min_trip_m
        world = World(cfg)
        stops = np.array([cfg.starts_m[0]] + [p for r in cfg.requests for p in (r.origin_m, r.destination_m)])
        assert world.point_feasible(stops).all()
    assert _drawn("munich", 2_000_000) == _drawn("munich", 2_000_000) != _drawn("munich", 2_000_001)


def test_munich_fleet_instances() -> None:
    cfg = make_fleet_instance("munich", 2_000_000, num_taxis=2, num_requests=12)
    assert cfg.scenario == "munich_fleet2x12_seed2000000" and cfg.radio.name == "munich"
    assert cfg.num_taxis == 2 and len(cfg.requests) == 12 and cfg.hover_action  # as berlin_fleet
    assert cfg.sinr_min_db in map_family("munich").thresholds_db


def _drawn(family: str, seed: int) -> tuple[object, ...]:
    """What an instance draws: its threshold, start and requests."""
    cfg = make_instance(family, seed)
    return cfg.sinr_min_db, cfg.starts_m, cfg.requests


def _copy_munich(folder: Path, stem: str) -> Path:
    folder.mkdir(parents=True, exist_ok=True)
    return save_radio_map_npz(load_radio_map("munich"), folder / f"{stem}.npz")


def test_a_map_file_is_a_family_by_path_seeded_by_its_stem(tmp_path: Path) -> None:
    path = _copy_munich(tmp_path / "a", "mycity")
    other = tmp_path / "b" / "mycity.npz"
    other.parent.mkdir()
    shutil.copy(path, other)
    fam = map_family(str(path))
    assert fam.name == "mycity" and fam.radio == str(path)
    assert fam.thresholds_db == map_family("munich").thresholds_db and fam.min_trip_m == 184.0  # the same map
    cfg = make_instance(str(path), 2_000_000)
    assert cfg.scenario == "mycity_seed2000000"
    assert _drawn(str(other), 2_000_000) == _drawn(str(path), 2_000_000)  # same stem, same instances
    assert _drawn(str(path), 2_000_000) != _drawn("munich", 2_000_000)  # another name, another seed stream
    assert make_fleet_instance(path, 2_000_000, 1, 6).scenario == "mycity_fleet1x6_seed2000000"
    model = tmp_path / "model.json"  # a file that is no map (a demand model's) names no family
    model.write_text("{}")
    assert str(path) in FAMILIES and str(model) not in FAMILIES


def test_a_spawned_worker_rebuilds_a_map_family_from_its_path(tmp_path: Path) -> None:
    path = str(_copy_munich(tmp_path, "spawned"))
    with mp.get_context("spawn").Pool(1) as pool:
        assert pool.apply(_drawn, (path, 2_000_003)) == _drawn(path, 2_000_003)


def test_named_families_come_first_and_are_unchanged() -> None:
    assert FAMILIES["berlin"].radio is None and FAMILIES["berlin"].scenario == "berlin_random"
    assert map_family("berlin") is FAMILIES["berlin"]  # the packaged Berlin map is the berlin family
    assert make_instance("berlin", 2_000_000).scenario == "berlin_seed2000000"
    assert list(FAMILIES) == ["berlin", "detroit3gpp", "berlin_stream", "berlin_peak", "berlin_burst"]
    assert family_of("munich_instances") == family_of("munich_random") == "munich"
    assert family_of("berlin_instances") == "berlin"


@pytest.mark.parametrize("bad", ["nowhere", "missing/city.npz", ["munich"]])
def test_a_bad_family_or_map_is_refused_in_one_line(bad: object) -> None:
    with pytest.raises(ValueError, match=r"unknown instance family .*; choose one of .*a packaged map .*munich.*"
                       r"or the path of an existing map file") as err:  # fmt: skip
        make_instance(bad, 0)  # type: ignore[arg-type]
    assert "\n" not in str(err.value)


def test_provenance_names_the_source_size_cell_and_the_maps_own_record(tmp_path: Path) -> None:
    line = map_provenance("munich")
    assert line.startswith("packaged map 'munich': 148 x 121 cells of 10 m, operating square 1200 m")
    assert "Sionna RT" in line and '"cell_m": 10.0' in line and "\n" not in line
    path = _copy_munich(tmp_path, "city")
    assert map_provenance(str(path)).startswith(f"map file {path}: 148 x 121 cells of 10 m")


def test_a_map_coarser_than_berlins_steps_is_flown_in_steps_of_its_cells_at_berlins_speed() -> None:
    fam = map_family("detroit_estimate")  # 320 m blocks: 100 m steps would leave blocks without a value
    assert fam.step_m == 320.0 and map_family("munich").step_m is None
    cfg = make_instance("detroit_estimate", 2_000_000)
    assert (cfg.step_m, cfg.slot_s) == (320.0, pytest.approx(9.6))  # 100 m per 3 s
    assert cfg.scenario == "detroit_estimate_seed2000000" and cfg.sinr_min_db in BERLIN_THRESHOLDS_DB
    assert all(r.release_step <= 120.0 // 9.6 for r in cfg.requests)  # the 2-minute window in 9.6 s steps


def test_the_demand_model_of_a_map_familys_world_is_its_familys_law(tmp_path: Path) -> None:
    from uamfleet.baselines.demand_models import NoDemandModelError, demand_model, world_family

    cfg = make_instance("munich", 2_000_000)
    assert world_family(cfg, "hedge") == "munich"
    assert world_family(make_fleet_instance("munich", 2_000_000, 2, 12), "hedge") == "munich"
    model = demand_model("family", cfg)
    assert model.law == map_family("munich").demand_law() and model.law.min_trip_m == 184.0
    path = str(_copy_munich(tmp_path, "town"))
    with pytest.raises(NoDemandModelError, match="scenario 'town_seed2000000' is none of"):
        world_family(make_config("berlin_random").replace(scenario="town_seed2000000"), "hedge")  # none drawn here
    assert world_family(make_instance(path, 2_000_000), "hedge") == path  # its instances drawn: the path read back
