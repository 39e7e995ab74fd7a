"""What the compiled kernels read of the world, passed to them whole: :class:`WorldArrays` (built by
:class:`uamfleet.sim.world.World`, read by :mod:`uamfleet.sim.motion` and the observation kernels of
:mod:`uamfleet.observe`). A leaf module, so that the geometry and the kernels both import it and neither
imports the other for its type.
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

# Feasibility rules (EnvConfig.feasibility) as integers for the kernels.
RULE_ENDPOINT_BLOCK = 0
RULE_SEGMENT_RASTER = 1


class WorldArrays(NamedTuple):
    """What the compiled kernels read of a :class:`World` (and of its config), passed to them whole."""

    moves_m: np.ndarray  # [NUM_HEADINGS, 2] float64, the move of each heading
    side_m: float  # the operating area is [0, side_m]^2
    step_m: float
    radius_m: float  # pick-up / drop-off radius
    min_separation_m: float
    rule: int  # RULE_ENDPOINT_BLOCK or RULE_SEGMENT_RASTER
    block_ok: np.ndarray  # [nbx, nby] bool, block SINR >= threshold
    block_m: float
    patch_lo: int  # patch rows b - patch_lo ... b + k - patch_lo - 1 around block b
    sinr_patch_source: np.ndarray  # [nbx + k, nby + k] float32, block SINR - threshold (dB), padded
    raster: np.ndarray  # [nx, ny] float64 SINR dB, NaN = not computed
    raster_origin: np.ndarray  # [2] float64, world coordinates of raster cell (0, 0)
    raster_res: float
    threshold_db: float
    seats: float
    time_limit_steps: float
