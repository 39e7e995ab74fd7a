"""Every fleet dispatcher over seeded held-out fleet instances, in parallel: the fleet table.

    .venv/bin/python -m eval.fleet_benchmark --count 100 --jobs 2                       # Berlin, 1 / 2 / 4 / 8 taxis
    .venv/bin/python -m eval.fleet_benchmark --family detroit3gpp --settings 4x24 --count 100 --jobs 2

Instances come from :func:`uamfleet.instances.make_fleet_instance` (``--split test`` by default; settings
:data:`uamfleet.instances.FLEET_SETTINGS`, or any ``<taxis>x<requests>`` such as the loaded ``4x48`` and ``8x96``:
taxis x requests per episode, released over the first 10 minutes, or ``--arrival-window-s``), flown as the
``*_fleet`` presets fly them: under the separation shield, idle taxis hovering (``--separation none`` and
``--no-hover-action`` fly the earliest recorded tables' rules). A learned fleet reads
every request of the episode on its passenger axis: it is flown with as many passenger slots as the setting has
requests (``learned:source=<file>,taxis=<n>,passenger_slots=<requests>``; the light settings' own default), or with
``--passenger-window K`` each taxi reads K rows, its riders and nearest waiting requests, for any number of requests
(``learned:...,passenger_window=K``, flown as ``learned:<name>+window<K>``; docs/rules.md "Passenger window"); it
flies each instance's world as made, observed by its spec. Every dispatcher is flown
through the same env and scored by :mod:`uamfleet.metrics`. Episodes run seed by seed across the settings, so an
interrupted run still covers every setting. Per setting and dispatcher the table gives means with 95 % intervals (normal
approximation, 1.96 standard errors over episodes) of the service rate, the episode's wait p50 and p95, the ride
detour, TD per delivered passenger, occupancy, separation violations and connectivity, and the decision time per
taxi per step (policy wall time of a step ÷ taxis; median and maximum over all steps; the feasible-path distance
field of every stop, which all dispatchers share, is computed once per instance before they fly and is not in it:
``fields_s`` in the CSV). Outputs: a CSV of every
(episode, dispatcher) row and the printed table (with ``--out-md FILE``, also the marked section ``fleet``, or
``--section``, of FILE; the results pages are generated from the CSVs by ``uamfleet docs-tables``), written
once, at the end of a complete run, and replacing existing results only with ``--overwrite``; a long run keeps
its partial rows beside the CSV (``<name>.partial.csv``; ``--from-csv`` renders them).
"""

from __future__ import annotations

import csv
import functools
import math
import multiprocessing as mp
import time
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

import numpy as np

from uamfleet.baselines import FLEET_DISPATCHERS
from uamfleet.baselines.assignment_value import VALUE_DISPATCHER, shipped_value_path
from uamfleet.baselines.fleet_steering import shared_fields
from uamfleet.checks import ConfigError, check_integer, check_number
from uamfleet.cli._common import (
    MapName,
    UsageError,
    check_jobs,
    check_map,
    check_outputs,
    earlier_rows,
    fmt,
    output_paths,
    run,
    with_provenance,
)
from uamfleet.cli.benchmark_tables import ci, command_header
from uamfleet.cli.docs_tables import REFRESH_HINT
from uamfleet.config import WorldConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import FLEET_ARRIVAL_WINDOW_S, FLEET_SETTINGS, fleet_setting, make_fleet_instance, split_seeds
from uamfleet.io import partial_path, replace_section, write_csv_atomic
from uamfleet.metrics import episode_metrics
from uamfleet.policies import PolicyNameError, available, kind_of, make, make_flown, parse
from uamfleet.policies.registry import BASE
from uamfleet.policies.search import FLEET_SEARCH
from uamfleet.rollout import fly

COLUMNS = ("family", "setting", "taxis", "seed", "threshold_db", "dispatcher", "num_requests", "delivered",
           "service_pct", "wait_p50_s", "wait_p95_s", "awt_s", "detour", "td_m", "td_per_delivered_m", "occupancy",
           "separation_violations", "connectivity_pct", "steps", "decision_p50_ms", "decision_max_ms",
           "policy_s", "fields_s", "shield_interventions", "hovers", "interventions_per_taxi_h",
           "hover_actions")  # fmt: skip


@dataclass
class Args:
    family: str = "berlin"
    """instance family (uamfleet.instances.FAMILIES)"""
    map: MapName = None
    settings: tuple[str, ...] = tuple(FLEET_SETTINGS)
    """fleet settings (taxis x requests): uamfleet.instances.FLEET_SETTINGS"""
    split: str = "test"
    count: int = 100
    """episodes per setting"""
    first: int = 0
    """index of the first seed in the split"""
    dispatchers: tuple[str, ...] = FLEET_DISPATCHERS
    """(insertion, batch_assignment and batch_assignment_value[:<price_s>] may end in +wait=<β>: schedules cost
    ride time + β · wait; the batch assignments also in +release: re-assigned at every release too; a dispatcher
    searched at decision time: fleet_search:OPTIONS(<dispatcher>), uamfleet.baselines.fleet_search)"""
    assignment_value: Path | None = None
    """the value file of the dispatchers batch_assignment_value[:<price_s>] (default: the shipped one,
    uamfleet/data/pretrained/assignment_value.json; train one with python -m train.assignment_value); with another
    file their rows are named <dispatcher>@<file stem>, apart from the shipped value's"""
    checkpoints: tuple[Path, ...] = ()
    """learned fleet policies (runs/<name>/best.pt), each flown on the settings of its fleet size as
    "learned:<run name>" ("learned:<file stem>" for other file names; its passenger axis padded to the instance)"""
    merge_csv: Path | None = None
    """add an earlier run's rows (e.g. the dispatchers) on the episodes flown now to this run's; rows of a
    dispatcher flown now replace its earlier rows"""
    separation: Literal["none", "shield"] = "shield"
    """EnvConfig.separation of every episode: "shield" (conflicts resolved before moves, as the *_fleet presets;
    docs/rules.md) or "none" (the earliest recorded fleet tables)"""
    hover_action: bool = True
    """EnvConfig.hover_action of every episode: idle taxis hover (action 16, as the *_fleet presets);
    --no-hover-action flies the 16 headings alone, where an idle dispatcher taxi zig-zags and its distance grows
    with the episode's idle time"""
    passenger_window: int | None = None
    """fly the learned fleets reading a passenger window of K rows (the learned policy's passenger_window option; the
    trained passenger slot count is the K to choose): any number of requests; default: one slot per request"""
    arrival_window_s: float = FLEET_ARRIVAL_WINDOW_S
    """requests are released over the first this many seconds of each episode (the episode's time limit follows)"""
    jobs: int = 2
    threads: int = 1
    """torch CPU threads of each worker process (torch's default, every core, makes the workers' threads spin against
    each other on shared cores: the decision times of reports/2026-12-04-decision-time-maps)"""
    out_csv: Path = Path("docs/results/fleet_benchmark.csv")
    out_md: Path | None = None
    """Markdown file whose marked section is (re)written; without it no Markdown is written (the results pages are
    generated from --out-csv by `uamfleet docs-tables`)"""
    section: str = "fleet"
    from_csv: Path | None = None
    """re-render the table from the CSV of an earlier run, flying nothing"""
    command: str = ""
    """the command line to print above the table (default: reconstructed)"""
    note: str = ""
    """with --from-csv: a line printed under the command (e.g. what ran and its wall-clock)"""
    overwrite: bool = False
    """replace an existing --out-csv or --section of --out-md (else the command refuses before flying)"""


Job = tuple[str, str, int, tuple[str, ...], tuple[Path, ...], str, bool, int | None, float, Path | None]  # (family,
# setting, seed, dispatchers, checkpoints, separation, hover_action, passenger_window, arrival_window_s,
# assignment_value)


def setting_size(setting: str) -> tuple[int, int]:
    """(taxis, requests) of a --settings value ``<taxis>x<requests>`` (e.g. ``8x96``; a name of FLEET_SETTINGS is
    one): :func:`uamfleet.instances.fleet_setting`."""
    return fleet_setting(setting, "--settings")


def dispatcher_row_name(name: str, assignment_value: Path | None) -> str:
    """A dispatcher's name in the rows: a valued dispatcher flown with a value file other than the shipped one is
    ``<name>@<file stem>`` (e.g. ``batch_assignment_value:100+wait=1+release@refit``), so that its rows stay apart
    from the shipped value's in one CSV (``--merge-csv`` replaces the earlier rows of a name flown now)."""
    if parse(name)[0] != VALUE_DISPATCHER or assignment_value is None:
        return name
    if Path(assignment_value).resolve() == shipped_value_path().resolve():
        return name
    return f"{name}@{Path(assignment_value).stem}"


def learned_name(checkpoint: Path, passenger_window: int | None = None) -> str:
    """``learned:<run name>`` for a run's best.pt / last.pt, else ``learned:<file stem>`` (e.g. a shipped policy);
    ``+window<K>`` after it when flown with a passenger window."""
    name = f"learned:{checkpoint.parent.name if checkpoint.stem in ('best', 'last') else checkpoint.stem}"
    return name if passenger_window is None else f"{name}+window{passenger_window}"


@functools.lru_cache(maxsize=16)
def _learned(checkpoint: Path, taxis: int, requests: int, passenger_window: int | None = None) -> Any:
    """The greedy policy of a checkpoint reading ``requests`` passenger slots for ``taxis`` taxis (or a passenger
    window of K rows): the same weights for any fleet its spec reads, fitted to each world at reset."""
    rows = {"passenger_window": passenger_window} if passenger_window is not None else {"passenger_slots": requests}
    return make("learned", source=str(checkpoint), taxis=taxis, **rows)


def refusal(policy: Any, world: WorldConfig) -> str | None:
    """None when ``policy`` flies ``world`` (its spec reads it and its network fits it), else the one line why
    not (e.g. another fleet size for a policy that reads the other taxis by position)."""
    try:
        policy.fit(world)
    except ConfigError as err:
        return str(err)
    return None


def dispatcher(name: str, taxis: int, value_path: Path | None, arrival_window_s: float | None) -> Any:
    """The dispatcher ``name`` (a recorded name or the grammar of :mod:`uamfleet.policies.names`) for ``taxis``
    taxis: a valued one reads ``value_path`` (None: the shipped value) for a service of ``arrival_window_s``; a
    single-taxi planner (:func:`~uamfleet.policies.make_flown`'s settings, refused for a fleet) flies one taxi."""
    call, options = parse(name)
    if available()[call][0] == "planner" and not options:
        return make_flown(call, num_taxis=taxis)
    if call == FLEET_SEARCH:  # the search over a dispatcher: its base as a dispatcher, its futures over the window
        base, base_options = options[BASE]
        options[BASE] = (base, _value_options(base, dict(base_options), value_path, arrival_window_s))
        if arrival_window_s is not None:
            options.setdefault("arrival_window_s", arrival_window_s)
        return make(call, **options)
    return make(call, **_value_options(call, options, value_path, arrival_window_s))


def _value_options(
    call: str, options: dict[str, Any], value_path: Path | None, arrival_window_s: float | None
) -> dict[str, Any]:
    """``options`` of the dispatcher ``call``, a valued one reading ``value_path`` for ``arrival_window_s``."""
    if call == VALUE_DISPATCHER:
        if value_path is not None:
            options.setdefault("value", str(value_path))
        if arrival_window_s is not None:
            options["arrival_window_s"] = arrival_window_s
    return options


def limit_threads(threads: int) -> None:
    """Give this process's torch ``threads`` CPU threads (a worker pool's initializer)."""
    import torch  # here, not at the top: the dispatchers alone never load it

    torch.set_num_threads(threads)


def run_episode_set(job: Job) -> list[dict[str, Any]]:
    """Every dispatcher (and learned policy of this fleet size) on one fleet instance (one worker process)."""
    family, setting, seed, dispatchers, checkpoints, separation, hover_action = job[:7]
    window, arrival_s = job[7:9] or (None, FLEET_ARRIVAL_WINDOW_S)  # a 7-field job: no window, the default arrivals
    value_path = job[9] if len(job) > 9 else None  # a 9-field job: the shipped value
    taxis, requests = setting_size(setting)
    cfg = make_fleet_instance(family, seed, taxis, requests, arrival_window_s=arrival_s, separation=separation,
                              hover_action=hover_action)  # fmt: skip
    start = time.perf_counter()
    env = VectorEnv(cfg, num_envs=1, autoreset=False)
    env.reset(seed=0)
    if dispatchers:  # every dispatcher steers by the same per-stop fields: computed once, untimed
        shared_fields(env.sim, warm=True)  # (a learned policy reads the env's distance table instead)
    fields_s = time.perf_counter() - start
    rows = []
    flights = [
        (
            dispatcher_row_name(name, value_path),
            cfg,
            dispatcher(name, taxis, value_path, arrival_s),
        )
        for name in dispatchers
    ]
    for checkpoint in checkpoints:
        policy = _learned(checkpoint, taxis, requests, window)
        if refusal(policy, cfg.world) is None:
            flights.append((learned_name(checkpoint, window), cfg, policy))
    for name, flown, policy in flights:
        start = time.perf_counter()
        traj = fly(flown, policy)
        elapsed = time.perf_counter() - start
        m = episode_metrics(traj, cfg.radio)
        per_taxi_ms = np.asarray(traj.decision_s) * 1000.0 / taxis
        rows.append({
            "family": family, "setting": setting, "taxis": taxis, "seed": seed, "threshold_db": cfg.sinr_min_db,
            "dispatcher": name, "num_requests": m.num_requests, "delivered": m.delivered, "service_pct": m.pr_pct,
            "wait_p50_s": m.wait_p50_s, "wait_p95_s": m.wait_p95_s, "awt_s": m.awt_s, "detour": m.detour_ratio,
            "td_m": m.td_m, "td_per_delivered_m": m.td_m / max(m.delivered, 1), "occupancy": m.occupancy,
            "separation_violations": m.separation_violations, "connectivity_pct": m.connectivity_pct,
            "steps": m.steps, "decision_p50_ms": float(np.median(per_taxi_ms)),
            "decision_max_ms": float(per_taxi_ms.max()), "policy_s": elapsed, "fields_s": fields_s,
            "shield_interventions": m.shield_interventions, "hovers": m.hovers,
            "interventions_per_taxi_h": m.interventions_per_taxi_h, "hover_actions": m.hover_actions,
        })  # fmt: skip
    return rows


def markdown(rows: list[dict[str, Any]], command: str, wall_s: float, note: str = "") -> str:
    lines = command_header(command, wall_s, note)
    lines += [
        "| family | setting (taxis x requests) | dispatcher | episodes | all delivered % | service % | wait p50 s "
        "| wait p95 s | ride detour | TD / delivered m | occupancy | separation viol. | shield interventions / taxi-h "
        "| conn. % "
        "| decision / taxi / step p50 / max ms |",
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|",
    ]
    keys = dict.fromkeys((r["family"], r["setting"], r["dispatcher"]) for r in rows)
    for key in sorted(keys, key=lambda k: (k[0], setting_size(k[1]), FLEET_DISPATCHERS.index(k[2])
                                           if k[2] in FLEET_DISPATCHERS else 99)):  # fmt: skip
        sel = [r for r in rows if (r["family"], r["setting"], r["dispatcher"]) == key]

        def col(name: str, sel: list[dict[str, Any]] = sel) -> np.ndarray:
            return np.array([float(r.get(name, math.nan)) for r in sel])  # nan: a CSV from before the column

        all_delivered = 100.0 * float(np.mean(col("service_pct") >= 100.0))
        lines.append(
            f"| {key[0]} | {key[1]} | {key[2]} | {len(sel)} | {all_delivered:.0f} | {ci(col('service_pct'))} | "
            f"{ci(col('wait_p50_s'))} | {ci(col('wait_p95_s'))} | {ci(col('detour') * 100)} % | "
            f"{ci(col('td_per_delivered_m'))} | {ci(col('occupancy') * 100)} % | "
            f"{ci(col('separation_violations'))} | {ci(col('interventions_per_taxi_h'))} | "
            f"{ci(col('connectivity_pct'))} | "
            f"{np.median(col('decision_p50_ms')):.1f} / {col('decision_max_ms').max():,.0f} |"
        )
    lines += [
        "",
        "Ride detour: in-vehicle time ÷ direct straight-line flight time, in % (100 % = direct). Occupancy: mean "
        "passengers on board per taxi-step ÷ seats, in %. Intervals: 95 % over episodes.",
        "",
    ]
    return "\n".join(lines)


def read_rows(path: Path) -> list[dict[str, Any]]:
    text = ("family", "setting", "dispatcher")
    with path.open(encoding="utf-8") as f:
        return [{k: (v if k in text else float(v)) for k, v in r.items()} for r in csv.DictReader(f)]


def rerun_command(args: Args) -> str:
    """The command line that flies this table again (printed above it): --command, else the options that differ
    from their defaults."""
    return args.command or (
        ".venv/bin/python -m eval.fleet_benchmark "
        + (f"--family {args.family} " if args.map is None else f"--map {args.map} ")
        + f"--settings {' '.join(args.settings)} "
        f"--split {args.split} --count {args.count} --first {args.first} --jobs {args.jobs}"
        + f" --threads {args.threads}" * (args.threads != 1)
        + (f" --dispatchers {' '.join(args.dispatchers)}" if tuple(args.dispatchers) != FLEET_DISPATCHERS else "")
        + (f" --assignment-value {args.assignment_value}" if args.assignment_value is not None else "")
        + (f" --checkpoints {' '.join(map(str, args.checkpoints))}" if args.checkpoints else "")
        + (f" --separation {args.separation}" if args.separation != "shield" else "")
        + ("" if args.hover_action else " --no-hover-action")
        + (f" --passenger-window {args.passenger_window}" if args.passenger_window is not None else "")
        + (f" --arrival-window-s {args.arrival_window_s:g}" if args.arrival_window_s != FLEET_ARRIVAL_WINDOW_S else "")
        + (f" --merge-csv {args.merge_csv}" if args.merge_csv is not None else "")
        + (" --overwrite" if args.overwrite else "")
    )


def write_outputs(args: Args, rows: list[dict[str, Any]], wall: float, note: str = "") -> None:
    if args.from_csv is None:
        write_csv_atomic(args.out_csv, rows, COLUMNS)
    body = with_provenance(markdown(rows, rerun_command(args), wall, note), args.map)
    if args.note:
        body = body.replace("```\n\n", f"```\n\n{args.note}\n\n", 1)
    minutes = fmt(wall / 60, ".1f", " min")  # "–" when re-rendered from a CSV of unknown wall-clock
    written = "" if args.from_csv is not None else f"{args.out_csv} and "
    if args.out_md is None:
        _print_table(body, written.removesuffix(" and "), f"({minutes}){note}")
        return
    replace_section(args.out_md, args.section, body)
    print(f"wrote {written}the {args.section} section of {args.out_md} ({minutes}){note}")


def _print_table(body: str, csv: str, tail: str) -> None:
    """Without --out-md: the table, the CSV written (if any), and where the results pages come from."""
    print(body)
    print(f"wrote {csv or 'nothing'} {tail}")
    print(REFRESH_HINT)


def check_args(args: Args) -> list[Job]:
    """The episodes to fly, once every option is valid, the selection is not empty, every checkpoint loads and
    flies at least one setting, and no existing result would be replaced without --overwrite: all checked before
    anything is flown or written."""
    if args.from_csv is not None:
        return []
    check_jobs(args.jobs)
    check_integer("--threads", args.threads, 1, 1024, fix=" (torch CPU threads per worker; 1 shares cores best)")
    if args.map is not None:
        check_map(args.map)
    _check_names(args)
    if not args.settings or args.count < 1:
        raise UsageError(
            f"no episode selected (--settings {' '.join(args.settings) or '(none)'}, --count {args.count}): give at "
            "least one setting and --count >= 1."
        )
    if not args.dispatchers and not args.checkpoints:
        raise UsageError("--dispatchers is empty and no --checkpoints are given: nothing to fly.")
    check_number("--arrival-window-s", args.arrival_window_s, positive=True)
    if args.passenger_window is not None and not args.checkpoints:
        raise UsageError(f"--passenger-window {args.passenger_window} applies to learned fleets: give --checkpoints.")
    for checkpoint in args.checkpoints:
        _check_checkpoint_flies(checkpoint, args)
    output_paths({"--out-csv": args.out_csv, "--out-md": args.out_md})
    check_outputs(args.overwrite, [args.out_csv], args.out_md, args.section)
    return [
        (
            family_of_args(args),
            setting,
            seed,
            tuple(args.dispatchers),
            tuple(args.checkpoints),
            args.separation,
            args.hover_action,
            args.passenger_window,
            args.arrival_window_s,
            args.assignment_value,
        )
        for seed in split_seeds(args.split, args.count, args.first)
        for setting in args.settings
    ]


def family_of_args(args: Args) -> str:
    """The family the episodes are drawn from: --map's (its name or path), else --family."""
    return args.family if args.map is None else args.map


def _check_names(args: Args) -> None:
    """Every setting and dispatcher named is known."""
    for setting in args.settings:
        setting_size(setting)
    repeated = sorted({d for d in args.dispatchers if list(args.dispatchers).count(d) > 1})
    if repeated:
        raise UsageError(f"--dispatchers names {', '.join(repeated)} more than once; name each dispatcher once.")
    unknown = [d for d in args.dispatchers if kind_of(d) not in ("planner", "dispatcher") and not _searches_fleet(d)]
    if unknown:
        raise ValueError(
            f"unknown --dispatchers {unknown}; choose from {(*FLEET_DISPATCHERS, VALUE_DISPATCHER)} (the schedule "
            "dispatchers with options such as +wait=<β> and +release, or batch_assignment:wait=1,release=true: "
            f"uamfleet.policies.names), or {FLEET_SEARCH}(<dispatcher>)."
        )
    # a name's options, value file and price are checked now, before anything flies (at the smallest fleet named,
    # where a one-taxi planner is still allowed)
    taxis = min((setting_size(setting)[0] for setting in args.settings), default=1)
    for name in args.dispatchers:
        dispatcher(name, taxis, args.assignment_value, args.arrival_window_s)


def _searches_fleet(name: str) -> bool:
    """Whether ``name`` is the fleet search over a dispatcher (``fleet_search:OPTIONS(DISPATCHER)``)."""
    try:
        call, options = parse(name)
    except PolicyNameError:
        return False
    return call == FLEET_SEARCH and available()[options[BASE][0]][0] == "dispatcher"


def _check_checkpoint_flies(checkpoint: Path, args: Args) -> None:
    """A learned policy must fly the first instance of at least one of the settings (its fleet size, or any for a
    designed variant); says which it skips."""
    settings, passenger_window = list(args.settings), args.passenger_window
    make("learned", source=str(checkpoint))  # a file it cannot read is refused here, not skipped
    reasons, first_seed = {}, split_seeds(args.split, 1, args.first)[0]
    for setting in settings:
        taxis, requests = setting_size(setting)
        world = make_fleet_instance(
            family_of_args(args), first_seed, taxis, requests,
            arrival_window_s=args.arrival_window_s, separation=args.separation, hover_action=args.hover_action,
        ).world  # fmt: skip
        reasons[setting] = refusal(_learned(checkpoint, taxis, requests, passenger_window), world)
    flies = [s for s in settings if reasons[s] is None]
    if not flies:
        raise UsageError(
            f"--checkpoints {checkpoint} cannot fly any of the settings {settings}: {reasons[settings[0]]} Give a "
            "fleet policy of a designed variant, settings of its fleet size, or the world it reads."
        )
    if len(flies) < len(settings):
        name = learned_name(checkpoint, passenger_window)
        print(f"{name} flies only the settings {flies} (the others need another fleet size)")


def main(args: Args) -> list[dict[str, Any]]:
    jobs = check_args(args)
    if args.from_csv is not None:
        earlier = earlier_rows(read_rows, args.from_csv)
        check_outputs(args.overwrite, [], args.out_md, args.section)
        write_outputs(args, earlier, math.nan)
        return earlier
    start = last = time.perf_counter()
    rows: list[dict[str, Any]] = []
    with mp.get_context("spawn").Pool(min(args.jobs, len(jobs)), limit_threads, (args.threads,)) as pool:
        for i, result in enumerate(pool.imap(run_episode_set, jobs)):
            rows += result
            print(f"[{i + 1}/{len(jobs)}] {result[0]['setting']} seed {result[0]['seed']}: "
                  + "  ".join(f"{r['dispatcher']} PR {r['service_pct']:.0f} wait {r['awt_s']:.0f}s "
                              f"TD/pax {r['td_per_delivered_m']:.0f}" for r in result), flush=True)  # fmt: skip
            if time.perf_counter() - last > 60.0 and i + 1 < len(jobs):  # survive an interruption, beside
                last = time.perf_counter()
                write_csv_atomic(partial_path(args.out_csv), rows, COLUMNS)
    if args.merge_csv is not None:  # the earlier run's rows on the episodes flown now, of the other dispatchers
        flown = {r["dispatcher"] for r in rows}
        episodes = {(r["family"], r["setting"], int(r["seed"])) for r in rows}
        earlier = [
            r for r in read_rows(args.merge_csv)
            if r["dispatcher"] not in flown and (r["family"], r["setting"], int(r["seed"])) in episodes
        ]  # fmt: skip
        rows = earlier + rows
    write_outputs(args, rows, time.perf_counter() - start)
    partial_path(args.out_csv).unlink(missing_ok=True)
    return rows


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-fleet-benchmark") -> int:
    """The ``uamfleet-fleet-benchmark`` command (``python -m eval.fleet_benchmark``)."""
    return run(main, Args, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.fleet_benchmark"))
