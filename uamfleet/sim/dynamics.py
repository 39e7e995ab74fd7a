"""The one batched transition: the separation shield, moves, block visits, drop-offs, pick-ups, releases, separation.

Order within a step (all taxis move simultaneously, one slot of ``slot_s`` seconds):
0. with ``EnvConfig.separation == "shield"``, conflicts are resolved first: a move whose end would come within
   ``min_separation_m`` of another taxi is replaced by the nearest clear allowed heading, else by a hover (the
   taxi stays: time passes, no distance flown), and a taxi that would stay closer than ``min_separation_m`` to
   another (taxis sharing a start) is moved apart where it can be; events ``heading_flown``,
   ``shield_intervened``, ``hovered`` (docs/rules.md "Separation shield");
1. each taxi flies one step along its heading if the move is allowed (``state.action_mask``); a move that is
   not allowed leaves the taxi in place (event ``blocked``: never a teleport, never a bounce); with
   ``EnvConfig.hover_action``, action 16 (``HOVER_ACTION``) hovers: the taxi stays, always allowed (``hovered``);
2. the time advances, visit counts of the taxi's block increase;
3. passengers on board whose destination is within ``radius_m`` are delivered (frees the seat);
4. waiting passengers within ``radius_m`` board the lowest-index taxi that reached them with a free seat:
   taxis in index order each take the lowest-index waiting passengers in reach until full. Only requests
   that were released *before* this step are waiting, so a request is always observed before its pick-up;
5. requests whose release step has come become visible (``WAITING``);
6. the action mask of the new positions is stored for the next observation.

The loops live in :mod:`uamfleet.sim.motion` (compiled); this module is their documented entry point. The rules
in full: ``docs/rules.md`` ("Motion", "Feasibility rules", "Release and pick-up").
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numba import njit

from uamfleet.sim import motion
from uamfleet.sim.pretyped import PreTyped
from uamfleet.sim.world import World
from uamfleet.types import HOVER_ACTION, NUM_HEADINGS, FleetState, StepEvents


class InvalidActionError(ValueError):
    """An action that is not an integer heading 0..NUM_HEADINGS - 1 (or the hover, 16, where the config has it),
    or actions of the wrong shape."""


def _actions_hint(num_actions: int = NUM_HEADINGS) -> str:
    """What a valid action is, for the error messages: the headings, and the hover where the config has one."""
    headings = f"{NUM_HEADINGS} headings, {360 / NUM_HEADINGS:g}° apart counter-clockwise from east"
    if num_actions > NUM_HEADINGS:
        return f"an integer action 0..{HOVER_ACTION} ({headings}; {HOVER_ACTION}: hover)"
    return f"an integer heading 0..{NUM_HEADINGS - 1} ({headings}; EnvConfig(hover_action=True) adds the hover, 16)"


def check_action(value: object, label: str, num_actions: int = NUM_HEADINGS) -> int:
    """One taxi's action as an int; :class:`InvalidActionError` naming ``label`` and the value otherwise.

    The rule of :func:`check_actions` for one scalar: a Python or NumPy integer (or a float with a whole value,
    or a 0-d array of either) in 0..num_actions - 1 (15, or 16 with the hover). Rejected, never truncated: 3.5,
    NaN, strings ('3'), bools and arrays with elements (``np.array([3])``: one taxi's action is a scalar).
    """
    hint = _actions_hint(num_actions)
    if isinstance(value, np.ndarray) and value.ndim > 0:
        raise InvalidActionError(
            f"the action of {label} is an array of shape {value.shape} ({value!r}); give one scalar: {hint}."
        )
    scalar = value[()] if isinstance(value, np.ndarray) else value
    if isinstance(scalar, bool | np.bool_) or not isinstance(scalar, int | float | np.integer | np.floating):
        raise InvalidActionError(f"the action of {label} is {value!r} ({type(value).__name__}); give {hint}.")
    number = scalar.item() if isinstance(scalar, np.generic) else scalar
    if isinstance(number, float) and not (math.isfinite(number) and number.is_integer()):
        raise InvalidActionError(f"action {number!r} of {label} is not a whole number; give {hint}, never rounded.")
    if not 0 <= number < num_actions:
        raise InvalidActionError(f"action {number!r} of {label} is outside 0..{num_actions - 1}: give {hint}.")
    return int(number)


@njit(cache=True)
def _all_valid(actions: np.ndarray, num_actions: int) -> bool:
    """Every entry of the [E, A] array is an action 0 .. num_actions - 1."""
    for e in range(actions.shape[0]):
        for a in range(actions.shape[1]):
            if actions[e, a] < 0 or actions[e, a] >= num_actions:
                return False
    return True


def check_actions(actions: np.ndarray, num_envs: int, num_taxis: int, num_actions: int = NUM_HEADINGS) -> np.ndarray:
    """Validated int64 actions [E, A]; raises :class:`InvalidActionError` naming the bad value. ``num_actions``:
    ``EnvConfig.num_actions`` (16 headings, 17 with the hover action).

    Integer arrays are taken as they are; float arrays only where every value is a whole number (a batch of
    headings that went through a float tensor), bool, string and object arrays never. NaN, 3.5 and
    out-of-range values are named with their env and taxi.
    """
    try:
        arr = np.asarray(actions)
    except (ValueError, TypeError) as exc:  # ragged nested lists
        raise InvalidActionError(
            f"actions {actions!r} are not an array of shape (num_envs, num_taxis) = ({num_envs}, {num_taxis}): {exc}"
        ) from None
    if arr.dtype == np.int64 and arr.shape == (num_envs, num_taxis) and _all_valid(arr, num_actions):
        return arr  # the common case, checked in one compiled pass
    hint = _actions_hint(num_actions)
    if arr.shape != (num_envs, num_taxis):
        raise InvalidActionError(
            f"actions have shape {arr.shape}, expected (num_envs, num_taxis) = ({num_envs}, {num_taxis}): "
            f"one heading per env and taxi."
        )
    if arr.dtype.kind == "f":
        bad = ~np.isfinite(arr) | (arr != np.round(arr))
        if bad.any():
            e, a = np.argwhere(bad)[0]
            raise InvalidActionError(
                f"action {arr[e, a].item()!r} of env {e}, taxi {a} is not a whole number; give {hint}, never rounded."
            )
    elif arr.dtype.kind not in "iu":
        kind = "headings" if num_actions == NUM_HEADINGS else "actions"
        raise InvalidActionError(f"actions must be integer {kind} 0..{num_actions - 1}, got dtype {arr.dtype}: {hint}.")
    bad = (arr < 0) | (arr >= num_actions)
    if bad.any():
        e, a = np.argwhere(bad)[0]
        raise InvalidActionError(
            f"action {arr[e, a].item()!r} of env {e}, taxi {a} is outside 0..{num_actions - 1}: give {hint}."
        )
    return arr.astype(np.int64, copy=False)


def step(
    state: FleetState, actions: np.ndarray, world: World, kernel: PreTyped | None = None, into: StepEvents | None = None
) -> StepEvents:
    """Advance every env of ``state`` by one slot, in place. ``actions`` [E, A] must be validated. With
    ``EnvConfig.separation == "shield"`` the moves are deconflicted first (:func:`motion.shield_headings`).
    ``into``: events arrays to write the step's events into (every field but ``actions``; returned), None: fresh
    ones. ``kernel``: the caller's pre-typed :func:`motion.step` (``into`` None) or :func:`motion.step_into` (an
    env steps the same state every time), used for actions of its usual type (C-contiguous, aligned, writable
    int64)."""
    shield = world.cfg.separation == "shield"
    flags = actions.flags
    run: Any = kernel
    if kernel is None or not (flags.c_contiguous and flags.aligned and flags.writeable):
        run = motion.step if into is None else motion.step_into
    if into is None:
        return run(state, world.arrays, actions, shield)
    run(state, world.arrays, actions, shield, into)
    return into
