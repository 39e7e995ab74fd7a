"""What the knob controller reads: a few numbers about the fleet's load and the dispatcher's schedules at a
decision, from released requests only (a hidden request counts only as one of the setting's known total)."""

from __future__ import annotations

import numpy as np

from uamfleet.baselines.sequencing import PICKUP
from uamfleet.types import DELIVERED, HIDDEN, ON_BOARD, WAITING

NAMES = (
    "bias",
    "time_frac",
    "released_frac",
    "waiting_per_taxi",
    "unassigned_per_taxi",
    "on_board_per_taxi",
    "delivered_frac",
    "idle_taxi_frac",
    "stops_per_taxi",
    "max_stops",
    "route_len_sides",
    "max_route_len_sides",
    "mean_wait_s_100",
    "oldest_wait_s_100",
    "detroit",
)


def features(state: dict, routes: list[list[tuple[int, object]]], time_limit_steps: int, slot_s: float,
             side_m: float) -> np.ndarray:  # fmt: skip
    """[len(NAMES)] float64 from one env's state arrays (``state``: FleetState field -> array of env 0)."""
    t = float(state["t"])
    status, exists = state["pax_status"], state["pax_exists"]
    taxis = len(routes)
    total = max(int(exists.sum()), 1)
    released = exists & (status != HIDDEN)
    waiting = np.flatnonzero(status == WAITING)
    assigned = {p for route in routes for p, kind in route}
    unassigned = [p for p in waiting if int(p) not in assigned]
    stops = np.array([len(r) for r in routes], float)
    pos = state["pos_m"]
    lengths = []
    for a, route in enumerate(routes):
        here, length = pos[a], 0.0
        for p, kind in route:
            stop = state["pax_origin_m"][p] if kind == PICKUP else state["pax_dest_m"][p]
            length += float(np.linalg.norm(stop - here))
            here = stop
        lengths.append(length / side_m)
    waits = (t - state["pax_release"][waiting]) * slot_s if len(waiting) else np.zeros(1)
    return np.array([
        1.0, t / time_limit_steps, released.sum() / total, len(waiting) / taxis, len(unassigned) / taxis,
        np.count_nonzero(status == ON_BOARD) / taxis, np.count_nonzero(status == DELIVERED) / total,
        float(np.mean(stops == 0)), stops.mean(), stops.max(), float(np.mean(lengths)), float(np.max(lengths)),
        float(np.mean(waits)) / 100, float(np.max(waits)) / 100, float(side_m > 10_500),
    ])  # fmt: skip
