"""The seeded instance generator: disjoint seed ranges, deterministic instances within the documented ranges."""

from __future__ import annotations

import numpy as np
import pytest

from uamfleet.instances import FAMILIES, SPLITS, TEST_SEEDS, TRAIN_SEEDS, VALIDATION_SEEDS, make_instance, split_seeds
from uamfleet.sim.world import World


def test_seed_ranges_are_disjoint_and_split_seeds_stays_inside():
    ranges = [TRAIN_SEEDS, VALIDATION_SEEDS, TEST_SEEDS]
    for i, a in enumerate(ranges):
        for b in ranges[i + 1 :]:
            assert a.stop <= b.start or b.stop <= a.start
    assert split_seeds("test", 3, first=2) == [TEST_SEEDS[2], TEST_SEEDS[3], TEST_SEEDS[4]]
    with pytest.raises(ValueError, match="outside"):
        split_seeds("validation", 2, first=len(SPLITS["validation"]) - 1)
    with pytest.raises(ValueError, match="unknown split"):
        split_seeds("holdout", 1)


def _summary(cfg):
    return (cfg.sinr_min_db, cfg.starts_m, tuple((r.release_step, r.origin_m, r.destination_m) for r in cfg.requests))


def test_instances_are_deterministic_valid_and_within_the_documented_ranges():
    fam = FAMILIES["berlin"]
    seeds = split_seeds("test", 4)
    first = [make_instance("berlin", s) for s in seeds]
    again = [make_instance("berlin", s) for s in seeds]
    assert [_summary(c) for c in first] == [_summary(c) for c in again]
    assert len({_summary(c) for c in first}) == len(seeds)  # different seeds, different instances
    assert _summary(make_instance("berlin", TRAIN_SEEDS[0])) not in {_summary(c) for c in first}
    padded = make_instance("berlin", seeds[0], max_passengers=6)  # a padded passenger axis, same instance
    assert padded.num_passengers == 6 and _summary(padded) == _summary(first[0])
    for cfg in first:
        assert cfg.sinr_min_db in fam.thresholds_db and cfg.num_taxis == 1
        assert fam.min_passengers <= len(cfg.requests) <= fam.max_passengers
        releases = [r.release_step for r in cfg.requests]
        assert releases[0] == 0 and releases == sorted(releases)
        assert max(releases) * cfg.slot_s <= fam.release_window_s
        world = World(cfg)
        stops = np.array([p for r in cfg.requests for p in (r.origin_m, r.destination_m)])
        assert world.point_feasible(stops).all() and world.point_feasible(np.array(cfg.starts_m)).all()
        assert all(np.linalg.norm(np.subtract(r.destination_m, r.origin_m)) >= fam.min_trip_m for r in cfg.requests)


def test_bad_family_and_seed_are_named():
    with pytest.raises(ValueError, match="unknown instance family"):
        make_instance("paris", 0)
    with pytest.raises(ValueError, match="seed"):
        make_instance("berlin", -1)


@pytest.mark.slow
def test_detroit_like_instances_use_its_thresholds():
    cfg = make_instance("detroit3gpp", TEST_SEEDS[0])
    assert cfg.sinr_min_db in FAMILIES["detroit3gpp"].thresholds_db and cfg.step_m == 320.0


def test_fleet_instances_are_deterministic_valid_and_differ_from_single_taxi_ones():
    from uamfleet.instances import FLEET_SETTINGS, make_fleet_instance
    from uamfleet.paths import DistanceFields

    assert FLEET_SETTINGS["4x24"] == (4, 24) and FLEET_SETTINGS["8x48"] == (8, 48)
    seeds = split_seeds("test", 3)
    first = [make_fleet_instance("berlin", s, 4, 24) for s in seeds]
    assert [_summary(c) for c in first] == [_summary(make_fleet_instance("berlin", s, 4, 24)) for s in seeds]
    assert len({_summary(c) for c in first}) == len(seeds)
    assert make_fleet_instance("berlin", seeds[0], 4, 24).requests != make_instance("berlin", seeds[0]).requests
    fam = FAMILIES["berlin"]
    for cfg in first:
        assert cfg.num_taxis == 4 and len(cfg.requests) == 24 and len(set(cfg.starts_m)) == 4
        assert cfg.sinr_min_db in fam.thresholds_db
        releases = [r.release_step for r in cfg.requests]
        assert releases == sorted(releases) and max(releases) * cfg.slot_s < 600.0
        world = World(cfg)
        stops = np.array([p for r in cfg.requests for p in (r.origin_m, r.destination_m)])
        assert world.point_feasible(stops).all() and world.point_feasible(np.array(cfg.starts_m)).all()
        assert np.isfinite(DistanceFields(world).remaining_m(np.array(cfg.starts_m[0]), stops)).all()
        assert all(np.linalg.norm(np.subtract(r.destination_m, r.origin_m)) >= fam.min_trip_m for r in cfg.requests)
    padded = make_fleet_instance("berlin", seeds[0], 4, 24, max_passengers=32)
    assert padded.num_passengers == 32 and _summary(padded) == _summary(first[0])
    ports = make_fleet_instance("berlin", seeds[0], 2, 12, num_vertiports=4)
    assert len({p for r in ports.requests for p in (r.origin_m, r.destination_m)}) <= 4
    with pytest.raises(ValueError, match="num_vertiports"):
        make_fleet_instance("berlin", seeds[0], 2, 12, num_vertiports=1)
