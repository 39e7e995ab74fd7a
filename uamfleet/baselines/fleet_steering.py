"""How a fleet dispatcher's taxis fly their schedules, move by move: toward the stop, idling, and out of the way.

How a taxi heads for its stop (``heading``, a name's ``heading=<rule>``): ``"field"`` (the default, every recorded
dispatcher's) flies the allowed move whose end is nearest the stop by the stop's distance field
(:meth:`~uamfleet.paths.DistanceFields.heading`); ``"table"`` flies the move the observation's ``stop_heading_mask``
marks for it, the least move plus distance-table distance left, a move ending within the pick-up radius costing the
move alone (:func:`uamfleet.observe.moves.progress_heading`). A fleet policy with a stop head steers by the latter,
so a dispatcher flying ``"table"`` separates what such a policy decides from how it steers. ``"onward"`` flies the
field rule, except on a move that makes the stop (ends within the pick-up radius of it): of those moves, the one
whose end is nearest, by its field, the stop after this one on the taxi's schedule (:func:`onward_heading`), so the
taxi leaves the stop already on its way (reports/2026-12-05-fleet-headings/).

A taxi with nothing to do hovers where the env has the hover action (``EnvConfig.hover_action``, on in the
``*_fleet`` presets), else zig-zags about the point where it became idle (:func:`fleet_action`). Under the
separation shield an idle taxi in the way of a busy taxi's next move steps aside (:func:`make_way`): the shield
moves a hovering taxi only when it is already in conflict, so one idle taxi hovering in a narrow passage otherwise
held a taxi with a rider back until the time limit (:func:`fleet_actions`).
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from uamfleet.checks import ConfigError
from uamfleet.observe.moves import progress_heading
from uamfleet.paths import DistanceFields, DistanceTable
from uamfleet.sim.core import Simulator
from uamfleet.sim.motion import passes_within_each
from uamfleet.types import HOVER_ACTION, NUM_HEADINGS

# The distance fields of the last instance flown: dispatchers flown one after another on the same instance (the
# fleet benchmark) share its per-stop Dijkstra fields instead of recomputing them. One entry, so memory stays flat.
_LAST_FIELDS: dict[tuple[int, bytes], DistanceFields] = {}


def shared_fields(sim: Simulator, warm: bool = False) -> DistanceFields:
    """The :class:`DistanceFields` of the simulator's world, shared with the previous dispatcher on the same instance;
    ``warm`` computes the field of every stop now (so that policies' decision times leave it out)."""
    s = sim.state
    fields = DistanceFields(sim.world)
    stops = np.concatenate([s.pos_m[0], s.pax_origin_m[0], s.pax_dest_m[0]])
    key = (id(fields.graph), stops.tobytes())
    if key not in _LAST_FIELDS:
        _LAST_FIELDS.clear()
        _LAST_FIELDS[key] = fields
    fields = _LAST_FIELDS[key]
    if warm:
        for stop in stops[sim.num_taxis :]:
            fields.remaining_m(stop, stop[None])
    return fields


HEADING_RULES = ("field", "table", "onward")
"""How a dispatcher's taxi heads for its stop (module docstring): by the stop's distance field, as the
observation's ``stop_heading_mask`` marks it, or by the field with the move that makes the stop aimed at the next."""


def check_heading(value: object, option: str = "heading") -> str:
    """``value`` if it is one of :data:`HEADING_RULES`; ConfigError naming it (as ``option``) otherwise."""
    if value not in HEADING_RULES:
        raise ConfigError(
            f"{option}={value!r}: choose one of {', '.join(HEADING_RULES)} (uamfleet.baselines.fleet_steering)."
        )
    return str(value)


def onward_heading(
    env: Simulator, fields: DistanceFields, taxi: int, stop: np.ndarray, onward: np.ndarray
) -> int:  # fmt: skip
    """Of taxi ``taxi``'s allowed moves (env 0) that end within the pick-up radius of ``stop`` (the stop is made on
    this move), the one whose end is nearest ``onward`` (the stop after it) by ``onward``'s distance field, ties to
    the lowest heading; -1 when no allowed move ends within the radius."""
    s = env.state
    ends = s.pos_m[0, taxi] + env.world.moves_m  # [16, 2]
    radius = env.cfg.radius_m
    makes_stop = s.action_mask[0, taxi, :NUM_HEADINGS] & (((ends - stop) ** 2).sum(-1) <= radius * radius)
    if not makes_stop.any():
        return -1
    return int(np.argmin(np.where(makes_stop, fields.remaining_m(onward, ends), np.inf)))


def fleet_action(
    env: Simulator, fields: DistanceFields, idle_at: list[np.ndarray | None], taxi: int, target: np.ndarray | None,
    table: DistanceTable | None = None, onward: np.ndarray | None = None,
) -> int:  # fmt: skip
    """Taxi ``taxi``'s action in env 0: the heading toward ``target`` along feasible paths (by ``fields``; with
    a ``table`` the move ``stop_heading_mask`` would mark; with the stop after it, ``onward``, the move that makes
    the stop nearest that one where a move makes it: module docstring); with nothing to do, the hover
    (:data:`~uamfleet.types.HOVER_ACTION`: no distance flown) where the env has it (``hover_action``), else the
    heading back toward the point where it became idle, so it zig-zags about that point (``idle_at`` keeps those
    points per taxi)."""
    s = env.state
    pos = s.pos_m[0, taxi]
    if target is not None:
        idle_at[taxi] = None
        goal = target
        if table is not None:
            heading = progress_heading(table, env.world.arrays, s.action_mask[0, taxi], pos, goal)
            if heading >= 0:  # -1: no allowed move reaches the stop by the table; the field's heading flies
                return heading
        if onward is not None:
            heading = onward_heading(env, fields, taxi, goal, onward)
            if heading >= 0:  # -1: the stop is more than one move away
                return heading
    elif env.cfg.hover_action:
        return HOVER_ACTION
    else:
        idle = idle_at[taxi]
        if idle is None:
            idle = idle_at[taxi] = pos.copy()
        goal = idle
    return fields.heading(pos, s.action_mask[0, taxi], goal)


def fleet_actions(
    sim: Simulator, fields: DistanceFields, idle_at: list[np.ndarray | None], targets: Sequence[np.ndarray | None],
    table: DistanceTable | None = None, onwards: Sequence[np.ndarray | None] | None = None,
) -> np.ndarray:  # fmt: skip
    """[1, A] every taxi's action in env 0: :func:`fleet_action` toward its target (None: nothing to do; ``table``
    and each taxi's ``onwards`` stop as there), then, under the separation shield, the idle taxis in the way of a
    busy taxi's next move step aside (:func:`make_way`)."""
    after = onwards if onwards is not None else [None] * len(targets)
    actions = np.array(
        [[fleet_action(sim, fields, idle_at, a, t, table, after[a]) for a, t in enumerate(targets)]], dtype=np.int64
    )
    if sim.cfg.separation == "shield":
        make_way(sim, actions[0], [t is None for t in targets], idle_at)
    return actions


def make_way(sim: Simulator, actions: np.ndarray, idle: Sequence[bool], idle_at: list[np.ndarray | None]) -> None:
    """Idle taxis step out of the way of busy ones (env 0, ``actions`` [A] changed in place).

    The shield keeps a hover and turns the other taxi aside (docs/rules.md "Separation shield"), so an idle taxi
    hovering in a passage a taxi with a rider must fly through held that taxi back until the time limit (Berlin
    8 x 96: ``batch_assignment`` test seeds 2000056 and 2000088, ``greedy`` 2000049, each one rider short). An
    idle taxi that the next move of a busy taxi would come within ``min_separation_m`` of, with the shield's own
    test (:func:`uamfleet.sim.motion.passes_within`), instead flies the allowed heading that ends farthest from
    where those busy taxis are headed (ties: the lowest heading), and, without the hover action, zig-zags about
    where it ends up.
    Only a move the shield would turn aside (or hold) triggers it, so with the hover action an episode without
    shield interventions flies as before."""
    s = sim.state
    pos, allowed = s.pos_m[0], s.action_mask[0]
    moves = sim.world.moves_m
    radius = sim.cfg.min_separation_m
    busy = [b for b, k in enumerate(actions) if not idle[b] and k < NUM_HEADINGS and allowed[b, k]]
    idle_taxis = np.flatnonzero(idle)
    if not busy or not idle_taxis.size:
        return
    busy_ends = pos[busy] + moves[actions[busy]]  # [B, 2] where each busy taxi's move ends
    near = passes_within_each(pos[busy], busy_ends, pos[idle_taxis], radius)  # [I, B], one compiled pass
    for i, a in enumerate(idle_taxis):
        headings = np.flatnonzero(allowed[a, :NUM_HEADINGS])
        if not near[i].any() or not headings.size:
            continue
        ends = pos[a] + moves[headings]  # [H, 2]
        clearance = np.linalg.norm(ends[:, None] - busy_ends[near[i]][None], axis=-1).min(axis=1)
        actions[a] = headings[int(np.argmax(clearance))]
        idle_at[a] = None


__all__ = [
    "HEADING_RULES",
    "check_heading",
    "fleet_action",
    "fleet_actions",
    "make_way",
    "onward_heading",
    "shared_fields",
]
