"""DistanceTable: entries against an independent shortest path (Bellman-Ford) and by hand round a wall, the
lookup's interpolation and unreachable pairs, rows on demand, and its error against DistanceFields on Berlin."""

from __future__ import annotations

import math

import numpy as np
import pytest
from numba import njit
from scipy.sparse import csgraph

import uamfleet
from uamfleet.paths import DistanceFields, DistanceTable, graph_for, table_for
from uamfleet.paths import distance_table as dt
from uamfleet.paths.distance_table import table_graph
from uamfleet.paths.grid_graph import GridGraph
from uamfleet.sim.world import World

RES, BLOCK = 25.0, 100.0


def walled_graph() -> GridGraph:
    """A 600 m square of 25 m cells (centres 0, 25, ..., 575); a wall of blocks x in [300, 400), y < 500."""
    centres = np.arange(int(600 / RES)) * RES
    x, y = np.meshgrid(centres, centres, indexing="ij")
    feasible = ~((x >= 300) & (x < 400) & (y < 500))
    return GridGraph(feasible, RES, label="walled")


def test_entries_match_bellman_ford_between_all_block_centres() -> None:
    graph = walled_graph()
    table = DistanceTable(graph, BLOCK, (6, 6)).fill()
    # Block centres (bx + 0.5) * 100 are cell centres here: no gaps, the entries are lattice distances.
    ok = table.nodes >= 0
    assert ok.sum() == 36 - 5 and np.all(table.gap_m[ok] == 0.0)  # the 5 wall blocks have no flyable centre
    nodes = table.nodes[ok]
    independent = csgraph.shortest_path(graph.adjacency, method="BF", directed=True, indices=nodes)[:, nodes]
    np.testing.assert_allclose(table.distance_m[np.ix_(ok, ok)], independent, rtol=1e-6)
    assert np.all(np.isinf(table.distance_m[~ok])) and np.all(np.isinf(table.distance_m[:, ~ok]))


def test_the_path_goes_round_the_wall_where_the_straight_line_crosses_it() -> None:
    table = DistanceTable(walled_graph(), BLOCK, (6, 6))
    a, b = np.array([150.0, 150.0]), np.array([550.0, 150.0])  # 400 m apart, the wall between them
    d = float(table.distance(a, b))
    # The wall cells' squares cover x in [287.5, 387.5], y < 487.5 and no edge may touch them: any path is at
    # least |a - (287.5, 487.5)| + 100 + |(387.5, 487.5) - b|. Straight legs through the cell centres
    # (275, 500), (400, 500) are a feasible route; the 16-connected lattice is within 1 / cos(13.28 deg) of it.
    lower = 2 * math.hypot(137.5, 337.5) + 100
    upper = (2 * math.hypot(125, 350) + 125) / math.cos(math.atan(0.5) / 2)
    assert lower <= d <= upper and d > 2 * 400


def test_lookup_interpolates_bilinearly_and_never_undercuts_the_straight_line() -> None:
    graph = GridGraph(np.ones((24, 24), bool), RES)  # open ground
    table = DistanceTable(graph, BLOCK, (6, 6))
    stop = np.array([550.0, 550.0])  # a block centre: one table row
    # at a block centre: the entry itself
    assert table.distance([150.0, 150.0], stop) == pytest.approx(table.distance_m[5 * 6 + 5, 1 * 6 + 1])
    # half-way between centres (150, 150) and (250, 150): the mean of both entries (row: the stop's centre)
    half = 0.5 * (table.distance_m[35, 1 * 6 + 1] + table.distance_m[35, 2 * 6 + 1])
    assert table.distance([200.0, 150.0], stop) == pytest.approx(half)
    # next to the stop the interpolated entries are too coarse: the straight line is the floor
    assert table.distance([560.0, 540.0], stop) == pytest.approx(math.hypot(10, 10))
    # on open ground the lookup stays within the lattice's detour of the straight line
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 600, (200, 2))
    d, straight = table.distance(pts, stop), np.linalg.norm(pts - stop, axis=-1)
    assert np.all(d >= straight - 1e-9) and np.all(d <= 1.03 * straight + 2 * RES)


def test_pairs_without_a_path_are_unreachable() -> None:
    n = int(600 / RES)
    feasible = np.ones((n, n), bool)
    feasible[:, 8:12] = False  # a full wall y in [200, 300): two components
    table = DistanceTable(GridGraph(feasible, RES), BLOCK, (6, 6))
    assert np.isinf(table.distance([150.0, 50.0], [150.0, 450.0]))
    assert np.isfinite(table.distance([150.0, 50.0], [450.0, 150.0]))
    # a point whose upper corners are wall blocks (no node): only the joined corner pairs count, and the entry
    # (lattice 323.6 m) exceeds the straight line (319.5 m)
    stop = [450.0, 50.0]
    assert table.distance([150.0, 160.0], stop) == table.distance([150.0, 150.0], stop) == table.distance_m[4 * 6, 7]


def test_rows_on_demand_give_the_entries_of_a_full_fill() -> None:
    graph = walled_graph()
    lazy, full = DistanceTable(graph, BLOCK, (6, 6)), DistanceTable(graph, BLOCK, (6, 6)).fill()
    stop = np.array([510.0, 190.0])
    assert np.isnan(lazy.distance_m).all()
    d = lazy.distance([[60.0, 70.0], [220.0, 580.0]], stop)
    assert lazy.filled.sum() == 4  # the 4 block centres around the stop
    np.testing.assert_array_equal(d, full.distance([[60.0, 70.0], [220.0, 580.0]], stop))
    np.testing.assert_array_equal(lazy.distance_m[lazy.filled], full.distance_m[lazy.filled])


def test_bad_construction() -> None:
    with pytest.raises(ValueError, match="block_m must be a finite number > 0"):
        DistanceTable(walled_graph(), 0.0, (6, 6))
    with pytest.raises(ValueError, match=r"shape must be \(nbx, nby\)"):
        DistanceTable(walled_graph(), BLOCK, (0, 6))


def test_berlin_lookup_against_distance_fields() -> None:
    """The table approximates DistanceFields.remaining_m (10 m field from the stop). On 3,000 random pairs
    (docs/rules.md "Rewards") the error was 4.4 m on average, 33 m at p99, 52 m at most; here a smaller sample."""
    world = World(uamfleet.make_config("berlin_random"))
    table, fields = table_for(world), DistanceFields(world)
    rng = np.random.default_rng(7)
    flyable = np.argwhere(world.block_ok)
    errors = []
    for k in range(10):
        goal = (flyable[rng.integers(len(flyable))] + (0.5 if k % 2 else rng.random(2))) * BLOCK
        pts = np.minimum((flyable[rng.integers(len(flyable), size=100)] + rng.random((100, 2))) * BLOCK, world.side_m)
        exact, looked_up = fields.remaining_m(goal, pts), table.distance(pts, goal)
        both = np.isfinite(exact)
        assert np.array_equal(np.isfinite(looked_up), both)  # the same pairs are reachable
        errors.append(looked_up[both] - exact[both])
    err = np.abs(np.concatenate(errors))
    assert err.mean() <= 8.0 and err.max() <= 80.0, (err.mean(), err.max())


def _fine_world(feasibility: str) -> World:
    """10 m raster, 200 m blocks (20 cells per block side): a wall of blocks x in [200, 400), y < 400, and one
    bad raster cell at (100, 500)."""
    from conftest import small_config

    from uamfleet.config import Request
    from uamfleet.radio import RadioMap

    x, y = np.meshgrid(np.arange(60) * 10.0, np.arange(60) * 10.0, indexing="ij")
    sinr = np.where((x >= 200) & (x < 400) & (y < 400), -10.0, 0.0)
    sinr[10, 50] = -10.0
    radio = RadioMap(sinr_db=sinr, resolution_m=10.0, origin_m=(0.0, 0.0), side_m=600.0, name="fine")
    cfg = small_config(radio=radio, step_m=200.0, feasibility=feasibility, starts_m=((100.0, 100.0),),
                       requests=(Request(0, (500.0, 100.0), (500.0, 300.0)),), nc_rule="nanmean")  # fmt: skip
    return World(cfg)


@pytest.mark.parametrize("feasibility", ["endpoint_block", "segment_raster"])
def test_a_fine_raster_gets_a_coarser_table_graph(feasibility: str) -> None:
    world = _fine_world(feasibility)
    graph = table_graph(world)
    assert graph.resolution_m == pytest.approx(200.0 / 9) and graph.shape == (27, 27)
    blocked = ~graph.feasible
    # the wall: coarse cells 9..17 along x, 0..17 along y (each lies in one block)
    assert blocked[9:18, 0:18].all()
    # the lone bad raster cell matters only cell by cell: in the coarse cell (4, 22) under segment_raster
    segment = feasibility == "segment_raster"
    assert blocked.sum() == 162 + segment and blocked[4, 22] == segment
    # and the table's distance round the wall stays close to the 10 m field's: a path on the coarse graph keeps
    # half a coarse cell (11.1 m, not 5 m) off the wall, ~20 m longer round its two corners (855 m -> 886 m)
    a, b = np.array([100.0, 100.0]), np.array([500.0, 100.0])
    exact = DistanceFields(world).remaining_m(b, a[None])[0]
    looked_up = float(table_for(world).distance(a, b))
    assert exact > 2 * 400 and exact <= looked_up <= 1.05 * exact


def test_the_berlin_table_uses_the_exact_metrics_graph() -> None:
    world = World(uamfleet.make_config("berlin_random"))
    assert table_for(world).graph is graph_for(world)


def test_prepared_lookups_equal_the_plain_lookup_bit_for_bit() -> None:
    """corner_distance from prepared points is table_distance exactly: on and between block centres, beyond the
    outer centres, across a wall (unreachable corner pairs and points), towards rows not computed yet (NaN)."""
    feasible = np.ones((24, 24), bool)
    feasible[:, 8:12] = False  # a full wall y in [200, 300): two components
    table = DistanceTable(GridGraph(feasible, RES), BLOCK, (6, 6))
    table.ensure(np.array([[510.0, 190.0], [50.0, 550.0], [350.0, 420.0]]))  # some rows only: others read NaN
    rng = np.random.default_rng(4)
    grid = np.array([-30.0, 0.0, 50.0, 150.0, 250.0, 350.0, 450.0, 550.0, 600.0, 640.0])  # centres, edges, beyond
    pts = np.concatenate([rng.uniform(-50, 650, (60, 2)), rng.choice(grid, (30, 2)), [[510.0, 190.0]]])
    corners = dt.new_corners(len(pts))
    for k, (x, y) in enumerate(pts):
        prepare_corners_py(table.arrays, x, y, corners, k)
    assert set(corners.used.tolist()) == {1, 2, 4}  # on a centre, on a centre line, between centres
    got = np.array([[_corner(table.arrays, corners, i, j, *a, *b) for j, b in enumerate(pts)]
                    for i, a in enumerate(pts)])  # fmt: skip
    want = np.array([[dt.table_distance(table.arrays, *a, *b) for b in pts] for a in pts])
    assert np.isnan(want).any() and np.isinf(want).any() and np.isfinite(want).any()
    np.testing.assert_array_equal(got, want)


@njit
def prepare_corners_py(t: dt.TableArrays, x: float, y: float, c: dt.Corners, k: int) -> None:
    dt.prepare_corners(t, x, y, c, k)  # inline-only in the kernels: called from here through a compiled wrapper


@njit
def _corner(t: dt.TableArrays, c: dt.Corners, i: int, j: int, ax: float, ay: float, bx: float, by: float) -> float:
    return dt.corner_distance(t, c, i, c, j, ax, ay, bx, by)


def _remaining_by_numpy(fields: DistanceFields, goal: np.ndarray, points: np.ndarray) -> np.ndarray:
    """The look-up written out in numpy (as DistanceFields had it before it was compiled): the goal's field at
    each of the 4 cell centres around the point plus the straight line to it, the least; the straight line where
    no flyable cell reaches the goal."""
    field_m = fields.field(goal)
    if field_m is None:
        return np.linalg.norm(points - goal, axis=-1)
    radio = fields.world.radio
    res, (ox, oy) = radio.resolution_m, radio.origin_m
    fx, fy = (points[:, 0] - ox) / res, (points[:, 1] - oy) / res
    best = np.full(len(points), np.inf)
    nx, ny = field_m.shape
    for dx in (0, 1):
        for dy in (0, 1):
            ix = np.clip(np.floor(fx).astype(int) + dx, 0, nx - 1)
            iy = np.clip(np.floor(fy).astype(int) + dy, 0, ny - 1)
            centre = np.stack([ox + ix * res, oy + iy * res], axis=-1)
            best = np.minimum(best, field_m[ix, iy] + np.linalg.norm(points - centre, axis=-1))
    return best


def test_the_compiled_lookup_gives_the_numpy_one_bit_for_bit() -> None:
    """``remaining_many`` (many goals, one compiled pass) and ``remaining_m`` (one goal) against the look-up written
    out in numpy: points inside and outside the raster, a goal no flyable cell reaches (straight line), and a
    second call with other goals (the slots are looked up again, not reused)."""
    world = World(uamfleet.make_config("berlin_random"))
    fields = DistanceFields(world)
    rng = np.random.default_rng(3)
    flyable = np.argwhere(world.block_ok)
    points = rng.uniform(-300.0, world.side_m + 300.0, (2_000, 2))
    for _ in range(2):
        goals = (flyable[rng.integers(len(flyable), size=5)] + rng.random((5, 2))) * BLOCK
        goals = np.concatenate([goals, [[-1e6, -1e6]]])  # out of every flyable cell's reach
        expected = np.stack([_remaining_by_numpy(fields, g, points) for g in goals], axis=1)
        assert np.isfinite(expected[:, :5]).mean() > 0.5  # inf where no flyable centre is near the point
        np.testing.assert_array_equal(fields.remaining_many(goals, points), expected)
        for g, goal in enumerate(goals):
            np.testing.assert_array_equal(fields.remaining_m(goal, points), expected[:, g])
    np.testing.assert_array_equal(expected[:, 5], np.linalg.norm(points - goals[5], axis=1))


def test_a_small_field_pool_evicts_and_recomputes_the_same_numbers() -> None:
    """DistanceFields keeps at most ``budget_bytes`` of fields, evicting the least recently used goal. With room
    for two fields, five goals asked in turn (and again), and more goals at once than the pool holds, give the
    numbers of an unbounded cache; the stops' table read off the fields is the graph's own, bit for bit."""
    world = World(uamfleet.make_config("berlin_random"))
    roomy = DistanceFields(world)
    field_bytes = 8 * roomy.graph.shape[0] * roomy.graph.shape[1]
    small = DistanceFields(world, budget_bytes=2 * field_bytes)
    assert small.max_slots == 2
    rng = np.random.default_rng(11)
    flyable = np.argwhere(world.block_ok)
    goals = (flyable[rng.integers(len(flyable), size=5)] + rng.random((5, 2))) * BLOCK
    points = rng.uniform(0.0, world.side_m, (500, 2))
    for g in [*goals, *goals[::-1]]:
        np.testing.assert_array_equal(small.remaining_m(g, points), roomy.remaining_m(g, points))
    assert len(small._pool) == 2
    np.testing.assert_array_equal(small.remaining_many(goals, points), roomy.remaining_many(goals, points))
    np.testing.assert_array_equal(small.remaining_many(goals[:2], points), roomy.remaining_many(goals[:2], points))
    np.testing.assert_array_equal(small.stop_distances(goals), roomy.graph.stop_distances(goals))


def test_a_partial_edge_block_gets_a_node_and_a_stop_there_is_reachable() -> None:
    """A 220 m square of 20 m cells (centres 10 ... 210 m) in 100 m blocks: the third row and column of block centres
    (250 m) lie 30 m off the map. With block (1, 0) closed, a stop at (215, 50) is read through the corners (1, 0)
    and (2, 0) only: reachable only if the off-map centre (250, 50) has a node. It takes the cell nearest to the
    centre moved onto the map, (220, 50): the cell (210, 50), 40 m from the centre (snap_m 30 m + the 30 m move)."""
    centres = 10.0 + np.arange(11) * 20.0
    x, y = np.meshgrid(centres, centres, indexing="ij")
    feasible = ~((x >= 100) & (x < 200) & (y < 100))  # block (1, 0) closed
    graph = GridGraph(feasible, 20.0, origin_m=(10.0, 10.0), label="partial")
    table = DistanceTable(graph, BLOCK, (3, 3)).fill()
    edge = 2 * 3 + 0  # block (2, 0), centre (250, 50)
    assert table.nodes[edge] >= 0 and tuple(graph.node_xy(table.nodes[edge])) == (210.0, 50.0)
    assert table.gap_m[edge] == pytest.approx(40.0)
    assert table.nodes[1 * 3 + 0] < 0  # the closed block has none
    assert table.gap_m[0] == 0.0 and tuple(graph.node_xy(table.nodes[0])) == (50.0, 50.0)  # on the map: as before
    a, stop = np.array([50.0, 50.0]), np.array([215.0, 50.0])
    d = float(table.distance(a, stop))
    # the straight line crosses the closed block: the path goes round it, above y = 100
    assert math.isfinite(d) and d > math.hypot(*(stop - a)) + 20
