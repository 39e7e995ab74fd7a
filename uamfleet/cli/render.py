"""Fly one episode and write it as a 3-D page (meshcat, one offline HTML file), optionally with PNG figures.

    uamfleet-render --scenario berlin_p4 --policy raster_replan --out berlin.html --png
    .venv/bin/python -m eval.render --scenario berlin_random --policy greedy --num-taxis 4 --out fleet.html

``--policy``: any name of :mod:`uamfleet.policies` in its grammar, as ``uamfleet rollout`` takes it: a planner
(single taxi: cptsp, pdpcc, raster_replan, raster_opt, straight, replan, best_known), a fleet dispatcher
(``greedy``, ``insertion``, ``batch_assignment``), ``random``, a learned policy (``learned:source=berlin_stops``)
or a search over one (``argmax(learned)``, ``guided:top_k=4(learned)``). ``--png`` also writes
``<out stem>_routes.png`` (the route over the radio map, stops S1…/D1…) and ``<out stem>_sinr.png`` (SINR along
the path over time, with the threshold). Screenshot the page with ``scripts/screenshot.sh``. ``--out`` is
relative to the current folder; its folder must exist or be one new folder inside an existing one.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Annotated, Any

import matplotlib
from cycler import cycler

import uamfleet
from uamfleet.cli._common import (
    SCENARIO_DEFAULT,
    MapName,
    Policy,
    Scenario,
    UsageError,
    check_map,
    check_outputs,
    flight,
    on_map,
    fmt,
    output_path,
    policy_call,
    run,
)
from uamfleet.metrics import episode_metrics
from uamfleet.rl.policy import load_policy
from uamfleet.instances import map_provenance
from uamfleet.rollout import Trajectory
from uamfleet.rollout import fly as fly_episode
from uamfleet.viz.colours import TAXI_HEX
from uamfleet.viz.figures import plot_routes
from uamfleet.viz.meshcat_view import FleetViewer
from uamfleet.viz.strip import plot_sinr_strip


@dataclass
class Args:
    scenario: Scenario = "berlin_p4"
    """scenario name (with --map: berlin_instances unless named, a scenario of random demand)"""
    map: MapName = None
    policy: Policy = "raster_replan"
    out: Path = Path("render.html")
    """HTML file to write (relative to the current folder; its folder must exist, or be one new folder in an
    existing one)"""
    png: bool = False
    """also write <stem>_routes.png and <stem>_sinr.png next to the HTML"""
    sinr_min_db: Annotated[float | None, SCENARIO_DEFAULT] = None
    """SINR threshold in dB"""
    num_taxis: Annotated[int | None, SCENARIO_DEFAULT] = None
    """fleet size"""
    seed: int = 0
    """episode seed (random demand and starts, the random policy)"""
    seconds_per_step: float = 0.25
    """playback time of one env step in the page"""
    checkpoint: Path | None = None
    """a policy trained by train/ppo.py (runs/<name>/best.pt); flies it greedily instead of --policy, on its
    training scenario and threshold unless --scenario / --sinr-min-db say otherwise"""
    overwrite: bool = False
    """replace an existing --out (and its PNG figures): else the command refuses before flying"""


def fly(args: Args) -> tuple[Trajectory, uamfleet.EnvConfig]:
    """One episode of ``args.policy``; returns it with the config whose threshold the picture shows (a planner
    may be flown under other rules, e.g. the straight line with the threshold off)."""
    overrides: dict[str, Any] = {
        k: v for k, v in (("sinr_min_db", args.sinr_min_db), ("num_taxis", args.num_taxis)) if v is not None
    }
    if args.checkpoint is not None:
        policy, trained = load_policy(args.checkpoint)
        overrides = {"feasibility": trained.env.feasibility, **trained.env_overrides(training=False), **overrides}
        scenario = trained.env.scenario if args.scenario == "berlin_p4" and args.map is None else args.scenario
        scenario, overrides = on_map(args.map, scenario, overrides)
        shown = uamfleet.make_config(scenario, **overrides)
        return fly_episode(shown, policy, seed=args.seed), shown
    scenario, overrides = on_map(args.map, args.scenario, overrides)
    flown, shown, policy = flight(scenario, args.policy, args.seed, overrides)
    return fly_episode(flown, policy, seed=args.seed), shown


def figure_paths(out: Path) -> dict[str, Path]:
    """The PNG figures of ``--png`` beside the page: ``<stem>_routes.png`` and ``<stem>_sinr.png``."""
    stem = out.with_suffix("")
    return {kind: stem.with_name(f"{stem.name}_{kind}.png") for kind in ("routes", "sinr")}


def main(args: Args) -> dict[str, Path]:
    if args.seed < 0:
        raise UsageError(f"--seed {args.seed}: seeds are integers >= 0 (e.g. --seed 0).")
    if not args.seconds_per_step > 0:
        raise UsageError(f"--seconds-per-step {args.seconds_per_step}: give a positive playback time (e.g. 0.25).")
    if args.checkpoint is None:
        policy_call(args.policy)
    if args.map is not None:
        check_map(args.map)
    output_path(args.out, "--out")
    check_outputs(args.overwrite, [args.out, *(figure_paths(args.out).values() if args.png else ())])
    if args.map is not None:
        print(f"Map: {map_provenance(args.map)}.")
    if args.checkpoint is not None:
        args.policy = "msha"
    traj, cfg = fly(args)
    radio, threshold = cfg.radio, cfg.sinr_min_db
    m = episode_metrics(traj, radio, threshold_db=threshold)
    fleet = f"{cfg.num_taxis} taxis" if cfg.num_taxis > 1 else "1 taxi"
    title = f"{cfg.scenario} · {args.policy} · {fleet} · γ_T = {threshold:g} dB · map: {radio.label}"
    written: dict[str, Path] = {}
    with FleetViewer(radio, threshold, seconds_per_step=args.seconds_per_step, title=title) as viewer:
        viewer.show_trajectory(traj)
        written["html"] = viewer.export_html(args.out)
    if args.png:
        routes = {f"taxi {a}" if cfg.num_taxis > 1 else args.policy: traj.positions_m[a] for a in range(cfg.num_taxis)}
        exists = traj.pax_exists
        written.update(figure_paths(args.out))
        # Fleet routes take the taxis' colours of the 3-D page (plot_routes colours unnamed routes by the cycle);
        # every taxi's start is starred in its colour.
        with matplotlib.rc_context({"axes.prop_cycle": cycler(color=list(TAXI_HEX))}):
            plot_routes(radio, threshold, routes, traj.origin_m[exists], traj.destination_m[exists],
                        traj.start_pos_m, f"{title}\n{m.delivered}/{m.num_requests} delivered, TD {m.td_m:.0f} m, "
                        f"connectivity {m.connectivity_pct:.1f} %", written["routes"])  # fmt: skip
        plot_sinr_strip(traj, radio, threshold, written["sinr"])
    end = "all delivered" if traj.terminated else "truncated"
    print(
        f"{title}: {traj.num_steps} steps ({end}), {m.delivered}/{m.num_requests} delivered, "
        f"TD {fmt(m.td_m, '.0f', ' m')}, connectivity {fmt(m.connectivity_pct, '.1f', ' %')}"
    )
    for kind, path in written.items():
        print(f"wrote {kind}: {path} ({path.stat().st_size / 1e6:.2f} MB)")
    return written


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-render") -> int:
    """The ``uamfleet-render`` command (``python -m eval.render``)."""
    return run(main, Args, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.render"))
