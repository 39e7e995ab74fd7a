"""GridGraph: lattice distances by hand, against an independent Floyd–Warshall, paths and bad input."""

from __future__ import annotations

import itertools
import math
from fractions import Fraction

import numpy as np
import pytest
from conftest import drawn_map

from uamfleet.paths.grid_graph import (
    GridGraph,
    UnreachableStopError,
    feasible_raster,
    feasible_raster_from_blocks,
)
from uamfleet.radio import RadioMap, load_radio_map

RES = 10.0
SQ2, SQ5 = math.sqrt(2.0), math.sqrt(5.0)


# -- an independent edge rule: exact segment / closed-square intersection, plain loops ------------------------
def _meets_closed_square(p: tuple[int, int], q: tuple[int, int], cell: tuple[int, int]) -> bool:
    """Liang–Barsky clip of segment p->q (cell-index coordinates) against the closed unit square at ``cell``."""
    half = Fraction(1, 2)
    t0, t1 = Fraction(0), Fraction(1)
    for start, delta, centre in ((p[0], q[0] - p[0], cell[0]), (p[1], q[1] - p[1], cell[1])):
        lo, hi = centre - half, centre + half
        if delta == 0:
            if not lo <= start <= hi:
                return False
            continue
        ta, tb = Fraction(lo - start, delta), Fraction(hi - start, delta)
        t0, t1 = max(t0, min(ta, tb)), min(t1, max(ta, tb))
        if t0 > t1:
            return False
    return True


def _edge_ok(mask: np.ndarray, p: tuple[int, int], q: tuple[int, int]) -> bool:
    nx, ny = mask.shape
    for x in range(min(p[0], q[0]), max(p[0], q[0]) + 1):
        for y in range(min(p[1], q[1]), max(p[1], q[1]) + 1):
            if _meets_closed_square(p, q, (x, y)) and not (0 <= x < nx and 0 <= y < ny and mask[x, y]):
                return False
    return True


def _moves(connectivity: int) -> list[tuple[int, int]]:
    out = []
    for a in range(-2, 3):
        for b in range(-2, 3):
            king = max(abs(a), abs(b)) == 1
            knight = abs(a) + abs(b) == 3 and a != 0 and b != 0
            if king or (connectivity == 16 and knight):
                out.append((a, b))
    return out


def _floyd_warshall(mask: np.ndarray, connectivity: int) -> list[list[float]]:
    nx, ny = mask.shape
    n = nx * ny
    d = [[0.0 if i == j else math.inf for j in range(n)] for i in range(n)]
    for x in range(nx):
        for y in range(ny):
            for a, b in _moves(connectivity):
                if 0 <= x + a < nx and 0 <= y + b < ny and _edge_ok(mask, (x, y), (x + a, y + b)):
                    d[x * ny + y][(x + a) * ny + y + b] = RES * math.hypot(a, b)
    for k in range(n):
        dk = d[k]
        for i in range(n):
            dik = d[i][k]
            if dik == math.inf:
                continue
            di = d[i]
            for j in range(n):
                if dik + dk[j] < di[j]:
                    di[j] = dik + dk[j]
    return d


def _open(nx: int, ny: int | None = None) -> np.ndarray:
    return np.ones((nx, ny or nx), dtype=bool)


def _centre(ix: int, iy: int) -> tuple[float, float]:
    return (ix * RES, iy * RES)


def _check_path(graph: GridGraph, mask: np.ndarray, poly: np.ndarray, length_m: float) -> None:
    """Interior points are feasible cell centres joined by lattice edges; the polyline length is the distance."""
    assert math.isclose(float(np.hypot(*np.diff(poly, axis=0).T).sum()), length_m, rel_tol=1e-9, abs_tol=1e-9)
    cells = np.rint(poly[1:-1] / RES).astype(int)
    np.testing.assert_allclose(cells * RES, poly[1:-1])
    assert all(mask[x, y] for x, y in cells)
    moves = set(_moves(graph.connectivity))
    for (x0, y0), (x1, y1) in itertools.pairwise(cells):
        assert (x1 - x0, y1 - y0) in moves
        assert _edge_ok(mask, (x0, y0), (x1, y1))


# -- hand-computed lattice distances ----------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("connectivity", "target", "expected_cells"),
    [
        (16, (4, 2), 2 * SQ5),  # two knight moves (2, 1)
        (16, (4, 4), 4 * SQ2),  # exact diagonal
        (16, (4, 0), 4.0),  # exact straight line
        (16, (2, 4), 2 * SQ5),
        (16, (4, 3), SQ5 + 2 * SQ2),  # (2, 1) + 2 x (1, 1) beats 2 x (2, 1) + (0, 1) = 2*sqrt5 + 1
        (8, (4, 2), 2 * SQ2 + 2),  # two diagonals + two straight
        (8, (4, 4), 4 * SQ2),
        (8, (4, 3), 3 * SQ2 + 1),
    ],
)
def test_open_grid_lattice_distance(connectivity: int, target: tuple[int, int], expected_cells: float) -> None:
    graph = GridGraph(_open(5), RES, connectivity=connectivity)
    paths = graph.shortest_paths(np.array([_centre(0, 0), _centre(*target)]))
    assert paths.distance_m[0, 1] == pytest.approx(expected_cells * RES)
    assert paths.distance_m[1, 0] == paths.distance_m[0, 1]
    assert graph.distances_from(_centre(0, 0))[target] == pytest.approx(expected_cells * RES)


@pytest.mark.parametrize(("connectivity", "bound"), [(16, 1.0275), (8, 1.0825)])
def test_open_grid_detour_bound(connectivity: int, bound: float) -> None:
    """The 16-connected lattice is <= 2.75 % longer than straight lines, the 8-connected <= 8.25 %."""
    graph = GridGraph(_open(60), RES, connectivity=connectivity)
    rng = np.random.default_rng(1)
    cells = rng.integers(0, 60, size=(60, 2))
    paths = graph.shortest_paths(cells * RES)
    euclid = np.hypot(*(cells[:, None] - cells[None]).transpose(2, 0, 1)) * RES
    far = euclid > 10 * RES
    ratio = paths.distance_m[far] / euclid[far]
    assert ratio.min() >= 1 - 1e-12
    assert ratio.max() <= bound
    # The whole field from one corner: the worst direction comes close to the bound, so the bound is the real one.
    field = graph.distances_from(_centre(0, 0))
    ix, iy = np.meshgrid(np.arange(60), np.arange(60), indexing="ij")
    r = np.hypot(ix, iy) * RES
    worst = (field[r > 0] / r[r > 0]).max()
    assert bound - 0.01 < worst <= bound


# -- against brute force ----------------------------------------------------------------------------------------
@pytest.mark.parametrize("connectivity", [8, 16])
@pytest.mark.parametrize("seed", range(5))
def test_matches_floyd_warshall_on_random_masks(connectivity: int, seed: int) -> None:
    rng = np.random.default_rng(seed)
    mask = rng.random((6, 6)) >= 0.3
    mask[0, 0] = True
    graph = GridGraph(mask, RES, connectivity=connectivity)
    expected = np.array(_floyd_warshall(mask, connectivity))
    # The edge sets agree (the module's vectorised rule against the exact geometric one) ...
    np.testing.assert_array_equal(graph.adjacency.toarray() > 0, _direct_edges(mask, connectivity))
    # ... and so do the distances from every feasible cell.
    for node in np.flatnonzero(mask):
        got = graph.distances_from(_centre(*divmod(int(node), 6))).ravel()
        np.testing.assert_allclose(got, expected[node], rtol=1e-12)


def _direct_edges(mask: np.ndarray, connectivity: int) -> np.ndarray:
    nx, ny = mask.shape
    out = np.zeros((nx * ny, nx * ny), dtype=bool)
    for x in range(nx):
        for y in range(ny):
            for a, b in _moves(connectivity):
                if 0 <= x + a < nx and 0 <= y + b < ny and _edge_ok(mask, (x, y), (x + a, y + b)):
                    out[x * ny + y, (x + a) * ny + y + b] = True
    return out


# -- paths --------------------------------------------------------------------------------------------------------
@pytest.mark.parametrize("connectivity", [8, 16])
def test_path_goes_through_the_gap_in_a_wall(connectivity: int) -> None:
    mask = _open(11)
    mask[5, :] = False
    mask[5, 8] = True  # the gap
    graph = GridGraph(mask, RES, connectivity=connectivity)
    start, goal = (13.0, 12.0), (91.0, 8.0)  # not at cell centres: snap legs are part of the path
    paths = graph.shortest_paths(np.array([start, goal]))
    poly = paths.path(0, 1)
    np.testing.assert_allclose(poly[0], start)
    np.testing.assert_allclose(poly[-1], goal)
    assert any(np.allclose(p, _centre(5, 8)) for p in poly)
    _check_path(graph, mask, poly, paths.distance_m[0, 1])
    back = paths.path(1, 0)
    _check_path(graph, mask, back, paths.distance_m[1, 0])
    # Longer than the straight line by the climb to the gap and back.
    assert paths.distance_m[0, 1] > 2 * math.hypot(50, 70)


def test_knight_move_needs_the_crossed_cells() -> None:
    mask = _open(2, 3)  # cells (0..1, 0..2)
    open_graph = GridGraph(mask, RES)
    assert open_graph.distances_from(_centre(0, 0))[1, 2] == pytest.approx(SQ5 * RES)
    mask[0, 1] = False  # one of the two cells the segment (0,0)->(1,2) crosses
    graph = GridGraph(mask, RES)
    # Now: diagonal (0,0)->(1,1) is also blocked (its corner touches (0,1)), so (1,0) -> (1,1) -> (1,2).
    assert graph.distances_from(_centre(0, 0))[1, 2] == pytest.approx(3 * RES)
    mask = _open(2, 3)
    mask[1, 1] = False  # the other crossed cell
    graph = GridGraph(mask, RES)
    # (0,0) -> (0,1) -> (0,2) -> (1,2); no knight, no diagonal around (1,1).
    assert graph.distances_from(_centre(0, 0))[1, 2] == pytest.approx(3 * RES)


def test_diagonal_never_cuts_between_two_infeasible_corners() -> None:
    mask = np.array([[True, False], [False, True]])  # a checkerboard: only corners touch
    graph = GridGraph(mask, RES, connectivity=8)
    assert math.isinf(graph.distances_from(_centre(0, 0))[1, 1])
    with pytest.raises(UnreachableStopError, match=r"'goal' at \(10\.0, 10\.0\) m is walled off"):
        graph.shortest_paths(np.array([_centre(0, 0), _centre(1, 1)]), labels=["start", "goal"])


def test_snap_within_snap_m_adds_the_leg() -> None:
    mask = _open(5)
    mask[2, 2] = False
    graph = GridGraph(mask, RES, label="ring")  # snap_m = 15 m
    stop = (21.0, 20.0)  # own cell (2, 2) is infeasible; nearest feasible centre (3, 2) is 9 m away
    paths = graph.shortest_paths(np.array([_centre(4, 2), stop]))
    assert paths.distance_m[0, 1] == pytest.approx(10.0 + 9.0)
    np.testing.assert_allclose(paths.path(0, 1), [[40.0, 20.0], [30.0, 20.0], [21.0, 20.0]])


def test_results_are_cached_and_read_only() -> None:
    graph = GridGraph(_open(5), RES)
    points = np.array([[0.0, 0.0], [40.0, 20.0]])
    first = graph.shortest_paths(points)
    assert graph.shortest_paths(points.copy()) is first
    with pytest.raises(ValueError, match="read-only"):
        first.distance_m[0, 1] = 0.0


# -- bad input ----------------------------------------------------------------------------------------------------
def test_stop_deep_in_an_infeasible_cell_is_named() -> None:
    mask = _open(7)
    mask[2:5, 2:5] = False
    graph = GridGraph(mask, RES, label="berlin @ -3 dB")
    with pytest.raises(UnreachableStopError, match=r"'P2 origin' at \(30\.0, 30\.0\) m lies in an infeasible cell"):
        graph.shortest_paths(np.array([[0.0, 0.0], [30.0, 30.0]]), labels=["start", "P2 origin"])
    with pytest.raises(UnreachableStopError, match="snap_m = 15 m"):
        graph.shortest_paths(np.array([[0.0, 0.0], [30.0, 30.0]]))
    # Outside the raster counts as infeasible too.
    with pytest.raises(UnreachableStopError, match=r"'stop 1' at \(500\.0, 0\.0\) m"):
        graph.shortest_paths(np.array([[0.0, 0.0], [500.0, 0.0]]))


def test_walled_off_stop_is_named() -> None:
    mask = _open(7)
    mask[3, :] = False
    graph = GridGraph(mask, RES)
    with pytest.raises(UnreachableStopError, match=r"'P1 destination' at \(60\.0, 10\.0\) m is walled off"):
        graph.shortest_paths(np.array([[0.0, 0.0], [10.0, 0.0], [60.0, 10.0]]), ["start", "P1", "P1 destination"])


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        (dict(feasible=np.ones((3, 3), bool), resolution_m=RES, connectivity=4), "connectivity must be 8 or 16"),
        (dict(feasible=np.ones(9, bool), resolution_m=RES), "2-D"),
        (dict(feasible=np.ones((3, 3)), resolution_m=RES), "bool mask"),
        (dict(feasible=np.zeros((3, 3), bool), resolution_m=RES), "no feasible cell"),
        (dict(feasible=np.ones((3, 3), bool), resolution_m=0.0), "resolution_m"),
    ],
)
def test_bad_construction(kwargs: dict, match: str) -> None:
    with pytest.raises(ValueError, match=match):
        GridGraph(**kwargs)


def test_bad_points() -> None:
    graph = GridGraph(_open(3), RES)
    with pytest.raises(ValueError, match=r"shape \[S, 2\]"):
        graph.shortest_paths(np.zeros((3, 3)))
    with pytest.raises(ValueError, match="finite"):
        graph.shortest_paths(np.array([[0.0, np.nan]]))
    with pytest.raises(ValueError, match="one label per stop"):
        graph.shortest_paths(np.zeros((2, 2)), labels=["only one"])


# -- feasible rasters ----------------------------------------------------------------------------------------------
def _tiny_radio() -> RadioMap:
    # 4 x 4 points at 10 m, side 30 m; 20 m blocks: block 0 holds centres 0 and 10, block 1 holds 20 and 30.
    sinr = np.full((4, 4), 1.0)
    sinr[0, 0] = -5.0  # block (0, 0) mean (-5 + 1 + 1 + 1) / 4 = -0.5
    sinr[2:, 2:] = [[-4.0, -4.0], [-4.0, np.nan]]  # block (1, 1): nanmean -4
    return RadioMap(sinr_db=sinr, resolution_m=10.0, side_m=30.0)


def test_feasible_raster_from_blocks_uses_block_means() -> None:
    radio = _tiny_radio()
    mask = feasible_raster_from_blocks(radio, radio.block_map(20.0, "nanmean"), -3.0)
    expected = np.ones((4, 4), bool)
    expected[2:, 2:] = False  # block (1, 1) at -4 dB; cell (0, 0) at -5 dB passes with its block at -0.5 dB
    np.testing.assert_array_equal(mask, expected)
    with pytest.raises(ValueError, match=r"radio\.block_map"):
        feasible_raster_from_blocks(radio, RadioMap(np.zeros((3, 3)), 10.0).block_map(10.0), -3.0)


def test_feasible_raster_uses_cells_and_side() -> None:
    radio = _tiny_radio()
    expected = np.ones((4, 4), bool)
    expected[0, 0] = False
    expected[2:, 2:] = False  # -4 dB and NaN (not computed)
    np.testing.assert_array_equal(feasible_raster(radio, -3.0), expected)
    # Centres beyond side_m are outside the operating square.
    drawn = drawn_map(".....\n.....\n.....\n.....\n.....")
    small = RadioMap(drawn.sinr_db, 100.0, origin_m=(50.0, 50.0), side_m=300.0)
    assert feasible_raster(small, -3.0).sum() == 9


def test_berlin_p4_stops_are_joined_by_feasible_paths() -> None:
    radio = load_radio_map("berlin")
    mask = feasible_raster_from_blocks(radio, radio.block_map(100.0), -3.0)
    graph = GridGraph(mask, radio.resolution_m, radio.origin_m, label="berlin @ -3 dB")
    stops = np.array(
        [(2600, 1500), (2220, 1400), (1850, 1100), (1450, 2000), (1270, 450), (650, 1000), (1700, 620)], float
    )
    paths = graph.shortest_paths(stops)
    euclid = np.hypot(*(stops[:, None] - stops[None]).transpose(2, 0, 1))
    assert (paths.distance_m >= euclid - 1e-9).all()
    np.testing.assert_array_equal(paths.distance_m, paths.distance_m.T)
    poly = paths.path(0, 4)
    cells = np.rint(poly[1:-1] / radio.resolution_m).astype(int)
    assert mask[cells[:, 0], cells[:, 1]].all()
