"""Matplotlib figures of a radio map and a fleet state (no simulation logic here)."""

from __future__ import annotations

import io
from pathlib import Path

import numpy as np
from matplotlib.figure import Figure

from uamfleet.env.world import World
from uamfleet.io import write_bytes_atomic
from uamfleet.radio import RadioMap
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
    path: str | Path,
) -> None:
    """Routes over the radio map, the paper's Figs. 7-8 style: raster SINR (cells below the threshold greyed),
    each route a coloured polyline, stops labelled S1…/D1…, the start a star. ``routes_m``: name -> [T, 2]."""
    fig = _new_figure(7.2, 6.0)
    ax = fig.add_axes((0.08, 0.08, 0.74, 0.84))
    side = float(radio.side_m or 0.0)
    ox, oy = radio.origin_m
    half = radio.resolution_m / 2
    nx, ny = radio.shape
    extent = (
        ox - half,
        ox + (nx - 1) * radio.resolution_m + half,
        oy - half,
        oy + (ny - 1) * radio.resolution_m + half,
    )
    im = ax.imshow(radio.sinr_db.T, origin="lower", extent=extent, cmap="viridis", interpolation="nearest")
    below = np.ma.masked_where(~(np.nan_to_num(radio.sinr_db, nan=-np.inf) < threshold_db), np.ones(radio.shape))
    ax.imshow(
        below.T, origin="lower", extent=extent, cmap="Greys", vmin=0, vmax=1.6, alpha=0.75, interpolation="nearest"
    )
    cax = fig.add_axes((0.84, 0.08, 0.03, 0.84))
    fig.colorbar(im, cax=cax, label=f"SINR [dB] (grey: below γ_T = {threshold_db:g} dB)")
    for name, route in routes_m.items():
        ax.plot(route[:, 0], route[:, 1], lw=1.8, color=ROUTE_COLOURS.get(name.split("-")[0]), label=name)
    ax.plot(*start_m, marker="*", ms=14, color="gold", mec="k", ls="none", label="start")
    for i, (o, d) in enumerate(zip(origins_m, destinations_m, strict=True)):
        ax.plot(*o, marker="^", ms=8, color="white", mec="k", ls="none")
        ax.plot(*d, marker="s", ms=7, color="white", mec="k", ls="none")
        ax.annotate(f"S{i + 1}", o, xytext=(4, 4), textcoords="offset points", color="w", fontsize=9, weight="bold")
        ax.annotate(f"D{i + 1}", d, xytext=(4, 4), textcoords="offset points", color="w", fontsize=9, weight="bold")
    ax.set_xlim(0, side)
    ax.set_ylim(0, side)
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title(title, fontsize=10)
    ax.legend(loc="lower left", fontsize=8, framealpha=0.85)
    save_figure(fig, path)


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
