"""The search warm start of a PPO run from scratch (``--warm-start-rounds``): a few seconds of DAgger from
``replan``'s step-level search (:class:`~uamfleet.rl.experts.ReplanExpert`) on the run's own world, before PPO.

The network starts from random weights, as every run from scratch does; no pretrained policy is read. Round 0 flies
the expert's own headings (``beta`` = 1), round ``r`` each env's heading is the expert's with probability
``0.5 ** r``, else the network's greedy one, so the later rounds label the states the network itself reaches
(Ross et al. 2011). After each round the actor is fitted to every label so far (cross-entropy on the masked
logits, a separate Adam: PPO's optimiser starts afresh). The observation statistics are updated with the raw
observations as PPO's collector updates them, the labels are fitted on the statistics as they stand after the
last round, and those statistics are then frozen for the rest of the run (:attr:`Run.obs_stats_frozen`). The
critic is fitted last, on a few of PPO's own rollouts of the warm-started policy (:func:`_fit_critic`).

PPO then trains from the warm-started network, and with ``--kl-to-init`` it is the reference of that term (saved
as ``warm_start.pt`` in the run folder, so a resumed run finds it again).
"""

from __future__ import annotations

import copy
import io
import time
from dataclasses import dataclass, field

import numpy as np
import torch
import torch.nn.functional as F

from uamfleet.config import ConfigError
from uamfleet.env.vector_env import VectorEnv
from uamfleet.io import write_bytes_atomic
from uamfleet.rl.collector import Run, collect_rollout, normalise
from uamfleet.rl.experts import NO_LABEL, ReplanExpert, released_count
from uamfleet.rl.learner import Learner, compute_advantages
from uamfleet.rl.networks import MSHAActorCritic, obs_to_torch

WARM_START_ENVS = 8
"""envs of the warm start (on a fixed instance such as Berlin P4 they differ only where the mixture differs)"""
STEPS_PER_ROUND = 64
EXPERT_BEAM = 16
"""beam of the expert's search (0.04 s a solve on Berlin P4)"""
FIT_EPOCHS = 30
FIT_MINIBATCH = 256
FIT_LEARNING_RATE = 1e-3
BETA_DECAY = 0.5
CRITIC_ROLLOUTS = 3
"""rollouts of the run's envs, as PPO samples them, whose returns the critic is fitted to before PPO starts"""
REFERENCE_FILE = "warm_start.pt"


@dataclass
class Labels:
    """The aggregated labelled states: raw observation rows, as the env gives them, and the expert's headings."""

    obs: list[dict[str, np.ndarray]] = field(default_factory=list)
    headings: list[np.ndarray] = field(default_factory=list)

    def __len__(self) -> int:
        return int(sum(len(h) for h in self.headings))


def warm_started(run: Run, learner: Learner, resumed: bool) -> dict[str, float]:
    """The run's warm start: on a fresh run :func:`search_warm_start` and, with ``--kl-to-init``, its network saved
    as the run's :data:`REFERENCE_FILE`; on a resumed run that file read back as the KL term's reference (the
    network itself comes from last.pt). The warm start's statistics (none when resumed)."""
    path = run.folder / REFERENCE_FILE
    if resumed:
        run.obs_stats_frozen = True  # last.pt holds the statistics the warm start fitted on
        if run.args.net.kl_to_init > 0:
            reference = copy.deepcopy(learner.net)
            reference.load_state_dict(torch.load(path, map_location=run.device, weights_only=True))
            learner.reference = reference.eval().requires_grad_(False)
        return {}
    stats = search_warm_start(run, learner, run.args.net.warm_start_rounds)
    if learner.reference is not None:
        buffer = io.BytesIO()
        torch.save(learner.reference.state_dict(), buffer)
        write_bytes_atomic(path, buffer.getvalue())
    return stats


def search_warm_start(run: Run, learner: Learner, rounds: int) -> dict[str, float]:
    """``rounds`` rounds of DAgger from ``replan``'s search on ``run``'s world into ``learner.net`` (module
    docstring); with ``--kl-to-init`` the result becomes ``learner.reference``. Returns the warm start's
    statistics (``warm/*``: labels, solves, seconds of search and in all, the fit's last loss and agreement)."""
    if run.cfg.num_taxis != 1 or run.ranks.active or run.venv.mixed_sizes:
        raise ConfigError(
            f"--warm-start-rounds={rounds} labels one taxi per env in one process; this run has "
            f"{run.cfg.num_taxis} taxi(s) per env{' under torchrun' if run.ranks.active else ''}: drop "
            "--warm-start-rounds (or train a lone taxi in one process)."
        )
    began = time.time()
    rng = np.random.default_rng(run.args.ppo.seed)
    envs = VectorEnv(run.cfg, WARM_START_ENVS, observer=run.spec)
    expert = ReplanExpert(run.cfg, WARM_START_ENVS, EXPERT_BEAM)
    obs, _ = envs.reset(seed=run.args.ppo.seed + 1_000_000)  # other seeds than the training envs'
    optimizer = torch.optim.Adam(_actor_parameters(learner.net), lr=FIT_LEARNING_RATE)
    labels, fitted = Labels(), {"loss": float("nan"), "agreement": float("nan")}
    for r in range(rounds):
        obs = _collect(run, learner, envs, expert, obs, BETA_DECAY**r, labels, rng)
        fitted = _fit(run, learner, labels, optimizer, rng)
    # PPO's rollouts sample the policy and reach states the expert's flights never did: folded into the observation
    # statistics they moved the fitted network's inputs enough that it delivered nobody after one rollout (Berlin
    # P4, seed 12). So the run keeps the statistics the labels were fitted on.
    run.obs_stats_frozen = True
    critic_loss = _fit_critic(run, learner, rng)
    if run.args.net.kl_to_init > 0:
        learner.reference = copy.deepcopy(learner.net).eval().requires_grad_(False)
    return {
        "warm/labels": float(len(labels)), "warm/solves": float(expert.solves), "warm/solve_s": expert.solve_s,
        "warm/wall_s": time.time() - began, "warm/bc_loss": fitted["loss"], "warm/bc_agreement": fitted["agreement"],
        "warm/value_loss": critic_loss,
    }  # fmt: skip


def _fit_critic(run: Run, learner: Learner, rng: np.random.Generator) -> float:
    """:data:`CRITIC_ROLLOUTS` of PPO's own rollouts of the warm-started policy (its reward scaler updated as PPO
    updates it), the critic regressed on each one's GAE returns (PPO's value targets) and the actor left as it is:
    with the critic still random, the first PPO update (learning rate 1e-3) moved the policy 2.1 nats and it
    delivered nobody after (Berlin P4, seed 11). The last pass's mean squared error."""
    critic = [p for name, p in learner.net.named_parameters() if name.startswith("critic.")]
    optimizer = torch.optim.Adam(critic, lr=run.args.ppo.learning_rate)
    buf, loss_value = run.buffer, float("nan")
    for _ in range(CRITIC_ROLLOUTS):
        collect_rollout(run, learner.net, learner.normalizer, learner.scaler)
        _, returns = compute_advantages(run, learner)
        obs = {k: v.reshape(-1, *v.shape[2:]) for k, v in buf.obs.items()}  # [T * N, ...]
        target = torch.as_tensor(returns.reshape(-1), dtype=torch.float32, device=run.device)
        n = len(target)
        for _ in range(run.args.ppo.update_epochs):
            losses = []
            for idx in np.array_split(rng.permutation(n), run.args.ppo.num_minibatches):
                _, value = learner.net(obs_to_torch({k: v[idx] for k, v in obs.items()}, run.device))
                loss = F.mse_loss(value, target[idx])
                optimizer.zero_grad(set_to_none=True)
                loss.backward()
                torch.nn.utils.clip_grad_norm_(critic, run.args.ppo.max_grad_norm)
                optimizer.step()
                losses.append(float(loss.detach()))
            loss_value = float(np.mean(losses))
    return loss_value


def _actor_parameters(net: MSHAActorCritic) -> list[torch.nn.Parameter]:
    """What the labels fit: every parameter but the critic's (a heading label says nothing of the value)."""
    return [p for name, p in net.named_parameters() if not name.startswith("critic.")]


def _collect(
    run: Run, learner: Learner, envs: VectorEnv, expert: ReplanExpert, obs: dict[str, np.ndarray], beta: float,
    labels: Labels, rng: np.random.Generator,
) -> dict[str, np.ndarray]:  # fmt: skip
    """One round: :data:`STEPS_PER_ROUND` steps of ``envs`` under the mixture (the expert's heading with
    probability ``beta``, else the network's greedy one); the labelled states go to ``labels``. Returns the
    envs' observation after the round (the next round goes on from there)."""
    E = envs.num_envs
    released = released_count(envs)
    for _ in range(STEPS_PER_ROUND):
        raw = {k: v.reshape(E, *v.shape[2:]) for k, v in obs.items()}  # one taxi per env
        normalised = normalise(run, learner.normalizer, raw, update=True)  # as PPO's collector does
        with torch.inference_mode():
            own = learner.net.masked_logits(obs_to_torch(normalised, run.device)).argmax(-1).cpu().numpy()
        expert_headings = expert.labels(envs)  # no challenge of ties: a random network's proposal costs a solve a step
        labelled = expert_headings != NO_LABEL
        # a heading the mask forbids leaves the taxi in place (a wait for a release): flown, never fitted
        fitted = labelled & envs.state.action_mask[np.arange(E), 0, np.where(labelled, expert_headings, 0)]
        if fitted.any():
            labels.obs.append({k: v[fitted].copy() for k, v in raw.items()})
            labels.headings.append(expert_headings[fitted])
        executed = np.where(labelled & (rng.random(E) < beta), expert_headings, own)
        obs, _, terminated, truncated, _ = envs.step(executed[:, None])
        ended = terminated | truncated
        now = released_count(envs)
        expert.advance(executed, (now != released) & ~ended, ended)
        released = now
    return obs


def _fit(
    run: Run, learner: Learner, labels: Labels, optimizer: torch.optim.Optimizer, rng: np.random.Generator
) -> dict[str, float]:
    """:data:`FIT_EPOCHS` passes of cross-entropy between the masked logits and every label so far, on the
    observation statistics as they stand; the last epoch's mean loss and agreement with the labels."""
    if not len(labels):
        return {"loss": float("nan"), "agreement": float("nan")}
    raw = {k: np.concatenate([o[k] for o in labels.obs]) for k in labels.obs[0]}
    obs = normalise(run, learner.normalizer, raw, update=False)
    headings = np.concatenate(labels.headings)
    net, n = learner.net, len(headings)
    net.train()
    losses: list[float] = []
    hits: list[float] = []
    for _ in range(FIT_EPOCHS):
        losses, hits = [], []
        order = rng.permutation(n)
        for begin in range(0, n, FIT_MINIBATCH):
            idx = order[begin : begin + FIT_MINIBATCH]
            logits = net.masked_logits(obs_to_torch({k: v[idx] for k, v in obs.items()}, run.device))
            target = torch.as_tensor(headings[idx], device=run.device)
            loss = F.cross_entropy(logits, target)
            optimizer.zero_grad(set_to_none=True)
            loss.backward()
            torch.nn.utils.clip_grad_norm_(_actor_parameters(net), run.args.ppo.max_grad_norm)
            optimizer.step()
            losses.append(float(loss.detach()))
            hits.append(float((logits.argmax(-1) == target).float().mean()))
    return {"loss": float(np.mean(losses)), "agreement": float(np.mean(hits))}


__all__ = ["REFERENCE_FILE", "search_warm_start", "warm_started"]
