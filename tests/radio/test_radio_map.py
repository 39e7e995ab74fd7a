"""RadioMap / BlockMap behaviour on small drawn rasters with hand-computed expectations."""

from __future__ import annotations

import math
import pickle

import numpy as np
import pytest

from uamfleet.radio import BaseStation, BlockMap, RadioMap

NAN = np.nan


def drawn_4x4() -> RadioMap:
    # [ix, iy]: row = x index, column = y index. Centres at 0, 10, 20, 30 m; side = 3 * 10 = 30 m.
    return RadioMap(
        np.array(
            [
                [1.0, 2.0, 3.0, 4.0],
                [5.0, NAN, 7.0, 8.0],
                [-9.0, 10.0, 11.0, 12.0],
                [13.0, 14.0, 15.0, 16.0],
            ]
        ),
        resolution_m=10.0,
        name="drawn",
    )


def test_defaults_and_description() -> None:
    radio = drawn_4x4()
    assert radio.shape == (4, 4)
    assert radio.side_m == 30.0  # min((4 - 1) * 10) over both axes
    assert radio.origin_m == (0.0, 0.0)
    assert radio.label == "drawn"
    est = RadioMap(np.zeros((3, 5)), resolution_m=2.0, name="x", is_estimate=True)
    assert est.side_m == 4.0
    assert est.label == "x (estimate)"
    assert "(estimate)" in repr(est)


def test_array_is_private_and_read_only() -> None:
    raw = np.zeros((3, 3))
    radio = RadioMap(raw, resolution_m=1.0)
    raw[0, 0] = 5.0
    assert radio.sinr_db[0, 0] == 0.0
    assert radio.sinr_db.dtype == np.float64
    with pytest.raises(ValueError):
        radio.sinr_db[0, 0] = 1.0


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"sinr_db": np.zeros(4), "resolution_m": 1.0}, "2-D"),
        ({"sinr_db": np.zeros((2, 2)), "resolution_m": 0.0}, "resolution_m"),
        ({"sinr_db": np.zeros((2, 2)), "resolution_m": -1.0}, "resolution_m"),
        ({"sinr_db": np.zeros((1, 5)), "resolution_m": 1.0}, "side_m"),
        ({"sinr_db": np.zeros((2, 2)), "resolution_m": 1.0, "side_m": -3.0}, "side_m"),
        ({"sinr_db": np.full((2, 2), np.inf), "resolution_m": 1.0}, "inf"),
        ({"sinr_db": np.zeros((2, 2)), "resolution_m": 1.0, "origin_m": (0.0,)}, "origin_m"),
    ],
)
def test_bad_construction_raises(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        RadioMap(**kwargs)


def test_base_station_checks() -> None:
    assert BaseStation(1.0, 2.0, 20.0).power_dbm == 40.0
    with pytest.raises(ValueError, match="loading"):
        BaseStation(0.0, 0.0, 20.0, loading=1.5)
    with pytest.raises(ValueError, match="x_m"):
        BaseStation(math.nan, 0.0, 20.0)


def test_base_stations_must_be_base_station_objects() -> None:
    stations = (BaseStation(1.0, 2.0, 20.0), (3.0, 4.0, 20.0))
    with pytest.raises(ValueError, match=r"^base_stations must hold BaseStation objects, got tuple$"):
        RadioMap(np.zeros((2, 2)), resolution_m=1.0, base_stations=stations)  # type: ignore[arg-type]
    radio = RadioMap(np.zeros((2, 2)), resolution_m=1.0, base_stations=[BaseStation(1.0, 2.0, 20.0)])  # type: ignore[arg-type]
    assert radio.base_stations == (BaseStation(1.0, 2.0, 20.0),)


def test_sinr_at_nearest_cell_and_boundaries() -> None:
    radio = drawn_4x4()
    # Exactly half-way between centres 0 and 10 goes to the higher cell.
    pts = np.array(
        [
            [0.0, 0.0],  # cell (0, 0) = 1
            [4.999, 0.0],  # still (0, 0)
            [5.0, 0.0],  # (1, 0) = 5
            [14.9, 25.0],  # (1, 3) = 8
            [-5.0, -5.0],  # half a cell outside the first centre: still (0, 0)
            [-5.001, 0.0],  # outside
            [34.99, 34.99],  # (3, 3) = 16
            [35.0, 0.0],  # outside (the raster covers [-5, 35))
            [10.0, 10.0],  # N.C.
            [np.nan, 0.0],  # non-finite: outside
        ]
    )
    expected = np.array([1.0, 1.0, 5.0, 8.0, 1.0, NAN, 16.0, NAN, NAN, NAN])
    np.testing.assert_array_equal(radio.sinr_at(pts), expected)
    ix, iy, inside = radio.cell_index(pts)
    np.testing.assert_array_equal(inside, [1, 1, 1, 1, 1, 0, 1, 0, 1, 0])
    np.testing.assert_array_equal(ix[inside], [0, 0, 1, 1, 0, 3, 1])
    np.testing.assert_array_equal(iy[inside], [0, 0, 0, 3, 0, 3, 1])
    assert radio.sinr_db[ix, iy].shape == (10,)  # clipped indices always index the array


def test_origin_offset_and_shapes() -> None:
    radio = RadioMap(np.arange(6.0).reshape(3, 2), resolution_m=2.0, origin_m=(100.0, 50.0), side_m=4.0)
    assert radio.sinr_at([100.0, 50.0]) == 0.0
    assert radio.sinr_at([104.0, 52.0]) == 5.0
    assert radio.sinr_at(np.zeros((2, 3, 2))).shape == (2, 3)
    assert np.isnan(radio.sinr_at([0.0, 0.0]))
    with pytest.raises(ValueError, match=r"\[\.\.\., 2\]"):
        radio.sinr_at([1.0, 2.0, 3.0])


def test_feasible() -> None:
    radio = drawn_4x4()
    pts = np.array([[0.0, 0.0], [0.0, 10.0], [10.0, 10.0], [-50.0, 0.0], [20.0, 0.0]])
    np.testing.assert_array_equal(radio.feasible(pts, 2.0), [False, True, False, False, False])
    np.testing.assert_array_equal(radio.feasible(pts, -9.0), [True, True, False, False, True])
    with pytest.raises(ValueError, match="threshold"):
        radio.feasible(pts, math.nan)


def test_block_map_global_min_by_hand() -> None:
    radio = drawn_4x4()
    # side 30, block 20 -> 2 blocks per axis: x in [0, 20) holds centres 0, 10; [20, 30) holds 20 (30 is
    # outside the square). N.C. (cell [1, 1]) becomes the global minimum -9.
    blocks = radio.block_map(20.0)
    assert isinstance(blocks, BlockMap)
    assert blocks.shape == (2, 2)
    expected = np.array(
        [
            [(1 + 2 + 5 - 9) / 4, (3 + 7) / 2],
            [(-9 + 10) / 2, 11.0],
        ]
    )
    np.testing.assert_allclose(blocks.sinr_db, expected, rtol=0, atol=1e-12)
    assert blocks.block_m == 20.0 and blocks.side_m == 30.0


def test_block_map_nanmean_by_hand() -> None:
    blocks = drawn_4x4().block_map(20.0, nc_rule="nanmean")
    expected = np.array([[(1 + 2 + 5) / 3, (3 + 7) / 2], [(-9 + 10) / 2, 11.0]])
    np.testing.assert_allclose(blocks.sinr_db, expected, rtol=0, atol=1e-12)
    # A block whose only point is N.C. is NaN under nanmean, the global minimum under global_min.
    radio = RadioMap(np.array([[NAN, 1.0], [2.0, 3.0]]), resolution_m=10.0, side_m=20.0)
    np.testing.assert_array_equal(radio.block_map(10.0, "nanmean").sinr_db, [[NAN, 1.0], [2.0, 3.0]])
    np.testing.assert_array_equal(radio.block_map(10.0).sinr_db, [[1.0, 1.0], [2.0, 3.0]])


def test_block_map_single_cells_and_cache() -> None:
    radio = drawn_4x4()
    blocks = radio.block_map(10.0)
    assert blocks.shape == (3, 3)  # ceil(30 / 10)
    np.testing.assert_array_equal(blocks.sinr_db, np.where(np.isnan(radio.sinr_db), -9.0, radio.sinr_db)[:3, :3])
    assert radio.block_map(10.0) is blocks
    assert radio.block_map(10.0, "nanmean") is not blocks
    with pytest.raises(ValueError):
        blocks.sinr_db[0, 0] = 0.0


def test_block_map_bad_rule() -> None:
    with pytest.raises(ValueError, match=r"'median'.*global_min.*nanmean"):
        drawn_4x4().block_map(20.0, nc_rule="median")
    with pytest.raises(ValueError, match="block_m"):
        drawn_4x4().block_map(0.0)


def test_block_map_queries() -> None:
    blocks = drawn_4x4().block_map(20.0)
    pts = np.array([[0.0, 0.0], [19.99, 0.0], [20.0, 0.0], [30.0, 30.0], [30.01, 0.0], [-0.01, 5.0]])
    bx, by = blocks.block_index(pts)
    np.testing.assert_array_equal(bx, [0, 0, 1, 1, 1, 0])  # clipped: x = side_m and beyond -> last block
    np.testing.assert_array_equal(by, [0, 0, 0, 1, 0, 0])
    np.testing.assert_array_equal(blocks.sinr_at(pts), [-0.25, -0.25, 0.5, 11.0, NAN, NAN])
    np.testing.assert_array_equal(blocks.feasible(pts, 0.0), [False, False, True, True, False, False])


def uniform_with_bad_cell() -> RadioMap:
    sinr = np.zeros((10, 10))
    sinr[5, 5] = -20.0
    return RadioMap(sinr, resolution_m=10.0)


def test_segment_through_vs_beside_a_bad_cell() -> None:
    radio = uniform_with_bad_cell()
    # y = 50 runs through cell (5, 5); y = 60 and y = 44.9 run beside it.
    p0 = np.array([[0.0, 50.0], [0.0, 60.0], [0.0, 44.9], [50.0, 0.0], [90.0, 90.0]])
    p1 = np.array([[90.0, 50.0], [90.0, 60.0], [90.0, 44.9], [50.0, 90.0], [0.0, 0.0]])
    np.testing.assert_array_equal(radio.segment_min_sinr(p0, p1), [-20.0, 0.0, 0.0, -20.0, -20.0])
    np.testing.assert_array_equal(radio.segment_feasible(p0, p1, -10.0), [False, True, True, False, False])
    # The endpoints alone are fine: only the path crosses the bad cell.
    assert radio.feasible(p0[0], -10.0) and radio.feasible(p1[0], -10.0)


def test_segment_outside_or_nc_is_minus_inf() -> None:
    radio = drawn_4x4()
    got = radio.segment_min_sinr([[0.0, 0.0], [0.0, 0.0], [0.0, 30.0]], [[0.0, 50.0], [20.0, 20.0], [0.0, 20.0]])
    # leaves the raster / crosses N.C. cell (1, 1) / stays on x = 0: min(4, 3) = 3
    np.testing.assert_array_equal(got, [-np.inf, -np.inf, 3.0])


def test_segment_broadcast_and_degenerate() -> None:
    radio = uniform_with_bad_cell()
    p1 = np.array([[50.0, 50.0], [0.0, 90.0], [20.0, 20.0]])
    assert radio.segment_min_sinr([0.0, 0.0], p1).shape == (3,)
    assert radio.segment_min_sinr([50.0, 50.0], [50.0, 50.0]) == -20.0  # zero length: the point itself
    # Batch composition does not change a segment's samples.
    alone = radio.segment_min_sinr([0.0, 48.0], [30.0, 55.0])
    batched = radio.segment_min_sinr([[0.0, 48.0], [0.0, 0.0]], [[30.0, 55.0], [90.0, 90.0]])
    assert batched[0] == alone


def test_segment_samples_cover_each_cell_on_an_axis() -> None:
    # 25 m at 10 m resolution is sampled at 0, 8.33, 16.67, 25 -> cells 0, 1, 2, 3 (25 rounds up).
    radio = RadioMap(np.array([[0.0], [1.0], [2.0], [3.0], [4.0]]) * np.ones((1, 2)), resolution_m=10.0)
    assert radio.segment_min_sinr([0.0, 0.0], [25.0, 0.0]) == 0.0
    assert radio.segment_min_sinr([25.0, 0.0], [40.0, 0.0]) == 3.0


@pytest.mark.parametrize(("step_m", "num_headings"), [(100.0, 16), (37.0, 16), (23.0, 7), (5.0, 4)])
def test_heading_table_equals_pointwise_segments(step_m: float, num_headings: int) -> None:
    rng = np.random.default_rng(7)
    sinr = rng.normal(0.0, 5.0, size=(23, 19))
    sinr[rng.random(sinr.shape) < 0.05] = np.nan
    radio = RadioMap(sinr, resolution_m=10.0)
    table = radio.heading_segment_min_sinr(step_m, num_headings)
    assert table.shape == (num_headings, 23, 19)
    ix = rng.integers(0, 23, size=60)
    iy = rng.integers(0, 19, size=60)
    p0 = np.stack([ix * 10.0, iy * 10.0], axis=-1)
    for k in range(num_headings):
        theta = 2 * math.pi * k / num_headings
        p1 = p0 + step_m * np.array([math.cos(theta), math.sin(theta)])
        np.testing.assert_array_equal(table[k, ix, iy], radio.segment_min_sinr(p0, p1), err_msg=f"heading {k}")


def test_heading_table_cached_read_only_and_checked() -> None:
    radio = uniform_with_bad_cell()
    table = radio.heading_segment_min_sinr(20.0, 8)
    assert radio.heading_segment_min_sinr(20.0, 8) is table
    with pytest.raises(ValueError):
        table[0, 0, 0] = 1.0
    # Heading 0 (east) from (3, 5) reaches (5, 5); from (6, 5) it does not.
    assert table[0, 3, 5] == -20.0 and table[0, 6, 5] == 0.0
    # Heading 2 (north) from (5, 3) reaches it; the last row cannot go north at all.
    assert table[2, 5, 3] == -20.0 and table[2, 0, 9] == -np.inf
    with pytest.raises(ValueError, match="step_m"):
        radio.heading_segment_min_sinr(0.0)
    with pytest.raises(ValueError, match="num_headings"):
        radio.heading_segment_min_sinr(10.0, 0)


def test_pickle_round_trip_stays_read_only() -> None:
    radio = drawn_4x4()
    blocks = radio.block_map(20.0)
    copy = pickle.loads(pickle.dumps(radio))
    np.testing.assert_array_equal(copy.sinr_db, radio.sinr_db)
    assert copy.side_m == radio.side_m and copy.name == "drawn"
    with pytest.raises(ValueError):
        copy.sinr_db[0, 0] = 0.0
    np.testing.assert_array_equal(copy.block_map(20.0).sinr_db, blocks.sinr_db)  # rebuilt, not shared
    block_copy = pickle.loads(pickle.dumps(blocks))
    with pytest.raises(ValueError):
        block_copy.sinr_db[0, 0] = 0.0
