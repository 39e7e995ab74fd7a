"""PPO with one shared MSHA policy over every taxi of every env: ``train(args) -> TrainResult``.

CleanRL's loop (``ppo.py``) made importable and cut into named parts, read top to bottom in :func:`train`: the
collector's :func:`~uamfleet.rl.collector.collect_rollout` (the batched core, N = E * A agents per step), the
learner's :func:`~uamfleet.rl.learner.compute_advantages` (GAE that bootstraps truncated episodes from their real
final observation) and :func:`~uamfleet.rl.learner.ppo_update` (clipped surrogate and value losses, entropy bonus,
gradient clipping), then :func:`evaluate_greedy` on a separate env. Advantage / observation / reward normalisation,
a linear learning-rate schedule and an optional centralised critic on the global state (MAPPO).

The rooms around the loop: the collector (the run's envs and buffer) in :mod:`uamfleet.rl.collector`, the learner
(the network, its optimiser and the PPO update) in :mod:`uamfleet.rl.learner`, the options in
:mod:`uamfleet.rl.options` (``TrainArgs``), the checkpoints in :mod:`uamfleet.rl.checkpoint`, the run folder and the
log in :mod:`uamfleet.rl.runs`, the policy at inference and ``load_policy`` in :mod:`uamfleet.rl.policy`. Their
public names are re-exported here, where users import them.

Under ``torchrun`` every rank runs this loop on its share of the envs, data-parallel on ``torch.distributed``
(uamfleet.rl.distributed says what keeps the ranks equal); rank 0 alone evaluates, logs and checkpoints.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
import math
import time
from collections.abc import Callable
from typing import Any, cast

import numpy as np
import torch

from uamfleet.config import REWARD_TERMS, EnvConfig
from uamfleet.observe.spec import layout_to_dict
from uamfleet.instances import FAMILIES, family_of, validation_metrics
from uamfleet.metrics import EpisodeMetrics, episode_metrics
from uamfleet.rl.checkpoint import (
    ARCHITECTURE_FIELDS,
    CHECKPOINT_FORMAT,
    ENVIRONMENT_FIELDS,
    Checkpoint,
    CheckpointError,
    check_state_dict,
    plain_numpy_rng,
    trained_spec,
    world_record,
)
from uamfleet.rl.collector import Counters, RolloutStats, Run, collect_rollout, make_run, restore_counters
from uamfleet.rl.distributed import RankZeroError, Ranks
from uamfleet.rl.legacy import checkpoint_args, upgrade_checkpoint
from uamfleet.rl.learner import (
    Learner,
    compute_advantages,
    make_learner,
    ppo_update,
    set_schedules,
    with_init_architecture,
)
from uamfleet.rl.options import TrainArgs, make_env_config
from uamfleet.rl.policy import GreedyPolicy, load_policy
from uamfleet.rl.ppo import PPOLossInfo
from uamfleet.rl.warm_start import warm_started
from uamfleet.rl.runs import RUN_FILES, RUN_NAME, Logger, RunClaim, TrainResult, claim_run, read_progress, run_folder
from uamfleet.rollout import fly


def evaluate(policy: GreedyPolicy, cfg: EnvConfig, seed: int = 0) -> EpisodeMetrics:
    return episode_metrics(fly(cfg, policy, seed=seed), cfg.radio)


def _score(m: dict[str, float]) -> tuple[float, float]:
    """Order evaluations: more delivered first, then shorter distance."""
    return (-m.get("pr_pct", 0.0), m.get("td_m", math.inf))


# ---- the state a checkpoint keeps and restores ----------------------------------------------------------------


def capture(run: Run, learner: Learner, counters: Counters) -> Checkpoint:
    """A checkpoint of the current state (copies: training goes on changing the live tensors)."""
    cuda = torch.cuda.get_rng_state(run.device) if run.device.type == "cuda" else None
    return Checkpoint(
        model=copy.deepcopy(learner.net.state_dict()), optimizer=copy.deepcopy(learner.optimizer.state_dict()),
        net_config=dataclasses.asdict(learner.net_cfg), args=run.args.flat(),
        obs_shapes={k: list(v) for k, v in run.obs_shapes.items()}, obs_layout=layout_to_dict(run.layout),
        observer=trained_spec(run.eval_cfg, dataclasses.asdict(learner.net_cfg), observer=run.spec).to_dict(),
        world=world_record(run.eval_cfg.world), iteration=counters.iteration,
        global_step=counters.global_step, wall_s=counters.wall_offset + time.time() - run.start_time,
        obs_normalizer=learner.normalizer.state_dict() if learner.normalizer is not None else None,
        reward_scaler=learner.scaler.rms.state_dict() if learner.scaler is not None else None,
        best_eval=dict(counters.best_eval), best_step=counters.best_step, target_step=counters.target_step,
        target_s=counters.target_s, torch_rng=torch.get_rng_state(), numpy_rng=numpy_rng_state(), cuda_rng=cuda,
    )  # fmt: skip


def restore(ckpt: Checkpoint, run: Run, learner: Learner) -> Counters:
    ckpt.check_matches(run.args, run.obs_shapes, layout=run.layout)
    shapes = {k: tuple(v.shape) for k, v in learner.net.state_dict().items()}
    check_state_dict(ckpt.model, shapes, str(run.folder / "last.pt"), run.args.net.variant)
    learner.net.load_state_dict(ckpt.model)
    learner.optimizer.load_state_dict(ckpt.optimizer)
    if learner.normalizer is not None and ckpt.obs_normalizer is not None:
        learner.normalizer.load_state_dict(ckpt.obs_normalizer)
    if learner.scaler is not None and ckpt.reward_scaler is not None:
        learner.scaler.rms.load_state_dict(ckpt.reward_scaler)
    torch.set_rng_state(ckpt.torch_rng.cpu())
    if ckpt.cuda_rng is not None and run.device.type == "cuda":
        torch.cuda.set_rng_state(ckpt.cuda_rng.cpu(), run.device)
    set_numpy_rng_state(ckpt.numpy_rng)
    return restore_counters(ckpt)


def start(run: Run, learner: Learner, claim: RunClaim | None) -> tuple[Counters, list[dict[str, float]]]:
    """Prepare the claimed folder (rank 0: an earlier run replaced with ``--overwrite`` is deleted now that every
    option is checked), resume from last.pt on every rank, and broadcast rank 0's parameters."""
    ranks, data, error = run.ranks, None, None
    if ranks.is_main:
        try:
            if claim is not None:
                claim.clear()
            data = (run.folder / "last.pt").read_bytes() if run.args.run.resume else None
        except Exception as err:
            error = err
    if not ranks.broadcast_flag(error is None):
        if error is not None:
            raise error
        raise RankZeroError("rank 0 could not set up the run folder; its error says why.")
    data = ranks.broadcast_bytes(data)
    counters, rows = Counters(), []
    if data is not None:
        counters = restore(Checkpoint.from_bytes(data, str(run.folder / "last.pt"), run.device), run, learner)
        if ranks.is_main:
            # rows logged after the checkpoint belong to iterations that are trained again
            progress = read_progress(run.folder / "progress.csv", required=("iteration",))
            rows = [r for r in progress if r["iteration"] <= counters.iteration]
    ranks.broadcast_module(learner.net)
    obs, _ = run.venv.reset(seed=run.args.ppo.seed + run.env_offset)  # global env e gets seed + e
    run.obs = run.flat(obs)
    return counters, rows


# ---- an iteration's row and the greedy evaluation ------------------------------------------------------------


def progress_row(
    run: Run, learner: Learner, counters: Counters, rollout: RolloutStats, infos: list[PPOLossInfo],
    advantages: np.ndarray, returns: np.ndarray, shaping_weight: float,
) -> dict[str, float]:  # fmt: skip
    """The iteration's CSV / TensorBoard row (CleanRL's names), pooled over ranks."""
    ranks = run.ranks
    values = ranks.gather_agents(run.buffer.values, run.agent_offset, run.total_agents)  # [T, N_global]
    returns = ranks.gather_agents(returns, run.agent_offset, run.total_agents)
    var_y = np.var(returns)
    explained_var = math.nan if var_y == 0 else float(1 - np.var(returns - values) / var_y)
    elapsed = counters.wall_offset + time.time() - run.start_time
    row: dict[str, float] = {
        "iteration": counters.iteration + 1, "global_step": counters.global_step, "wall_s": elapsed,
        "charts/learning_rate": learner.optimizer.param_groups[0]["lr"],
        "charts/shaping_weight": shaping_weight,
        "charts/SPS": counters.global_step / max(elapsed, 1e-9),
    }  # fmt: skip
    names = ["value_loss", "policy_loss", "entropy", "old_approx_kl", "approx_kl", "clipfrac"]
    for name in names + (["kl_to_init"] if learner.reference is not None else []):
        row[f"losses/{name}"] = float(np.mean([getattr(i, name) for i in infos]))
    row["losses/explained_variance"] = explained_var
    terms = ranks.all_sum(rollout.term_sums)
    for name, total in zip(REWARD_TERMS, terms, strict=True):
        row[f"reward/{name}"] = float(total / run.batch_size)  # mean per agent-step
    sums = rollout.episodes.pooled(ranks)
    if sums.count:
        row["charts/episodic_return"] = float(sums.episode_return / sums.count)
        row["charts/episodic_length"] = float(sums.length / sums.count)
        row["charts/service_rate"] = float(sums.service_rate / sums.count)
        row["charts/episodic_distance_m"] = float(sums.distance_m / sums.count)
    return row


def evaluate_greedy(
    run: Run, learner: Learner, counters: Counters, row: dict[str, float], last: bool = False
) -> bool:  # fmt: skip
    """Rank 0: fly the greedy policy (one episode, or the validation instances), add eval/* to the row, keep the
    best; True when it is a new best. The policy reads the run's spec (:attr:`Run.spec`) in the evaluation world.
    The curve's validation panel is flown at every ``--curve-every``-th evaluation and at the ``last``."""
    policy = GreedyPolicy(learner.net, learner.normalizer, run.device, spec=run.spec)
    if run.args.eval.eval_instances:
        m = validation_metrics(policy, family_of(run.args.env.scenario), run.args.eval.eval_instances, run.eval_cfg)
    else:
        m = evaluate(policy, run.eval_cfg).as_dict()
    row.update({f"eval/{k}": v for k, v in m.items()})
    curve_due = last or int(row["iteration"]) % run.args.eval.curve_every == 0
    if run.args.eval.curve_instances and curve_due:  # the curve's validation panel; never used to keep the best
        curve = curve_metrics(run, policy)
        row["val_td_m"], row["val_pr_pct"] = curve["td_m"], curve["pr_pct"]
    target = run.args.eval.stop_at_td_m
    if counters.target_step is None and target is not None and m["pr_pct"] >= 100.0 and m["td_m"] <= target:
        counters.target_step, counters.target_s = counters.global_step, row["wall_s"]
    if counters.best_eval and _score(m) >= _score(counters.best_eval):
        return False
    counters.best_eval, counters.best_step = m, counters.global_step
    return True


def curve_metrics(run: Run, policy: GreedyPolicy) -> dict[str, float]:
    """The greedy ``policy`` on the first ``--curve-instances`` validation instances of the curve's family
    (:func:`~uamfleet.instances.validation_metrics`) under the evaluation's rules. Where those instances hold more
    requests than the run's world has passenger rows (Berlin P4's 4 against a Berlin instance's up to 6), the
    policy reads as many rows as it trained on, its nearest requests (a passenger window), in a world whose
    passenger axis holds them all."""
    family = run.args.curve_family_name()
    like, most = run.eval_cfg, FAMILIES[family].max_passengers
    if like.num_passengers < most:
        assert policy.spec is not None
        if policy.spec.passenger_window is None:
            rows = policy.spec.rows(like.world)
            policy = policy.reading(dataclasses.replace(policy.spec, passenger_window=rows, slots_per_taxi=None))
        like = _with_passenger_rows(like, most)
    return validation_metrics(policy, family, run.args.eval.curve_instances, like)


@functools.lru_cache(maxsize=1)
def _with_passenger_rows(like: EnvConfig, rows: int) -> EnvConfig:
    """``like`` with a passenger axis of ``rows``: one object per run's config, since
    :func:`~uamfleet.instances.fly_instances` keeps its batch for the config object it was built for (configs
    hash by identity), so every evaluation after the first reuses the instances."""
    return like.replace(max_passengers=rows)


def evaluate_start(run: Run, learner: Learner, counters: Counters) -> dict[str, float]:
    """Rank 0, before a run from ``--init-from`` trains: the start's greedy evaluation becomes the best so far and
    best.pt, so fine-tuning keeps the start unless an evaluation beats it. Its row (iteration 0) goes to
    progress.csv."""
    row: dict[str, float] = {"iteration": 0, "global_step": 0, "wall_s": time.time() - run.start_time}
    evaluate_greedy(run, learner, counters, row)
    capture(run, learner, counters).save(run.folder / "best.pt")
    return row


def start_row(run: Run, learner: Learner, counters: Counters) -> list[dict[str, float]]:
    """The run's start before PPO: the search warm start (``--warm-start-rounds``; a resumed run reads its
    reference back), then, for a fresh run from ``--init-from`` or a warm start, rank 0's row of iteration 0
    (:func:`evaluate_start`, with the warm start's statistics); no row otherwise."""
    args, fresh = run.args, counters.iteration == 0
    warm = warm_started(run, learner, not fresh) if args.net.warm_start_rounds else {}
    if fresh and run.ranks.is_main and (args.net.init_from is not None or args.net.warm_start_rounds):
        return [{**evaluate_start(run, learner, counters), **warm}]
    return []


# ---- the loop --------------------------------------------------------------------------------------------------


def train(
    args: TrainArgs,
    env_config: EnvConfig | None = None,
    on_iteration: Callable[[int, torch.nn.Module], None] | None = None,
) -> TrainResult:
    """Train; ``env_config`` replaces the named scenario (e.g. a user's own map or instance). Under torchrun
    every rank calls this; ``on_iteration(iteration, net)`` runs on every rank after each update (tests)."""
    if args.run.threads:
        torch.set_num_threads(args.run.threads)
    ranks, device = Ranks.from_env(args.run.device, args.run.backend)
    args = with_init_architecture(args)
    claim = claim_folder(args, ranks)  # before any env or table is built: a second run of the name fails at once
    try:
        run = make_run(args, env_config, ranks, device)
        try:
            return _train(run, on_iteration, claim)
        finally:
            run.venv.close()  # env workers stop with the training, however it ends
    finally:
        if claim is not None:
            claim.release()


def claim_folder(args: TrainArgs, ranks: Ranks) -> RunClaim | None:
    """Rank 0 claims the run folder (:func:`~uamfleet.rl.runs.claim_run`; with ``--resume`` its progress.csv is
    read, so a damaged one fails now) and every rank learns the outcome: rank 0 raises its error, the others
    :class:`~uamfleet.rl.distributed.RankZeroError`. The claim on rank 0, None on the others."""
    claim, error = None, None
    if ranks.is_main:
        try:
            claim = claim_run(args.run.run_dir, args.name, resume=args.run.resume, overwrite=args.run.overwrite)
            if args.run.resume:
                read_progress(claim.folder / "progress.csv", required=("iteration",))
        except Exception as err:
            if claim is not None:
                claim.release()
            error = err
    if not ranks.broadcast_flag(error is None):
        if error is not None:
            raise error
        raise RankZeroError(
            f"rank 0 could not claim the run folder {args.run.run_dir / args.name}; its error says why."
        )
    return claim


def _train(
    run: Run, on_iteration: Callable[[int, torch.nn.Module], None] | None, claim: RunClaim | None
) -> TrainResult:
    args, ranks = run.args, run.ranks
    learner = make_learner(run)
    counters, rows = start(run, learner, claim)
    rows += start_row(run, learner, counters)
    clock_start = first_delivery(run, rows)
    if counters.iteration >= run.num_iterations:
        _say_finished(run, counters)
        return _result(run, counters, rows, interrupted=False)
    log = open_log(run, counters)
    snapshot = capture(run, learner, counters) if ranks.is_main else None
    try:
        for iteration in range(counters.iteration, run.num_iterations):
            shaping_weight, rollout, advantages, returns, infos = ppo_iteration(run, learner, iteration, clock_start)
            counters.global_step += run.batch_size
            if on_iteration is not None:
                on_iteration(iteration, learner.net)
            row = progress_row(run, learner, counters, rollout, infos, advantages, returns, shaping_weight)
            stop, new_best = evaluate_and_decide(run, learner, counters, row, iteration)
            if clock_start is None and args.ppo.schedule_clock == "first_delivery":
                clock_start = first_delivery(run, [row])
            if log is not None:
                rows.append(row)
                snapshot = record(run, learner, counters, log, rows, new_best, stop)
            if stop:
                break
    except KeyboardInterrupt:
        return _interrupted(run, counters, rows, snapshot)
    finally:
        if log is not None:
            log.close()
    ranks.barrier()
    return _result(run, counters, rows, interrupted=False)


def ppo_iteration(
    run: Run, learner: Learner, iteration: int, clock_start: int | None = None
) -> tuple[float, RolloutStats, np.ndarray, np.ndarray, list[PPOLossInfo]]:
    """One iteration of PPO on every rank: the iteration's schedules, a rollout of the run's envs, GAE and the
    clipped update (with the KL term toward ``learner.reference`` when it has one). Returns the shaping weight,
    the rollout's statistics, the advantages and returns [T, N] and the minibatches' loss figures."""
    shaping_weight = set_schedules(run, learner, iteration, clock_start)
    rollout = collect_rollout(run, learner.net, learner.normalizer, learner.scaler)
    advantages, returns = compute_advantages(run, learner)
    infos = ppo_update(run, learner, advantages, returns)
    return shaping_weight, rollout, advantages, returns, infos


def first_delivery(run: Run, rows: list[dict[str, float]]) -> int | None:
    """With ``--schedule-clock first_delivery``: the iteration the schedules count from, on every rank (rank 0's
    ``rows`` decide): the first row's whose greedy evaluation delivered everyone (a row's ``iteration`` counts the
    iterations done, so it is the next one to train; a resumed run finds it in its progress.csv, a fine-tuning run
    in its start's evaluation, iteration 0); None when no row has, and always with ``steps``."""
    if run.args.ppo.schedule_clock != "first_delivery":
        return None
    found = None
    if run.ranks.is_main:
        delivered = [r for r in rows if r.get("eval/pr_pct", 0.0) >= 100.0]
        if delivered:
            found = int(delivered[0]["iteration"])
    data = run.ranks.broadcast_bytes(None if found is None else str(found).encode())
    return None if data is None else int(data)


def _say_finished(run: Run, counters: Counters) -> None:
    if run.ranks.is_main:
        print(f"{run.folder} is finished ({counters.iteration} of {run.num_iterations} iterations, "
              f"{counters.global_step:,} agent-steps); raise --total-timesteps to train it further")  # fmt: skip


def open_log(run: Run, counters: Counters) -> Logger | None:
    """Rank 0's logger (None on the other ranks); a resumed run says where it goes on."""
    if not run.ranks.is_main:
        return None
    resumed_at = counters.global_step if run.args.run.resume else None
    if resumed_at is not None:
        print(f"resumed {run.folder} at iteration {counters.iteration}, step {counters.global_step:,} "
              "(envs restart their episodes)")  # fmt: skip
    return Logger(run.folder, run.args, run.num_iterations, counters.iteration, resumed_at)


def evaluate_and_decide(
    run: Run, learner: Learner, counters: Counters, row: dict[str, float], iteration: int
) -> tuple[bool, bool]:
    """End of an iteration on every rank: rank 0 evaluates when it is due (every ``eval_every`` iterations and at
    the last), the counters move on, and all ranks agree whether to stop. Returns (stop, new best)."""
    args, ranks = run.args, run.ranks
    out_of_time = args.eval.max_wall_s is not None and time.time() - run.start_time >= args.eval.max_wall_s
    last = ranks.broadcast_flag(iteration == run.num_iterations - 1 or out_of_time)
    new_best = False
    if ranks.is_main and ((args.eval.eval_every and (iteration + 1) % args.eval.eval_every == 0) or last):
        new_best = evaluate_greedy(run, learner, counters, row, last=last)
    counters.iteration = iteration + 1
    stop = ranks.broadcast_flag(last or (counters.target_step is not None and args.eval.stop_at_td_m is not None))
    return stop, new_best


def record(
    run: Run, learner: Learner, counters: Counters, log: Logger, rows: list[dict[str, float]], new_best: bool,
    stop: bool,
) -> Checkpoint:  # fmt: skip
    """Rank 0: log the rows, write best.pt on a new best and last.pt every ``checkpoint_every`` iterations and at
    the stop; returns the state after this iteration (what an interrupt saves)."""
    log.write(rows, counters.best_eval)
    snapshot = capture(run, learner, counters)
    if new_best:
        snapshot.save(run.folder / "best.pt")
    if stop or counters.iteration % run.args.run.checkpoint_every == 0:
        snapshot.save(run.folder / "last.pt")
    return snapshot


def _interrupted(
    run: Run, counters: Counters, rows: list[dict[str, float]], snapshot: Checkpoint | None
) -> TrainResult:
    """Ctrl-C: save the state after the last finished iteration (the interrupted one is redone on --resume)."""
    if snapshot is not None:
        snapshot.save(run.folder / "last.pt")
        counters = restore_counters(snapshot)
        rows = [r for r in rows if r["iteration"] <= snapshot.iteration]
        print(f"\ninterrupted: checkpoint of iteration {snapshot.iteration} saved to {run.folder / 'last.pt'}; "
              "continue with --resume")  # fmt: skip
    return _result(run, counters, rows, interrupted=True)


def _result(run: Run, counters: Counters, rows: list[dict[str, float]], interrupted: bool) -> TrainResult:
    final_eval = {k.removeprefix("eval/"): v for k, v in rows[-1].items() if k.startswith("eval/")} if rows else {}
    return TrainResult(
        run_dir=run.folder, global_step=counters.global_step, iterations=len(rows),
        wall_s=counters.wall_offset + time.time() - run.start_time, final_eval=final_eval,
        best_eval=counters.best_eval, best_step=counters.best_step, target_reached_step=counters.target_step,
        target_reached_s=counters.target_s,
        losses=[{k: v for k, v in r.items() if k.startswith("losses/")} for r in rows], interrupted=interrupted,
        rank=run.ranks.rank,
    )  # fmt: skip


def numpy_rng_state() -> dict[str, Any]:
    """NumPy's global generator state as plain values (a checkpoint loads with ``weights_only=True``)."""
    return plain_numpy_rng(cast(tuple[Any, ...], np.random.get_state()))  # legacy=True (the default): a tuple


def set_numpy_rng_state(state: dict[str, Any]) -> None:
    """Restore what :func:`numpy_rng_state` saved."""
    keys = np.array(state["keys"], dtype=np.uint32)
    np.random.set_state((state["name"], keys, state["pos"], state["has_gauss"], state["cached_gaussian"]))


__all__ = [
    "ARCHITECTURE_FIELDS", "CHECKPOINT_FORMAT", "ENVIRONMENT_FIELDS", "RUN_FILES", "RUN_NAME", "Checkpoint",
    "CheckpointError", "GreedyPolicy", "Logger", "TrainArgs", "TrainResult", "checkpoint_args", "collect_rollout",
    "compute_advantages", "evaluate", "load_policy", "make_env_config", "ppo_iteration", "ppo_update",
    "read_progress", "run_folder", "train", "upgrade_checkpoint",
]  # fmt: skip
