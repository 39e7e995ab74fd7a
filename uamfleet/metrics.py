"""Episode metrics from a :class:`~uamfleet.rollout.Trajectory` (the paper's definitions; the list
below is also section "Metrics" of ``docs/rules.md``).

Everything is computed from the recorded events and the instance; nothing re-simulates the episode. Times are
in seconds (steps × ``slot_s``), distances in metres.

- TD: distance flown by all taxis until the last drop-off (the whole episode if some passenger was not
  delivered).
- ATT / AWT: mean over delivered passengers of drop-off − request / pick-up − request.
- ELR: share of flight time (taxi-steps until the last drop-off) with **nobody** on board (the paper's
  definition; the authors' code counted steps with the taxi *full*).
- PR: share of passengers delivered.
- Connectivity: share of points sampled every ``<= sample_m`` along the flown path (same span as TD) whose
  raster SINR (N.C. = outage) is at or above the threshold; and the minimum SINR along it.
- Fleet: service rate, wait p50 / p95, ride detour (ride time ÷ direct straight-line flight time), occupancy
  (mean passengers on board per taxi-step ÷ seats), separation violations (taxi-steps closer than the
  minimum), decision latency per step.
- Separation shield (``EnvConfig.separation="shield"``, docs/rules.md "Separation shield"): interventions (taxi-steps
  whose allowed move the shield replaced, its hovers included), over the same span as TD; per taxi-hour
  ``count / (taxis * completion_s / 3600)``.
- Hovers: taxi-steps spent in place by a hover, chosen (the hover action, ``EnvConfig.hover_action``) or the
  shield's; ``hover_actions`` counts the chosen ones. The shield's are ``hovers - hover_actions`` except where it
  moved a taxi in conflict apart instead of the hover it chose (docs/rules.md "Separation shield", rule 7). Same span as
  TD; hover seconds are ``hovers * slot_s`` (the time an energy model prices, docs/rules.md "Motion").
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass

import numpy as np

from uamfleet.radio import RadioMap
from uamfleet.rollout import Trajectory
from uamfleet.types import HOVER_ACTION


@dataclass(frozen=True)
class EpisodeMetrics:
    td_m: float
    att_s: float
    awt_s: float
    elr_pct: float
    pr_pct: float
    connectivity_pct: float
    min_sinr_db: float
    completion_s: float  # time of the last drop-off (or of the episode's end)
    delivered: int
    num_requests: int
    wait_p50_s: float
    wait_p95_s: float
    detour_ratio: float  # mean over delivered passengers
    occupancy: float
    separation_violations: int
    decision_ms_mean: float
    steps: int
    shield_interventions: int = 0  # taxi-steps whose move the separation shield replaced (its hovers included)
    hovers: int = 0  # taxi-steps in place by a hover (chosen or the shield's): time passes, no distance flown
    hover_actions: int = 0  # taxi-steps that chose the hover action (EnvConfig.hover_action)
    interventions_per_taxi_h: float = 0.0  # shield_interventions / (taxis * completion_s / 3600 s)

    def as_dict(self) -> dict[str, float]:
        return {k: float(v) for k, v in asdict(self).items()}


def polyline_samples(path_m: np.ndarray, sample_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Points along a polyline [T + 1, 2], spaced at most ``sample_m`` apart, each vertex once: ([K, 2] points,
    [K] where each lies in segments flown: segment index + fraction, T at the last vertex)."""
    if len(path_m) == 1:
        return path_m.copy(), np.zeros(1)
    starts, ends = path_m[:-1], path_m[1:]
    lengths = np.linalg.norm(ends - starts, axis=-1)
    counts = np.maximum(np.ceil(lengths / sample_m - 1e-9), 1).astype(np.int64)  # samples per segment, start incl.
    seg = np.repeat(np.arange(len(starts)), counts)
    frac = (np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts)) / counts[seg]
    points = starts[seg] + frac[:, None] * (ends[seg] - starts[seg])
    return np.concatenate([points, path_m[-1:]]), np.concatenate([seg + frac, [len(starts)]])


def path_samples(path_m: np.ndarray, sample_m: float) -> np.ndarray:
    """[K, 2] points along a polyline [T + 1, 2], spaced at most ``sample_m`` apart, each vertex once."""
    return polyline_samples(path_m, sample_m)[0]


def connectivity(
    path_m: np.ndarray, radio: RadioMap, threshold_db: float, sample_m: float = 10.0
) -> tuple[float, float]:
    """(share of samples with SINR >= threshold in %, minimum SINR in dB) along one taxi's polyline."""
    samples = path_samples(path_m, min(sample_m, radio.resolution_m))
    sinr = radio.sinr_at(samples)
    ok = np.nan_to_num(sinr, nan=-np.inf) >= threshold_db
    return 100.0 * float(ok.mean()), float(np.nan_to_num(sinr, nan=-np.inf).min())


def fleet_connectivity(
    positions: np.ndarray, radio: RadioMap, threshold_db: float, sample_m: float = 10.0
) -> tuple[float, float]:
    """(share of samples with SINR >= threshold over all taxis' polylines [A, T, 2] in %, weighted by each
    polyline's samples; the minimum SINR in dB over them)."""
    conn = [connectivity(positions[a], radio, threshold_db, sample_m) for a in range(positions.shape[0])]
    samples = [len(path_samples(positions[a], min(sample_m, radio.resolution_m))) for a in range(positions.shape[0])]
    return float(np.average([c[0] for c in conn], weights=samples)), min(c[1] for c in conn)


def _mean_or_nan(x: np.ndarray) -> float:
    return float(np.mean(x)) if x.size else math.nan


def _service_steps(traj: Trajectory) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(release, pick-up, drop-off) step of each existing passenger; NaN where the pick-up or drop-off never
    happened."""
    exists = traj.pax_exists
    picked = traj.stacked("picked_up")[:, exists]  # [T, N]
    dropped = traj.stacked("dropped_off")[:, exists]
    steps_idx = np.arange(1, traj.num_steps + 1)  # the step index after each transition
    release = traj.release_step[exists].astype(float)
    pickup_step = np.where(picked.any(0), steps_idx[np.argmax(picked, axis=0)], np.nan)
    dropoff_step = np.where(dropped.any(0), steps_idx[np.argmax(dropped, axis=0)], np.nan)
    return release, pickup_step, dropoff_step


def _load_shares(traj: Trajectory, span: int) -> tuple[float, float]:
    """(ELR in %: share of taxi-steps with nobody on board, occupancy: mean passengers on board per seat) over
    the first ``span`` steps."""
    pickups = traj.stacked("pickups")[:span]
    dropoffs = traj.stacked("dropoffs")[:span]
    # passengers on board during each step = boarded before it minus delivered before it
    on_board = np.cumsum(pickups - dropoffs, axis=0) - (pickups - dropoffs)  # [span, A]
    return 100.0 * float(np.mean(on_board == 0)), float(np.mean(on_board) / traj.seats)


def episode_metrics(
    traj: Trajectory, radio: RadioMap, threshold_db: float | None = None, sample_m: float = 10.0
) -> EpisodeMetrics:
    """Metrics of one recorded episode. ``threshold_db`` defaults to the episode's own threshold (pass the
    real one when the episode was flown with SINR ignored, e.g. the straight-line baseline)."""
    if traj.num_steps == 0:
        raise ValueError("the trajectory has no steps; run at least one step before computing metrics.")
    threshold = traj.sinr_min_db if threshold_db is None else threshold_db
    slot = traj.slot_s
    exists = traj.pax_exists
    release, pickup_step, dropoff_step = _service_steps(traj)
    delivered = ~np.isnan(dropoff_step)
    num_requests = int(exists.sum())
    # span: until the last drop-off when everyone was delivered, else the whole episode
    span = int(np.nanmax(dropoff_step)) if delivered.all() and num_requests else traj.num_steps

    moved = traj.stacked("moved")[:span]  # [span, A]
    td = float(moved.sum() * traj.step_m)
    elr, occupancy = _load_shares(traj, span)

    wait_s = (pickup_step - release) * slot
    ride_s = (dropoff_step - release) * slot
    direct_s = np.linalg.norm(traj.destination_m[exists] - traj.origin_m[exists], axis=-1) / (traj.step_m / slot)
    in_vehicle_s = (dropoff_step - pickup_step) * slot
    detour = in_vehicle_s[delivered] / np.maximum(direct_s[delivered], 1e-9)

    conn_pct, min_sinr = fleet_connectivity(traj.positions_m[:, : span + 1], radio, threshold, sample_m)
    interventions = int(traj.stacked("shield_intervened")[:span].sum())
    taxi_hours = traj.start_pos_m.shape[0] * max(span, 1) * slot / 3600.0  # an episode lasts at least one step
    return EpisodeMetrics(
        td_m=td,
        att_s=_mean_or_nan(ride_s[delivered]),
        awt_s=_mean_or_nan(wait_s[~np.isnan(wait_s)]),
        elr_pct=elr,
        pr_pct=100.0 * float(delivered.mean()) if num_requests else 100.0,
        connectivity_pct=conn_pct,
        min_sinr_db=min_sinr,
        completion_s=span * slot,
        delivered=int(delivered.sum()),
        num_requests=num_requests,
        wait_p50_s=float(np.nanpercentile(wait_s, 50)) if np.isfinite(wait_s).any() else math.nan,
        wait_p95_s=float(np.nanpercentile(wait_s, 95)) if np.isfinite(wait_s).any() else math.nan,
        detour_ratio=_mean_or_nan(detour),
        occupancy=occupancy,
        separation_violations=int(traj.stacked("separation_violation")[:span].sum()),
        decision_ms_mean=1000.0 * float(np.mean(traj.decision_s)) if traj.decision_s else math.nan,
        steps=traj.num_steps,
        shield_interventions=interventions,
        hovers=int(traj.stacked("hovered")[:span].sum()),
        hover_actions=int((traj.stacked("actions")[:span] == HOVER_ACTION).sum()),
        interventions_per_taxi_h=interventions / taxi_hours,
    )
