"""The PettingZoo env's ``render_mode`` values, drawn here (the env only knows the
:class:`~uamfleet.env.parallel_env.Renderer` protocol; ``import uamfleet`` registers :func:`make_renderer`).

- ``"rgb_array"``: :class:`FrameRenderer`, a matplotlib frame of the block SINR map, the trails and the stops.
- ``"human"``: :class:`LiveViewer`, the meshcat scene served to the browser (its address is printed), updated
  with the live state at every ``render()``; ``close()`` kills its server.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from uamfleet.viz.figures import render_frame
from uamfleet.viz.meshcat_view import FleetViewer

if TYPE_CHECKING:
    from uamfleet.env.parallel_env import Renderer, UAMFleetParallelEnv


class FrameRenderer:
    """``render_mode="rgb_array"``: an RGB frame [H, W, 3] uint8 of the env's current state and trails."""

    def render(self, env: UAMFleetParallelEnv) -> np.ndarray:
        return render_frame(env.core.world, env.core.state, env.trails_m)

    def close(self) -> None:
        pass


class LiveViewer(FleetViewer):
    """``render_mode="human"``: a :class:`FleetViewer` with its server open, showing the env's live state."""

    def render(self, env: UAMFleetParallelEnv) -> None:
        s = env.core.state
        self.update_live(
            s.pos_m[0], s.pax_status[0], s.pax_origin_m[0], s.pax_dest_m[0], int(s.t[0]),
            pax_taxi=s.pax_taxi[0], seats=env.cfg.seats,
        )  # fmt: skip


def make_renderer(render_mode: str, env: UAMFleetParallelEnv) -> Renderer:
    """The renderer of ``render_mode`` (``"rgb_array"`` or ``"human"``) for ``env``."""
    if render_mode == "rgb_array":
        return FrameRenderer()
    if render_mode == "human":
        world, cfg = env.core.world, env.cfg
        title = f"{cfg.scenario} · {cfg.num_taxis} taxi(s) · γ_T = {world.threshold_db:g} dB (live)"
        return LiveViewer(world.radio, world.threshold_db, open_server=True, title=title)
    raise ValueError(f"render_mode={render_mode!r} has no renderer; use 'rgb_array' or 'human'.")
