"""Expert iteration: the network learns the decisions of the hedge built on it, on the states it visits itself.

The hedge (:class:`uamfleet.rl.guided.AnticipatingGuidedSearch`) flies the network as the base of a search over
sampled futures and beats it; this loop teaches the network what the search chose (Anthony et al. 2017, ExIt;
Silver et al. 2017) and hedges again with the network it made:

1. **Label** fresh training instances of the family (a new block of train seeds each round) with
   :func:`uamfleet.rl.labels.label_instances`: the network flies greedily (DAgger: its own states), and on the way
   the hedge over it scores its candidates in sampled futures (soft targets over the candidates) while a request may
   still come, and the step-level solver over the then-complete requests labels the steps after.
2. **Fit** every parameter to the aggregated labels: the weighted cross-entropy to the soft targets plus
   ``kl_anchor`` times the KL divergence from the round's start network over the headings on the same states (a fit
   that drifts off the headings it flew well is held back, while whether to hover is left to the labels).
3. **Validate** the fitted network greedily on the validation block, paired per instance against the round's start
   network, and accept the round only if it flies shorter on average without delivering fewer passengers; a rejected
   round keeps the start network (its labels stay in the data). Stop after ``patience`` rejections in a row.

Instances fly in worlds with the hover action (``hover=True``, the network converted by
:func:`uamfleet.rl.hover.with_hover_anytime` so that waiting, the hedge's most valuable move, can be learnt).
Choices are made on validation seeds only; the test seeds are flown once per shipped policy, elsewhere.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from uamfleet.config import ConfigError, EnvConfig, check_integer, check_number
from uamfleet.instances import FAMILIES, make_instance, split_seeds
from uamfleet.io import write_csv_atomic
from uamfleet.metrics import episode_metrics
from uamfleet.presets import SCENARIOS, make_config
from uamfleet.rl.checkpoint import PRETRAINED, Checkpoint, pretrained_path
from uamfleet.rl.collector import make_run
from uamfleet.rl.distributed import Ranks
from uamfleet.rl.hover import NEW_PARAMETERS, hover_checkpoint, with_hover_anytime
from uamfleet.rl.labels import LabelOptions, Labels, label_instances, load_labels
from uamfleet.rl.learner import make_learner, with_init_architecture
from uamfleet.rl.networks import obs_to_torch
from uamfleet.rl.options import TrainArgs
from uamfleet.rl.policy import GreedyPolicy, load_policy
from uamfleet.rl.ppo import PPOLossInfo
from uamfleet.rl.runs import claim_run
from uamfleet.rl.trainer import ppo_iteration
from uamfleet.rl.trainer import start as trainer_start
from uamfleet.rollout import fly
from uamfleet.types import NUM_HEADINGS

CLOSED_LOGP = -1e3
"""A log-probability below this is a masked action: it carries no target and no anchor mass."""


@dataclass(frozen=True)
class ExItOptions:
    """The options of one expert-iteration run (``uamfleet exit``), checked on construction."""

    init: str = "berlin"
    """the start: a shipped policy's name or a checkpoint file"""
    family: str = "berlin"
    """the instance family labelled and validated on"""
    hover: bool = True
    """worlds with the hover action, the network able to hover at any step and the hedge waiting by hovering"""
    demand: str = "family"
    """the hedge's demand model: family (the true law), a family's name, wrong, or a fitted model's .json"""
    rounds: int = 4
    label_instances: int = 60
    """training instances labelled per round (a fresh block of train seeds each round)"""
    label_every: int = 2
    label_futures: int = 16
    label_temperature: float = 0.5
    finish_beam: int = 32
    val_instances: int = 80
    val_first: int = 200
    """index of the first validation seed (the block earlier choices did not use)"""
    workers: int = 2
    epochs: int = 5
    learning_rate: float = 1e-3
    """chosen with ``epochs`` on the first two rounds' labels of a run, flown on the validation block
    (reports/2026-12-04-expert-iteration)"""
    minibatch: int = 256
    kl_anchor: float = 1.0
    """weight of the KL divergence from the round's start over the headings (given no hover)"""
    hover_lr_scale: float = 30.0
    """the hover logit's parameters learn this many times faster than the rest"""
    max_samples: int = 200_000
    ppo_after: int = 0
    """agent-steps of PPO after each round's fit, on the family's random training episodes in hover worlds, with a
    KL term toward the fitted network (0: none, the fit alone is validated)"""
    ppo_kl: float = 0.01
    """weight of that KL term (``TrainArgs.net.kl_to_init``; the main job's recipe's 0.01)"""
    ppo_learning_rate: float = 3e-4
    """PPO's learning rate, annealed to 0 over ``ppo_after`` (the main job's fine-tuning recipe's)"""
    ppo_envs: int = 10
    """PPO's envs, spread over the start's thresholds; an iteration is ``ppo_envs`` x ``ppo_steps`` agent-steps"""
    ppo_steps: int = 128
    ppo_hover_reward: float = 1.0
    """reward of a hover step in PPO's worlds (``RewardConfig.hover``, on top of every step's -2): 0 prices a hover
    like a move, +2 makes it free (the distance the loop validates, but then hovering to the time limit is the best
    return, since an instance's reward pays no delivery); +1, half a move, keeps waiting cheaper than flying and a
    600-step hover dearer than a tour"""
    patience: int = 2
    seed: int = 0
    threads: int = 1
    run_name: str = "exit"
    run_dir: Path = Path("runs")
    overwrite: bool = False

    def __post_init__(self) -> None:
        if self.family not in FAMILIES:
            raise ConfigError(f"family={self.family!r} is unknown; choose one of {sorted(FAMILIES)}.")
        if self.init not in PRETRAINED and not Path(self.init).is_file():
            raise ConfigError(f"init={self.init!r} is neither a shipped policy {tuple(PRETRAINED)} nor a file.")
        for name, low in (("rounds", 1), ("label_instances", 1), ("label_every", 1), ("label_futures", 1),
                          ("finish_beam", 1), ("val_instances", 2), ("val_first", 0), ("workers", 1),
                          ("epochs", 1), ("minibatch", 1), ("max_samples", 1), ("patience", 1), ("seed", 0),
                          ("threads", 1)):  # fmt: skip
            check_integer(name, getattr(self, name), low)
        check_number("label_temperature", self.label_temperature, positive=True)
        check_number("learning_rate", self.learning_rate, positive=True)
        check_number("kl_anchor", self.kl_anchor, minimum=0.0)
        check_number("hover_lr_scale", self.hover_lr_scale, positive=True)
        self._check_ppo()

    def _check_ppo(self) -> None:
        """``--ppo-after`` 0, or at least one PPO iteration on a family with a training scenario."""
        for name, low in (("ppo_after", 0), ("ppo_envs", 1), ("ppo_steps", 1)):
            check_integer(name, getattr(self, name), low)
        check_number("ppo_kl", self.ppo_kl, minimum=0.0)
        check_number("ppo_learning_rate", self.ppo_learning_rate, positive=True)
        check_number("ppo_hover_reward", self.ppo_hover_reward)
        if not self.ppo_after:
            return
        batch = self.ppo_envs * self.ppo_steps
        if self.ppo_after < batch:
            raise ConfigError(
                f"ppo_after={self.ppo_after} is less than one PPO iteration of ppo_envs x ppo_steps = {batch} "
                f"agent-steps; give --ppo-after 0 (no PPO) or at least {batch}, or fewer --ppo-envs / --ppo-steps."
            )
        if ppo_scenario(self.family) not in SCENARIOS:
            raise ConfigError(
                f"ppo_after={self.ppo_after}: the family {self.family!r} has no training scenario "
                f"{ppo_scenario(self.family)!r} to fine-tune on; give --ppo-after 0, or a family whose *_instances "
                "scenario exists (e.g. berlin)."
            )

    def label_options(self) -> LabelOptions:
        return LabelOptions(
            every=self.label_every, futures=self.label_futures, temperature=self.label_temperature,
            finish_beam=self.finish_beam, wait_action="hover" if self.hover else "forbidden",
        )  # fmt: skip


@dataclass
class LabelSet:
    """The aggregated labels as the network reads them: normalised observation rows, soft targets and weights."""

    obs: dict[str, np.ndarray]
    target: np.ndarray  # [N, actions]
    weight: np.ndarray  # [N]

    def __len__(self) -> int:
        return len(self.weight)

    def extended(self, other: LabelSet, limit: int) -> LabelSet:
        """These labels and ``other``'s after them, the oldest dropped beyond ``limit``."""
        if not len(self):
            return other.tail(limit)
        obs = {k: np.concatenate([self.obs[k], other.obs[k]]) for k in self.obs}
        return LabelSet(
            obs, np.concatenate([self.target, other.target]), np.concatenate([self.weight, other.weight])
        ).tail(limit)

    def tail(self, limit: int) -> LabelSet:
        if len(self) <= limit:
            return self
        return LabelSet({k: v[-limit:] for k, v in self.obs.items()}, self.target[-limit:], self.weight[-limit:])


def fit(
    policy: GreedyPolicy, anchor: GreedyPolicy, data: LabelSet, opts: ExItOptions, rng: np.random.Generator
) -> dict[str, float]:
    """``opts.epochs`` passes over ``data``: Σ w · CE(q, π) / Σ w + ``kl_anchor`` · KL(ρ_anchor ‖ ρ), every
    parameter of ``policy``'s network, where ρ is the distribution over the 16 headings alone (given no hover): the
    anchor holds which heading the network prefers, never whether it hovers. The hover logit's parameters learn
    ``hover_lr_scale`` times faster (it starts 12 logits down, out of reach of the rest's step sizes). Targets on
    actions the state masks are dropped and the rest renormalised. Returns the last epoch's mean loss, the agreement
    of the argmax with the target's, and the mean KL."""
    net, anchor_net = policy.net, anchor.net
    hover = [p for name, p in net.named_parameters() if name.startswith(NEW_PARAMETERS)]
    rest = [p for name, p in net.named_parameters() if not name.startswith(NEW_PARAMETERS)]
    groups = [{"params": rest, "lr": opts.learning_rate}]
    groups += [{"params": hover, "lr": opts.learning_rate * opts.hover_lr_scale}] if hover else []
    optimizer = torch.optim.Adam(groups)
    net.train()
    losses: list[float] = []
    hits: list[float] = []
    kls: list[float] = []
    n = len(data)
    for _ in range(opts.epochs):
        order = rng.permutation(n)
        del losses[:], hits[:], kls[:]  # the last epoch's figures are reported
        for start in range(0, n, opts.minibatch):
            idx = order[start : start + opts.minibatch]
            batch = obs_to_torch({k: v[idx] for k, v in data.obs.items()}, "cpu")
            with torch.no_grad():
                anchor_logits = anchor_net.masked_logits(batch)
                anchor_logp = torch.log_softmax(anchor_logits, -1).clamp(min=-1e4)
                anchor_headings = torch.log_softmax(anchor_logits[:, :NUM_HEADINGS], -1).clamp(min=-1e4)
            logits = net.masked_logits(batch)
            logp = torch.log_softmax(logits, -1).clamp(min=-1e4)  # [b, A]
            headings = torch.log_softmax(logits[:, :NUM_HEADINGS], -1).clamp(min=-1e4)  # [b, 16] given no hover
            allowed = anchor_logp > CLOSED_LOGP
            width = logp.shape[-1]
            target = torch.as_tensor(data.target[idx][:, :width]) * allowed
            mass = target.sum(-1, keepdim=True)
            kept = mass.squeeze(-1) > 0
            target = target / mass.clamp(min=1e-12)
            weight = torch.as_tensor(data.weight[idx]) * kept
            ce = -(target * torch.where(allowed, logp, torch.zeros_like(logp))).sum(-1)
            kl = (anchor_headings.exp() * (anchor_headings - headings)).sum(-1)
            loss = (ce * weight).sum() / weight.sum().clamp(min=1e-12) + opts.kl_anchor * kl.mean()
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), 0.5)
            optimizer.step()
            losses.append(float(loss.detach()))
            kls.append(float(kl.detach().mean()))
            agree = (logp.argmax(-1) == target.argmax(-1))[kept]
            hits.append(float(agree.float().mean()) if len(agree) else math.nan)
    net.eval()
    agreement = float(np.nanmean(hits)) if np.isfinite(hits).any() else math.nan  # nan: no state kept a target
    return {"fit_loss": float(np.mean(losses)), "fit_agreement": agreement, "fit_kl": float(np.mean(kls))}


def fine_tune(policy: GreedyPolicy, source: Checkpoint, opts: ExItOptions, folder: Path, r: int) -> dict[str, float]:
    """``opts.ppo_after`` agent-steps of the trainer's PPO on ``policy``'s network, in place, with the KL term toward
    ``policy`` as it came from the fit (the trainer's ``--kl-to-init``, from ``folder/fit<r>.pt``). The envs draw the
    family's random training episodes (:func:`ppo_world`) at the start's thresholds; the observation statistics stay
    frozen, since the aggregated labels were normalised with them. Returns PPO's cost and last iteration's figures."""
    fitted = folder / f"fit{r}.pt"
    save_policy(fitted, source, policy, opts, {})
    args = ppo_args(source, fitted, opts, r)
    cpu, wall = time.process_time(), time.time()
    run = make_run(args, ppo_world(opts), Ranks(), torch.device("cpu"))
    try:
        learner = make_learner(run)
        trainer_start(run, learner, None)
        run.obs_stats_frozen = True
        sums, infos = np.zeros(4), list[PPOLossInfo]()
        for iteration in range(run.num_iterations):
            _, rollout, _, _, infos = ppo_iteration(run, learner, iteration)
            episodes = rollout.episodes
            sums += (episodes.count, episodes.episode_return, episodes.distance_m, episodes.service_rate)
    finally:
        run.venv.close()
    policy.net.load_state_dict(learner.net.state_dict())
    policy.net.eval()
    return {
        "ppo_agent_steps": float(run.num_iterations * run.batch_size), "ppo_cpu_s": time.process_time() - cpu,
        "ppo_wall_s": time.time() - wall, "ppo_episodes": float(sums[0]),
        "ppo_return": float(sums[1] / max(sums[0], 1)), "ppo_distance_m": float(sums[2] / max(sums[0], 1)),
        "ppo_service_rate": float(sums[3] / max(sums[0], 1)),
        "ppo_kl_to_fit": float(np.mean([i.kl_to_init for i in infos])),
        "ppo_approx_kl": float(np.mean([i.approx_kl for i in infos])),
    }  # fmt: skip


def ppo_scenario(family: str) -> str:
    """The training scenario of ``family``'s PPO: its random episodes (``berlin`` -> ``berlin_instances``)."""
    return f"{family}_instances"


def ppo_world(opts: ExItOptions) -> EnvConfig:
    """The world PPO trains in: the family's training scenario with the hover action, a hover step rewarded
    ``opts.ppo_hover_reward`` (on top of every step's time cost)."""
    cfg = make_config(ppo_scenario(opts.family), hover_action=True)
    return cfg.replace(reward=dataclasses.replace(cfg.reward, hover=opts.ppo_hover_reward))


def ppo_args(source: Checkpoint, fitted: Path, opts: ExItOptions, r: int) -> TrainArgs:
    """The trainer's options for round ``r``'s PPO: the start's own (discount, clipping, epochs, minibatches, reward
    normalisation), from ``fitted`` with the KL term toward it, at the family's thresholds, on ``opts``' budget."""
    saved = TrainArgs.from_saved(source.args)
    return with_init_architecture(saved.with_options(
        scenario=ppo_scenario(opts.family), map=None, sinr_min_db=None, thresholds=FAMILIES[opts.family].thresholds_db,
        init_from=str(fitted), kl_to_init=opts.ppo_kl, total_timesteps=opts.ppo_after,
        learning_rate=opts.ppo_learning_rate, anneal_lr=True, num_envs=opts.ppo_envs, num_steps=opts.ppo_steps,
        seed=opts.seed + r, threads=opts.threads, device="cpu", env_workers=0, vector_backend="auto",
        run_dir=fitted.parent, run_name=f"ppo{r}", resume=False, overwrite=False, tensorboard=False, progress=False,
    ))  # fmt: skip


def validation_flights(policy: GreedyPolicy | Any, family: str, seeds: list[int], hover: bool) -> np.ndarray:
    """[n, 3]: (passengers delivered %, distance flown m, average wait s) of ``policy`` on each instance of
    ``seeds``, one recorded episode each in the instance's world (with the hover action when ``hover``)."""
    out = np.zeros((len(seeds), 3))
    for i, seed in enumerate(seeds):
        cfg = instance_world(family, seed, hover)
        m = episode_metrics(fly(cfg, policy), cfg.radio, threshold_db=cfg.sinr_min_db)
        out[i] = (m.pr_pct, m.td_m, m.awt_s)
    return out


def instance_world(family: str, seed: int, hover: bool) -> EnvConfig:
    """Instance ``seed`` of ``family``, with the hover action when ``hover`` (as ``uamfleet bench --hover-action``)."""
    cfg = make_instance(family, seed)
    return cfg.replace(hover_action=True) if hover else cfg


def paired(a: np.ndarray, b: np.ndarray) -> tuple[float, float]:
    """Mean of a − b and the half-width of its 95 % interval (normal approximation)."""
    d = np.asarray(a, float) - np.asarray(b, float)
    half = 1.96 * d.std(ddof=1) / math.sqrt(len(d)) if len(d) > 1 else math.nan
    return float(d.mean()), float(half)


def expert_iteration(opts: ExItOptions) -> dict[str, float]:
    """Run expert iteration (module docstring); writes ``start.pt``, ``best.pt`` (the last accepted network),
    ``progress.csv`` (a row per round: labelling cost, fit, validation paired against the round's start and against
    ``replan``) and the labels of each round under ``labels/<round>/`` in the run folder. Returns the last row."""
    with claim_run(opts.run_dir, opts.run_name, overwrite=opts.overwrite, resumable=False) as claim:
        claim.clear()
        return _iterate(opts, claim.folder)


def _iterate(opts: ExItOptions, folder: Path) -> dict[str, float]:
    torch.set_num_threads(opts.threads)
    torch.manual_seed(opts.seed)
    rng = np.random.default_rng(opts.seed)
    source, policy = start_policy(opts)
    val_seeds = [int(s) for s in split_seeds("validation", opts.val_instances, opts.val_first)]
    started = time.time()
    reference = validation_flights(_replan(), opts.family, val_seeds, opts.hover)
    current = validation_flights(policy, opts.family, val_seeds, opts.hover)
    save_policy(folder / "start.pt", source, policy, opts, {})
    save_policy(folder / "best.pt", source, policy, opts, {})
    rows: list[dict[str, float]] = [_row(-1, current, current, reference, started, accepted=True)]
    _report(folder, rows)
    data: LabelSet | None = None
    rejected = 0
    for r in range(opts.rounds):
        seeds = [int(s) for s in split_seeds("train", opts.label_instances, opts.label_instances * r)]
        cost = label_instances(
            folder / "best.pt", opts.family, seeds, opts.demand, opts.label_options(), opts.workers,
            folder / "labels" / str(r),
        )  # fmt: skip
        new = label_set(policy, load_labels(folder / "labels" / str(r), seeds), opts)
        data = new.tail(opts.max_samples) if data is None else data.extended(new, opts.max_samples)
        candidate = copy.deepcopy(policy)
        stats = fit(candidate, policy, data, opts, rng)
        if opts.ppo_after:
            stats |= fine_tune(candidate, source, opts, folder / "ppo", r)
        flights = validation_flights(candidate, opts.family, val_seeds, opts.hover)
        delta, _ = paired(flights[:, 1], current[:, 1])
        accepted = delta < 0 and flights[:, 0].mean() >= current[:, 0].mean()
        row = {**_row(r, flights, current, reference, started, accepted), **_cost_columns(cost), **stats,
               "samples": float(len(data)), "new_samples": float(len(new))}  # fmt: skip
        rows.append(row)
        print(", ".join(f"{k}={v:.4g}" for k, v in row.items()), flush=True)
        if accepted:
            policy, current, rejected = candidate, flights, 0
            save_policy(folder / f"round{r}.pt", source, policy, opts, row)
            save_policy(folder / "best.pt", source, policy, opts, row)
        else:
            rejected += 1
        _report(folder, rows)
        if rejected >= opts.patience:
            break
    return rows[-1]


def _row(
    r: int, flights: np.ndarray, start: np.ndarray, reference: np.ndarray, started: float, accepted: bool
) -> dict[str, float]:
    """A progress row: validation PR, TD and AWT, TD paired against the round's start and against ``replan``."""
    vs_start, vs_start_ci = paired(flights[:, 1], start[:, 1])
    vs_replan, vs_replan_ci = paired(flights[:, 1], reference[:, 1])
    return {
        "round": float(r), "wall_s": time.time() - started, "val_pr_pct": float(flights[:, 0].mean()),
        "val_td_m": float(flights[:, 1].mean()), "vs_start_m": vs_start, "vs_start_ci_m": vs_start_ci,
        "vs_replan_m": vs_replan, "vs_replan_ci_m": vs_replan_ci, "replan_td_m": float(reference[:, 1].mean()),
        "accepted": float(accepted), "val_awt_s": float(np.nanmean(flights[:, 2])),
        "replan_awt_s": float(np.nanmean(reference[:, 2])),
    }  # fmt: skip


def _report(folder: Path, rows: list[dict[str, float]]) -> None:
    write_csv_atomic(folder / "progress.csv", rows, list(dict.fromkeys(k for r in rows for k in r)))


def _replan() -> Any:
    from uamfleet.policies import make

    return make("replan")


def start_policy(opts: ExItOptions) -> tuple[Checkpoint, GreedyPolicy]:
    """The start's checkpoint and its policy, able to hover at any step with ``opts.hover``."""
    path = pretrained_path(opts.init) if opts.init in PRETRAINED else Path(opts.init)
    policy = load_policy(path)[0]
    return Checkpoint.load(path), with_hover_anytime(policy) if opts.hover else policy


def save_policy(path: Path, source: Checkpoint, policy: GreedyPolicy, opts: ExItOptions, row: dict[str, float]) -> None:
    """``policy`` in ``source``'s checkpoint (:func:`~uamfleet.rl.hover.hover_checkpoint`: loadable with
    ``load_policy``, ``torch.load(weights_only=True)``), with the run's options and its validation row."""
    ckpt = hover_checkpoint(source, policy)
    options = {
        f.name: (str(v) if isinstance(v := getattr(opts, f.name), Path) else v) for f in dataclasses.fields(opts)
    }
    dataclasses.replace(
        ckpt, args={**source.args, "exit": options}, best_eval={k: float(v) for k, v in row.items()}
    ).save(path)


def label_set(policy: GreedyPolicy, labels: Labels, opts: ExItOptions) -> LabelSet:
    """``labels`` as ``policy``'s network reads them: its fields normalised (one row per labelled state)."""
    policy.fit(instance_world(opts.family, int(labels.seed[0]), opts.hover).world)
    rows = policy.network_input(labels.obs)  # obs fields [N, 1, ...]: N envs of one taxi
    return LabelSet(rows, labels.target.astype(np.float32), labels.weight.astype(np.float32))


def _cost_columns(cost: Any) -> dict[str, float]:
    return {
        "label_instances": float(cost.instances), "hedge_labels": float(cost.hedge_labels),
        "finish_labels": float(cost.finish_labels), "searches": float(cost.searches), "solves": float(cost.solves),
        "label_cpu_s": cost.cpu_s, "label_wall_s": cost.wall_s, "labels_per_cpu_s": cost.labels_per_cpu_s,
    }  # fmt: skip
