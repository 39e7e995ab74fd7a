"""Who served whom and when, from a trajectory's events; the SINR-over-time strip of a flown path.

Shared by the matplotlib strip and the meshcat viewer (no simulation logic here: everything comes from the
recorded :class:`~uamfleet.types.StepEvents`).
"""

from __future__ import annotations

from pathlib import Path
from typing import NamedTuple

import numpy as np

from uamfleet.metrics import polyline_samples
from uamfleet.radio import RadioMap
from uamfleet.rollout import Trajectory
from uamfleet.viz.colours import TAXI_HEX


class StopEvent(NamedTuple):
    step: int  # the step after which it happened: position index step in Trajectory.positions_m
    taxi: int
    passenger: int
    kind: str  # "pickup" or "dropoff"


def stop_events(traj: Trajectory) -> list[StopEvent]:
    """Every pick-up and drop-off of the episode with the taxi that made it, in time order.

    The events say who boarded (``picked_up`` [P]) and how many each taxi boarded (``pickups`` [A]) at each
    step; when several taxis boarded someone in the same step, each passenger goes to the nearest of them that
    still has a boarding to account for (the env boards within ``pickup_radius_m``). A drop-off is made by the
    taxi that boarded the passenger.
    """
    if traj.num_steps == 0:
        return []
    positions = traj.positions_m  # [A, T + 1, 2]
    picked, dropped = traj.stacked("picked_up"), traj.stacked("dropped_off")  # [T, P]
    pickups, dropoffs = traj.stacked("pickups"), traj.stacked("dropoffs")  # [T, A]
    out: list[StopEvent] = []
    carrier: dict[int, int] = {}
    for t in range(traj.num_steps):
        # Drop-offs first: the env drops off before it boards within a step, freeing seats.
        for kind, per_pax, per_taxi, where in (
            ("dropoff", dropped[t], dropoffs[t], traj.destination_m),
            ("pickup", picked[t], pickups[t], traj.origin_m),
        ):
            left = per_taxi.astype(np.int64).copy()  # [A] stops still to attribute
            for p in np.flatnonzero(per_pax):
                if kind == "dropoff" and int(p) in carrier:
                    a = carrier[int(p)]
                else:
                    dist = np.linalg.norm(positions[:, t + 1] - where[p], axis=-1)
                    a = int(np.argmin(np.where(left > 0, dist, np.inf) if (left > 0).any() else dist))
                left[a] -= 1
                carrier[int(p)] = a
                out.append(StopEvent(t + 1, a, int(p), kind))
    return out


def onboard_counts(traj: Trajectory) -> np.ndarray:
    """[A, T + 1] passengers on board of each taxi at each position index (0 at the start)."""
    num_taxis = traj.start_pos_m.shape[0]
    if traj.num_steps == 0:
        return np.zeros((num_taxis, 1), dtype=np.int64)
    delta = traj.stacked("pickups").astype(np.int64) - traj.stacked("dropoffs").astype(np.int64)  # [T, A]
    return np.concatenate([np.zeros((1, num_taxis), np.int64), np.cumsum(delta, axis=0)]).T


def sinr_along_path(
    positions_m: np.ndarray, radio: RadioMap, slot_s: float, sample_m: float = 10.0
) -> tuple[np.ndarray, np.ndarray]:
    """(time [K] in s, SINR [K] in dB) at points spaced at most ``sample_m`` (and one raster cell) along a
    polyline [T + 1, 2] flown one segment per ``slot_s``; NaN where the raster has no value."""
    points, along = polyline_samples(positions_m, min(sample_m, radio.resolution_m))
    return along * slot_s, radio.sinr_at(points)


def plot_sinr_strip(traj: Trajectory, radio: RadioMap, threshold_db: float, path: str | Path) -> None:
    """SINR along each taxi's flown path over time (one row per taxi), the threshold as a dashed line, time
    below it shaded red, and the pick-ups (S1…) / drop-offs (D1…) as vertical marks. Written atomically."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    from uamfleet.viz.figures import save_figure

    positions = traj.positions_m  # [A, T + 1, 2]
    num_taxis = positions.shape[0]
    fig = Figure(figsize=(8.0, 1.2 + 1.7 * num_taxis), dpi=120)
    FigureCanvasAgg(fig)
    axes = fig.subplots(num_taxis, 1, sharex=True, squeeze=False)[:, 0]
    events = stop_events(traj)
    number = {int(p): i + 1 for i, p in enumerate(np.flatnonzero(traj.pax_exists))}  # S1… as in the other views
    for a, ax in enumerate(axes):
        times, sinr = sinr_along_path(positions[a], radio, traj.slot_s)
        colour = TAXI_HEX[a % len(TAXI_HEX)]
        ax.plot(times, sinr, color=colour, lw=1.3, label=f"taxi {a}")
        ax.axhline(threshold_db, color="k", ls="--", lw=1.0, label=f"γ_T = {threshold_db:g} dB")
        below = np.nan_to_num(sinr, nan=-np.inf) < threshold_db
        low = np.nanmin(sinr) if np.isfinite(sinr).any() else threshold_db
        ax.fill_between(times, min(low, threshold_db) - 1.0, threshold_db, where=below, color="tab:red", alpha=0.3,
                        lw=0, label="below γ_T")  # fmt: skip
        for e in (e for e in events if e.taxi == a):
            t_s = e.step * traj.slot_s
            ax.axvline(t_s, color="0.35", lw=0.8, ls=":")
            tag = f"{'S' if e.kind == 'pickup' else 'D'}{number.get(e.passenger, e.passenger + 1)}"
            ax.annotate(tag, (t_s, 1.0), xycoords=("data", "axes fraction"), xytext=(2, -10),
                        textcoords="offset points", fontsize=8, weight="bold")  # fmt: skip
        ax.set_ylabel("SINR [dB]")
        ax.grid(alpha=0.3)
        ax.legend(loc="lower right", fontsize=7, framealpha=0.85, ncols=3)
    axes[-1].set_xlabel("time [s]")
    delivered = sum(e.kind == "dropoff" for e in events)
    title = f"{traj.scenario} on {radio.label}: SINR along the flown path, γ_T = {threshold_db:g} dB"
    fig.suptitle(f"{title} ({delivered} delivered)", fontsize=10)
    fig.tight_layout()
    save_figure(fig, path)
