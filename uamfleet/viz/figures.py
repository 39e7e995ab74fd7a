"""Matplotlib figures of a radio map and a fleet state (no simulation logic here)."""

from __future__ import annotations

import io
from pathlib import Path
from typing import Any

import numpy as np
from matplotlib.figure import Figure
from matplotlib.legend_handler import HandlerTuple

from uamfleet.io import write_bytes_atomic
from uamfleet.radio import RadioMap
from uamfleet.sim.world import World
from uamfleet.types import HIDDEN, WAITING, FleetState
from uamfleet.viz.colours import TAXI_HEX


def render_frame(world: World, state: FleetState, trails_m: np.ndarray, env: int = 0, size_px: int = 640) -> np.ndarray:
    """RGB frame [H, W, 3] uint8: block SINR map (hatched below the threshold), taxi trails, passengers.

    ``trails_m`` [A, T, 2]: the positions each taxi has been at this episode.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure(figsize=(size_px / 100, size_px / 100), dpi=100)
    ax = fig.add_axes((0.08, 0.08, 0.8, 0.84))
    side, blocks = world.side_m, world.blocks
    im = ax.imshow(blocks.sinr_db.T, origin="lower", extent=(0, side, 0, side), cmap="viridis")
    ax.contourf(
        (np.arange(world.num_blocks[0]) + 0.5) * blocks.block_m,
        (np.arange(world.num_blocks[1]) + 0.5) * blocks.block_m,
        (~world.block_ok).T.astype(float),
        levels=[0.5, 1.5],
        colors="none",
        hatches=["//"],
    )
    fig.colorbar(im, ax=ax, fraction=0.04, label="block SINR [dB]")
    for p in range(state.pax_status.shape[1]):
        status = int(state.pax_status[env, p])
        if not state.pax_exists[env, p] or status == HIDDEN:
            continue
        o, d = state.pax_origin_m[env, p], state.pax_dest_m[env, p]
        ax.plot(*o, marker="^", color="white" if status == WAITING else "grey", mec="k")
        ax.plot(*d, marker="s", color="white", mec="k")
        ax.annotate(f"S{p + 1}", o, color="w", fontsize=8)
        ax.annotate(f"D{p + 1}", d, color="w", fontsize=8)
    for a in range(trails_m.shape[0]):
        colour = TAXI_HEX[a % len(TAXI_HEX)]
        ax.plot(trails_m[a, :, 0], trails_m[a, :, 1], color=colour, lw=1.5)
        ax.plot(*state.pos_m[env, a], marker="o", color=colour, mec="k")
    ax.set_xlim(0, side)
    ax.set_ylim(0, side)
    ax.set_title(f"{world.radio.label}  γ_T = {world.threshold_db:g} dB  t = {int(state.t[env])}")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    canvas = FigureCanvasAgg(fig)
    canvas.draw()
    rgba = np.asarray(canvas.buffer_rgba())
    return rgba[..., :3].copy()


ROUTE_COLOURS = {"raster_opt": "tab:red", "raster_replan": "tab:orange", "best_known": "tab:brown",
                 "replan": "tab:pink", "pdpcc": "tab:blue", "cptsp": "tab:green",
                 "straight": "black", "msha": "tab:purple"}  # fmt: skip


def _new_figure(width_in: float, height_in: float) -> Figure:
    from matplotlib.backends.backend_agg import FigureCanvasAgg

    fig = Figure(figsize=(width_in, height_in), dpi=120)
    FigureCanvasAgg(fig)
    return fig


def plot_routes(
    radio: RadioMap,
    threshold_db: float,
    routes_m: dict[str, np.ndarray],
    origins_m: np.ndarray,
    destinations_m: np.ndarray,
    start_m: np.ndarray,
    title: str,
    path: str | Path | None,
) -> Figure:
    """Routes over the radio map, the paper's Figs. 7-8 style: raster SINR (cells below the threshold greyed),
    each route a coloured polyline, stops labelled S1…/D1…, starts as stars. ``routes_m``: name -> [T, 2];
    ``start_m``: [2], one start shared by every route (a gold star), or [R, 2], route r's start (a fleet: each
    taxi's start a star in its route's colour). The legend sits below the map, so it covers no stop or label.
    Written to ``path`` as a PNG (byte-stable: same input, same bytes) unless it is None; returned either way."""
    starts = np.asarray(start_m, dtype=float).reshape(-1, 2)
    if len(starts) not in (1, len(routes_m)):
        raise ValueError(f"start_m holds {len(starts)} starts for {len(routes_m)} routes; give one, or one per route.")
    # Inches: the map is MAP_IN square; below it the tick labels and the axis label (0.5 in), then the legend
    # (two rows at most); above it a two-line title.
    width_in, height_in, left_in, bottom_in = 7.3, 6.65, 0.8, 1.05
    fig = _new_figure(width_in, height_in)
    box = (left_in / width_in, bottom_in / height_in, MAP_IN / width_in, MAP_IN / height_in)
    ax = fig.add_axes(box)
    side = float(radio.side_m or 0.0)
    im = _draw_sinr(ax, radio, threshold_db)
    cax = fig.add_axes((box[0] + box[2] + 0.2 / width_in, box[1], 0.2 / width_in, box[3]))
    fig.colorbar(im, cax=cax, label=f"SINR [dB] (grey: below γ_T = {threshold_db:g} dB)")
    handles: list[Any] = []
    for name, route in routes_m.items():
        handles.append(
            ax.plot(route[:, 0], route[:, 1], lw=1.8, color=ROUTE_COLOURS.get(name.split("-")[0]), label=name)[0]
        )
    if len(starts) == 1:
        handles.append(ax.plot(*starts[0], marker="*", ms=14, color="gold", mec="k", ls="none", label="start")[0])
    else:  # each taxi's start in its route's colour; the legend pairs a route's line with its star
        for r, (line, start) in enumerate(zip(list(handles), starts, strict=True)):
            star = ax.plot(*start, marker="*", ms=14, color=line.get_color(), mec="k", ls="none")[0]
            handles[r] = (line, star)
    stops = [(o, f"S{i + 1}") for i, o in enumerate(origins_m)] + [
        (d, f"D{i + 1}") for i, d in enumerate(destinations_m)
    ]
    for o in origins_m:
        ax.plot(*o, marker="^", ms=8, color="white", mec="k", ls="none")
    for d in destinations_m:
        ax.plot(*d, marker="s", ms=7, color="white", mec="k", ls="none")
    ax.set_xlim(0, side)
    ax.set_ylim(0, side)
    _label_stops(ax, stops, obstacles_m=[*(point for point, _ in stops), *starts])
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=10)
    labels = [*routes_m, *(["start"] if len(starts) == 1 else [])]
    fig.legend(
        handles, labels, handler_map={tuple: HandlerTuple(ndivide=None)}, loc="upper center", fontsize=8,
        ncol=min(len(handles), 5), frameon=False, bbox_to_anchor=(box[0] + box[2] / 2, (bottom_in - 0.5) / height_in),
    )  # fmt: skip
    if path is not None:
        save_figure(fig, path)
    return fig


def _draw_sinr(ax: Any, radio: RadioMap, threshold_db: float) -> Any:
    """The SINR raster on ``ax`` in the map's frame, the cells below ``threshold_db`` greyed; the image (for a
    colour bar)."""
    ox, oy = radio.origin_m
    half = radio.resolution_m / 2
    nx, ny = radio.shape
    x_max, y_max = ox + (nx - 1) * radio.resolution_m, oy + (ny - 1) * radio.resolution_m
    extent = (ox - half, x_max + half, oy - half, y_max + half)
    im = ax.imshow(radio.sinr_db.T, origin="lower", extent=extent, cmap="viridis", interpolation="nearest")
    below = np.ma.masked_where(~(np.nan_to_num(radio.sinr_db, nan=-np.inf) < threshold_db), np.ones(radio.shape))
    ax.imshow(
        below.T, origin="lower", extent=extent, cmap="Greys", vmin=0, vmax=1.6, alpha=0.75, interpolation="nearest"
    )
    return im


MAP_IN = 5.0
"""Side of the routes figure's map in inches (the map is square: one metre is as long on both axes)."""
LABEL_PT = 9.0
"""Font size of the stop labels (S1…/D1…)."""
LABEL_SIDES = ((0, 0), (-1, 0), (0, -1), (-1, -1), (1, 0), (-2, 0), (0, 1), (-1, 1), (0, -2), (-1, -2))
"""Where a stop label may go, in label widths / heights from the marker: NE, NW, SE, SW first, then one label
further out on each side."""


def _label_stops(ax: Any, stops: list[tuple[np.ndarray, str]], obstacles_m: list[np.ndarray]) -> None:
    """Label each stop beside its marker, at the first of :data:`LABEL_SIDES` where the label overlaps no label
    placed before it, no other stop or start marker (``obstacles_m``: the stops' points in order, then the starts)
    and stays inside the map; else where it costs least (a label cut off by the map's edge costs most, one over
    another label next, one over a marker least). Greedy and deterministic (same stops, same figure), in points."""
    ax.apply_aspect()
    to_pt = ax.transData + ax.figure.dpi_scale_trans.inverted()  # data -> inches
    frame = ax.get_window_extent().transformed(ax.figure.dpi_scale_trans.inverted())
    frame_pt = (frame.x0 * 72, frame.y0 * 72, frame.x1 * 72, frame.y1 * 72)
    markers = [_box(72 * to_pt.transform(p), 6.0) for p in obstacles_m]
    placed: list[tuple[float, float, float, float]] = []
    gap = 4.0  # points between a marker's centre and its label
    for i, (point, text) in enumerate(stops):
        others = markers[:i] + markers[i + 1 :]  # its own marker is beside every side alike
        x, y = 72 * to_pt.transform(point)
        w, h = 0.7 * LABEL_PT * len(text), LABEL_PT  # bold capitals and digits: about 0.7 em wide, 1 em tall
        # Side r >= 0: r labels (and gaps) beyond the gap to the right / above; r < 0: -r labels to the left / below.
        offsets = [(rx * (w + gap) + gap * (rx >= 0), ry * (h + gap) + gap * (ry >= 0)) for rx, ry in LABEL_SIDES]
        costs = []
        for dx, dy in offsets:
            label = (x + dx, y + dy, x + dx + w, y + dy + h)
            cost = 4 * (w * h - _overlap(label, frame_pt))
            cost += 2 * sum(_overlap(label, other) for other in placed) + sum(_overlap(label, m) for m in others)
            costs.append(cost)
        dx, dy = offsets[int(np.argmin(costs))]  # the first of least cost: NE when nothing is in the way
        placed.append((x + dx, y + dy, x + dx + w, y + dy + h))
        ax.annotate(
            text, point, xytext=(dx, dy), textcoords="offset points", color="w", fontsize=LABEL_PT, weight="bold",
            va="bottom",  # the box starts at the offset, as estimated (the baseline would leave the descent below)
        )  # fmt: skip


def _box(centre: np.ndarray, half: float) -> tuple[float, float, float, float]:
    """The square of side ``2 * half`` around ``centre`` as (x0, y0, x1, y1)."""
    return (centre[0] - half, centre[1] - half, centre[0] + half, centre[1] + half)


def _overlap(a: tuple[float, float, float, float], b: tuple[float, float, float, float]) -> float:
    """Area shared by two boxes (x0, y0, x1, y1)."""
    return max(0.0, min(a[2], b[2]) - max(a[0], b[0])) * max(0.0, min(a[3], b[3]) - max(a[1], b[1]))


def plot_connectivity(
    thresholds_db: list[float], connectivity_pct: dict[str, list[float]], title: str, path: str | Path
) -> None:
    """Connectivity (% of 10 m path samples at or above the threshold) per threshold, one line per method."""
    fig = _new_figure(6.0, 4.0)
    ax = fig.add_axes((0.12, 0.14, 0.84, 0.76))
    for name, values in connectivity_pct.items():
        ax.plot(thresholds_db, values, marker="o", color=ROUTE_COLOURS.get(name, None), label=name)
    ax.set_xlabel("SINR threshold γ_T [dB]")
    ax.set_ylabel("connectivity [%]")
    ax.set_title(title, fontsize=10)
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    save_figure(fig, path)


def save_figure(fig: Figure, path: str | Path) -> None:
    """Write a PNG atomically (temp file + rename), creating the folder."""
    buffer = io.BytesIO()
    fig.savefig(buffer, format="png", metadata={"Software": None})  # no version stamp: same input, same bytes
    write_bytes_atomic(path, buffer.getvalue())
