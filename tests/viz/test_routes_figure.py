"""The routes figure (``uamfleet-render --png``, ``uamfleet-paper-table``): every taxi's start starred in its
route's colour, the legend outside the map, stop labels inside the map and clear of each other, and the same
bytes for the same input. Checked on matplotlib's own rendered extents, not on the placement's estimates."""

from __future__ import annotations

import re
from pathlib import Path
from typing import Any

import numpy as np
import pytest
from matplotlib.colors import to_hex
from matplotlib.transforms import Bbox

import uamfleet
from uamfleet.viz.colours import TAXI_HEX
from uamfleet.viz.figures import plot_routes

# A crowded layout: stops 60 m apart (two labels would print over each other), stops on the right edge and in
# the corners (a label there would be cut off), stops in the lower left (where the legend used to sit).
ORIGINS_M = np.array(
    [[1250, 2050], [1310, 2050], [3240, 1500], [3240, 3240], [100, 100], [150, 140], [1600, 1600], [2000, 500]]
)
DESTINATIONS_M = np.array(
    [[1700, 1600], [2060, 500], [3180, 1560], [10, 3200], [3200, 20], [1640, 1660], [500, 500], [520, 520]]
)
STARTS_M = np.array([[950.0, 950.0], [1650.0, 2650.0], [2750.0, 2950.0], [2050.0, 2150.0]])


def fleet_routes() -> dict[str, np.ndarray]:
    """Four taxis, each flying from its start through two stops."""
    return {
        f"taxi {a}": np.array([start, ORIGINS_M[2 * a], DESTINATIONS_M[2 * a + 1]], dtype=float)
        for a, start in enumerate(STARTS_M)
    }


def drawn(fig: Any) -> tuple[Any, Any]:
    fig.canvas.draw()
    return fig.axes[0], fig.canvas.get_renderer()


def stop_labels(ax: Any, renderer: Any) -> dict[str, Bbox]:
    return {t.get_text(): t.get_window_extent(renderer) for t in ax.texts if re.fullmatch(r"[SD]\d+", t.get_text())}


def fleet_figure() -> Any:
    radio = uamfleet.load_radio_map("berlin")
    return plot_routes(radio, -3.0, fleet_routes(), ORIGINS_M, DESTINATIONS_M, STARTS_M, "four taxis", None)


def test_every_taxi_start_is_a_star_in_its_route_colour():
    import matplotlib

    with matplotlib.rc_context({"axes.prop_cycle": matplotlib.cycler(color=list(TAXI_HEX))}):  # as the CLI does
        ax, _ = drawn(fleet_figure())
    stars = {
        tuple(np.ravel(line.get_xydata())): to_hex(line.get_color()) for line in ax.lines if line.get_marker() == "*"
    }
    assert stars == {tuple(start): TAXI_HEX[a] for a, start in enumerate(STARTS_M)}


def test_the_legend_is_outside_the_map_and_the_stop_labels_inside_and_apart():
    fig = fleet_figure()
    ax, renderer = drawn(fig)
    frame = ax.get_window_extent(renderer)
    legend = fig.legends[0].get_window_extent(renderer)
    assert not legend.overlaps(frame), (legend, frame)
    assert [text.get_text() for text in fig.legends[0].get_texts()] == [f"taxi {a}" for a in range(4)]
    labels = stop_labels(ax, renderer)
    assert sorted(labels) == sorted([f"S{i + 1}" for i in range(8)] + [f"D{i + 1}" for i in range(8)])
    for name, box in labels.items():
        assert frame.contains(box.x0, box.y0) and frame.contains(box.x1, box.y1), f"{name} leaves the map: {box}"
    # Beside its marker: the label's nearest corner within 10 points of the stop (a side further out only where
    # the crowd leaves no room: at most a quarter of the labels here).
    to_px = ax.transData.transform
    stops = {f"S{i + 1}": o for i, o in enumerate(ORIGINS_M)} | {f"D{i + 1}": d for i, d in enumerate(DESTINATIONS_M)}
    px_per_pt = fig.dpi / 72
    far = []
    for name, box in labels.items():
        x, y = to_px(stops[name])
        gap_x, gap_y = max(box.x0 - x, x - box.x1, 0.0), max(box.y0 - y, y - box.y1, 0.0)
        if max(gap_x, gap_y) > 10 * px_per_pt:
            far.append(name)
    assert len(far) <= len(labels) // 4, far
    names = sorted(labels)
    for i, a in enumerate(names):
        for b in names[i + 1 :]:
            assert not labels[a].overlaps(labels[b]), f"{a} {labels[a]} overlaps {b} {labels[b]}"


def test_one_shared_start_is_one_gold_star_named_start_in_the_legend():
    radio = uamfleet.load_radio_map("berlin")
    routes = {"raster_replan": np.array([[950.0, 950.0], [1250.0, 2050.0]]), "straight": np.array([[950.0, 950.0]])}
    fig = plot_routes(radio, -3.0, routes, ORIGINS_M[:2], DESTINATIONS_M[:2], np.array([950.0, 950.0]), "t", None)
    ax, _ = drawn(fig)
    stars = [line for line in ax.lines if line.get_marker() == "*"]
    assert len(stars) == 1 and to_hex(stars[0].get_color()) == to_hex("gold")
    assert [text.get_text() for text in fig.legends[0].get_texts()] == ["raster_replan", "straight", "start"]
    with pytest.raises(ValueError, match="start_m holds 2 starts for 4 routes"):
        plot_routes(radio, -3.0, fleet_routes(), ORIGINS_M, DESTINATIONS_M, STARTS_M[:2], "t", None)


def test_the_same_routes_give_the_same_bytes(tmp_path: Path):
    radio = uamfleet.load_radio_map("berlin")
    for name in ("a.png", "b.png"):
        plot_routes(radio, -3.0, fleet_routes(), ORIGINS_M, DESTINATIONS_M, STARTS_M, "four taxis", tmp_path / name)
    assert (tmp_path / "a.png").read_bytes() == (tmp_path / "b.png").read_bytes()
