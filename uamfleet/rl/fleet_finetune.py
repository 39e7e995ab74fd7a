"""Fine-tune a claims fleet policy with the return: PPO-style policy gradient on the issue's own measures.

A policy trained by DAgger (:mod:`uamfleet.rl.fleet_imitation`) with the dispatcher's claims as inputs
(:mod:`uamfleet.rl.fleet_claims`) copies the dispatcher's plan; imitation gives it no reason to depart from the plan
where the plan is wrong. Here the same network (one set of weights for every taxi and fleet size) is trained on the
return, the dispatcher still running alongside every step and its claims still inputs:

- **Cost.** Per env-step the fleet pays the distance its taxis flew in that step (m) plus :attr:`~FleetFinetuneArgs.
  wait_weight` (λ, m per passenger-second) times the seconds passengers wait during it (released and not picked up
  in the state the step starts from, times the slot): summed over an episode, the fleet's distance flown plus λ times
  the sum of every passenger's wait, the measures of issue 42 (TD per delivered passenger, waits). A passenger not
  delivered when the episode ends costs :attr:`~FleetFinetuneArgs.undelivered_m` more. The env's own reward terms
  (step, pick-up, drop-off, exploration) are not used: they are not the measures. Every taxi shares the fleet's
  reward, ``-cost / COST_SCALE``.
- **Baseline.** Each training episode is flown :attr:`~FleetFinetuneArgs.samples_per_episode` times (K ≥ 2, the same
  instance, actions sampled independently); a sample's advantage at step t is its discounted cost-to-go from t
  minus the mean of the other samples' at t (a leave-one-out baseline: independent of the sample's own actions, so
  the gradient stays unbiased). No critic.
- **Update.** CleanRL's clipped surrogate (:func:`uamfleet.rl.ppo.ppo_loss`, no value loss) over the taxi-steps of the
  iteration, plus :attr:`~FleetFinetuneArgs.kl_anchor` times the KL divergence from the start policy
  (:func:`uamfleet.rl.ppo.categorical_kl`), so that it cannot drift far from the plan it copies.
- **Acting.** While training, each taxi's action is sampled from the network's masked distribution (no loop guard);
  the saved checkpoints fly greedily through the loop guard as ``fleet_claims:source=<file>``.

Checkpoints are chosen on validation episodes afterwards (``uamfleet fleet-bench --split validation``), never here.
"""

from __future__ import annotations

import copy
import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import torch

from uamfleet.checks import ConfigError, check_integer, check_number
from uamfleet.config import EnvConfig
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import FAMILIES
from uamfleet.io import write_csv_atomic
from uamfleet.rl.checkpoint import Checkpoint, checkpoint_source
from uamfleet.rl.fleet_claims import with_claims
from uamfleet.rl.fleet_imitation import (
    MIXTURE, TEACHER, FleetImitationArgs, check_mixture, fleet_policy, make_teacher, padded_rows,
    save_fleet_checkpoint, teacher_claims, training_episodes,
)  # fmt: skip
from uamfleet.rl.networks import MSHAActorCritic, obs_to_torch
from uamfleet.rl.policy import GreedyPolicy
from uamfleet.rl.ppo import categorical_kl, ppo_loss
from uamfleet.rl.runs import RunClaim, check_run_name, claim_run
from uamfleet.rollout import observer_of
from uamfleet.types import DELIVERED, WAITING

COST_SCALE = 100.0
"""Metres per unit of reward (one taxi's step): reward = -cost / COST_SCALE."""


@dataclass(frozen=True)
class FleetFinetuneArgs:
    """Policy-gradient fine-tuning of a claims fleet policy (every option is a flag of ``uamfleet fleet-finetune``)."""

    init: str = "reports/2026-12-04-fleet-claims/claims_r3.pt"
    """the policy to start from: a checkpoint file (or shipped name); one without claims inputs is converted at zero"""
    teacher: str = TEACHER
    """the schedule dispatcher that runs alongside and whose claims the network reads"""
    family: str = "berlin"
    """instance family of the training episodes (its training seeds; uamfleet.instances.FAMILIES)"""
    mixture: tuple[str, ...] = MIXTURE
    """fleet settings of the training episodes (<taxis>x<requests>), ``episodes_per_setting`` of each per iteration"""
    also_family: str | None = None
    """a second instance family whose training episodes join every iteration (e.g. detroit3gpp), ``also_mixture``"""
    also_mixture: tuple[str, ...] = ("2x12", "4x24")
    """fleet settings of ``also_family``'s episodes (Detroit's validation setting is 4x24)"""
    passenger_window: int = 24
    iterations: int = 10
    episodes_per_setting: int = 1
    """episodes (instances) of each mixture setting per iteration, fresh training seeds every iteration"""
    samples_per_episode: int = 2
    """K: times each instance is flown with sampled actions; each sample's baseline is the others' mean"""
    wait_weight: float = 20.0
    """λ: metres of cost per passenger-second of wait (a mean wait of 74 s then weighs ~1,500 m against ~2,100 m
    flown per passenger at Berlin 4x48)"""
    undelivered_m: float = 5000.0
    """cost per passenger not delivered when the episode ends (m)"""
    gamma: float = 0.99
    """discount per step of the cost-to-go (3 s steps: a horizon of about 100 steps)"""
    temperature: float = 2.0
    """T: actions are sampled from, and the loss reads, softmax(logits / T); the greedy flight of a checkpoint is the
    same for every T (argmax), while T > 1 lets sampled episodes differ where DAgger left the logits far apart"""
    clip_coef: float = 0.2
    kl_anchor: float = 0.1
    """weight of KL(policy || start policy) on the iteration's taxi-steps"""
    ent_coef: float = 0.0
    epochs: int = 2
    minibatch: int = 512
    learning_rate: float = 3e-5
    """Adam's step size (0 leaves the weights as they are: a check)"""
    max_grad_norm: float = 0.5
    seed: int = 0
    run_dir: Path = Path("runs")
    run_name: str = "fleet_finetune"
    overwrite: bool = False
    threads: int = 1
    max_wall_s: float | None = None
    """stop starting iterations after this many seconds"""

    def __post_init__(self) -> None:
        for name in ("passenger_window", "iterations", "episodes_per_setting", "epochs", "minibatch", "threads"):
            check_integer(f"--{name.replace('_', '-')}", getattr(self, name), 1)
        if check_integer("--samples-per-episode", self.samples_per_episode, 1) < 2:
            raise ConfigError(
                f"--samples-per-episode={self.samples_per_episode}: the baseline is the other samples' mean; use 2 or "
                "more."
            )
        for name in ("learning_rate", "wait_weight", "undelivered_m", "kl_anchor", "ent_coef"):
            check_number(f"--{name.replace('_', '-')}", getattr(self, name), minimum=0.0)
        check_number("--max-grad-norm", self.max_grad_norm, positive=True)
        check_number("--temperature", self.temperature, positive=True)
        for name in ("gamma", "clip_coef"):
            value = check_number(f"--{name.replace('_', '-')}", getattr(self, name), positive=True)
            if value > 1:
                raise ConfigError(f"--{name.replace('_', '-')}={value} is above 1: use a value in (0, 1].")
        check_mixture(self.mixture, self.also_mixture)
        for name, family in (("--family", self.family), ("--also-family", self.also_family)):
            if family is not None and family not in FAMILIES:
                raise ConfigError(f"{name}={family!r} is unknown; use one of {sorted(FAMILIES)}.")
        if self.also_family is not None and not self.also_mixture:
            raise ConfigError(
                f"--also-family={self.also_family!r} with an empty --also-mixture: give settings, e.g. 4x24."
            )
        check_run_name(self.run_name, self.run_dir)

    def episode_args(self) -> FleetImitationArgs:
        """The DAgger options whose :func:`~uamfleet.rl.fleet_imitation.training_episodes` draw this run's episodes
        of ``family`` (the same training seeds for the same seed, iteration and mixture)."""
        return FleetImitationArgs(
            init=self.init, teacher=self.teacher, family=self.family, mixture=self.mixture,
            episodes_per_setting=self.episodes_per_setting, seed=self.seed, run_dir=self.run_dir,
            run_name=self.run_name,
        )  # fmt: skip

    def episodes(self, iteration: int) -> list[EnvConfig]:
        """Iteration ``iteration``'s training instances: ``family``'s mixture, then ``also_family``'s."""
        out = training_episodes(self.episode_args(), iteration)
        if self.also_family is not None:
            also = dataclasses.replace(self.episode_args(), family=self.also_family, mixture=self.also_mixture)
            out += training_episodes(also, iteration)
        return out


@dataclass
class Episode:
    """One sampled episode: every taxi-step's network rows, action and the fleet's cost at each step."""

    obs: dict[str, np.ndarray]  # padded rows, [T * A, ...]
    actions: np.ndarray  # [T * A]
    step: np.ndarray  # [T * A] the step of each taxi-step
    costs: np.ndarray  # [T] the fleet's cost of each step (m)
    distance_m: float
    wait_s: float
    delivered: int
    num_requests: int


def step_cost(env: VectorEnv, distance_before: float, waiting_before: int, wait_weight: float) -> float:
    """The fleet's cost of the step just flown in env 0 (module docstring): the distance its taxis flew in it plus
    ``wait_weight`` times the passenger-seconds of wait in it (``waiting_before`` passengers waited in the state it
    started from, each for one slot)."""
    return float(env.state.distance_m[0].sum() - distance_before) + wait_weight * waiting_before * env.cfg.slot_s


def waiting_now(env: VectorEnv) -> int:
    """Passengers of env 0 released and not picked up now."""
    s = env.state
    return int(np.count_nonzero((s.pax_status[0] == WAITING) & s.pax_exists[0]))


def sample_episode(
    cfg: EnvConfig, policy: GreedyPolicy, teacher_name: str, args: FleetFinetuneArgs, generator: torch.Generator
) -> Episode:
    """Fly one episode of ``cfg`` with each taxi's action sampled from the policy's masked distribution, a fresh
    ``teacher_name`` dispatcher watching every step and supplying its claims (as ``fleet_claims`` flies)."""
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy))
    obs, _ = env.reset(seed=0)
    teacher = make_teacher(teacher_name, cfg.num_taxis)
    policy.reset(env.sim)
    teacher.reset(env.sim)
    parts: list[dict[str, np.ndarray]] = []
    actions: list[np.ndarray] = []
    steps: list[np.ndarray] = []
    costs: list[float] = []
    wait_s = 0.0
    while True:
        teacher.act(obs)  # its schedules advance by this step, as when it flies
        inputs = with_claims(policy.network_input(obs), teacher_claims(env, teacher))
        logits = policy.logits_of(inputs) / args.temperature  # [A, 16 or 17], masked
        action = torch.multinomial(torch.softmax(logits.double(), -1), 1, generator=generator)[:, 0]
        action_np = action.numpy().astype(np.int64)
        parts.append(padded_rows(policy, inputs))
        actions.append(action_np)
        steps.append(np.full(len(action_np), len(costs)))
        distance, waiting = float(env.state.distance_m[0].sum()), waiting_now(env)
        obs, _, terminated, truncated, _ = env.step(action_np[None])
        costs.append(step_cost(env, distance, waiting, args.wait_weight))
        wait_s += waiting * cfg.slot_s
        if terminated[0] or truncated[0]:
            break
    s = env.state
    delivered = int(np.count_nonzero((s.pax_status[0] == DELIVERED) & s.pax_exists[0]))
    num_requests = int(np.count_nonzero(s.pax_exists[0]))
    costs[-1] += args.undelivered_m * (num_requests - delivered)
    return Episode(
        {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}, np.concatenate(actions), np.concatenate(steps),
        np.asarray(costs), float(s.distance_m[0].sum()), wait_s, delivered, num_requests,
    )  # fmt: skip


def cost_to_go(costs: np.ndarray, gamma: float, length: int) -> np.ndarray:
    """[length] discounted cost-to-go of each step (zero past the episode's end)."""
    out = np.zeros(length)
    running = 0.0
    for t in range(len(costs) - 1, -1, -1):
        running = costs[t] + gamma * running
        out[t] = running
    return out


def advantages(episodes: list[Episode], gamma: float) -> list[np.ndarray]:
    """Per sample of one instance, [T_k] the advantage of each step in reward units: minus (its cost-to-go minus the
    mean of the other samples' cost-to-go at the same step) / :data:`COST_SCALE`."""
    length = max(len(e.costs) for e in episodes)
    togo = np.stack([cost_to_go(e.costs, gamma, length) for e in episodes])  # [K, L]
    K = len(episodes)
    others = (togo.sum(0, keepdims=True) - togo) / (K - 1)
    return [-(togo[k, : len(e.costs)] - others[k, : len(e.costs)]) / COST_SCALE for k, e in enumerate(episodes)]


def tempered(net: MSHAActorCritic, rows: dict[str, np.ndarray], temperature: float) -> torch.Tensor:
    """[B, 16 or 17] the masked logits of padded rows ``rows`` divided by ``temperature`` (masked ones stay far
    below the rest: NOT_THIS / T)."""
    return net.masked_logits(obs_to_torch(rows, "cpu")) / temperature


def update(
    policy: GreedyPolicy, reference: MSHAActorCritic, optimizer: torch.optim.Optimizer, batch: dict[str, Any],
    args: FleetFinetuneArgs, rng: np.random.Generator,
) -> dict[str, float]:  # fmt: skip
    """``args.epochs`` passes of the clipped surrogate plus the KL anchor over the iteration's taxi-steps ``batch``
    (``obs``, ``actions``, ``advantages``); the last epoch's means."""
    net = policy.net
    obs, actions, adv = batch["obs"], torch.as_tensor(batch["actions"]), torch.as_tensor(batch["advantages"])
    n = len(actions)
    with torch.no_grad():  # the behaviour policy's log-probabilities, on the same rows as the update reads
        net.eval()
        old_logprob = torch.cat([
            torch.log_softmax(tempered(net, {k: v[i : i + 4096] for k, v in obs.items()}, args.temperature), -1)
            .gather(1, actions[i : i + 4096, None])[:, 0]
            for i in range(0, n, 4096)
        ])  # fmt: skip
    adv = (adv - adv.mean()) / (adv.std() + 1e-8)  # normalised once over the iteration
    zeros = torch.zeros(n)
    net.train()
    stats: list[dict[str, float]] = []
    for _ in range(args.epochs):
        order = rng.permutation(n)
        stats = []
        for start in range(0, n, args.minibatch):
            idx = order[start : start + args.minibatch]
            x = {k: v[idx] for k, v in obs.items()}
            logits = tempered(net, x, args.temperature)
            log_probs = torch.log_softmax(logits, -1)
            new_logprob = log_probs.gather(1, actions[idx, None])[:, 0]
            entropy = -(log_probs.exp() * log_probs).sum(-1)
            loss, info = ppo_loss(
                new_logprob, old_logprob[idx], entropy, zeros[idx], zeros[idx], adv[idx], zeros[idx],
                clip_coef=args.clip_coef, vf_coef=0.0, ent_coef=args.ent_coef, clip_vloss=False, norm_adv=False,
            )  # fmt: skip
            with torch.no_grad():
                ref_logits = tempered(reference, x, args.temperature)
            kl = categorical_kl(logits, ref_logits).mean()
            loss = loss + args.kl_anchor * kl
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(net.parameters(), args.max_grad_norm)
            optimizer.step()
            stats.append({"policy_loss": info.policy_loss, "entropy": info.entropy, "approx_kl": info.approx_kl,
                          "clipfrac": info.clipfrac, "kl_to_start": float(kl.detach())})  # fmt: skip
    net.eval()
    return {k: float(np.mean([s[k] for s in stats])) for k in stats[0]}


def fleet_finetune(args: FleetFinetuneArgs) -> list[dict[str, float]]:
    """Fine-tune (module docstring); writes ``iter<i>.pt`` after every iteration's update, ``last.pt`` and
    ``progress.csv`` in the run folder, and returns the progress rows."""
    with claim_run(args.run_dir, args.run_name, overwrite=args.overwrite, resumable=False) as claim:
        return _fleet_finetune(args, claim)


def _fleet_finetune(args: FleetFinetuneArgs, claim: RunClaim) -> list[dict[str, float]]:
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    generator = torch.Generator().manual_seed(args.seed)
    start = time.time()
    initial = Checkpoint.load(checkpoint_source(args.init))
    policy = fleet_policy(args.init, args.passenger_window, dispatch_claims=True)  # one set of weights, any fleet
    policy.loop_guard = None  # sampled actions while training; the saved checkpoint flies with its guard
    reference = copy.deepcopy(policy.net).eval().requires_grad_(False)
    optimizer = torch.optim.Adam(policy.net.parameters(), lr=args.learning_rate, eps=1e-5)
    claim.clear()
    rows: list[dict[str, float]] = []
    for i in range(args.iterations):
        if args.max_wall_s is not None and time.time() - start > args.max_wall_s:
            break
        parts: list[dict[str, np.ndarray]] = []
        actions, advs = [], []
        totals: dict[str, float] = {"episodes": 0, "cost": 0.0, "distance_m": 0.0, "wait_s": 0.0, "delivered": 0,
                                    "requests": 0, "cost_per_request": 0.0}  # fmt: skip
        for cfg in args.episodes(i):
            samples = [
                sample_episode(cfg, policy, args.teacher, args, generator) for _ in range(args.samples_per_episode)
            ]
            for e, a in zip(samples, advantages(samples, args.gamma), strict=True):
                parts.append(e.obs)
                actions.append(e.actions)
                advs.append(a[e.step])
                totals["episodes"] += 1
                totals["cost"] += float(e.costs.sum())
                totals["distance_m"] += e.distance_m
                totals["wait_s"] += e.wait_s
                totals["delivered"] += e.delivered
                totals["requests"] += e.num_requests
                totals["cost_per_request"] += float(e.costs.sum()) / max(e.num_requests, 1)
        batch = {"obs": {k: np.concatenate([p[k] for p in parts]) for k in parts[0]},
                 "actions": np.concatenate(actions), "advantages": np.concatenate(advs).astype(np.float32)}  # fmt: skip
        n_episodes = totals["episodes"]
        collected = time.time() - start
        stats = update(policy, reference, optimizer, batch, args, rng)
        row = {
            "iteration": i, "episodes": n_episodes, "taxi_steps": sum(len(a) for a in actions),
            "mean_return": -totals["cost"] / n_episodes / COST_SCALE,
            "cost_per_request_m": totals["cost_per_request"] / n_episodes,
            "td_per_delivered_m": totals["distance_m"] / max(totals["delivered"], 1),
            "mean_wait_s": totals["wait_s"] / max(totals["requests"], 1),
            "undelivered": totals["requests"] - totals["delivered"], **stats,
            "collect_s": collected, "wall_s": time.time() - start,
        }  # fmt: skip
        rows.append(row)
        print(", ".join(f"{k}={v:.4g}" for k, v in row.items()), flush=True)
        for name in (f"iter{i}.pt", "last.pt"):
            save_fleet_checkpoint(claim.folder / name, initial, policy.net, args, row, key="fleet_finetune")
        write_csv_atomic(claim.folder / "progress.csv", rows, list(rows[0]))
    return rows


__all__ = [
    "COST_SCALE",
    "Episode",
    "FleetFinetuneArgs",
    "advantages",
    "cost_to_go",
    "fleet_finetune",
    "sample_episode",
    "step_cost",
    "tempered",
    "update",
    "waiting_now",
]
