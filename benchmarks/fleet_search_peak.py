"""Fleet dispatchers and searches on fleet episodes drawn with another release law than the one the fleet search's
``demand=true`` model assumes: a peak in the middle of the arrival window.

Each episode is a fleet validation instance (:func:`uamfleet.instances.make_fleet_instance`: its taxis, trips and
threshold) whose release steps are redrawn from a normal law centred on the window's middle (standard deviation
``--peak-sd`` of the window), rounded and clipped to the window. The scenario name is the instance's, so a search
with ``demand=true`` samples uniform releases (the law of the instances, wrong here), and one with
``demand=estimated`` estimates a homogeneous rate from what it has seen (also wrong, but learnt). One row per
(episode, method), the fleet benchmark's metrics:

    OMP_NUM_THREADS=1 nice -n 10 .venv/bin/python benchmarks/fleet_search_peak.py --count 10 \\
        --out-csv docs/results/fleet_search_peak_val_4x48.csv
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch
import tyro
from fleet_search_time import fly_fleet

from uamfleet.baselines.assignment_value import CHOSEN_DISPATCHER
from uamfleet.cli.fleet_benchmark import dispatcher
from uamfleet.config import EnvConfig, Request, fleet_window_steps
from uamfleet.instances import make_fleet_instance, split_seeds
from uamfleet.io import write_csv_atomic
from uamfleet.metrics import episode_metrics


@dataclass
class Args:
    names: tuple[str, ...] = (
        CHOSEN_DISPATCHER,
        f"fleet_search:demand=estimated,futures=2,waits=3,end_wait=1({CHOSEN_DISPATCHER})",
    )
    family: str = "berlin"
    taxis: int = 4
    requests: int = 48
    count: int = 10
    first: int = 0
    peak_sd: float = 0.125
    """the releases' standard deviation, as a share of the arrival window"""
    out_csv: Path | None = None


def peaked(cfg: EnvConfig, seed: int, sd_share: float) -> EnvConfig:
    """``cfg`` with its requests' release steps redrawn around the window's middle (the trips kept, in order)."""
    window = fleet_window_steps(cfg.slot_s)
    rng = np.random.default_rng([seed, 7])
    steps = np.sort(np.clip(np.rint(rng.normal(window / 2, sd_share * window, len(cfg.requests))), 0, window - 1))
    requests = tuple(Request(int(s), r.origin_m, r.destination_m) for s, r in zip(steps, cfg.requests, strict=True))
    return cfg.replace(requests=requests)


def episode_row(cfg: EnvConfig, name: str, seed: int, setting: str) -> dict[str, Any]:
    """The fleet benchmark's metrics of ``name`` flown once on ``cfg``."""
    traj = fly_fleet(cfg, dispatcher(name, cfg.num_taxis, None, None))
    m = episode_metrics(traj, cfg.radio)
    return {
        "family": "berlin_peak", "setting": setting, "seed": seed, "dispatcher": name, "num_requests": m.num_requests,
        "delivered": m.delivered, "service_pct": m.pr_pct, "wait_p50_s": m.wait_p50_s, "wait_p95_s": m.wait_p95_s,
        "td_m": m.td_m, "td_per_delivered_m": m.td_m / max(m.delivered, 1),
        "separation_violations": m.separation_violations, "shield_interventions": m.shield_interventions,
        "policy_s": float(np.sum(traj.decision_s)),
    }  # fmt: skip


def main(args: Args) -> list[dict[str, Any]]:
    torch.set_num_threads(1)
    setting = f"{args.taxis}x{args.requests}"
    rows = []
    for seed in split_seeds("validation", args.count, args.first):
        base = make_fleet_instance(args.family, seed, args.taxis, args.requests, separation="shield", hover_action=True)
        cfg = peaked(base, seed, args.peak_sd)
        for name in args.names:
            row = episode_row(cfg, name, seed, setting)
            rows.append(row)
            print(
                f"{seed} {name}: TD/delivered {row['td_per_delivered_m']:,.1f} m, wait p50 "
                f"{row['wait_p50_s']:.1f} p95 {row['wait_p95_s']:.1f} s, delivered {row['delivered']}",
                flush=True,
            )
        if args.out_csv is not None:  # after every episode: a run stopped early keeps what it flew
            write_csv_atomic(args.out_csv, rows, list(rows[0]))
    return rows


if __name__ == "__main__":
    main(tyro.cli(Args))
