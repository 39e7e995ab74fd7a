"""Fit a demand model on past episodes of an instance family, and score it on held-out ones against the true law.

    uamfleet demand fit --family berlin_stream --split train --count 500 \\
        --out docs/results/demand_models/berlin_stream.json
    uamfleet demand check --model docs/results/demand_models/berlin_stream.json --family berlin_stream \\
        --split validation --count 200

``fit`` reads the requests of ``--count`` instances of the split (uamfleet/instances.py) and writes the fitted
:class:`~uamfleet.baselines.demand_models.EstimatedDemand` as JSON (atomically; an existing file only with
``--overwrite``). ``check`` prints the log-likelihood per episode of other instances under the fitted model, the
family's true law and the deliberately wrong one (uamfleet/baselines/demand_models.py), the mean over the episodes
that every model finds possible, the count of episodes each finds impossible, the paired difference fitted − true
with its 95 % interval, and the total variation between the fitted and the true origin and destination pmfs.
"""

from __future__ import annotations

import math
import sys
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from uamfleet.baselines.demand_models import EstimatedDemand, FamilyLaw, wrong_model
from uamfleet.cli._common import Family, Split, UsageError, check_outputs, output_path, run
from uamfleet.config import EnvConfig
from uamfleet.instances import make_instance, split_seeds
from uamfleet.sim.generator import flyable_sites
from uamfleet.sim.world import World

SUBCOMMANDS = ("fit", "check")


@dataclass
class FitArgs:
    out: Path
    """the model's JSON file"""
    family: Family = "berlin_stream"
    """instance family whose past episodes are read"""
    split: Split = "train"
    count: int = 500
    """episodes (instances) to fit on"""
    first: int = 0
    """index of the first seed in the split"""
    bin_steps: int = 5
    """steps per bin of the arrival intensity"""
    floor: float = 0.05
    """share of origins and destinations spread uniformly over a world's sites"""
    overwrite: bool = False
    """replace an existing --out"""


@dataclass
class CheckArgs:
    model: Path
    """a model written by `uamfleet demand fit`"""
    family: Family = "berlin_stream"
    """instance family of the held-out episodes"""
    split: Split = "validation"
    count: int = 200
    """held-out episodes"""
    first: int = 0
    """index of the first seed in the split"""


def _instances(family: str, split: str, count: int, first: int) -> list[EnvConfig]:
    if count < 1:
        raise UsageError(f"--count {count}: read at least one episode, e.g. --count 200.")
    return [make_instance(family, seed) for seed in split_seeds(split, count, first)]


def fit_main(args: FitArgs) -> int:
    output_path(args.out, "--out")
    check_outputs(args.overwrite, [args.out])
    cfgs = _instances(args.family, args.split, args.count, args.first)
    model = EstimatedDemand.fit([c.requests or () for c in cfgs], cfgs[0].slot_s, args.bin_steps, floor=args.floor)
    model.save(args.out)
    expected = float(np.arange(len(model.initial_pmf)) @ model.initial_pmf + model.intensity.sum())
    print(
        f"fitted on {model.episodes} {args.family} {args.split} episodes: requests at step 0 "
        f"{np.round(model.initial_pmf, 3).tolist()}, arrivals until step {model.window_steps} "
        f"({expected:.2f} requests per episode before the cap of {model.cap}), origin / destination bandwidth "
        f"{model.origin_bw_m:g} / {model.dest_bw_m:g} m, shortest trip {model.min_trip_m:g} m; wrote {args.out}"
    )
    return 0


def _tv(a: np.ndarray, b: np.ndarray) -> float:
    return 0.5 * float(np.abs(a - b).sum())


def check_main(args: CheckArgs) -> int:
    fitted = EstimatedDemand.load(args.model)
    cfgs = _instances(args.family, args.split, args.count, args.first)
    if not math.isclose(fitted.slot_s, cfgs[0].slot_s):
        raise UsageError(f"--model {args.model} counts steps of {fitted.slot_s:g} s and {args.family} of "
                         f"{cfgs[0].slot_s:g} s: fit it on this family.")  # fmt: skip
    names = ("fitted", "true", "wrong")
    worlds: dict[float, tuple[EstimatedDemand, FamilyLaw, FamilyLaw]] = {}
    ll = np.zeros((len(cfgs), 3))
    for i, cfg in enumerate(cfgs):
        if cfg.sinr_min_db not in worlds:  # one binding per threshold: the sites differ
            sites = flyable_sites(World(cfg))
            worlds[cfg.sinr_min_db] = (fitted.on_world(sites), FamilyLaw.of_family(args.family, cfg),
                                       wrong_model(args.family, cfg))  # fmt: skip
        ll[i] = [m.log_likelihood(cfg.requests or (), cfg.slot_s) for m in worlds[cfg.sinr_min_db]]
    possible = np.isfinite(ll).all(1)
    print(f"{args.family} {args.split} episodes {args.first}..{args.first + args.count - 1} ({len(cfgs)}); model "
          f"{args.model} fitted on {fitted.episodes} episodes")  # fmt: skip
    print(f"log-likelihood per episode over the {int(possible.sum())} episodes every model finds possible:")
    print("| model | mean log-likelihood | impossible episodes |")
    print("|---|---:|---:|")
    for j, name in enumerate(names):
        mean = float(ll[possible, j].mean()) if possible.any() else math.nan
        print(f"| {name} | {mean:.2f} | {int((~np.isfinite(ll[:, j])).sum())} |")
    if possible.sum() > 1:
        diff = ll[possible, 0] - ll[possible, 1]
        half = 1.96 * float(diff.std(ddof=1)) / math.sqrt(len(diff))
        print(f"fitted - true: {diff.mean():+.2f} ± {half:.2f} per episode (95 %)")
    tv = [(_tv(f.origin_pmf, t.origin_pmf), _tv(f.dest_pmf, t.dest_pmf)) for f, t, _ in worlds.values()]
    origins, dests = np.mean(tv, axis=0)
    print(f"total variation fitted vs true, mean over the {len(tv)} thresholds: origins {origins:.3f}, "
          f"destinations {dests:.3f}")  # fmt: skip
    return 0


def usage(prog: str) -> str:
    return (f"usage: {prog} {{fit,check}} [options]\n\n{(__doc__ or '').strip()}\n\n"
            f"'{prog} fit --help' and '{prog} check --help' list their options.")  # fmt: skip


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet demand") -> int:
    """The ``uamfleet demand`` command: ``fit`` or ``check`` and its options."""
    args = list(sys.argv[1:] if argv is None else argv)
    if args[:1] in (["-h"], ["--help"]):
        print(usage(prog))
        return 0
    if not args or args[0] not in SUBCOMMANDS:
        given = f"unknown subcommand {args[0]!r}" if args else "no subcommand"
        print(f"{prog}: error: {given}; use `{prog} fit ...` or `{prog} check ...` ({prog} --help).", file=sys.stderr)
        return 2
    if args[0] == "fit":
        return run(fit_main, FitArgs, args[1:], f"{prog} fit", __doc__)
    return run(check_main, CheckArgs, args[1:], f"{prog} check", __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.demand"))
