"""The compiled bucket Dijkstra against scipy's Dijkstra, bit for bit, and its refusals."""

from __future__ import annotations

import functools

import numpy as np
import pytest
import scipy.sparse as sp
from scipy.sparse import csgraph

from uamfleet.paths.bucket_dijkstra import _bucket_rows, lattice_distances, lattice_of
from uamfleet.paths.grid_graph import GridGraph, UnreachableStopError


def cluttered_graph(connectivity: int, seed: int) -> GridGraph:
    """A 40 x 37 raster of 7.5 m cells, about a third of them blocked at random (walls, pockets, islands)."""
    rng = np.random.default_rng(seed)
    return GridGraph(rng.random((40, 37)) > 0.35, 7.5, connectivity=connectivity, label="cluttered")


@pytest.mark.parametrize("connectivity", [8, 16])
@pytest.mark.parametrize("seed", [0, 1])
def test_distances_equal_scipy_dijkstra_bit_for_bit(connectivity: int, seed: int) -> None:
    graph = cluttered_graph(connectivity, seed)
    nodes = np.flatnonzero(graph.feasible)
    sources = nodes[:: max(nodes.size // 25, 1)]
    expected = csgraph.dijkstra(graph.adjacency, directed=True, indices=sources)
    got = lattice_distances(lattice_of(graph.adjacency), sources, np.arange(graph.feasible.size))
    assert np.isinf(expected).any() and np.isfinite(expected).any()  # the clutter walls some cells off
    np.testing.assert_array_equal(got, expected)


def test_a_path_round_a_corner_by_hand() -> None:
    # 3 x 3 cells of 10 m, the centre blocked, 8-connected: a diagonal move may not cut the blocked cell's
    # corner, so from (0, 0) to (2, 2) the path runs along the edge: 4 straight moves, 40 m.
    feasible = np.ones((3, 3), bool)
    feasible[1, 1] = False
    graph = GridGraph(feasible, 10.0, connectivity=8)
    d = lattice_distances(lattice_of(graph.adjacency), [0], [8, 1, 4])
    assert d.tolist() == [[40.0, 10.0, np.inf]]


def test_a_bucket_overflow_redoes_the_row_with_more_room() -> None:
    graph = cluttered_graph(16, 2)
    lattice = lattice_of(graph.adjacency)
    sources, targets = np.flatnonzero(graph.feasible)[:3], np.arange(graph.feasible.size)
    out = np.empty((3, targets.size))
    # Room for 2 nodes per bucket: the first row's wavefront overflows it, and the call says where it stopped.
    assert _bucket_rows(lattice.offsets, lattice.weights, lattice.moves, sources, targets, 2, 0, out) == 0
    expected = csgraph.dijkstra(graph.adjacency, directed=True, indices=sources)
    np.testing.assert_array_equal(lattice_distances(lattice, sources, targets), expected)


def test_a_graph_without_edges_reaches_only_its_sources() -> None:
    graph = GridGraph(np.eye(4, dtype=bool), 10.0, connectivity=8)  # diagonal cells: corners cut, no edges
    assert graph.adjacency.nnz == 0
    d = lattice_distances(lattice_of(graph.adjacency), [0, 5], [0, 5, 15])
    assert d.tolist() == [[0.0, np.inf, np.inf], [np.inf, 0.0, np.inf]]


def test_a_graph_that_is_not_a_lattice_is_refused() -> None:
    uneven = sp.csr_matrix(np.array([[0, 1.0, 0], [1.0, 0, 1.0], [0, 2.0, 0]]))  # offset +-1 weighs 1 and 2
    with pytest.raises(ValueError, match="one finite weight > 0 per move"):
        lattice_of(uneven)
    rng = np.random.default_rng(0)
    scattered = sp.random(200, 200, density=0.3, random_state=rng, format="csr")  # ~200 distinct offsets
    with pytest.raises(ValueError, match="at most 32 distinct moves"):
        lattice_of(scattered)


@pytest.mark.parametrize("connectivity", [8, 16])
def test_the_graphs_distance_fields_equal_scipy_dijkstra_bit_for_bit(connectivity: int) -> None:
    """``GridGraph.distances_from`` (the step planners' fields) is compiled: scipy's numbers from the same node."""
    graph = cluttered_graph(connectivity, 3)
    for node in np.flatnonzero(graph.feasible)[::97]:
        point = graph.node_xy(node)
        expected = csgraph.dijkstra(graph.adjacency, directed=True, indices=int(node)).reshape(graph.shape)
        got = graph.distances_from(point)
        assert got.shape == graph.shape and got[np.unravel_index(node, graph.shape)] == 0.0
        np.testing.assert_array_equal(got, expected)


@pytest.mark.parametrize("connectivity", [8, 16])
def test_the_graphs_own_lattice_is_its_matrix_as_moves(connectivity: int) -> None:
    """The lattice ``GridGraph`` builds beside its matrix gives the distances of the one read back from the matrix
    (``lattice_of``); on a raster too narrow for distinct moves it has none, and its fields are scipy's."""
    graph = cluttered_graph(connectivity, 4)
    assert graph.lattice is not None
    sources, targets = np.flatnonzero(graph.feasible)[::50], np.arange(graph.feasible.size)
    np.testing.assert_array_equal(
        lattice_distances(graph.lattice, sources, targets),
        lattice_distances(lattice_of(graph.adjacency), sources, targets),
    )
    narrow = GridGraph(np.ones((6, 3), bool), 10.0, connectivity=connectivity)
    assert narrow.lattice is None
    expected = csgraph.dijkstra(narrow.adjacency, directed=True, indices=4).reshape(narrow.shape)
    np.testing.assert_array_equal(narrow.distances_from(narrow.node_xy(4)), expected)


@pytest.mark.parametrize("connectivity", [8, 16])
def test_stop_distances_are_the_shortest_paths_distances_bit_for_bit(connectivity: int) -> None:
    """``GridGraph.stop_distances`` (compiled, no paths) against ``shortest_paths(...).distance_m`` (scipy), stops
    off the cell centres so the snaps count; and the same refusal for a stop that stop 0 does not reach."""
    graph = cluttered_graph(connectivity, 5)
    rng = np.random.default_rng(5)
    nodes = np.flatnonzero(graph.feasible)
    reach = csgraph.dijkstra(graph.adjacency, directed=True, indices=int(nodes[0]))
    joined = nodes[np.isfinite(reach[nodes])]
    stops = graph.node_xy(rng.choice(joined, size=7, replace=False)) + rng.uniform(-2.0, 2.0, size=(7, 2))
    expected = graph.shortest_paths(stops).distance_m
    np.testing.assert_array_equal(graph.stop_distances(stops), expected)
    # read off each stop's whole field (DistanceFields' cache) instead of Dijkstras between the stops: the same
    np.testing.assert_array_equal(graph.stop_distances(stops, field_of=graph.distances_from), expected)
    walled = nodes[~np.isfinite(reach[nodes])][0]
    cut_off = np.vstack([stops[:2], graph.node_xy(walled)[None]])
    from_fields = functools.partial(graph.stop_distances, field_of=graph.distances_from)
    for call in (graph.stop_distances, graph.shortest_paths, from_fields):
        with pytest.raises(UnreachableStopError, match=r"'stop 2' .* is walled off from stop 'stop 0'"):
            call(cut_off)
