"""Static, precomputed geometry of one environment config: block map, flyable blocks, patches, headings.

Built once per config (milliseconds; the block map is cached on the radio map) and shared by the generator,
the dynamics, the observer and the baselines, so that every one of them applies the same rule. Segment tests
sample the raster along each move in the compiled kernels (:mod:`uamfleet.radio._sampling`). The stop point a
passenger row offers a taxi (:func:`row_stop`, :func:`stop_of`) is read by the reward, the observer and the planners.
"""

from __future__ import annotations

import numpy as np
from numba import njit
from scipy import ndimage

from uamfleet.config import EnvConfig, heading_vectors
from uamfleet.radio import BlockMap
from uamfleet.sim.arrays import RULE_ENDPOINT_BLOCK, RULE_SEGMENT_RASTER, WorldArrays
from uamfleet.sim.motion import action_mask
from uamfleet.types import NUM_HEADINGS, ON_BOARD, WAITING, FleetState

# WorldArrays lives in uamfleet.sim.arrays
__all__ = ["PATCH_CLIP_DB", "PATCH_PAD_DB", "World", "WorldArrays", "row_stop", "stop_of"]

PATCH_PAD_DB = -30.0
"""Value of SINR-patch cells outside the map (relative to the threshold, dB): clearly not flyable."""
PATCH_CLIP_DB = 30.0


class World:
    """Geometry derived from an :class:`EnvConfig`; read-only after construction."""

    def __init__(self, cfg: EnvConfig) -> None:
        self.cfg = cfg
        self.radio = cfg.radio
        self.side_m = cfg.side_m
        self.step_m = cfg.step_m
        self.threshold_db = cfg.sinr_min_db
        self.moves_m = cfg.step_m * heading_vectors()  # [NUM_HEADINGS, 2]
        self.blocks: BlockMap = self.radio.block_map(cfg.block_size_m, nc_rule=cfg.nc_rule)
        with np.errstate(invalid="ignore"):
            self.block_ok = np.asarray(self.blocks.sinr_db >= self.threshold_db)  # [nbx, nby] bool, NaN -> False
        self.num_blocks = self.block_ok.shape
        k = cfg.patch_size
        self.patch_lo = k // 2  # patch rows b - k//2 ... b + k - k//2 - 1 around the taxi's block b
        rel = np.nan_to_num(self.blocks.sinr_db - self.threshold_db, nan=PATCH_PAD_DB)
        rel = np.clip(rel, PATCH_PAD_DB, PATCH_CLIP_DB)
        self.sinr_patch_source = np.pad(
            rel, ((self.patch_lo, k - self.patch_lo),) * 2, constant_values=PATCH_PAD_DB
        ).astype(np.float32)  # [nbx + k, nby + k]
        self.raster_origin = np.asarray(self.radio.origin_m, dtype=np.float64)
        self.rule = RULE_ENDPOINT_BLOCK if cfg.feasibility == "endpoint_block" else RULE_SEGMENT_RASTER
        # 8-connected components of flyable blocks: the reachability test for stops.
        self.components, self.num_components = ndimage.label(self.block_ok, structure=np.ones((3, 3), bool))
        self.arrays = WorldArrays(
            moves_m=np.ascontiguousarray(self.moves_m, dtype=np.float64),
            side_m=float(self.side_m),
            step_m=float(cfg.step_m),
            radius_m=float(cfg.radius_m),
            min_separation_m=float(cfg.min_separation_m),
            rule=int(self.rule),
            block_ok=np.ascontiguousarray(self.block_ok),
            block_m=float(self.blocks.block_m),
            patch_lo=int(self.patch_lo),
            sinr_patch_source=self.sinr_patch_source,
            raster=np.ascontiguousarray(self.radio.sinr_db, dtype=np.float64),
            raster_origin=self.raster_origin,
            raster_res=float(self.radio.resolution_m),
            threshold_db=float(self.threshold_db),
            seats=float(cfg.seats),
            time_limit_steps=float(cfg.time_limit_steps),
        )

    # ---- points --------------------------------------------------------------------------------------
    def in_domain(self, points: np.ndarray) -> np.ndarray:
        """bool [...]: inside the square operating area [0, side]^2."""
        return np.all((points >= 0.0) & (points <= self.side_m), axis=-1)

    def block_index(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        return self.blocks.block_index(points)

    def point_feasible(self, points: np.ndarray) -> np.ndarray:
        """bool [...]: a taxi may be at this point under the config's feasibility rule."""
        inside = self.in_domain(points)
        if self.cfg.feasibility == "endpoint_block":
            bx, by = self.block_index(points)
            return inside & self.block_ok[bx, by]
        return inside & self.radio.feasible(points, self.threshold_db)

    def component_of(self, points: np.ndarray) -> np.ndarray:
        """int [...]: label of the flyable-block component containing each point (0 = not flyable)."""
        bx, by = self.block_index(points)
        labels = np.asarray(self.components[bx, by])
        return np.where(self.in_domain(points), labels, 0)

    # ---- moves ---------------------------------------------------------------------------------------
    def action_mask(self, pos_m: np.ndarray) -> np.ndarray:
        """bool [..., NUM_HEADINGS]: which headings are allowed from each position."""
        pos = np.ascontiguousarray(pos_m, dtype=np.float64)
        flat = pos.reshape(-1, 2)
        out = np.empty((flat.shape[0], NUM_HEADINGS), dtype=bool)
        action_mask(flat, self.arrays, out)
        return out.reshape(*pos.shape[:-1], NUM_HEADINGS)


@njit(cache=True, inline="always")
def row_stop(s: FleetState, e: int, a: int, p: int) -> int:
    """The stop point row p offers taxi a (its *actionable* stop; the shaping potential's stops too): its
    destination (2p + 1) while p rides in a, its origin (2p) while p waits and a has a free seat, else -1."""
    return stop_of(s.pax_status[e, p], s.pax_taxi[e, p], s.free_seats[e, a], a, p)


@njit(cache=True, inline="always")
def stop_of(status: int, carrier: int, free_seats: int, a: int, p: int) -> int:
    """:func:`row_stop` from row p's status and carrier and taxi a's free seats. Hot loops call this rather than
    :func:`row_stop`: a call that passes the state, even inlined, reference-counts each of its ~30 arrays (~0.25 µs)."""
    if status == ON_BOARD and carrier == a:
        return 2 * p + 1
    if status == WAITING and free_seats > 0:
        return 2 * p
    return -1
