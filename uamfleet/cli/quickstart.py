"""The main job: MSHA-PPO trained from random weights on Berlin P4, then its evaluation beside the paper.

    uamfleet-quickstart                                   # from scratch: search warm start + PPO, 2-3 min on 2 cores
    uamfleet-quickstart --recipe fine-tune                # PPO from the shipped generalist (--init-from berlin)
    uamfleet-quickstart --recipe scratch                  # pure PPO from scratch (150k agent-steps, 6-10 minutes)
    uamfleet-quickstart --recipe scratch --variant full   # the full MSHA model from scratch (~3x slower per step)
    uamfleet-quickstart --map munich --test-count 20      # on another map (a packaged one, or a map file's path)

The default recipe, ``scratch-search-start``, starts the ``de_msfea`` network from random weights on Berlin P4 at
γ_T = -3 dB (the paper's hardest Berlin threshold), warm-starts it with 2 rounds of DAgger from replan's online
search on P4 (:mod:`uamfleet.rl.warm_start`), then trains it with PPO for 100k agent-steps with a KL term toward the
warm start. The warm start is evaluated first and after every iteration, and the shortest greedy tour of those
evaluations is kept (runs/quickstart/best.pt); over 10 seeds every run kept best_known's tour
(docs/getting-started.md, "The main job"). ``--recipe fine-tune`` fine-tunes a start (``--init-from``, the shipped
generalist ``uamfleet.pretrained("berlin")`` by default) with PPO and a KL term toward it; ``--recipe scratch``
trains from random weights with PPO alone for 150k agent-steps, with shaping that pays only for progress (that
recipe left 3 of 10 seeds above 5 % of the best known tour). It prints TD / ATT /
AWT / ELR / PR / connectivity next to the paper's MSHA-RL row and our raster planners (``raster_replan``, online;
``raster_opt``, clairvoyant: best stop orders over shortest feasible paths) flown under the same rules (the
authors' endpoint-block rule by default). Then it flies the shipped generalist zero-shot on Berlin P4 at
-7 ... -3 dB beside the paper's MSHA-RL, and on the held-out test instances beside the planners' recorded rows.
The training's learning curve (greedy TD and PR of every evaluation against agent-steps, with best_known's tour
and the band within 5 % of it, and beside it the same on 10 validation instances) is drawn as curve.png in the run
folder, beside its TensorBoard logs (tb/).
``--recipe`` names the training (:data:`RECIPES`): ``scratch-search-start`` (the default), ``fine-tune`` (from
``--init-from``; the default when ``--init-from`` is given), ``scratch``, and the other recipes from scratch measured
against them (docs/results/quickstart_seeds.csv). Every evaluation also flies the first ``--curve-instances``
validation instances (the curve's second panel). It keeps no files outside ``--run-dir`` (the distance-table rows
it needs are computed in memory; only a complete table, as training on random demand fills, is cached in
``~/.cache/uamfleet``).
"""

from __future__ import annotations

import csv
import math
import time
from collections.abc import Sequence
from typing import Any

import numpy as np

from dataclasses import dataclass
from pathlib import Path


from uamfleet.checks import ConfigError
from uamfleet.cli._common import Feasibility, MapName, Variant, check_map, fmt, run
from uamfleet.cli.paper_numbers import PAPER_TABLE_II
from uamfleet.baselines.planner_policy import PlannerPolicy, planner_configs
from uamfleet.presets import make_config
from uamfleet.metrics import EpisodeMetrics, episode_metrics
from uamfleet.rl.checkpoint import Checkpoint, checkpoint_source
from uamfleet.rl.legacy import checkpoint_args
from uamfleet.rl.trainer import TrainArgs, TrainResult, load_policy, train
from uamfleet.rollout import fly as fly_episode
from uamfleet.viz.curves import plot_learning_curve


DEFAULT_RUN = "quickstart"
DEFAULT_RECIPE = "scratch-search-start"
"""The main job's training when neither --recipe nor --init-from is given."""
FINE_TUNE_START = "berlin"
"""The policy ``--recipe fine-tune`` starts from when --init-from is not given: the shipped generalist."""


FINE_TUNE_STEPS = 49_152  # 24 iterations of 32 envs x 64 steps
SCRATCH_STEPS = 150_000
SEARCH_START_ROUNDS = 2
SEARCH_START_STEPS = 100_000
"""DAgger rounds of the search warm start (``--recipe scratch-search-start``)"""
RECIPES: dict[str, str] = {
    "fine-tune": "PPO from --init-from (the shipped generalist) with a KL term toward it, 49,152 agent-steps",
    "scratch": "the de_msfea network from scratch, 150,000 agent-steps, shaping that pays only for progress",
    "scratch-first-delivery": "scratch, with the learning-rate decay and the shaping anneal counted from the first "
    "greedy evaluation that delivers everyone (--schedule-clock first_delivery)",
    "scratch-workers": "scratch-first-delivery with 64 envs stepped in 2 worker processes (--env-workers 2)",
    "scratch-search-start": "the de_msfea network from random weights, warm-started by 2 rounds of DAgger from "
    "replan's search on P4 (--warm-start-rounds 2), then 100,000 agent-steps of PPO (learning rate 3e-4, a KL term "
    "toward the warm start, schedules on the first-delivery clock)",
}
"""The main job's trainings, by ``--recipe`` name."""
FIXED_CSV = Path("docs/results/benchmark_fixed.csv")
"""The planners' recorded rows on the paper's fixed scenarios (best_known on P4 is the learning curve's reference)."""


@dataclass
class Args:
    recipe: str | None = None
    """the training (one of RECIPES: scratch-search-start, fine-tune, scratch, scratch-first-delivery,
    scratch-workers); None: fine-tune when --init-from is given, else scratch-search-start"""
    init_from: str | None = None
    """the policy --recipe fine-tune starts from: a shipped name (uamfleet.zoo.PRETRAINED) or a checkpoint file;
    None: the shipped generalist, berlin. Giving it selects fine-tune; the recipes from scratch refuse it"""
    total_timesteps: int | None = None
    """agent-steps of training; None: 100,000 for scratch-search-start, 49,152 when fine-tuning, 150,000 for the
    other recipes from scratch"""
    minutes: float = 10.0
    """wall-clock cap of the training (it stops after a final evaluation)"""
    sinr_min_db: float = -3.0
    seed: int = 1
    variant: Variant = "de_msfea"
    """network variant from scratch (de_msfea learns the tour fastest on a CPU; full is ~3x slower per step:
    docs/benchmarks.md, "Training"); fine-tuning trains the start's network"""
    feasibility: Feasibility = "endpoint_block"
    """move rule of training and of every row printed (endpoint_block: the authors'; see docs/rules.md, "Feasibility
    rules")"""
    threads: int = 1
    """torch CPU threads. With 1 the run repeats exactly on one machine (not across machines) and is the seed-1 run
    of the spread over 10 seeds (docs/getting-started.md, "The main job"); more threads change floating-point
    reductions, hence the whole run (a 2-thread run of seed 1 from scratch stalled at 1 of 4 passengers)"""
    shaping_gamma: float | None = 1.0
    """from scratch: discount inside the shaping term gamma_Phi Phi(s') - Phi(s) (TrainArgs.env.shaping_gamma; None:
    the trainer's gamma, 0.9). 1: a step pays only for progress toward the next stop. With 0.9 the term also pays
    w (1 - 0.9) |Phi| per step for staying far from it: seeds 3 and 6 learned to hover there
    (reports/2026-12-03-results-history/README.md, "The main job over 10 seeds"). Fine-tuning uses the start's reward
    (no shaping)"""
    kl_to_init: float = 0.01
    """fine-tuning and scratch-search-start: weight of the KL divergence from the start (the warm start) in the PPO loss
    (TrainArgs.net.kl_to_init)"""
    eval_every: int = 1
    """greedy evaluation every this many iterations; best.pt keeps the shortest tour of any of them (one episode,
    well under a second; with 5, tours flown between two evaluations were never kept)"""
    curve_instances: int = 10
    """after each evaluation also fly the first this many validation instances of the family (Berlin's, or --map's)
    in one batch (TrainArgs.eval.curve_instances: progress.csv's val_td_m / val_pr_pct, the curve's second panel;
    about 1 s per evaluation for 10); 0: none. The training itself is the same with or without them"""
    curve_every: int = 4
    """fly the curve's validation instances at every this-many-th evaluation and at the last
    (TrainArgs.eval.curve_every); 1: at every evaluation (four times the panel's cost)"""
    run_dir: Path = Path("runs")
    """folder of the run (relative to the current folder)"""
    run_name: str = DEFAULT_RUN
    """name of the run; the quickstart's own (the default) is retrained on a rerun, any other existing run is kept
    unless --overwrite is given"""
    overwrite: bool = False
    """replace an existing run of another --run-name"""
    generalist: bool = True
    """then fly the shipped Berlin generalist (uamfleet.pretrained("berlin")) on Berlin P4 at -7 ... -3 dB and on
    the held-out test instances"""
    test_count: int = 200
    """test instances the generalist flies (the first of the 200 of docs/results.md, "The generalist on the test
    sets")"""
    planner_csv: Path = Path("docs/results/benchmark_berlin_test.csv")
    """the planners' recorded rows on the test instances, shown beside the generalist's (skipped if absent)"""
    map: MapName = None
    """(the main job on that map: training on berlin_instances there at the strictest threshold of the map's family,
    in place of Berlin P4 and --sinr-min-db; then the trained policy, replan, raster_opt and, with --generalist, the
    shipped generalist zero-shot on the first --test-count test instances of the map's family)"""


def fly(policy: object, threshold: float, **overrides: object) -> EpisodeMetrics:
    """Metrics of one Berlin P4 episode of ``policy`` (a planner flies under its own rules, as everywhere)."""
    flown, scored = planner_configs("berlin_p4", getattr(policy, "planner", ""), sinr_min_db=threshold, **overrides)
    traj = fly_episode(flown, policy)  # type: ignore[arg-type]
    return episode_metrics(traj, scored.radio, threshold_db=scored.sinr_min_db)


def recipe_of(args: Args) -> str:
    """The recipe the command line names: ``--recipe``, else fine-tune when ``--init-from`` is given, else
    :data:`DEFAULT_RECIPE`; ConfigError for an unknown name, or for a start given to a recipe from scratch."""
    recipe = args.recipe if args.recipe is not None else ("fine-tune" if args.init_from else DEFAULT_RECIPE)
    if recipe not in RECIPES:
        raise ConfigError(f"--recipe={recipe!r} is unknown; use one of {', '.join(RECIPES)}.")
    if recipe != "fine-tune" and args.init_from is not None:
        raise ConfigError(
            f"--recipe {recipe} trains from random weights, but --init-from={args.init_from!r} names a start; drop "
            "--init-from, or use --recipe fine-tune to train from it."
        )
    return recipe


def training_args(args: Args) -> TrainArgs:
    """The trainer's options for the main job's recipe (:func:`recipe_of`): fine-tuning from ``args.init_from``, or
    one of the recipes from scratch."""
    recipe = recipe_of(args)
    common = dict(
        scenario="berlin_p4", sinr_min_db=args.sinr_min_db, seed=args.seed, run_dir=args.run_dir,
        run_name=args.run_name, max_wall_s=60.0 * args.minutes, feasibility=args.feasibility, threads=args.threads,
        eval_every=args.eval_every,
        overwrite=args.overwrite or args.run_name == DEFAULT_RUN,  # a rerun retrains its own run, never another
    )  # fmt: skip
    if args.map is not None:  # its instances' world, at the map family's strictest threshold (TrainArgs.env.map)
        common.update(scenario="berlin_instances", map=args.map, sinr_min_db=None)
    if args.curve_instances:
        common.update(curve_instances=args.curve_instances, curve_every=args.curve_every,
                      curve_family=args.map or "berlin")  # fmt: skip
    if recipe != "fine-tune":
        steps = SEARCH_START_STEPS if recipe == "scratch-search-start" else SCRATCH_STEPS
        steps = steps if args.total_timesteps is None else args.total_timesteps
        scratch = {**common, "total_timesteps": steps, "variant": args.variant, "shaping_gamma": args.shaping_gamma}
        if recipe in ("scratch-first-delivery", "scratch-workers", "scratch-search-start"):
            scratch["schedule_clock"] = "first_delivery"
        if recipe == "scratch-search-start":
            scratch.update(warm_start_rounds=SEARCH_START_ROUNDS, kl_to_init=args.kl_to_init, learning_rate=3e-4)
        if recipe == "scratch-workers":
            scratch.update(num_envs=64, env_workers=2)
        return TrainArgs.from_flat(scratch)
    # The start's own reward (read from its checkpoint: for the shipped generalist no shaping and a long horizon),
    # a smaller step than from scratch, an entropy bonus to try other flights and a KL term to stay near the start
    # where the return does not say otherwise.
    init_from = args.init_from or FINE_TUNE_START
    start = checkpoint_args(Checkpoint.load(checkpoint_source(init_from), map_location="cpu"))
    steps = FINE_TUNE_STEPS if args.total_timesteps is None else args.total_timesteps
    return TrainArgs.from_flat(dict(
        common, total_timesteps=steps, init_from=init_from, kl_to_init=args.kl_to_init,
        shaping=start.env.shaping, shaping_metric=start.env.shaping_metric, shaping_gamma=start.env.shaping_gamma,
        gamma=start.ppo.gamma, learning_rate=3e-4, ent_coef=0.01,
    ))  # fmt: skip


def main(args: Args) -> dict[str, EpisodeMetrics] | dict[str, list[dict[str, Any]]]:
    if args.map is not None:
        return map_job(args)
    train_args = training_args(args)
    scratch = train_args.net.init_from is None
    if scratch:
        print(f"training MSHA-PPO ({args.variant}) from scratch on Berlin P4 at {args.sinr_min_db:g} dB for "
              f"{train_args.ppo.total_timesteps:,} agent-steps (at most {args.minutes:g} min; recipe "
              f"{recipe_of(args)}) ...")  # fmt: skip
    else:
        print(f"fine-tuning {train_args.net.init_from!r} with PPO on Berlin P4 at {args.sinr_min_db:g} dB for "
              f"{train_args.ppo.total_timesteps:,} agent-steps (at most {args.minutes:g} min) ...")  # fmt: skip
    result = train(train_args)
    policy, trained = load_policy(result.run_dir / "best.pt")
    rule = {"feasibility": args.feasibility}
    name = f"MSHA-PPO {trained.net.variant} (ours)" if scratch else "MSHA-PPO fine-tuned (ours)"
    rows = {
        name: fly(policy, args.sinr_min_db, **rule),
        "raster_replan (ours)": fly(PlannerPolicy("raster_replan"), args.sinr_min_db, **rule),
        "raster_opt (ours)": fly(PlannerPolicy("raster_opt"), args.sinr_min_db, **rule),
    }
    paper = PAPER_TABLE_II["berlin"]["MSHA-RL"].get(args.sinr_min_db)
    print(
        f"\nBerlin P4, γ_T = {args.sinr_min_db:g} dB, after {result.global_step:,} agent-steps ({result.wall_s:.0f} s)"
    )
    print(f"{'method':<26} {'PR %':>5} {'TD m':>6} {'ATT s':>7} {'AWT s':>7} {'ELR %':>6} {'conn. %':>8}")
    if paper is not None:
        td, att, awt, elr = paper
        print(f"{'MSHA-RL (paper)':<26} {100:>5.0f} {td:>6.0f} {att:>7.2f} {awt:>7.2f} {elr:>6.2f} {'100':>8}")
    for name, m in rows.items():
        print(f"{name:<26} {fmt(m.pr_pct, '.0f'):>5} {fmt(m.td_m, '.0f'):>6} {fmt(m.att_s, '.2f'):>7} "
              f"{fmt(m.awt_s, '.2f'):>7} {fmt(m.elr_pct, '.2f'):>6} {fmt(m.connectivity_pct, '.1f'):>8}")  # fmt: skip
    print_start(result, train_args)
    print(f"\ncheckpoints and logs: {result.run_dir} (TensorBoard: tensorboard --logdir {result.run_dir / 'tb'})")
    title = f"Berlin P4 at {args.sinr_min_db:g} dB"
    curve = plot_learning_curve(result.run_dir, best_known_m=recorded_best_known(args), title=title)
    where = f"on P4 and on {args.curve_instances} validation instances" if args.curve_instances else "on P4"
    print(f"learning curve (greedy TD and PR against agent-steps, {where}): {curve}")
    if args.generalist:
        generalist_report(args.test_count, args.planner_csv)
    return rows


def map_job(args: Args) -> dict[str, list[dict[str, Any]]]:
    """The main job on ``--map``: training on its ``berlin_instances`` world (:func:`training_args`), then the trained
    policy beside ``replan`` and ``raster_opt`` (and the shipped generalist, zero-shot) on the first ``--test-count``
    test instances of the map's family, each flown by :func:`uamfleet.cli.benchmark.run_instance`; rows by method."""
    from uamfleet.cli.benchmark import Job, job_options, run_instance
    from uamfleet.cli.benchmark import Args as BenchmarkArgs
    from uamfleet.instances import map_family, map_provenance, split_seeds
    from uamfleet.zoo import pretrained_path

    assert args.map is not None
    check_map(args.map)
    print(f"Map: {map_provenance(args.map)}.")
    train_args = training_args(args)
    threshold = map_family(args.map).thresholds_db[-1]
    start = "from scratch" if train_args.net.init_from is None else f"from {train_args.net.init_from!r}"
    print(f"training MSHA-PPO {start} on berlin_instances on {args.map} at {threshold:g} dB for "
          f"{train_args.ppo.total_timesteps:,} agent-steps (at most {args.minutes:g} min) ...")  # fmt: skip
    result = train(train_args)
    options = job_options(BenchmarkArgs())
    seeds = split_seeds("test", args.test_count)
    flights: list[tuple[tuple[str, ...], Path, str]] = [
        (("replan", "raster_opt", "learned"), result.run_dir / "best.pt", "")
    ]
    if args.generalist:
        flights.append((("learned",), pretrained_path("berlin"), "generalist (shipped, zero-shot)"))
    rows: dict[str, list[dict[str, Any]]] = {}
    for methods, checkpoint, label in flights:
        for seed in seeds:
            for row in run_instance(
                Job(("test", args.map, seed, None, args.feasibility), methods, checkpoint, options)
            ):
                name = label or ("MSHA-PPO (ours)" if row["method"] == "learned" else row["method"])
                rows.setdefault(name, []).append(row)
    print(f"\n{args.map}: the first {args.test_count} test instances of its family ({args.feasibility} rule), after "
          f"{result.global_step:,} agent-steps ({result.wall_s:.0f} s)")  # fmt: skip
    print(f"{'method':<44} {'all delivered %':>15} {'PR %':>6} {'TD m (mean)':>12}")
    for name, flown in rows.items():
        pr = np.array([r["pr_pct"] for r in flown])
        td = np.array([r["td_m"] for r in flown])
        print(f"{name:<44} {100 * np.mean(pr >= 100):>15.1f} {pr.mean():>6.1f} {td.mean():>12,.0f}")
    print(f"\ncheckpoints and logs: {result.run_dir} (TensorBoard: tensorboard --logdir {result.run_dir / 'tb'})")
    return rows


def print_start(result: TrainResult, train_args: TrainArgs) -> None:
    """What a run with a start (fine-tuning, or a search warm start) kept: the start itself, or a PPO evaluation;
    for a warm start also its evaluation, so the output shows what PPO added to it."""
    warm = warm_start_row(result.run_dir) if train_args.net.warm_start_rounds else None
    if warm is not None:
        print(f"search warm start ({warm['warm/wall_s']:.0f} s, {warm['warm/solves']:.0f} solves of replan's "
              f"search, {warm['warm/labels']:.0f} labels): PR {warm['eval/pr_pct']:.0f} %, "
              f"TD {warm['eval/td_m']:.0f} m")  # fmt: skip
    if train_args.net.init_from is None and warm is None:
        return
    start = "the warm start" if warm is not None else "the start itself"
    kept = (
        f"{start}: no evaluation after PPO's updates beat it"
        if result.best_step == 0
        else f"the evaluation after {result.best_step:,} agent-steps"
    )
    print(f"kept: {kept}")


def warm_start_row(run_dir: Path) -> dict[str, float] | None:
    """The row of a warm-started run's iteration 0 in its progress.csv (the warm start's statistics and greedy
    evaluation, before any PPO update); None when the run has none."""
    with (run_dir / "progress.csv").open(encoding="utf-8") as f:
        first = next(csv.DictReader(f), None)
    if first is None or not first.get("warm/labels"):
        return None
    return {k: float(v) for k, v in first.items() if v != ""}


def recorded_best_known(args: Args, path: Path = FIXED_CSV) -> float | None:
    """``best_known``'s recorded TD on Berlin P4 at the run's threshold and rule (None when not recorded): the
    learning curve's reference line."""
    if not path.is_file():
        return None
    instance = f"berlin_p4@{args.sinr_min_db:g}dB"
    with path.open(encoding="utf-8") as f:
        for r in csv.DictReader(f):
            if (r["instance"], r["method"], r["feasibility"]) == (instance, "best_known", args.feasibility):
                return float(r["td_m"])
    return None


def generalist_report(test_count: int, planner_csv: Path) -> dict[str, float]:
    """The shipped generalist beside the paper on Berlin P4 and beside the planners on the test instances."""
    from uamfleet.instances import fly_instances, split_seeds
    from uamfleet.zoo import pretrained

    start = time.perf_counter()
    planner = pretrained("berlin")
    print("\nThe shipped Berlin generalist, uamfleet.pretrained('berlin'): one policy for any instance, trained on "
          "random demand;\nnever trained on Berlin P4 nor on the test instances (docs/results.md).")  # fmt: skip
    print(f"\nBerlin P4 (zero-shot)   {'PR %':>5} {'TD m':>7} {'paper MSHA-RL TD m':>19}")
    for threshold in (-7.0, -6.0, -5.0, -4.0, -3.0):
        cfg = make_config("berlin_p4", sinr_min_db=threshold)
        m = episode_metrics(planner.fly(cfg), cfg.radio, threshold_db=threshold)
        paper = PAPER_TABLE_II["berlin"]["MSHA-RL"].get(threshold)
        print(f"  {threshold:>4g} dB{'':14} {fmt(m.pr_pct, '.0f'):>5} {fmt(m.td_m, ',.0f'):>7} "
              f"{fmt(paper[0] if paper else math.nan, ',.0f'):>19}")  # fmt: skip
    seeds = split_seeds("test", test_count)
    assert planner.trained_on is not None
    served, distance = fly_instances(planner, "berlin", seeds, planner.trained_on)
    print(f"\nBerlin test instances (first {test_count} of the 200 held-out seeds, endpoint-block rule)")
    print(f"{'method':<28} {'all delivered %':>15} {'PR %':>6} {'TD m (mean)':>12}")
    print(f"{'generalist (shipped)':<28} {100 * np.mean(served >= 1):>15.1f} {100 * served.mean():>6.1f} "
          f"{distance.mean():>12,.0f}")  # fmt: skip
    recorded = _recorded_rows(planner_csv, {str(s) for s in seeds})
    for method in ("replan", "best_known"):
        rows = recorded.get(method, [])
        if len(rows) == len(seeds):
            pr = np.array([r[0] for r in rows])
            td = np.array([r[1] for r in rows])
            print(f"{method + ' (recorded)':<28} {100 * np.mean(pr >= 100):>15.1f} {pr.mean():>6.1f} "
                  f"{td.mean():>12,.0f}")  # fmt: skip
    if not recorded:
        print(f"(the planners' recorded rows are in {planner_csv} in the repository; not found here)")
    print(f"(generalist section: {time.perf_counter() - start:.0f} s)")
    return {"all_delivered_pct": float(100 * np.mean(served >= 1)), "td_m": float(distance.mean())}


def _recorded_rows(path: Path, instances: set[str]) -> dict[str, list[tuple[float, float]]]:
    """(PR %, TD m) per method of the benchmark CSV's rows on ``instances`` (empty when the file is absent)."""
    if not path.is_file():
        return {}
    out: dict[str, list[tuple[float, float]]] = {}
    with path.open(encoding="utf-8") as f:
        for r in csv.DictReader(f):
            if r["instance"] in instances and r["feasibility"] == "endpoint_block":
                out.setdefault(r["method"], []).append((float(r["pr_pct"]), float(r["td_m"])))
    return out


def cli(argv: Sequence[str] | None = None, prog: str = "uamfleet-quickstart") -> int:
    """The ``uamfleet-quickstart`` command (``python -m eval.quickstart``)."""
    return run(main, Args, argv, prog, __doc__)


if __name__ == "__main__":
    raise SystemExit(cli(prog="python -m uamfleet.cli.quickstart"))
