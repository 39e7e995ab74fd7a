"""The one batched transition: moves, block visits, drop-offs, pick-ups, releases, separation.

Order within a step (all taxis move simultaneously, one slot of ``slot_s`` seconds):
1. each taxi flies one step along its heading if the move is allowed (``state.action_mask``); a move that is
   not allowed leaves the taxi in place (event ``blocked``: never a teleport, never a bounce);
2. the time advances, visit counts of the taxi's block increase;
3. passengers on board whose destination is within ``radius_m`` are delivered (frees the seat);
4. waiting passengers within ``radius_m`` board the lowest-index taxi that reached them with a free seat:
   taxis in index order each take the lowest-index waiting passengers in reach until full. Only requests
   that were released *before* this step are waiting, so a request is always observed before its pick-up;
5. requests whose release step has come become visible (``WAITING``);
6. the action mask of the new positions is stored for the next observation.

The loops live in :mod:`uamfleet.env.kernels` (compiled); this module is their documented entry point. The rules
in full: ``docs/rules.md`` ("Motion", "Feasibility rules", "Release and pick-up").
"""

from __future__ import annotations

import numpy as np

from uamfleet.env import kernels
from uamfleet.env.world import World
from uamfleet.types import NUM_HEADINGS, FleetState, StepEvents


class InvalidActionError(ValueError):
    """An action outside 0..NUM_HEADINGS - 1 or of the wrong shape."""


def check_actions(actions: np.ndarray, num_envs: int, num_taxis: int) -> np.ndarray:
    """Validated int64 actions [E, A]; raises :class:`InvalidActionError` naming the bad value."""
    arr = np.asarray(actions)
    if arr.dtype == np.int64 and arr.shape == (num_envs, num_taxis) and 0 <= arr.min() and arr.max() < NUM_HEADINGS:
        return arr  # the common case, checked with two reductions
    if arr.shape != (num_envs, num_taxis):
        raise InvalidActionError(
            f"actions have shape {arr.shape}, expected (num_envs, num_taxis) = ({num_envs}, {num_taxis})."
        )
    if arr.dtype.kind not in "iu":
        if arr.dtype.kind == "f" and np.all(np.isfinite(arr)) and np.all(arr == np.round(arr)):
            arr = arr.astype(np.int64)
        else:
            raise InvalidActionError(f"actions must be integer headings 0..{NUM_HEADINGS - 1}, got dtype {arr.dtype}.")
    bad = (arr < 0) | (arr >= NUM_HEADINGS)
    if bad.any():
        e, a = np.argwhere(bad)[0]
        raise InvalidActionError(
            f"action {int(arr[e, a])} of env {e}, taxi {a} is outside 0..{NUM_HEADINGS - 1} "
            f"({NUM_HEADINGS} headings, {360 / NUM_HEADINGS:g}° apart counter-clockwise from east)."
        )
    return arr.astype(np.int64, copy=False)


def step(state: FleetState, actions: np.ndarray, world: World) -> StepEvents:
    """Advance every env of ``state`` by one slot, in place. ``actions`` [E, A] must be validated."""
    return kernels.step(state, world.arrays, actions)
