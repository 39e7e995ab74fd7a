"""PPO with one shared MSHA policy over every taxi of every env: ``train(args) -> TrainResult``.

CleanRL's loop (``ppo.py``) made importable: rollouts from the batched core (N = E * A agents per step), GAE
that bootstraps truncated episodes from their real final observation, clipped surrogate and value losses,
entropy bonus, gradient clipping, advantage / observation / reward normalisation, a linear learning-rate
schedule and an optional centralised critic on the global state (MAPPO). Periodic greedy evaluation on a
separate env, CSV + TensorBoard logs with CleanRL's metric names, atomic checkpoints and ``resume``.
"""

from __future__ import annotations

import csv
import dataclasses
import io
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Literal

import numpy as np
import torch

from uamfleet.config import REWARD_TERMS, EnvConfig, make_config
from uamfleet.env.vector_env import VectorEnv
from uamfleet.io import write_bytes_atomic, write_text_atomic
from uamfleet.metrics import EpisodeMetrics, episode_metrics
from uamfleet.rl.buffer import ObservationNormalizer, RewardScaler, RolloutBuffer, compute_gae
from uamfleet.rl.networks import VARIANTS, MSHAActorCritic, NetConfig, obs_to_torch
from uamfleet.rl.ppo import ppo_loss
from uamfleet.rollout import fly


@dataclass
class TrainArgs:
    """PPO training of the shared MSHA policy (every option is a command-line flag of ``train/ppo.py``)."""

    # environment
    scenario: str = "berlin_p4"
    """scenario name (uamfleet.SCENARIOS)"""
    sinr_min_db: float | None = None
    """SINR threshold in dB (default: the scenario's)"""
    num_taxis: int | None = None
    """fleet size (default: the scenario's)"""
    feasibility: Literal["endpoint_block", "segment_raster"] = "endpoint_block"
    """move rule: endpoint block SINR (the paper) or every raster cell along the step"""
    time_limit_steps: int = 200
    """episode time limit while training (steps)"""
    shaping: float = 50.0
    """weight of the potential-based shaping term (0 = the authors' reward only). Strong on purpose: one step of
    progress along the feasible path is then worth 50, a quarter of a pick-up, so the heading that makes progress
    stands out of the value noise from the first iterations"""
    shaping_metric: Literal["path", "path_exact", "euclidean"] = "path"
    """distance in the shaping potential: along feasible paths, or straight line"""
    shaping_gamma: float | None = None
    """discount inside the shaping term gamma * Phi(s') - Phi(s) (default: the trainer's gamma, which keeps it
    potential-based; 1.0 removes the per-step bonus w (1 - gamma) |Phi| for staying away from the stop)"""
    shaping_anneal_frac: float = 0.5
    """decay the shaping weight linearly to 0 over the LAST this fraction of training (0: constant). Shaping is
    potential-based, so the optimum is unchanged: it helps find every passenger early, and annealing it leaves
    the end of training to the true reward (shorter tours)"""
    # network
    variant: Literal["le", "de", "de_msfea", "full"] = "de_msfea"
    """MSHA ablation variant: linear encoders / designed encoders / + multi-source features / + hybrid attention.
    Default de_msfea: on Berlin P4 it came within 5 % of the optimum in 40-140k agent-steps in 8 of 10 runs, at
    3x the full model's speed per step; the full model learned slower per step too (docs/results.md)"""
    d_model: int = 64
    """token / feature width of the network"""
    num_heads: int = 4
    """attention heads; half attend locally (windows), half globally"""
    local_window: int = 2
    """side of the local attention windows on the k x k patch (must divide k)"""
    readout: Literal["flatten", "mean"] = "flatten"
    """how the designed variants read the k x k grid: linear over the flattened cells (keeps positions) or mean"""
    centralised_critic: bool = False
    """critic reads the global env state (MAPPO)"""
    # PPO
    seed: int = 1
    """seed of torch, numpy and the envs (env e gets seed + e)"""
    total_timesteps: int = 200_000
    """agent-steps (env steps x taxis) to train for"""
    num_envs: int = 32
    """parallel envs of the batched core (agents per step = num_envs x taxis)"""
    num_steps: int = 64
    """rollout length per env and iteration"""
    num_minibatches: int = 16
    """minibatches per update epoch"""
    update_epochs: int = 4
    """passes over each rollout"""
    learning_rate: float = 1e-3
    """Adam learning rate"""
    anneal_lr: bool = True
    """decay the learning rate linearly to 0"""
    gamma: float = 0.9
    """discount factor (also the shaping term's unless shaping_gamma is set, so the shaping stays potential-based).
    0.9, not CleanRL's 0.99:
    with the path-distance potential every step's progress is paid at once, so a short horizon loses little
    and cuts the variance of the advantages; on Berlin P4 it took the LE variant from TD 8,900 m (gamma 0.95) to
    5,200-5,300 m in 150k agent-steps (docs/results.md). Raise it for sparse rewards (shaping 0)"""
    gae_lambda: float = 0.9
    """GAE lambda"""
    clip_coef: float = 0.2
    """PPO ratio clip (also the value clip)"""
    clip_vloss: bool = True
    """clip the value loss as PPO2"""
    ent_coef: float = 0.003
    """entropy bonus weight"""
    vf_coef: float = 0.5
    """value loss weight"""
    max_grad_norm: float = 0.5
    """global gradient-norm clip"""
    target_kl: float | None = None
    """stop an update early when the approximate KL exceeds this"""
    norm_adv: bool = True
    """normalise advantages per minibatch"""
    norm_obs: bool = True
    """normalise continuous observation fields with running statistics"""
    norm_reward: bool = True
    """scale rewards by the running std of the discounted return"""
    # evaluation, logging, checkpoints
    eval_every: int = 5
    """greedy evaluation every this many iterations (0: only at the end)"""
    eval_time_limit_steps: int | None = None
    """time limit of the greedy evaluation episodes (default: the training one; the observation's time
    features are fractions of the time limit, so a different one shifts them)"""
    checkpoint_every: int = 5
    """iterations between checkpoints"""
    stop_at_td_m: float | None = None
    """stop once a greedy evaluation delivers everyone with TD at or below this (measures time-to-target)"""
    max_wall_s: float | None = None
    """stop (after a final evaluation and checkpoint) once training has run this many seconds"""
    run_dir: Path = Path("runs")
    """folder of all runs"""
    run_name: str | None = None
    """default: {scenario}_{sinr}dB_{variant}_s{seed}"""
    resume: bool = False
    """continue from run_dir/run_name/last.pt"""
    device: Literal["auto", "cpu", "cuda"] = "auto"
    """torch device (auto: CUDA when available)"""
    threads: int = 0
    """torch CPU threads (0: torch's default)"""
    progress: bool = True
    """show a progress bar"""
    tensorboard: bool = True
    """write TensorBoard events to run_dir/name/tb"""

    @property
    def name(self) -> str:
        if self.run_name:
            return self.run_name
        sinr = "default" if self.sinr_min_db is None else f"{self.sinr_min_db:g}"
        return f"{self.scenario}_{sinr}dB_{self.variant}_s{self.seed}"

    def env_overrides(self, training: bool = True) -> dict[str, Any]:
        overrides: dict[str, Any] = {"feasibility": self.feasibility}
        if self.sinr_min_db is not None:
            overrides["sinr_min_db"] = self.sinr_min_db
        if self.num_taxis is not None:
            overrides["num_taxis"] = self.num_taxis
        limit = self.time_limit_steps if training or self.eval_time_limit_steps is None else self.eval_time_limit_steps
        overrides["time_limit_steps"] = limit
        return overrides


@dataclass
class TrainResult:
    run_dir: Path
    global_step: int
    iterations: int
    wall_s: float
    final_eval: dict[str, float]
    best_eval: dict[str, float]
    best_step: int
    target_reached_step: int | None = None
    target_reached_s: float | None = None
    losses: list[dict[str, float]] = field(default_factory=list)
    interrupted: bool = False


def make_env_config(scenario: str | EnvConfig, args: TrainArgs, training: bool = True) -> EnvConfig:
    """The env config a run trains (or evaluates) on: the scenario with the run's overrides and shaping.

    The shaping term uses the trainer's discount unless ``args.shaping_gamma`` is set, so by default it stays
    potential-based for the return PPO maximises (Ng et al. 1999: F = gamma * Phi(s') - Phi(s) with the MDP's own
    gamma)."""
    cfg = make_config(scenario, **args.env_overrides(training=training))
    reward = dataclasses.replace(
        cfg.reward,
        shaping=args.shaping,
        shaping_metric=args.shaping_metric,
        shaping_gamma=args.gamma if args.shaping_gamma is None else args.shaping_gamma,
    )
    return cfg.replace(reward=reward)


class GreedyPolicy:
    """The trained policy acting greedily (argmax of the masked logits) on a core's ``[E, A, ...]`` obs."""

    def __init__(self, net: MSHAActorCritic, normalizer: ObservationNormalizer | None, device: torch.device) -> None:
        self.net, self.normalizer, self.device = net, normalizer, device

    @torch.no_grad()
    def __call__(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        E, A = obs["action_mask"].shape[:2]
        flat = {k: v.reshape(E * A, *v.shape[2:]) for k, v in obs.items()}
        if self.normalizer is not None:
            flat = self.normalizer(flat)
        logits = self.net.masked_logits(obs_to_torch(flat, self.device))  # [E * A, 16]; needs no critic state
        return logits.argmax(-1).cpu().numpy().reshape(E, A)


def evaluate(policy: GreedyPolicy, cfg: EnvConfig, seed: int = 0) -> EpisodeMetrics:
    return episode_metrics(fly(cfg, policy, seed=seed), cfg.radio)


def _score(m: dict[str, float]) -> tuple[float, float]:
    """Order evaluations: more delivered first, then shorter distance."""
    return (-m.get("pr_pct", 0.0), m.get("td_m", math.inf))


def _device(choice: str) -> torch.device:
    if choice == "auto":
        return torch.device("cuda" if torch.cuda.is_available() else "cpu")
    if choice == "cuda" and not torch.cuda.is_available():
        raise ValueError("device='cuda' but torch sees no CUDA device; use --device cpu or auto.")
    return torch.device(choice)


def train(args: TrainArgs, env_config: EnvConfig | None = None) -> TrainResult:  # noqa: C901 - one loop, as CleanRL
    """Train; ``env_config`` replaces the named scenario (e.g. a user's own map or instance)."""
    if args.num_envs < 1 or args.num_steps < 1 or args.num_minibatches < 1:
        raise ValueError(
            f"num_envs={args.num_envs}, num_steps={args.num_steps}, num_minibatches={args.num_minibatches} "
            "must all be >= 1."
        )
    if args.variant not in VARIANTS:
        raise ValueError(f"variant={args.variant!r} is unknown; use one of {VARIANTS}.")
    if args.threads:
        torch.set_num_threads(args.threads)
    device = _device(args.device)
    run_dir = args.run_dir / args.name
    run_dir.mkdir(parents=True, exist_ok=True)

    base: str | EnvConfig = env_config if env_config is not None else args.scenario
    cfg = make_env_config(base, args, training=True)
    eval_cfg = make_env_config(base, args, training=False)
    venv = VectorEnv(cfg, num_envs=args.num_envs)
    num_taxis = cfg.num_taxis
    num_agents = args.num_envs * num_taxis
    batch_size = args.num_steps * num_agents
    minibatch_size = batch_size // args.num_minibatches
    num_iterations = max(1, args.total_timesteps // batch_size)
    shapes = {k: tuple(s.shape or ()) for k, s in venv.single_observation_space.spaces.items()}
    state_dim = int(venv.state_space.shape[0]) if args.centralised_critic else 0

    np.random.seed(args.seed)
    torch.manual_seed(args.seed)
    net_cfg = NetConfig(
        variant=args.variant, d_model=args.d_model, num_heads=args.num_heads, local_window=args.local_window,
        readout=args.readout, critic_state_dim=state_dim or None,
    )  # fmt: skip
    net = MSHAActorCritic(venv.single_observation_space, net_cfg).to(device)
    optimizer = torch.optim.Adam(net.parameters(), lr=args.learning_rate, eps=1e-5)
    normalizer = ObservationNormalizer(shapes) if args.norm_obs else None
    scaler = RewardScaler(num_agents, args.gamma) if args.norm_reward else None
    buffer = RolloutBuffer(args.num_steps, num_agents, shapes, state_dim)

    start_iteration, global_step, wall_offset = 0, 0, 0.0
    best_eval: dict[str, float] = {}
    best_step, target_step, target_s = 0, None, None
    rows: list[dict[str, float]] = []
    ckpt_path = run_dir / "last.pt"
    if args.resume:
        if not ckpt_path.exists():
            raise FileNotFoundError(f"--resume: no checkpoint at {ckpt_path}; train without --resume first.")
        ckpt = torch.load(ckpt_path, map_location=device, weights_only=False)
        net.load_state_dict(ckpt["model"])
        optimizer.load_state_dict(ckpt["optimizer"])
        if normalizer is not None:
            normalizer.load_state_dict(ckpt["obs_normalizer"])
        if scaler is not None:
            scaler.rms.load_state_dict(ckpt["reward_scaler"])
        start_iteration, global_step = ckpt["iteration"], ckpt["global_step"]
        wall_offset = ckpt["wall_s"]
        best_eval, best_step = ckpt["best_eval"], ckpt["best_step"]
        target_step, target_s = ckpt.get("target_step"), ckpt.get("target_s")
        torch.set_rng_state(ckpt["torch_rng"])
        np.random.set_state(ckpt["numpy_rng"])
        rows = read_progress(run_dir / "progress.csv")
        print(f"resumed {run_dir} at iteration {start_iteration}, step {global_step} (envs restart their episodes)")

    writer = None
    if args.tensorboard:
        from torch.utils.tensorboard import SummaryWriter

        writer = SummaryWriter(str(run_dir / "tb"), purge_step=global_step if args.resume else None)
        writer.add_text("hyperparameters", "|param|value|\n|-|-|\n" + "\n".join(
            f"|{k}|{v}|" for k, v in dataclasses.asdict(args).items()))  # fmt: skip

    def save_checkpoint(iteration: int, path: Path = ckpt_path) -> None:
        payload = {
            "model": net.state_dict(), "optimizer": optimizer.state_dict(), "net_config": dataclasses.asdict(net_cfg),
            "args": {k: (str(v) if isinstance(v, Path) else v) for k, v in dataclasses.asdict(args).items()},
            "iteration": iteration, "global_step": global_step, "wall_s": wall_offset + time.time() - start_time,
            "obs_normalizer": normalizer.state_dict() if normalizer is not None else None,
            "reward_scaler": scaler.rms.state_dict() if scaler is not None else None,
            "best_eval": best_eval, "best_step": best_step, "target_step": target_step, "target_s": target_s,
            "torch_rng": torch.get_rng_state(), "numpy_rng": np.random.get_state(),
        }  # fmt: skip
        data = io.BytesIO()
        torch.save(payload, data)
        write_bytes_atomic(path, data.getvalue())

    def flat(obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {k: v.reshape(num_agents, *v.shape[2:]) for k, v in obs.items()}

    def prepare(obs: dict[str, np.ndarray], update: bool) -> dict[str, np.ndarray]:
        if normalizer is None:
            return obs
        if update:
            normalizer.update(obs)
        return normalizer(obs)

    def global_state() -> np.ndarray | None:
        if not state_dim:
            return None
        return np.repeat(venv.global_state(), num_taxis, axis=0)  # [N, S]: each taxi's row is its env's state

    obs_np, _ = venv.reset(seed=args.seed)
    obs = flat(obs_np)
    start_time = time.time()
    episode_returns: list[float] = []
    episode_stats: list[dict[str, float]] = []
    interrupted = False
    iteration = start_iteration
    progress = _progress(args.progress, num_iterations, start_iteration)
    try:
        for iteration in range(start_iteration, num_iterations):
            if args.anneal_lr:
                optimizer.param_groups[0]["lr"] = args.learning_rate * (1.0 - iteration / num_iterations)
            shaping_weight = args.shaping
            if args.shaping > 0 and args.shaping_anneal_frac > 0:
                # keep a sliver of shaping so the env's shaping machinery stays on (its metric is fixed)
                start = (1.0 - args.shaping_anneal_frac) * num_iterations
                decay = min(1.0, max(0.0, 1.0 - (iteration - start) / (args.shaping_anneal_frac * num_iterations)))
                shaping_weight = max(args.shaping * decay, 1e-6)
                venv.set_reward_weights(dataclasses.replace(cfg.reward, shaping=shaping_weight))
            term_sums = np.zeros(len(REWARD_TERMS))
            for step in range(args.num_steps):
                global_step += num_agents
                norm_obs = prepare(obs, update=True)
                for key, field_value in norm_obs.items():
                    buffer.obs[key][step] = field_value
                state = global_state()
                if buffer.state is not None and state is not None:
                    buffer.state[step] = state
                with torch.no_grad():
                    action, logprob, _, value = net.get_action_and_value(
                        obs_to_torch(norm_obs, device), state=_tensor(state, device)
                    )
                buffer.actions[step] = action.cpu().numpy()
                buffer.logprobs[step] = logprob.cpu().numpy()
                buffer.values[step] = value.cpu().numpy()
                next_obs, rewards, terminated, truncated, info = venv.step(buffer.actions[step].reshape(-1, num_taxis))
                term_sums += info["reward_terms"].sum(axis=(0, 1))
                done_env = terminated | truncated
                buffer.terminated[step] = np.repeat(terminated, num_taxis)
                buffer.truncated[step] = np.repeat(truncated, num_taxis)
                raw_rewards = rewards.reshape(-1)
                buffer.rewards[step] = scaler(raw_rewards, np.repeat(done_env, num_taxis)) if scaler else raw_rewards
                if truncated.any():
                    final = prepare(flat(info["final_obs"]), update=False)
                    with torch.no_grad():
                        _, final_value = net(obs_to_torch(final, device), state=_tensor(state, device))
                    buffer.final_values[step] = final_value.cpu().numpy()
                if done_env.any():
                    ep = info["episode"]
                    for e in np.flatnonzero(done_env):
                        episode_returns.append(float(ep["return"][e].mean()))
                        episode_stats.append({"service_rate": float(ep["service_rate"][e]),
                                              "distance_m": float(ep["distance_m"][e].sum()),
                                              "length": float(ep["length"][e])})  # fmt: skip
                obs = flat(next_obs)

            with torch.no_grad():
                _, next_value = net(
                    obs_to_torch(prepare(obs, update=False), device), state=_tensor(global_state(), device)
                )
            advantages, returns = compute_gae(
                buffer.rewards, buffer.values, buffer.terminated, buffer.truncated, buffer.final_values,
                next_value.cpu().numpy(), args.gamma, args.gae_lambda,
            )  # fmt: skip
            flat_adv = torch.as_tensor(advantages.reshape(-1), dtype=torch.float32, device=device)
            flat_ret = torch.as_tensor(returns.reshape(-1), dtype=torch.float32, device=device)
            flat_val = torch.as_tensor(buffer.values.reshape(-1), dtype=torch.float32, device=device)

            order = np.arange(batch_size)
            infos = []
            for _epoch in range(args.update_epochs):
                np.random.shuffle(order)
                for start in range(0, batch_size, minibatch_size):
                    idx = order[start : start + minibatch_size]
                    mb_obs, mb_state, mb_actions, mb_logprobs = buffer.minibatch(idx, device)
                    _, new_logprob, entropy, new_value = net.get_action_and_value(mb_obs, mb_actions, state=mb_state)
                    loss, loss_info = ppo_loss(
                        new_logprob, mb_logprobs, entropy, new_value, flat_val[idx], flat_adv[idx], flat_ret[idx],
                        args.clip_coef, args.vf_coef, args.ent_coef, args.clip_vloss, args.norm_adv,
                    )  # fmt: skip
                    optimizer.zero_grad()
                    loss.backward()
                    torch.nn.utils.clip_grad_norm_(net.parameters(), args.max_grad_norm)
                    optimizer.step()
                    infos.append(loss_info)
                if args.target_kl is not None and infos[-1].approx_kl > args.target_kl:
                    break

            var_y = np.var(returns)
            explained_var = math.nan if var_y == 0 else float(1 - np.var(returns - buffer.values) / var_y)
            elapsed = wall_offset + time.time() - start_time
            row: dict[str, float] = {
                "iteration": iteration + 1, "global_step": global_step, "wall_s": elapsed,
                "charts/learning_rate": optimizer.param_groups[0]["lr"],
                "charts/shaping_weight": shaping_weight,
                "charts/SPS": global_step / max(elapsed, 1e-9),
                "losses/value_loss": float(np.mean([i.value_loss for i in infos])),
                "losses/policy_loss": float(np.mean([i.policy_loss for i in infos])),
                "losses/entropy": float(np.mean([i.entropy for i in infos])),
                "losses/old_approx_kl": float(np.mean([i.old_approx_kl for i in infos])),
                "losses/approx_kl": float(np.mean([i.approx_kl for i in infos])),
                "losses/clipfrac": float(np.mean([i.clipfrac for i in infos])),
                "losses/explained_variance": explained_var,
            }  # fmt: skip
            for name, total in zip(REWARD_TERMS, term_sums, strict=True):
                row[f"reward/{name}"] = float(total / (args.num_steps * num_agents))  # mean per agent-step
            if episode_returns:
                row["charts/episodic_return"] = float(np.mean(episode_returns))
                row["charts/episodic_length"] = float(np.mean([s["length"] for s in episode_stats]))
                row["charts/service_rate"] = float(np.mean([s["service_rate"] for s in episode_stats]))
                row["charts/episodic_distance_m"] = float(np.mean([s["distance_m"] for s in episode_stats]))
            episode_returns.clear()
            episode_stats.clear()

            out_of_time = args.max_wall_s is not None and time.time() - start_time >= args.max_wall_s
            last = iteration == num_iterations - 1 or out_of_time
            if (args.eval_every and (iteration + 1) % args.eval_every == 0) or last:
                policy = GreedyPolicy(net, normalizer, device)
                m = evaluate(policy, eval_cfg).as_dict()
                row.update({f"eval/{k}": v for k, v in m.items()})
                if not best_eval or _score(m) < _score(best_eval):
                    best_eval, best_step = m, global_step
                    save_checkpoint(iteration + 1, run_dir / "best.pt")
                if (target_step is None and args.stop_at_td_m is not None and m["pr_pct"] >= 100.0
                        and m["td_m"] <= args.stop_at_td_m):  # fmt: skip
                    target_step, target_s = global_step, elapsed
            rows.append(row)
            _log(writer, row, global_step)
            write_text_atomic(run_dir / "progress.csv", _csv(rows))
            if progress is not None:
                progress.update(1)
                progress.set_postfix_str(_postfix(row, best_eval))
            if (iteration + 1) % args.checkpoint_every == 0 or last:
                save_checkpoint(iteration + 1)
            if (target_step is not None and args.stop_at_td_m is not None) or out_of_time:
                save_checkpoint(iteration + 1)
                break
    except KeyboardInterrupt:
        interrupted = True
        save_checkpoint(iteration)  # the current iteration restarts on resume
        print(f"\ninterrupted: checkpoint saved to {ckpt_path}; continue with --resume")
    finally:
        if progress is not None:
            progress.close()
        if writer is not None:
            writer.close()

    final_eval = {k.removeprefix("eval/"): v for k, v in rows[-1].items() if k.startswith("eval/")} if rows else {}
    return TrainResult(
        run_dir=run_dir, global_step=global_step, iterations=len(rows), wall_s=wall_offset + time.time() - start_time,
        final_eval=final_eval, best_eval=best_eval, best_step=best_step, target_reached_step=target_step,
        target_reached_s=target_s,
        losses=[{k: v for k, v in r.items() if k.startswith("losses/")} for r in rows], interrupted=interrupted,
    )  # fmt: skip


def _tensor(x: np.ndarray | None, device: torch.device) -> torch.Tensor | None:
    return None if x is None else torch.as_tensor(x, dtype=torch.float32, device=device)


def _progress(enabled: bool, total: int, initial: int) -> Any:
    if not enabled:
        return None
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, unit="it", dynamic_ncols=True)


def _postfix(row: dict[str, float], best: dict[str, float]) -> str:
    parts = []
    if "charts/episodic_return" in row:
        parts.append(f"return {row['charts/episodic_return']:.0f}")
        parts.append(f"train PR {100 * row['charts/service_rate']:.0f}%")
    if "eval/pr_pct" in row:
        parts.append(f"eval PR {row['eval/pr_pct']:.0f}% TD {row['eval/td_m']:.0f} m")
    if best:
        parts.append(f"best PR {best['pr_pct']:.0f}% TD {best['td_m']:.0f} m")
    return ", ".join(parts)


def _log(writer: Any, row: dict[str, float], step: int) -> None:
    if writer is None:
        return
    for key, value in row.items():
        if "/" in key and isinstance(value, float | int) and math.isfinite(value):
            writer.add_scalar(key, value, step)


def _csv(rows: list[dict[str, float]]) -> str:
    keys = list(dict.fromkeys(k for r in rows for k in r))
    buffer = io.StringIO()
    writer = csv.DictWriter(buffer, fieldnames=keys, lineterminator="\n")
    writer.writeheader()
    writer.writerows(rows)
    return buffer.getvalue()


def read_progress(path: Path) -> list[dict[str, float]]:
    """The rows of a run's ``progress.csv`` as floats (empty cells left out; no file: no rows)."""
    if not path.exists():
        return []
    with path.open() as f:
        return [{k: float(v) for k, v in r.items() if v not in ("", None)} for r in csv.DictReader(f)]


def load_policy(
    path: str | Path, device: str = "cpu", env_config: EnvConfig | None = None
) -> tuple[GreedyPolicy, TrainArgs]:
    """A greedy policy and the training arguments from a checkpoint written by :func:`train` (pass the same
    ``env_config`` when it was trained on one)."""
    path = Path(path)
    if not path.exists():
        raise FileNotFoundError(f"checkpoint {path} does not exist; train one with `python train/ppo.py`.")
    ckpt = torch.load(path, map_location=device, weights_only=False)
    fields = {f.name for f in dataclasses.fields(TrainArgs)}
    saved = {k: v for k, v in ckpt["args"].items() if k in fields}
    saved["run_dir"] = Path(saved.get("run_dir", "runs"))
    args = TrainArgs(**saved)
    base: str | EnvConfig = env_config if env_config is not None else args.scenario
    venv = VectorEnv(make_env_config(base, args, training=False), num_envs=1)
    net = MSHAActorCritic(venv.single_observation_space, NetConfig(**ckpt["net_config"]))
    net.load_state_dict(ckpt["model"])
    net.eval()
    normalizer = None
    if ckpt["obs_normalizer"] is not None:
        shapes = {k: tuple(s.shape or ()) for k, s in venv.single_observation_space.spaces.items()}
        normalizer = ObservationNormalizer(shapes)
        normalizer.load_state_dict(ckpt["obs_normalizer"])
    return GreedyPolicy(net, normalizer, torch.device(device)), args


__all__ = ["GreedyPolicy", "TrainArgs", "TrainResult", "evaluate", "load_policy", "read_progress", "train"]
