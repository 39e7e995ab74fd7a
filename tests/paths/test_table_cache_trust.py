"""A cached distance table is an input: a file of ``inf``, of zeros, truncated, of another key or with a wrong
checksum is deleted with a warning and the rows are computed again, so every distance (and every flight that
reads them) is what a fresh table gives. Old cache files (format 1, ``table-*.npy``) are left alone, so code of
either format can share one cache folder."""

from __future__ import annotations

import hashlib
import io
import warnings
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from tests.conftest import small_config
from uamfleet.paths.distance_table import DistanceTable, table_graph
from uamfleet.sim.world import World

# Two flyable regions (the '#' column cuts the map), so a plausible table has both finite and infinite entries.
SPLIT = """
..#..
..#..
..#..
..#..
..#..
"""
POINTS = np.array([[50.0, 50.0], [150.0, 420.0], [380.0, 60.0], [460.0, 460.0]])
STOPS = np.array([[60.0, 440.0], [450.0, 250.0], [140.0, 150.0], [30.0, 30.0]])


def make_table() -> DistanceTable:
    world = World(small_config(SPLIT, sinr_min_db=-3.0))
    return DistanceTable(table_graph(world), world.blocks.block_m, world.blocks.shape)


def fresh_distances() -> np.ndarray:
    table = make_table()
    assert not table.filled.any()
    return table.fill().distance(POINTS[:, None], STOPS[None])  # [4, 4]


def write(path: Path, table: np.ndarray, key: str, checksum: str | None = None) -> None:
    buffer = io.BytesIO()
    checksum = checksum or hashlib.sha256(table.tobytes()).hexdigest()
    np.savez(buffer, distance_m=table, key=np.array(key), sha256=np.array(checksum))
    path.write_bytes(buffer.getvalue())


def with_entries(fill: float) -> Callable[[Path, DistanceTable], None]:
    def damage(path: Path, good: DistanceTable) -> None:
        write(path, np.full_like(good.distance_m, fill), good.cache_key)

    return damage


def truncated(path: Path, good: DistanceTable) -> None:
    path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])


def wrong_checksum(path: Path, good: DistanceTable) -> None:
    write(path, good.distance_m * 0.5, good.cache_key, hashlib.sha256(good.distance_m.tobytes()).hexdigest())


def other_key(path: Path, good: DistanceTable) -> None:
    write(path, good.distance_m, "0" * 40)


def asymmetric(path: Path, good: DistanceTable) -> None:
    table = good.distance_m.copy()
    i, j = np.argwhere(np.isfinite(table) & (table > 0))[3]
    table[i, j] += 250.0
    write(path, table, good.cache_key)


def connected_made_unreachable(path: Path, good: DistanceTable) -> None:
    table = good.distance_m.copy()
    i, j = np.argwhere(np.isfinite(table) & (table > 0))[3]
    table[i, j] = table[j, i] = np.inf
    write(path, table, good.cache_key)


DAMAGES = {
    "inf": (with_entries(np.inf), "finite where the blocks are not connected, or infinite where they are"),
    "zeros": (with_entries(0.0), "finite where the blocks are not connected"),
    "truncated": (truncated, "cannot be read"),
    "wrong checksum": (wrong_checksum, "do not match their SHA-256 checksum"),
    "other key": (other_key, "holds the key 000000000000"),
    "asymmetric": (asymmetric, "not symmetric"),
    "a path removed": (connected_made_unreachable, "infinite where they are"),
}


@pytest.mark.parametrize("damage", list(DAMAGES))
def test_a_bad_cache_file_is_rebuilt_with_a_warning(tmp_path, monkeypatch, damage):
    monkeypatch.setenv("UAMFLEET_CACHE", str(tmp_path))
    expected = fresh_distances()  # and a good file on disk
    [path] = tmp_path.glob("table*")
    good = make_table()
    assert good.filled.all()  # the good file is used as it is, without a warning
    damaging, message = DAMAGES[damage]
    damaging(path, good)
    with pytest.warns(RuntimeWarning, match=message):
        table = make_table()
    assert not table.filled.any() and not path.exists()  # not used, deleted
    np.testing.assert_array_equal(table.distance(POINTS[:, None], STOPS[None]), expected)
    table.fill()  # rebuilt: the next table loads it without a warning
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert make_table().filled.all()


def test_zeros_with_the_right_unreachable_pattern_are_refused(tmp_path, monkeypatch):
    """Zeros where the blocks are connected would make far stops look close: shorter than the straight line."""
    monkeypatch.setenv("UAMFLEET_CACHE", str(tmp_path))
    fresh_distances()
    [path] = tmp_path.glob("table*")
    good = make_table()
    finite = np.isfinite(good.distance_m)
    write(path, np.where(finite, np.float32(0.0), good.distance_m).astype(np.float32), good.cache_key)
    with pytest.warns(RuntimeWarning, match="its diagonal is not twice|shorter than the straight line"):
        assert not make_table().filled.any()


def test_an_old_format_file_is_left_alone(tmp_path, monkeypatch):
    monkeypatch.setenv("UAMFLEET_CACHE", str(tmp_path))
    old = tmp_path / f"table-{make_table().cache_key}.npy"
    np.save(old, np.zeros((25, 25), np.float32))  # what format 1 would trust
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        assert not make_table().filled.any()
    assert old.exists()


def stop_paths(cfg) -> np.ndarray:
    """The stop features a learned policy reads (they come from the distance table) after a reset."""
    from uamfleet.env.vector_env import VectorEnv

    obs, _ = VectorEnv(cfg, num_envs=1).reset(seed=3)
    return obs["stop_paths"]


@pytest.mark.parametrize("damage", ["inf", "zeros", "truncated", "wrong checksum"])
def test_what_a_policy_reads_is_unchanged_over_a_damaged_cache(tmp_path, monkeypatch, damage):
    """Issue 22's case (a table of ``inf`` made the Berlin policy deliver nobody) on a small map: the stop
    features a policy reads are those of a fresh table, whatever the cache file holds."""
    from uamfleet.paths import distance_table

    cfg = small_config(SPLIT, starts_m=((50.0, 50.0), (450.0, 450.0)), stop_features=True)
    monkeypatch.setenv("UAMFLEET_CACHE", str(tmp_path))
    clean = stop_paths(cfg)
    world = World(cfg)
    good = DistanceTable(table_graph(world), world.blocks.block_m, world.blocks.shape).fill()
    [path] = tmp_path.glob("table*")
    DAMAGES[damage][0](path, good)
    distance_table._TABLES.clear()  # as in a new process: the next env reads the disk cache
    with pytest.warns(RuntimeWarning, match="is not used"):
        np.testing.assert_array_equal(stop_paths(cfg), clean)
    # the features do read the table: had the file been trusted, they would differ
    distance_table._TABLES.clear()
    trusted = distance_table.table_for(World(cfg))  # what the old loader did with the file's entries
    trusted.distance_m[:], trusted.filled[:] = (np.inf if damage == "inf" else 0.0), True
    assert not np.array_equal(stop_paths(cfg), clean)
