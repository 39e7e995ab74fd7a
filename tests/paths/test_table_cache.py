"""Filled distance tables are kept on disk and loaded whole by a later table of the same graph, never by another."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from tests.conftest import small_config
from uamfleet.paths.distance_table import CACHE_FORMAT, DistanceTable, table_graph
from uamfleet.sim.world import World

WALLED = """
.....
..#..
..#..
.....
.....
"""


def _table(threshold: float) -> DistanceTable:
    world = World(small_config(WALLED, sinr_min_db=threshold))
    return DistanceTable(table_graph(world), world.blocks.block_m, world.blocks.shape)


def test_a_filled_table_is_loaded_by_the_next_one(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("UAMFLEET_CACHE", str(tmp_path))
    first = _table(-3.0)
    assert not first.filled.any()
    first.fill()
    files = list(tmp_path.glob("table*"))
    assert [f.name for f in files] == [f"table{CACHE_FORMAT}-{first.cache_key}.npz"]
    second = _table(-3.0)
    assert second.filled.all()
    np.testing.assert_array_equal(second.distance_m, first.distance_m)
    # another threshold makes another graph (the wall is flyable at -12 dB): its own key, nothing loaded
    other = _table(-12.0)
    assert other.cache_key != first.cache_key and not other.filled.any()


def test_a_damaged_file_is_ignored(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("UAMFLEET_CACHE", str(tmp_path))
    table = _table(-3.0)
    (tmp_path / f"table{CACHE_FORMAT}-{table.cache_key}.npz").write_bytes(b"not a table")
    with pytest.warns(RuntimeWarning, match="cannot be read"):
        assert not _table(-3.0).filled.any()


def test_off_writes_nothing(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setenv("UAMFLEET_CACHE", "off")
    monkeypatch.setenv("HOME", str(tmp_path))
    _table(-3.0).fill()
    assert not any(tmp_path.rglob("*.np[yz]"))
