"""Matplotlib figures of a radio map and a fleet state (no simulation logic here)."""

from __future__ import annotations

import numpy as np

from uamfleet.env.world import World
from uamfleet.types import HIDDEN, WAITING, FleetState

TAXI_COLOURS = (
    "tab:red",
    "tab:blue",
    "tab:green",
    "tab:orange",
    "tab:purple",
    "tab:brown",
    "tab:pink",
    "tab:cyan",
)


def render_frame(world: World, state: FleetState, trails_m: np.ndarray, env: int = 0, size_px: int = 640) -> np.ndarray:
    """RGB frame [H, W, 3] uint8: block SINR map (hatched below the threshold), taxi trails, passengers.

    ``trails_m`` [A, T, 2]: the positions each taxi has been at this episode.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

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
        colour = TAXI_COLOURS[a % len(TAXI_COLOURS)]
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
