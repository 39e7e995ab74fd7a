"""Fly a policy (a planner, a fleet dispatcher or random) for a few episodes of a scenario and print each
episode's metrics.

    uamfleet-rollout --scenario berlin_p4 --policy raster_replan --episodes 3
    .venv/bin/python -m eval.rollout --scenario berlin_random --policy greedy --num-taxis 4
    uamfleet-rollout --map munich --policy replan --episodes 2       # a packaged map, or a map file's path
    uamfleet-rollout --scenario berlin_p4 --policy "guided:top_k=4(learned:source=berlin_stops)" --episodes 1

``--policy`` takes any name of :mod:`uamfleet.policies` (``uamfleet.policies.available()``) in its grammar: a
planner, a fleet dispatcher, ``random``, a learned policy (``learned:source=<shipped name or checkpoint file>``)
or a search over one (``argmax(learned)``, ``guided(...)``, ``hedge(...)``, ``finish(...)``), and the names the
benchmarks recorded (``batch_assignment+wait=1+release``, ``learned:berlin_stops``).

Undefined figures print as "–": ATT / AWT when no ride finished or began, and "(min –)" when a taxi's path
crosses a cell the radio map has no value for (NaN: "N.C.", not computed, in a WinProp file; black in the
viewer): such a sample counts as an outage in connectivity, and the minimum SINR along the path is then -inf.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Annotated

import numpy as np

import uamfleet
from uamfleet.env.protocol import observer_of
from uamfleet.cli._common import (
    SCENARIO_DEFAULT,
    MapName,
    Policy,
    Scenario,
    UsageError,
    flight,
    fmt,
    on_map,
    policy_call,
    run,
)
from uamfleet.instances import map_provenance
from uamfleet.metrics import episode_metrics
from uamfleet.rollout import run_episode


@dataclass
class Args:
    scenario: Scenario = "berlin_p4"
    """scenario name (with --map: berlin_instances unless named, a scenario of random demand)"""
    map: MapName = None
    sinr_min_db: Annotated[float | None, SCENARIO_DEFAULT] = None
    """SINR threshold in dB"""
    num_taxis: Annotated[int | None, SCENARIO_DEFAULT] = None
    """fleet size"""
    policy: Policy = "random"
    episodes: int = 3
    """number of episodes (>= 1)"""
    seed: int = 0
    """seed of the first episode (episode i uses seed + i; >= 0)"""
    time_limit_steps: Annotated[int | None, SCENARIO_DEFAULT] = None
    """episode time limit in steps"""

    def __post_init__(self) -> None:
        if self.episodes < 1:
            raise UsageError(f"--episodes {self.episodes}: fly at least one episode (e.g. --episodes 3).")
        if self.seed < 0:
            raise UsageError(f"--seed {self.seed}: seeds are integers >= 0 (e.g. --seed 0).")
        policy_call(self.policy)


def main(args: Args) -> list[dict[str, float]]:
    overrides = {
        k: v
        for k, v in (
            ("sinr_min_db", args.sinr_min_db),
            ("num_taxis", args.num_taxis),
            ("time_limit_steps", args.time_limit_steps),
        )
        if v is not None
    }
    scenario, overrides = on_map(args.map, args.scenario, overrides)
    flown, cfg, policy = flight(scenario, args.policy, args.seed, overrides)  # cfg: the rules it is scored by
    env = uamfleet.VectorEnv(flown, num_envs=1, autoreset=False, observer=observer_of(policy))
    if args.map is not None:
        print(f"Map: {map_provenance(args.map)}.")
    print(
        f"{cfg.scenario} on {cfg.radio.label}: {cfg.num_taxis} taxi(s), γ_T = {cfg.sinr_min_db:g} dB, "
        f"{cfg.num_passengers} passenger slot(s), policy={args.policy}"
    )
    rows = []
    for i in range(args.episodes):
        traj = run_episode(env, policy, seed=args.seed + i)
        m = episode_metrics(traj, cfg.radio, threshold_db=cfg.sinr_min_db)
        rows.append(m.as_dict())
        end = "terminated" if traj.terminated else "truncated"
        print(
            f"  episode {i}: {end} after {m.steps} steps, PR {m.pr_pct:.0f} % ({m.delivered}/{m.num_requests}), "
            f"TD {fmt(m.td_m, '.0f', ' m')}, ATT {fmt(m.att_s, '.1f', ' s')}, AWT {fmt(m.awt_s, '.1f', ' s')}, "
            f"ELR {fmt(m.elr_pct, '.1f', ' %')}, connectivity {fmt(m.connectivity_pct, '.1f', ' %')} "
            f"(min {fmt(m.min_sinr_db, '.2f', ' dB')}), "
            f"return {float(np.sum(traj.episode['return'])):.1f}"
        )
    return rows


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-rollout") -> int:
    """The ``uamfleet-rollout`` command (``python -m eval.rollout``)."""
    return run(main, Args, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.rollout"))
