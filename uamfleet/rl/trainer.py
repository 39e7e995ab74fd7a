"""PPO with one shared MSHA policy over every taxi of every env: ``train(args) -> TrainResult``.

CleanRL's loop (``ppo.py``) made importable and cut into named parts: :func:`collect_rollout` (the batched
core, N = E * A agents per step), :func:`compute_advantages` (GAE that bootstraps truncated episodes from their
real final observation), :func:`ppo_update` (clipped surrogate and value losses, entropy bonus, gradient
clipping), :func:`evaluate_greedy` on a separate env, :class:`Logger` (CSV + TensorBoard with CleanRL's metric
names) and :class:`Checkpoint` (atomic, loadable with ``torch.load(weights_only=True)``, ``--resume``).
Advantage / observation / reward normalisation, a linear learning-rate schedule and an optional centralised
critic on the global state (MAPPO).

Under ``torchrun`` every rank runs this loop on its share of the envs, data-parallel on ``torch.distributed``
(uamfleet.rl.distributed says what keeps the ranks equal); rank 0 alone evaluates, logs and checkpoints.
"""

from __future__ import annotations

import copy
import csv
import dataclasses
import io
import math
import os
import re
import shutil
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
import torch
from torch.distributions import Categorical

from uamfleet.config import (
    FEASIBILITY_RULES,
    PRESETS,
    REWARD_TERMS,
    SCENARIOS,
    ConfigError,
    EnvConfig,
    check_integer,
    check_number,
    make_config,
)
from uamfleet.env.layout import layout_shapes, observation_layout, observation_space
from uamfleet.env.mixture import MixtureVectorEnv
from uamfleet.env.vector_env import VectorEnv
from uamfleet.paths import table_for
from uamfleet.instances import VALIDATION_SEEDS, family_of, validation_metrics
from uamfleet.io import write_text_atomic
from uamfleet.metrics import EpisodeMetrics, episode_metrics
from uamfleet.rl.checkpoint import (
    ARCHITECTURE_FIELDS,
    CHECKPOINT_FORMAT,
    ENVIRONMENT_FIELDS,
    Checkpoint,
    CheckpointError,
    check_network,
    check_state_dict,
    upgrade_checkpoint,
)
from uamfleet.rl.buffer import ObservationNormalizer, RewardScaler, RolloutBuffer, compute_gae
from uamfleet.rl.distributed import World, sample_actions
from uamfleet.rl.networks import VARIANTS, MSHAActorCritic, NetConfig, obs_to_torch
from uamfleet.rl.policy import GreedyPolicy
from uamfleet.rl.ppo import PPOLossInfo, ppo_loss
from uamfleet.rollout import fly

# The known names as Literal types built from the package's tuples (tyro offers them as choices); mypy sees str.
if TYPE_CHECKING:
    ScenarioName = str
    FeasibilityRule = str
    VariantName = str
else:
    ScenarioName, FeasibilityRule, VariantName = Literal[SCENARIOS], Literal[FEASIBILITY_RULES], Literal[VARIANTS]


@dataclass
class TrainArgs:
    """PPO training of the shared MSHA policy (every option is a command-line flag of ``train/ppo.py``)."""

    # environment
    scenario: ScenarioName = "berlin_p4"
    """scenario name"""
    sinr_min_db: float | None = None
    """SINR threshold in dB; None: the scenario's"""
    num_taxis: int | None = None
    """fleet size; None: the scenario's"""
    thresholds: tuple[float, ...] = ()
    """train on several SINR thresholds at once (dB; the envs split into one group per threshold, see
    uamfleet.env.mixture); empty: the one of --sinr-min-db. A generalist over -7 ... -3 dB on Berlin:
    --scenario berlin_instances --thresholds -7 -6 -5 -4 -3"""
    feasibility: FeasibilityRule = "endpoint_block"
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
    """discount inside the shaping term gamma * Phi(s') - Phi(s); None: the trainer's gamma (which keeps it
    potential-based; 1.0 removes the per-step bonus w (1 - gamma) |Phi| for staying away from the stop)"""
    shaping_anneal_frac: float = 0.5
    """decay the shaping weight linearly to 0 over the LAST this fraction of training (0: constant). Shaping is
    potential-based, so the optimum is unchanged: it helps find every passenger early, and annealing it leaves
    the end of training to the true reward (shorter tours)"""
    # network
    variant: VariantName = "de_msfea"
    """MSHA ablation variant: linear encoders / designed encoders / + multi-source features / + hybrid attention.
    Default de_msfea: on Berlin P4 it came within 5 % of raster_opt (a raster planner, not an optimum of the env's
    moves) in 40-140k agent-steps in 8 of 10 runs, at 3x the full model's speed per step; the full model learned
    slower per step too (docs/results.md)"""
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
    action_head: Literal["headings", "stops"] = "headings"
    """headings: a logit per heading (the paper); stops: a pointer over the actionable stops, each flown along
    its progress heading (needs the stop features, e.g. the *_instances scenarios)"""
    stop_free_move: bool = False
    """with --action-head stops: a free move (any heading) beside the stops, not only when no stop is actionable"""
    stop_prior: Literal["tour", "nearest"] = "tour"
    """with --action-head stops: the prior prefers the stop that starts the shortest tour through every known stop
    (one taxi), or the nearest stop (a fleet with claims: the greedy dispatcher's rule along feasible paths)"""
    # PPO
    seed: int = 1
    """seed of torch, numpy and the envs (env e gets seed + e)"""
    total_timesteps: int = 200_000
    """agent-steps (env steps x taxis) to train for (under torchrun: of all ranks together); rounded down to whole
    iterations of num_steps x num_envs x taxis, at least one"""
    num_envs: int = 32
    """parallel envs of the batched core (agents per step = num_envs x taxis); under torchrun the global count,
    split evenly among the ranks"""
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
    fill_tables: bool = True
    """with stop features on random demand: compute the feasible-path distance tables before training (or load
    them from the disk cache, uamfleet.paths.distance_table), ~30 s per threshold on Berlin the first time"""
    eval_instances: int = 0
    """evaluate on this many held-out validation instances of the scenario's family (uamfleet.instances;
    *_instances scenarios), flown in one batch, and keep the best on them; 0: one episode of the training
    scenario. Never the test instances: those are for the final report"""
    eval_time_limit_steps: int | None = None
    """time limit of the greedy evaluation episodes; None: the training one (the observation's time
    features are fractions of the time limit, so a different one shifts them)"""
    checkpoint_every: int = 5
    """iterations between checkpoints"""
    stop_at_td_m: float | None = None
    """stop once a greedy evaluation delivers everyone with TD at or below this (measures time-to-target)"""
    max_wall_s: float | None = None
    """stop (after a final evaluation and checkpoint) once training has run this many seconds"""
    run_dir: Path = Path("runs")
    """folder of all runs (relative to the current folder)"""
    run_name: str | None = None
    """None: {scenario}_{sinr}dB_{variant}_s{seed}"""
    resume: bool = False
    """continue from run_dir/run_name/last.pt"""
    overwrite: bool = False
    """replace an existing run of this name (without it, or --resume, an existing run is an error)"""
    device: Literal["auto", "cpu", "cuda"] = "auto"
    """torch device (auto: CUDA when available); under torchrun, cuda means cuda:LOCAL_RANK"""
    backend: Literal["auto", "gloo", "nccl"] = "auto"
    """torch.distributed backend under torchrun (auto: NCCL when each local rank has a GPU of its own, else
    gloo)"""
    threads: int = 0
    """torch CPU threads (0: torch's default)"""
    progress: bool = True
    """show a progress bar"""
    tensorboard: bool = True
    """write TensorBoard events to run_dir/name/tb"""

    def __post_init__(self) -> None:
        """Every numeric option in its range (:class:`~uamfleet.config.ConfigError` naming the flag otherwise),
        so a typo fails before any env is built, not after training (``checkpoint_every=0``)."""
        for name, minimum in _COUNTS.items():
            check_integer(_flag(name), getattr(self, name), minimum)
        most = 4 * (os.cpu_count() or 1)
        check_integer("--threads", self.threads, 0, most, fix=" (4 per CPU core at most; 0: torch's default)")
        for name in ("num_taxis", "eval_time_limit_steps"):
            if getattr(self, name) is not None:
                check_integer(_flag(name), getattr(self, name), 1)
        for name, (low, high, low_open) in _RANGES.items():
            value = getattr(self, name)
            if value is None:
                continue
            check_number(_flag(name), value)
            if (value <= low if low_open else value < low) or (high is not None and value > high):
                interval = f"{'(' if low_open else '['}{low:g}, {'inf)' if high is None else f'{high:g}]'}"
                raise ConfigError(f"{_flag(name)}={value!r} is out of range: it must lie in {interval}.")
        if isinstance(self.thresholds, str | bytes) or not hasattr(self.thresholds, "__iter__"):
            raise ConfigError(f"--thresholds={self.thresholds!r} must be a list of dB values, e.g. -7 -6 -5.")
        self.thresholds = tuple(check_number("--thresholds", t) for t in self.thresholds)
        repeated = sorted({t for t in self.thresholds if self.thresholds.count(t) > 1})
        if repeated:
            raise ConfigError(
                f"--thresholds={list(self.thresholds)} repeats {repeated}: each threshold is one share of the envs; "
                "give each once."
            )
        if self.thresholds and self.sinr_min_db is not None:
            raise ConfigError(
                f"--sinr-min-db={self.sinr_min_db} and --thresholds={list(self.thresholds)} both set the threshold; "
                "give one of them."
            )
        if self.eval_instances > len(VALIDATION_SEEDS):
            raise ConfigError(
                f"--eval-instances={self.eval_instances} exceeds the {len(VALIDATION_SEEDS):,} seeds of the "
                f"validation split; give at most {len(VALIDATION_SEEDS):,} (e.g. 50)."
            )
        if self.eval_instances and not self.scenario.endswith(("_instances", "_fleet")):
            raise ConfigError(
                f"--eval-instances={self.eval_instances} flies held-out instances of a family; it needs a "
                f"*_instances or *_fleet scenario (not {self.scenario!r}), e.g. --scenario berlin_instances."
            )
        for name in ("scenario", "run_name"):
            value = getattr(self, name)
            if value is not None and not isinstance(value, str):
                raise ConfigError(f"{_flag(name)}={value!r} must be a string.")

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


# Lower bounds of TrainArgs' integer options.
_COUNTS: dict[str, int] = {
    "time_limit_steps": 1, "d_model": 1, "num_heads": 1, "local_window": 1, "seed": 0, "total_timesteps": 1,
    "num_envs": 1, "num_steps": 1, "num_minibatches": 1, "update_epochs": 1, "eval_every": 0,
    "checkpoint_every": 1, "threads": 0, "eval_instances": 0,
}  # fmt: skip
# (low, high or None, low excluded) of TrainArgs' float options; None values (unset options) are skipped.
_RANGES: dict[str, tuple[float, float | None, bool]] = {
    "sinr_min_db": (-math.inf, None, True), "shaping": (0.0, None, False), "shaping_gamma": (0.0, 1.0, True),
    "shaping_anneal_frac": (0.0, 1.0, False), "learning_rate": (0.0, None, True), "gamma": (0.0, 1.0, True),
    "gae_lambda": (0.0, 1.0, False), "clip_coef": (0.0, None, True), "ent_coef": (0.0, None, False),
    "vf_coef": (0.0, None, False), "max_grad_norm": (0.0, None, True), "target_kl": (0.0, None, True),
    "stop_at_td_m": (0.0, None, False), "max_wall_s": (0.0, None, True),
}  # fmt: skip


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


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
    rank: int = 0
    """torch.distributed rank (under torchrun only rank 0 logs, so only its rows and evaluations are filled)"""


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


def evaluate(policy: GreedyPolicy, cfg: EnvConfig, seed: int = 0) -> EpisodeMetrics:
    return episode_metrics(fly(cfg, policy, seed=seed), cfg.radio)


def _score(m: dict[str, float]) -> tuple[float, float]:
    """Order evaluations: more delivered first, then shorter distance."""
    return (-m.get("pr_pct", 0.0), m.get("td_m", math.inf))


# ---- checkpoints ----------------------------------------------------------------------------------------------


def _plain_args(args: TrainArgs) -> dict[str, Any]:
    return {k: (str(v) if isinstance(v, Path) else v) for k, v in dataclasses.asdict(args).items()}


def _numpy_rng_state() -> dict[str, Any]:
    name, keys, pos, has_gauss, cached = np.random.get_state()
    return {"name": str(name), "keys": [int(k) for k in keys], "pos": int(pos), "has_gauss": int(has_gauss),
            "cached_gaussian": float(cached)}  # fmt: skip


def _set_numpy_rng_state(state: dict[str, Any]) -> None:
    keys = np.array(state["keys"], dtype=np.uint32)
    np.random.set_state((state["name"], keys, state["pos"], state["has_gauss"], state["cached_gaussian"]))


def checkpoint_args(ckpt: Checkpoint) -> TrainArgs:
    """The training arguments a checkpoint was written with (options added since take their defaults)."""
    known = {f.name for f in dataclasses.fields(TrainArgs)}
    saved = {k: v for k, v in ckpt.args.items() if k in known}
    saved["run_dir"] = Path(saved.get("run_dir", "runs"))
    return TrainArgs(**saved)


# ---- the run: its folder, its parts, and the state a checkpoint restores ------------------------------------

RUN_NAME = re.compile(r"[A-Za-z0-9][A-Za-z0-9._=+,-]*")
RUN_FILES = ("progress.csv", "last.pt", "best.pt")


def run_folder(args: TrainArgs) -> Path:
    """run_dir/<name>, checked: one folder name, never a path out of run_dir; an existing run is continued
    only with ``resume``, replaced only with ``overwrite``."""
    name = args.name
    if not RUN_NAME.fullmatch(name):
        raise ValueError(
            f"run_name={name!r} must be one folder name (letters, digits and '._=+,-', not starting with '.'): "
            f"runs live in {args.run_dir}/<run_name>."
        )
    if args.resume and args.overwrite:
        raise ValueError("--resume continues the run and --overwrite replaces it: pass one of them.")
    folder = args.run_dir / name
    held = [f for f in RUN_FILES if (folder / f).exists()]
    if held and not args.resume:
        if not args.overwrite:
            raise FileExistsError(
                f"{folder} already holds a run ({', '.join(held)}); continue it with --resume, replace it with "
                "--overwrite, or choose another --run-name."
            )
        for f in held:
            (folder / f).unlink()
        shutil.rmtree(folder / "tb", ignore_errors=True)
    if args.resume and not (folder / "last.pt").exists():
        raise FileNotFoundError(f"--resume: no checkpoint at {folder / 'last.pt'}; train without --resume first.")
    folder.mkdir(parents=True, exist_ok=True)
    return folder


@dataclass
class Learner:
    """What PPO trains and keeps between iterations, identical on every rank."""

    net: MSHAActorCritic
    optimizer: torch.optim.Optimizer
    net_cfg: NetConfig
    normalizer: ObservationNormalizer | None
    scaler: RewardScaler | None


@dataclass
class Counters:
    """Progress of the run; a checkpoint holds them as of the end of an iteration."""

    iteration: int = 0
    global_step: int = 0
    wall_offset: float = 0.0
    best_eval: dict[str, float] = field(default_factory=dict)
    best_step: int = 0
    target_step: int | None = None
    target_s: float | None = None


@dataclass
class Run:
    """One rank's share of a run: its envs (global envs [env_offset, env_offset + num_envs)), rollout buffer
    and the current observation."""

    args: TrainArgs
    world: World
    device: torch.device
    folder: Path
    cfg: EnvConfig
    eval_cfg: EnvConfig
    venv: VectorEnv | MixtureVectorEnv
    obs_shapes: dict[str, tuple[int, ...]]
    buffer: RolloutBuffer
    env_offset: int
    num_agents: int  # this rank's agents per step
    agent_offset: int  # index of its first agent in the global agent axis
    total_agents: int  # agents per step over all ranks
    num_iterations: int
    state_dim: int
    obs: dict[str, np.ndarray] = field(default_factory=dict)
    start_time: float = field(default_factory=time.time)

    @property
    def batch_size(self) -> int:  # global
        return self.args.num_steps * self.total_agents

    def flat(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        return {k: v.reshape(self.num_agents, *v.shape[2:]) for k, v in obs.items()}

    def global_state(self) -> np.ndarray | None:
        """[N, S + A] the critic's agent-specific global state (MAPPO): each taxi's env state and a one-hot of
        the taxi, so the critic knows whose value it predicts (rewards are per taxi)."""
        if not self.state_dim:
            return None
        taxis = self.venv.num_taxis
        env_state = np.repeat(self.venv.global_state(), taxis, axis=0)  # [N, S]
        own = np.tile(np.eye(taxis, dtype=np.float32), (env_state.shape[0] // taxis, 1))  # [N, A]
        return np.concatenate([env_state, own], axis=1)


def make_run(args: TrainArgs, env_config: EnvConfig | None, world: World, device: torch.device) -> Run:
    if args.variant not in VARIANTS:
        raise ValueError(f"variant={args.variant!r} is unknown; use one of {VARIANTS}.")
    env_offset, local_envs = world.shard(args.num_envs)
    base: str | EnvConfig = env_config if env_config is not None else args.scenario
    cfg = make_env_config(base, args, training=True)
    venv: VectorEnv | MixtureVectorEnv = VectorEnv(cfg, num_envs=local_envs)
    if args.thresholds:
        venv = MixtureVectorEnv([cfg.replace(sinr_min_db=t) for t in args.thresholds], num_envs=local_envs)
    if args.fill_tables and cfg.stop_features and cfg.requests is None:
        # Random demand reads every row of the distance tables within minutes: compute them now (or load them
        # from the disk cache), instead of a few Dijkstras in every new episode's reset.
        for env in venv.envs if isinstance(venv, MixtureVectorEnv) else [venv]:
            table_for(env.world).fill()
    taxis = cfg.num_taxis
    shapes = {k: tuple(s.shape or ()) for k, s in venv.single_observation_space.spaces.items()}
    state_dim = int(venv.state_space.shape[0]) + taxis if args.centralised_critic else 0
    batch = args.num_steps * args.num_envs * taxis
    if args.total_timesteps < batch or args.num_minibatches > batch:
        raise ConfigError(
            f"--total-timesteps={args.total_timesteps} and --num-minibatches={args.num_minibatches} need at least "
            f"one iteration's batch of {batch} agent-steps (--num-steps {args.num_steps} x --num-envs "
            f"{args.num_envs} x {taxis} taxi(s)) to split; raise --total-timesteps to >= {batch} or lower "
            "--num-envs / --num-steps."
        )
    if batch % args.num_minibatches:  # else the last minibatch would be a silent extra, smaller update
        divisor = max(d for d in range(1, args.num_minibatches) if batch % d == 0)
        raise ConfigError(
            f"--num-minibatches={args.num_minibatches} does not divide the batch of {batch} agent-steps (--num-steps "
            f"x --num-envs x taxis); choose a divisor of {batch}, e.g. {divisor}."
        )
    return Run(
        args=args, world=world, device=device, folder=args.run_dir / args.name, cfg=cfg,
        eval_cfg=make_env_config(base, args, training=False), venv=venv, obs_shapes=shapes,
        buffer=RolloutBuffer(args.num_steps, local_envs * taxis, shapes, state_dim), env_offset=env_offset,
        num_agents=local_envs * taxis, agent_offset=env_offset * taxis, total_agents=args.num_envs * taxis,
        num_iterations=max(1, args.total_timesteps // batch), state_dim=state_dim,
    )  # fmt: skip


def make_learner(run: Run) -> Learner:
    args = run.args
    np.random.seed(args.seed)
    torch.manual_seed(args.seed)
    net_cfg = NetConfig(
        variant=args.variant, d_model=args.d_model, num_heads=args.num_heads, local_window=args.local_window,
        readout=args.readout, critic_state_dim=run.state_dim or None, action_head=args.action_head,
        stop_free_move=args.stop_free_move, stop_prior=args.stop_prior,
    )  # fmt: skip
    net = MSHAActorCritic(run.venv.single_observation_space, net_cfg).to(run.device)
    return Learner(
        net=net, optimizer=torch.optim.Adam(net.parameters(), lr=args.learning_rate, eps=1e-5), net_cfg=net_cfg,
        normalizer=ObservationNormalizer(run.obs_shapes) if args.norm_obs else None,
        scaler=RewardScaler(run.num_agents, args.gamma) if args.norm_reward else None,
    )  # fmt: skip


def capture(run: Run, learner: Learner, counters: Counters) -> Checkpoint:
    """A checkpoint of the current state (copies: training goes on changing the live tensors)."""
    cuda = torch.cuda.get_rng_state(run.device) if run.device.type == "cuda" else None
    return Checkpoint(
        model=copy.deepcopy(learner.net.state_dict()), optimizer=copy.deepcopy(learner.optimizer.state_dict()),
        net_config=dataclasses.asdict(learner.net_cfg), args=_plain_args(run.args),
        obs_shapes={k: list(v) for k, v in run.obs_shapes.items()}, iteration=counters.iteration,
        global_step=counters.global_step, wall_s=counters.wall_offset + time.time() - run.start_time,
        obs_normalizer=learner.normalizer.state_dict() if learner.normalizer is not None else None,
        reward_scaler=learner.scaler.rms.state_dict() if learner.scaler is not None else None,
        best_eval=dict(counters.best_eval), best_step=counters.best_step, target_step=counters.target_step,
        target_s=counters.target_s, torch_rng=torch.get_rng_state(), numpy_rng=_numpy_rng_state(), cuda_rng=cuda,
    )  # fmt: skip


def restore(ckpt: Checkpoint, run: Run, learner: Learner) -> Counters:
    ckpt.check_matches(run.args, run.obs_shapes)
    shapes = {k: tuple(v.shape) for k, v in learner.net.state_dict().items()}
    check_state_dict(ckpt.model, shapes, str(run.folder / "last.pt"), run.args.variant)
    learner.net.load_state_dict(ckpt.model)
    learner.optimizer.load_state_dict(ckpt.optimizer)
    if learner.normalizer is not None and ckpt.obs_normalizer is not None:
        learner.normalizer.load_state_dict(ckpt.obs_normalizer)
    if learner.scaler is not None and ckpt.reward_scaler is not None:
        learner.scaler.rms.load_state_dict(ckpt.reward_scaler)
    torch.set_rng_state(ckpt.torch_rng.cpu())
    if ckpt.cuda_rng is not None and run.device.type == "cuda":
        torch.cuda.set_rng_state(ckpt.cuda_rng.cpu(), run.device)
    _set_numpy_rng_state(ckpt.numpy_rng)
    return restore_counters(ckpt)


def start(run: Run, learner: Learner) -> tuple[Counters, list[dict[str, float]]]:
    """Prepare the folder (rank 0), resume from last.pt on every rank, and broadcast rank 0's parameters."""
    world, data, error = run.world, None, None
    if world.is_main:
        try:
            run_folder(run.args)
            data = (run.folder / "last.pt").read_bytes() if run.args.resume else None
        except Exception as err:
            error = err
    if not world.broadcast_flag(error is None):
        if error is not None:
            raise error
        raise RuntimeError("rank 0 could not set up the run folder; its error says why.")
    data = world.broadcast_bytes(data)
    counters, rows = Counters(), []
    if data is not None:
        counters = restore(Checkpoint.from_bytes(data, str(run.folder / "last.pt"), run.device), run, learner)
        if world.is_main:
            # rows logged after the checkpoint belong to iterations that are trained again
            rows = [r for r in read_progress(run.folder / "progress.csv") if r["iteration"] <= counters.iteration]
    world.broadcast_module(learner.net)
    obs, _ = run.venv.reset(seed=run.args.seed + run.env_offset)  # global env e gets seed + e
    run.obs = run.flat(obs)
    return counters, rows


# ---- one PPO iteration in named parts -----------------------------------------------------------------------


@dataclass
class RolloutStats:
    term_sums: np.ndarray  # [terms] reward term totals of this rank
    episodes: np.ndarray  # [5] sums over finished episodes: return, length, service rate, distance; count


def set_schedules(run: Run, learner: Learner, iteration: int) -> float:
    """Linear learning-rate decay and the shaping weight's anneal; returns the shaping weight."""
    args, n = run.args, run.num_iterations
    if args.anneal_lr:
        learner.optimizer.param_groups[0]["lr"] = args.learning_rate * (1.0 - iteration / n)
    if args.shaping <= 0 or args.shaping_anneal_frac <= 0:
        return args.shaping
    # keep a sliver of shaping so the env's shaping machinery stays on (its metric is fixed)
    begin = (1.0 - args.shaping_anneal_frac) * n
    decay = min(1.0, max(0.0, 1.0 - (iteration - begin) / (args.shaping_anneal_frac * n)))
    weight = max(args.shaping * decay, 1e-6)
    run.venv.set_reward_weights(dataclasses.replace(run.cfg.reward, shaping=weight))
    return weight


def normalise(run: Run, learner: Learner, obs: dict[str, np.ndarray], update: bool) -> dict[str, np.ndarray]:
    if learner.normalizer is None:
        return obs
    if update:
        learner.normalizer.update(obs, run.world)
    return learner.normalizer(obs)


def collect_rollout(run: Run, learner: Learner) -> RolloutStats:
    """num_steps steps of this rank's envs into ``run.buffer``; actions sampled from the current policy."""
    buf, net, dev, taxis = run.buffer, learner.net, run.device, run.venv.num_taxis
    term_sums, episodes = np.zeros(len(REWARD_TERMS)), np.zeros(5)
    for step in range(run.args.num_steps):
        norm_obs = normalise(run, learner, run.obs, update=True)
        for key, value in norm_obs.items():
            buf.obs[key][step] = value
        state = run.global_state()
        if buf.state is not None and state is not None:
            buf.state[step] = state
        with torch.no_grad():
            logits, value = net(obs_to_torch(norm_obs, dev), state=_tensor(state, dev))  # [N, 16], [N]
            action = sample_actions(logits, run.agent_offset, run.total_agents)  # [N]
            logprob = Categorical(logits=logits).log_prob(action)  # [N]
        buf.actions[step] = action.cpu().numpy()
        buf.logprobs[step] = logprob.cpu().numpy()
        buf.values[step] = value.cpu().numpy()
        next_obs, rewards, terminated, truncated, info = run.venv.step(buf.actions[step].reshape(-1, taxis))
        term_sums += info["reward_terms"].sum(axis=(0, 1))
        done = terminated | truncated  # [E]
        buf.terminated[step] = np.repeat(terminated, taxis)
        buf.truncated[step] = np.repeat(truncated, taxis)
        buf.rewards[step] = rewards.reshape(-1)
        if learner.scaler is not None and not run.world.active:
            buf.rewards[step] = learner.scaler(buf.rewards[step], np.repeat(done, taxis))
        if truncated.any():  # bootstrap a time limit from the real final observation
            final = normalise(run, learner, run.flat(info["final_obs"]), update=False)
            with torch.no_grad():
                _, final_value = net(obs_to_torch(final, dev), state=_tensor(state, dev))
            buf.final_values[step] = final_value.cpu().numpy()
        for e in np.flatnonzero(done):
            ep = info["episode"]
            episodes += [ep["return"][e].mean(), ep["length"][e], ep["service_rate"][e], ep["distance_m"][e].sum(), 1]
        run.obs = run.flat(next_obs)
    if learner.scaler is not None and run.world.active:  # all steps' statistics in one all-reduce
        buf.rewards[:] = learner.scaler.scale_rollout(buf.rewards, buf.terminated | buf.truncated, run.world)
    return RolloutStats(term_sums, episodes)


def compute_advantages(run: Run, learner: Learner) -> tuple[np.ndarray, np.ndarray]:
    """GAE over this rank's rollout: (advantages [T, N], returns [T, N])."""
    buf = run.buffer
    with torch.no_grad():
        norm_obs = normalise(run, learner, run.obs, update=False)
        _, next_value = learner.net(obs_to_torch(norm_obs, run.device), state=_tensor(run.global_state(), run.device))
    return compute_gae(
        buf.rewards, buf.values, buf.terminated, buf.truncated, buf.final_values, next_value.cpu().numpy(),
        run.args.gamma, run.args.gae_lambda,
    )  # fmt: skip


def ppo_update(run: Run, learner: Learner, advantages: np.ndarray, returns: np.ndarray) -> list[PPOLossInfo]:
    """update_epochs passes of minibatch Adam steps on the clipped PPO loss.

    The permutation is of the GLOBAL flat batch [T * N_global] (the same on every rank: the NumPy generator
    is); each rank takes its own samples of each global minibatch (see uamfleet.rl.distributed)."""
    args, buf, dev, world = run.args, run.buffer, run.device, run.world
    minibatch_size = run.batch_size // args.num_minibatches
    adv = torch.as_tensor(advantages.reshape(-1), dtype=torch.float32, device=dev)
    ret = torch.as_tensor(returns.reshape(-1), dtype=torch.float32, device=dev)
    val = torch.as_tensor(buf.values.reshape(-1), dtype=torch.float32, device=dev)
    global_adv = torch.as_tensor(
        world.gather_agents(advantages, run.agent_offset, run.total_agents).reshape(-1),
        dtype=torch.float32,
        device=dev,
    )  # [T * N_global] the same on every rank
    params = list(learner.net.parameters())
    order = np.arange(run.batch_size)
    infos: list[PPOLossInfo] = []
    for _epoch in range(args.update_epochs):
        np.random.shuffle(order)
        for begin in range(0, run.batch_size, minibatch_size):
            idx = order[begin : begin + minibatch_size]  # global flat indices t * N_global + n
            local, share = _local_indices(run, idx)
            mb_obs, mb_state, mb_actions, mb_logprobs = buf.minibatch(local, dev)
            _, new_logprob, entropy, new_value = learner.net.get_action_and_value(mb_obs, mb_actions, state=mb_state)
            stats, denominator = None, None
            if world.active:
                stats, denominator = (global_adv[idx].mean(), global_adv[idx].std()), len(idx)
            loss, info = ppo_loss(
                new_logprob, mb_logprobs, entropy, new_value, val[local], adv[local], ret[local], args.clip_coef,
                args.vf_coef, args.ent_coef, args.clip_vloss, args.norm_adv, stats, denominator,
            )  # fmt: skip
            learner.optimizer.zero_grad()
            (loss * share).backward()
            summed = world.all_reduce_grads(params, share * np.array(dataclasses.astuple(info)))
            infos.append(PPOLossInfo(*(float(x) for x in summed)))
            torch.nn.utils.clip_grad_norm_(params, args.max_grad_norm)
            learner.optimizer.step()
        if args.target_kl is not None and infos[-1].approx_kl > args.target_kl:
            break
    return infos


def _local_indices(run: Run, idx: np.ndarray) -> tuple[np.ndarray, float]:
    """This rank's samples of a global minibatch as flat indices into its buffer, and 1.0; a rank with no
    sample in it takes sample 0 with weight 0.0 (it must still join the gradient all-reduce)."""
    if not run.world.active:
        return idx, 1.0
    t, n = np.divmod(idx, run.total_agents)
    mine = (n >= run.agent_offset) & (n < run.agent_offset + run.num_agents)
    if not mine.any():
        return np.zeros(1, dtype=np.int64), 0.0
    return t[mine] * run.num_agents + (n[mine] - run.agent_offset), 1.0


def progress_row(
    run: Run, learner: Learner, counters: Counters, rollout: RolloutStats, infos: list[PPOLossInfo],
    advantages: np.ndarray, returns: np.ndarray, shaping_weight: float,
) -> dict[str, float]:  # fmt: skip
    """The iteration's CSV / TensorBoard row (CleanRL's names), pooled over ranks."""
    world = run.world
    values = world.gather_agents(run.buffer.values, run.agent_offset, run.total_agents)  # [T, N_global]
    returns = world.gather_agents(returns, run.agent_offset, run.total_agents)
    var_y = np.var(returns)
    explained_var = math.nan if var_y == 0 else float(1 - np.var(returns - values) / var_y)
    elapsed = counters.wall_offset + time.time() - run.start_time
    row: dict[str, float] = {
        "iteration": counters.iteration + 1, "global_step": counters.global_step, "wall_s": elapsed,
        "charts/learning_rate": learner.optimizer.param_groups[0]["lr"],
        "charts/shaping_weight": shaping_weight,
        "charts/SPS": counters.global_step / max(elapsed, 1e-9),
    }  # fmt: skip
    for name in ("value_loss", "policy_loss", "entropy", "old_approx_kl", "approx_kl", "clipfrac"):
        row[f"losses/{name}"] = float(np.mean([getattr(i, name) for i in infos]))
    row["losses/explained_variance"] = explained_var
    terms = world.all_sum(rollout.term_sums)
    for name, total in zip(REWARD_TERMS, terms, strict=True):
        row[f"reward/{name}"] = float(total / run.batch_size)  # mean per agent-step
    ret_sum, len_sum, served_sum, dist_sum, count = world.all_sum(rollout.episodes)
    if count:
        row["charts/episodic_return"] = float(ret_sum / count)
        row["charts/episodic_length"] = float(len_sum / count)
        row["charts/service_rate"] = float(served_sum / count)
        row["charts/episodic_distance_m"] = float(dist_sum / count)
    return row


def evaluate_greedy(run: Run, learner: Learner, counters: Counters, row: dict[str, float]) -> bool:
    """Rank 0: fly the greedy policy (one episode, or the validation instances), add eval/* to the row, keep the
    best; True when it is a new best."""
    policy = GreedyPolicy(learner.net, learner.normalizer, run.device)
    if run.args.eval_instances:
        m = validation_metrics(policy, family_of(run.args.scenario), run.args.eval_instances, run.eval_cfg)
    else:
        m = evaluate(policy, run.eval_cfg).as_dict()
    row.update({f"eval/{k}": v for k, v in m.items()})
    target = run.args.stop_at_td_m
    if counters.target_step is None and target is not None and m["pr_pct"] >= 100.0 and m["td_m"] <= target:
        counters.target_step, counters.target_s = counters.global_step, row["wall_s"]
    if counters.best_eval and _score(m) >= _score(counters.best_eval):
        return False
    counters.best_eval, counters.best_step = m, counters.global_step
    return True


# ---- the loop --------------------------------------------------------------------------------------------------


def train(
    args: TrainArgs,
    env_config: EnvConfig | None = None,
    on_iteration: Callable[[int, torch.nn.Module], None] | None = None,
) -> TrainResult:
    """Train; ``env_config`` replaces the named scenario (e.g. a user's own map or instance). Under torchrun
    every rank calls this; ``on_iteration(iteration, net)`` runs on every rank after each update (tests)."""
    if args.threads:
        torch.set_num_threads(args.threads)
    world, device = World.from_env(args.device, args.backend)
    run = make_run(args, env_config, world, device)
    learner = make_learner(run)
    counters, rows = start(run, learner)
    if counters.iteration >= run.num_iterations:
        if world.is_main:
            print(f"{run.folder} is finished ({counters.iteration} of {run.num_iterations} iterations, "
                  f"{counters.global_step:,} agent-steps); raise --total-timesteps to train it further")  # fmt: skip
        return _result(run, counters, rows, interrupted=False)
    if args.resume and world.is_main:
        print(f"resumed {run.folder} at iteration {counters.iteration}, step {counters.global_step:,} "
              "(envs restart their episodes)")  # fmt: skip
    log = Logger(run, counters, resumed=args.resume) if world.is_main else None
    snapshot = capture(run, learner, counters) if world.is_main else None
    try:
        for iteration in range(counters.iteration, run.num_iterations):
            shaping_weight = set_schedules(run, learner, iteration)
            rollout = collect_rollout(run, learner)
            advantages, returns = compute_advantages(run, learner)
            infos = ppo_update(run, learner, advantages, returns)
            counters.global_step += run.batch_size
            if on_iteration is not None:
                on_iteration(iteration, learner.net)
            row = progress_row(run, learner, counters, rollout, infos, advantages, returns, shaping_weight)
            out_of_time = args.max_wall_s is not None and time.time() - run.start_time >= args.max_wall_s
            last = world.broadcast_flag(iteration == run.num_iterations - 1 or out_of_time)
            new_best = False
            if world.is_main and ((args.eval_every and (iteration + 1) % args.eval_every == 0) or last):
                new_best = evaluate_greedy(run, learner, counters, row)
            counters.iteration = iteration + 1
            stop = world.broadcast_flag(last or (counters.target_step is not None and args.stop_at_td_m is not None))
            if log is not None:
                rows.append(row)
                log.write(rows, counters.best_eval)
                snapshot = capture(run, learner, counters)
                if new_best:
                    snapshot.save(run.folder / "best.pt")
                if stop or counters.iteration % args.checkpoint_every == 0:
                    snapshot.save(run.folder / "last.pt")
            if stop:
                break
    except KeyboardInterrupt:
        if snapshot is not None:  # the state after the last finished iteration: the interrupted one is redone
            snapshot.save(run.folder / "last.pt")
            counters = restore_counters(snapshot)
            rows = [r for r in rows if r["iteration"] <= snapshot.iteration]
            print(f"\ninterrupted: checkpoint of iteration {snapshot.iteration} saved to {run.folder / 'last.pt'}; "
                  "continue with --resume")  # fmt: skip
        return _result(run, counters, rows, interrupted=True)
    finally:
        if log is not None:
            log.close()
    world.barrier()
    return _result(run, counters, rows, interrupted=False)


def restore_counters(ckpt: Checkpoint) -> Counters:
    best = {k: float(v) for k, v in ckpt.best_eval.items()}
    return Counters(
        ckpt.iteration, ckpt.global_step, ckpt.wall_s, best, ckpt.best_step, ckpt.target_step, ckpt.target_s
    )


def _result(run: Run, counters: Counters, rows: list[dict[str, float]], interrupted: bool) -> TrainResult:
    final_eval = {k.removeprefix("eval/"): v for k, v in rows[-1].items() if k.startswith("eval/")} if rows else {}
    return TrainResult(
        run_dir=run.folder, global_step=counters.global_step, iterations=len(rows),
        wall_s=counters.wall_offset + time.time() - run.start_time, final_eval=final_eval,
        best_eval=counters.best_eval, best_step=counters.best_step, target_reached_step=counters.target_step,
        target_reached_s=counters.target_s,
        losses=[{k: v for k, v in r.items() if k.startswith("losses/")} for r in rows], interrupted=interrupted,
        rank=run.world.rank,
    )  # fmt: skip


class Logger:
    """Rank 0's progress.csv, TensorBoard events and progress bar. A resumed run's TensorBoard continues after
    the checkpoint's step: events logged later (iterations trained again) are purged, its own are kept."""

    def __init__(self, run: Run, counters: Counters, resumed: bool) -> None:
        self.folder, self.writer = run.folder, None
        if run.args.tensorboard:
            from torch.utils.tensorboard import SummaryWriter

            purge = counters.global_step + 1 if resumed else None
            self.writer = SummaryWriter(str(run.folder / "tb"), purge_step=purge)
            self.writer.add_text("hyperparameters", "|param|value|\n|-|-|\n" + "\n".join(
                f"|{k}|{v}|" for k, v in dataclasses.asdict(run.args).items()))  # fmt: skip
        self.bar = _progress(run.args.progress, run.num_iterations, counters.iteration)

    def write(self, rows: list[dict[str, float]], best: dict[str, float]) -> None:
        row = rows[-1]
        _log(self.writer, row, int(row["global_step"]))
        write_text_atomic(self.folder / "progress.csv", _csv(rows))
        if self.bar is not None:
            self.bar.update(1)
            self.bar.set_postfix_str(_postfix(row, best))

    def close(self) -> None:
        if self.bar is not None:
            self.bar.close()
        if self.writer is not None:
            self.writer.close()


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
    # counters stay integers when a resumed run writes back the rows it read (as floats)
    writer.writerows({**r, **{k: int(r[k]) for k in ("iteration", "global_step") if k in r}} for r in rows)
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
    ``env_config`` when it was trained on one). Loads with ``weights_only=True``: a foreign or pickle-only
    file is refused with a ValueError, a checkpoint of another observation layout says what differs."""
    ckpt = Checkpoint.load(path, map_location=device)
    args = checkpoint_args(ckpt)
    cfg = env_config if env_config is not None else make_env_config(args.scenario, args, training=False)
    layout = observation_layout(cfg)  # the spec: no env is built
    try:
        ckpt.check_matches(None, layout_shapes(layout), extra_ok=True)
    except ValueError as err:
        raise ValueError(
            f"{path}: {err} The policy flies any config of its observation layout (any threshold, instance or "
            f"fewer passengers): num_taxis={args.num_taxis or 'as trained'}, max_passengers="
            f"{ckpt.obs_shapes.get('passengers', ['?'])[0]}, stop_features={'stop_paths' in ckpt.obs_shapes}, "
            f"stop_rivals={'stop_rivals' in ckpt.obs_shapes}, stop_claims={'stop_claims' in ckpt.obs_shapes}."
        ) from None
    read = {k: spec for k, spec in layout.items() if k in ckpt.obs_shapes}  # fields added since are not read
    space, shapes = observation_space(read), layout_shapes(read)
    net = MSHAActorCritic(space, check_network(ckpt, space, str(path))).to(device)
    net.load_state_dict(ckpt.model)
    net.eval()
    normalizer = None
    if ckpt.obs_normalizer is not None:
        normalizer = ObservationNormalizer(shapes)
        normalizer.load_state_dict(ckpt.obs_normalizer)
    trained_on = env_config if env_config is not None else cfg
    if env_config is not None and args.scenario in PRESETS:
        trained_on = make_env_config(args.scenario, args, training=False)
    return GreedyPolicy(
        net, normalizer, torch.device(device), shapes, cfg.num_taxis, cfg.num_passengers, trained_on
    ), args


__all__ = [
    "ARCHITECTURE_FIELDS",
    "CHECKPOINT_FORMAT",
    "ENVIRONMENT_FIELDS",
    "Checkpoint",
    "CheckpointError",
    "GreedyPolicy",
    "TrainArgs",
    "TrainResult",
    "checkpoint_args",
    "collect_rollout",
    "compute_advantages",
    "evaluate",
    "load_policy",
    "ppo_update",
    "read_progress",
    "train",
    "upgrade_checkpoint",
]
