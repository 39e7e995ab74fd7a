"""PPO with one shared MSHA policy over every taxi of every env: ``train(args) -> TrainResult``.

CleanRL's loop (``ppo.py``) made importable and cut into named parts, read top to bottom in :func:`train`:
:func:`collect_rollout` (the batched core, N = E * A agents per step), :func:`compute_advantages` (GAE that
bootstraps truncated episodes from their real final observation), :func:`ppo_update` (clipped surrogate and value
losses, entropy bonus, gradient clipping), :func:`evaluate_greedy` on a separate env. Advantage / observation /
reward normalisation, a linear learning-rate schedule and an optional centralised critic on the global state (MAPPO).

The rooms around the loop: the options in :mod:`uamfleet.rl.options` (``TrainArgs``), the checkpoints in
:mod:`uamfleet.rl.checkpoint`, the run folder and the log in :mod:`uamfleet.rl.runs`, the policy at inference and
``load_policy`` in :mod:`uamfleet.rl.policy`. Their public names are re-exported here, where users import them.

Under ``torchrun`` every rank runs this loop on its share of the envs, data-parallel on ``torch.distributed``
(uamfleet.rl.distributed says what keeps the ranks equal); rank 0 alone evaluates, logs and checkpoints.
"""

from __future__ import annotations

import copy
import dataclasses
import math
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch.distributions import Categorical

from uamfleet.config import REWARD_TERMS, ConfigError, EnvConfig
from uamfleet.env.layout import Layout, layout_differences, layout_shapes, layout_to_dict, observation_layout
from uamfleet.env.mixture import MixtureVectorEnv
from uamfleet.env.vector_env import VectorEnv
from uamfleet.env.workers import ShardedVectorEnv
from uamfleet.instances import family_of, validation_metrics
from uamfleet.metrics import EpisodeMetrics, episode_metrics
from uamfleet.paths import table_for
from uamfleet.paths.distance_table import cache_dir
from uamfleet.rl.buffer import EpisodeSums, ObservationNormalizer, RewardScaler, RolloutBuffer, compute_gae
from uamfleet.rl.checkpoint import (
    ARCHITECTURE_FIELDS,
    CHECKPOINT_FORMAT,
    ENVIRONMENT_FIELDS,
    Checkpoint,
    CheckpointError,
    check_state_dict,
    checkpoint_args,
    checkpoint_source,
    numpy_rng_state,
    run_config,
    set_numpy_rng_state,
    upgrade_checkpoint,
)
from uamfleet.rl.distributed import RankZeroError, Ranks, sample_actions
from uamfleet.rl.networks import VARIANTS, MSHAActorCritic, NetConfig, obs_to_torch, observed_inputs
from uamfleet.rl.options import TrainArgs, make_env_config, plain_args
from uamfleet.rl.policy import GreedyPolicy, load_policy
from uamfleet.rl.ppo import PPOLossInfo, categorical_kl, ppo_loss
from uamfleet.rl.runs import RUN_FILES, RUN_NAME, Logger, RunClaim, TrainResult, claim_run, read_progress, run_folder
from uamfleet.rollout import fly
from uamfleet.sim.world import World


def evaluate(policy: GreedyPolicy, cfg: EnvConfig, seed: int = 0) -> EpisodeMetrics:
    return episode_metrics(fly(cfg, policy, seed=seed), cfg.radio)


def _score(m: dict[str, float]) -> tuple[float, float]:
    """Order evaluations: more delivered first, then shorter distance."""
    return (-m.get("pr_pct", 0.0), m.get("td_m", math.inf))


# ---- the run: its parts, and the state a checkpoint restores --------------------------------------------------


@dataclass
class Learner:
    """What PPO trains and keeps between iterations, identical on every rank."""

    net: MSHAActorCritic
    optimizer: torch.optim.Optimizer
    net_cfg: NetConfig
    normalizer: ObservationNormalizer | None
    scaler: RewardScaler | None
    reference: MSHAActorCritic | None = None  # the --init-from policy, frozen, for the --kl-to-init term


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
    and the current observation. Its agents are the envs' taxis, env-major; in a mixture of fleet sizes
    (``--fleet-mixture``) the envs are padded to the largest fleet and the agents are the real taxis only
    (:attr:`agent_rows`: what :meth:`flat`, :meth:`per_agent` and :meth:`env_actions` convert through)."""

    args: TrainArgs
    ranks: Ranks
    device: torch.device
    folder: Path
    cfg: EnvConfig
    eval_cfg: EnvConfig
    venv: VectorEnv | MixtureVectorEnv | ShardedVectorEnv
    obs_shapes: dict[str, tuple[int, ...]]
    layout: Layout  # the spec of one taxi's observation (stored in checkpoints)
    buffer: RolloutBuffer
    env_offset: int
    num_agents: int  # this rank's agents per step
    agent_offset: int  # index of its first agent in the global agent axis
    total_agents: int  # agents per step over all ranks
    num_iterations: int
    state_dim: int
    agent_rows: np.ndarray | None = None  # a mixture of fleet sizes: flat indices of the real taxis in [E * A_max]
    obs: dict[str, np.ndarray] = field(default_factory=dict)
    start_time: float = field(default_factory=time.time)

    @property
    def batch_size(self) -> int:  # global
        return self.args.num_steps * self.total_agents

    def flat(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """The core's [E, A, ...] observation as the agents' [N, ...] rows (a mixture's padding taxis left out)."""
        return {k: self.per_agent(v) for k, v in obs.items()}

    def per_agent(self, x: np.ndarray) -> np.ndarray:
        """A per-taxi array [E, A, ...] as [N, ...], or a per-env array [E] repeated for each of its taxis."""
        if x.ndim == 1:
            x = np.repeat(x[:, None], self.venv.num_taxis, axis=1)
        flat = x.reshape(-1, *x.shape[2:])
        return flat if self.agent_rows is None else flat[self.agent_rows]

    def env_actions(self, actions: np.ndarray) -> np.ndarray:
        """The agents' actions [N] as the core's [E, A] (a mixture's padding taxis get heading 0, ignored)."""
        if self.agent_rows is None:
            return actions.reshape(-1, self.venv.num_taxis)
        full = np.zeros(self.venv.num_envs * self.venv.num_taxis, actions.dtype)
        full[self.agent_rows] = actions
        return full.reshape(-1, self.venv.num_taxis)

    def finished_episode(self, episode: dict[str, np.ndarray], e: int) -> dict[str, np.ndarray]:
        """Env ``e``'s episode statistics (``info["episode"]``) as a batch of one, its own taxis only."""
        taxis = int(self.venv.taxis_per_env[e]) if isinstance(self.venv, MixtureVectorEnv) else self.venv.num_taxis
        return {k: v[e : e + 1, :taxis] if v.ndim >= 2 else v[e : e + 1] for k, v in episode.items()}

    def global_state(self) -> np.ndarray | None:
        """[N, S + A] the critic's agent-specific global state (MAPPO): each taxi's env state and a one-hot of
        the taxi, so the critic knows whose value it predicts (rewards are per taxi)."""
        if not self.state_dim:
            return None
        taxis = self.venv.num_taxis
        env_state = np.repeat(self.venv.global_state(), taxis, axis=0)  # [N, S]
        own = np.tile(np.eye(taxis, dtype=np.float32), (env_state.shape[0] // taxis, 1))  # [N, A]
        return np.concatenate([env_state, own], axis=1)


def make_run(args: TrainArgs, env_config: EnvConfig | None, ranks: Ranks, device: torch.device) -> Run:
    if args.variant not in VARIANTS:
        raise ValueError(f"variant={args.variant!r} is unknown; use one of {VARIANTS}.")
    env_offset, local_envs = ranks.shard(args.num_envs)
    base: str | EnvConfig = env_config if env_config is not None else args.scenario
    cfg = run_config(args, base, training=True)
    venv = _training_envs(args, cfg, base, local_envs)
    taxis = cfg.num_taxis  # taxis per env (a mixture of fleet sizes: its largest, padded; --num-taxis)
    shapes = {k: tuple(s.shape or ()) for k, s in venv.single_observation_space.spaces.items()}
    layout = observation_layout(cfg)
    assert layout_shapes(layout) == shapes, "the env's observation is built from its spec"
    state_dim = _critic_state_dim(args, venv)
    rows = None
    if isinstance(venv, MixtureVectorEnv) and venv.mixed_sizes:
        if ranks.active:
            raise ConfigError(
                f"--fleet-mixture={list(args.fleet_mixture)} mixes fleet sizes, whose agents do not split evenly "
                "among torchrun ranks; train it in one process."
            )
        rows = np.flatnonzero(venv.taxi_mask.reshape(-1))
    local_agents = local_envs * taxis if rows is None else len(rows)
    total_agents = args.num_envs * taxis if rows is None else len(rows)
    batch = args.num_steps * total_agents
    _check_batch(args, batch, taxis)
    return Run(
        args=args, ranks=ranks, device=device, folder=args.run_dir / args.name, cfg=cfg,
        eval_cfg=run_config(args, base, training=False), venv=venv, obs_shapes=shapes, layout=layout,
        buffer=RolloutBuffer(args.num_steps, local_agents, shapes, state_dim), env_offset=env_offset,
        num_agents=local_agents, agent_offset=env_offset * taxis, total_agents=total_agents,
        num_iterations=max(1, args.total_timesteps // batch), state_dim=state_dim, agent_rows=rows,
    )  # fmt: skip


def _critic_state_dim(args: TrainArgs, venv: VectorEnv | MixtureVectorEnv | ShardedVectorEnv) -> int:
    """Size of the centralised critic's state (the env state and a one-hot of the taxi); 0 without one.
    ConfigError for a mixture whose settings' global states differ in size (no one critic input holds them)."""
    if not args.centralised_critic:
        return 0
    if venv.state_space is None:
        raise ConfigError(
            f"--centralised-critic reads one global state, but the settings of --fleet-mixture="
            f"{list(args.fleet_mixture)} have states of different sizes (taxis and passengers); train with "
            "--no-centralised-critic (the critic reads each taxi's own features, of any fleet), and with an "
            "--init-from policy whose critic is centralised add --reinit-critic."
        )
    return int(venv.state_space.shape[0]) + venv.num_taxis


def _training_envs(
    args: TrainArgs, cfg: EnvConfig, base: str | EnvConfig, local_envs: int
) -> VectorEnv | MixtureVectorEnv | ShardedVectorEnv:
    """This rank's training envs: one config, or a mixture over ``--thresholds`` and ``--fleet-mixture``; tables
    filled if asked."""
    cfgs = training_configs(args, cfg, base)
    fill = args.fill_tables and cfg.stop_features and cfg.requests is None
    if args.env_workers:
        if args.env_workers > local_envs:
            raise ConfigError(
                f"--env-workers={args.env_workers} exceeds this rank's {local_envs} envs; give at most {local_envs} "
                "(each worker steps one env at least), or more --num-envs."
            )
        if fill and cache_dir() is not None:  # filled once here and saved to the disk cache, which every worker loads
            for c in cfgs:  # (without a disk cache each worker fills its own: filling here would be lost)
                table_for(World(c)).fill()
        try:
            # copy=False: collect_rollout copies each observation into its buffer before it steps again
            return ShardedVectorEnv(
                cfgs, local_envs, args.env_workers, global_state=args.centralised_critic, fill_tables=fill, copy=False
            )
        except ValueError as err:
            raise ConfigError(f"--env-workers={args.env_workers}: {err}") from err
    venv: VectorEnv | MixtureVectorEnv = VectorEnv(cfg, num_envs=local_envs)
    if args.thresholds or args.fleet_mixture:
        venv = MixtureVectorEnv(cfgs, num_envs=local_envs)
    if fill:
        # Random demand reads every row of the distance tables within minutes: compute them now (or load them
        # from the disk cache), instead of a few Dijkstras in every new episode's reset.
        for env in venv.envs if isinstance(venv, MixtureVectorEnv) else [venv]:
            table_for(env.world).fill()
    return venv


def training_configs(args: TrainArgs, cfg: EnvConfig, base: str | EnvConfig) -> list[EnvConfig]:
    """The configs of the training envs' groups: ``cfg`` (the run's config) at each ``--thresholds`` value, in each
    ``--fleet-mixture`` setting (threshold-major); ``[cfg]`` without either."""
    settings = [cfg]
    if args.fleet_mixture:
        if not isinstance(base, str):
            raise ConfigError(
                f"--fleet-mixture={list(args.fleet_mixture)} draws each setting from a *_fleet scenario by name; "
                "it cannot vary a config given as an EnvConfig (train one setting, or name the scenario)."
            )
        settings = [
            run_config(dataclasses.replace(args, num_taxis=taxis, num_requests=requests, fleet_mixture=()), base)
            for taxis, requests in args.fleet_settings()
        ]  # the run's own options (window, time limit, reward, the start's layout) in each setting
    if not args.thresholds:
        return settings
    return [c.replace(sinr_min_db=t) for t in args.thresholds for c in settings]


def _check_batch(args: TrainArgs, batch: int, taxis: int) -> None:
    """ConfigError unless an iteration's ``batch`` of agent-steps fits the run and splits into the minibatches."""
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


def with_init_architecture(args: TrainArgs) -> TrainArgs:
    """``args`` with the architecture options of the ``--init-from`` policy (its network is what trains), so the
    run's checkpoints state what they hold; unchanged without ``init_from``. With ``--reinit-critic`` the critic
    starts afresh, so ``--centralised-critic`` stays the run's own. ConfigError when the start lies in the run's own
    folder (replacing the run would delete the file its checkpoints point at)."""
    if args.init_from is None:
        return args
    source = checkpoint_source(args.init_from)
    folder = (args.run_dir / args.name).resolve()
    if folder in source.resolve().parents:
        raise ConfigError(
            f"--init-from={args.init_from!r} lies inside this run's own folder {folder}; copy it elsewhere or "
            "choose another --run-name."
        )
    start = checkpoint_args(Checkpoint.load(source, map_location="cpu"))
    if args.centralised_critic != start.centralised_critic and not args.reinit_critic:
        reads = "the global state" if start.centralised_critic else "its own features"
        raise ConfigError(
            f"--centralised-critic={args.centralised_critic} differs from the --init-from policy's "
            f"({start.centralised_critic}): its critic reads {reads}; set --centralised-critic "
            f"{start.centralised_critic}, or add --reinit-critic to start the critic afresh."
        )
    # (the env's layout, look-ahead included, follows the start through run_config, not through these flags)
    taken = [name for name in ARCHITECTURE_FIELDS if not (args.reinit_critic and name == "centralised_critic")]
    return dataclasses.replace(args, **{name: getattr(start, name) for name in taken})


def make_learner(run: Run) -> Learner:
    args = run.args
    np.random.seed(args.seed)
    torch.manual_seed(args.seed)
    if args.init_from is not None:
        return _learner_from(run, checkpoint_source(args.init_from))
    net_cfg = NetConfig(
        variant=args.variant, d_model=args.d_model, num_heads=args.num_heads, local_window=args.local_window,
        readout=args.readout, critic_state_dim=run.state_dim or None, action_head=args.action_head,
        stop_free_move=args.stop_free_move, stop_prior=args.stop_prior, hover_logit=args.hover_logit,
        **observed_inputs(run.layout, args.variant, args.action_head),  # from the env's spec
    )  # fmt: skip
    _check_hover_logit(net_cfg, run.cfg)
    net = MSHAActorCritic(run.venv.single_observation_space, net_cfg).to(run.device)
    return Learner(
        net=net, optimizer=torch.optim.Adam(net.parameters(), lr=args.learning_rate, eps=1e-5), net_cfg=net_cfg,
        normalizer=ObservationNormalizer(run.obs_shapes) if args.norm_obs else None,
        scaler=RewardScaler(run.num_agents, args.gamma) if args.norm_reward else None,
    )  # fmt: skip


def _learner_from(run: Run, source: Path) -> Learner:
    """A learner whose network and observation statistics are the policy at ``source`` (``--init-from``): the
    reward scaler starts afresh (the new task's rewards), and with ``--kl-to-init`` a frozen copy is the
    reference.

    The start is fitted to this run's layout as :meth:`GreedyPolicy.for_fleet` flies it at another fleet size or
    passenger window (the same weights: the network reads the other taxis and the passengers as sets; their
    normaliser statistics pooled over the rows). Its actor and torso are always loaded; its critic when it reads
    this run's input (own features, or a global state of the same fleet and passenger count), else only with
    ``--reinit-critic``, which starts it afresh and says so."""
    args = run.args
    start, trained_on = _fitted_start(run, source)
    if set(start.obs_shapes or {}) != set(run.obs_shapes):
        unread = sorted(set(run.obs_shapes) - set(start.obs_shapes or {}))
        raise ConfigError(
            f"--init-from={args.init_from!r} reads {sorted(start.obs_shapes or {})}, but this run's env also observes "
            f"{unread}, which its network has no weights for; train that policy from scratch, or use a scenario "
            "without those fields."
        )
    hover_logit = start.net.cfg.hover_logit or args.hover_logit  # an untrained switch keeps every weight
    net_cfg = dataclasses.replace(start.net.cfg, critic_state_dim=run.state_dim or None, hover_logit=hover_logit)
    _check_hover_logit(net_cfg, run.cfg)
    net = MSHAActorCritic(run.venv.single_observation_space, net_cfg).to(run.device)
    weights = start.net.state_dict()
    critic_reads = _critic_input(start.net.cfg.critic_state_dim, trained_on)
    if critic_reads == _critic_input(net_cfg.critic_state_dim, run.cfg) and not args.reinit_critic:
        net.load_state_dict(weights)
    elif not args.reinit_critic:
        raise ConfigError(
            f"--init-from={args.init_from!r}: its critic reads {critic_reads}, this run's would read "
            f"{_critic_input(net_cfg.critic_state_dim, run.cfg)}; add --reinit-critic to start the critic afresh "
            "(the actor and its torso are still the start's), or train at the start's fleet size and load."
        )
    else:
        missing, unexpected = net.load_state_dict(
            {k: v for k, v in weights.items() if not k.startswith("critic.")}, strict=False
        )
        assert all(k.startswith("critic.") for k in missing) and not unexpected, (missing, unexpected)
        if run.ranks.is_main:
            print(f"--init-from={args.init_from!r}: actor and torso loaded; critic re-initialised (--reinit-critic): "
                  f"the start's read {critic_reads}, this run's reads "
                  f"{_critic_input(net_cfg.critic_state_dim, run.cfg)}")  # fmt: skip
    net.train()
    reference = None
    if args.kl_to_init > 0:
        reference = copy.deepcopy(net).eval().requires_grad_(False)
    return Learner(
        net=net, optimizer=torch.optim.Adam(net.parameters(), lr=args.learning_rate, eps=1e-5), net_cfg=net_cfg,
        normalizer=start.normalizer if args.norm_obs else None,
        scaler=RewardScaler(run.num_agents, args.gamma) if args.norm_reward else None, reference=reference,
    )  # fmt: skip


def _check_hover_logit(net_cfg: NetConfig, cfg: EnvConfig) -> None:
    """ConfigError when the network takes the hover action (``NetConfig.hover_logit``) but the run's env has none."""
    if net_cfg.hover_logit and not cfg.hover_action:
        raise ConfigError(
            "--hover-logit makes the network take the hover action (16), which this run's env lacks: train on a "
            "scenario with EnvConfig.hover_action (a *_fleet preset), or drop --hover-logit."
        )


def _fitted_start(run: Run, source: Path) -> tuple[GreedyPolicy, EnvConfig]:
    """The ``--init-from`` policy laid out for this run (its fleet size and passenger window or axis: the largest
    fleet of a mixture), and the config it trained on; ConfigError naming every field whose meaning differs from
    this run's."""
    start, _ = load_policy(source, device=str(run.device))
    assert start.trained_on is not None, "load_policy always gives the config it trained on"
    trained_on = start.trained_on
    window = run.cfg.passenger_window
    slots = None if window is not None else run.cfg.num_passengers
    try:
        start = start.for_fleet(run.cfg.num_taxis, passenger_slots=slots, passenger_window=window)
    except ValueError as err:
        raise ConfigError(f"--init-from={run.args.init_from!r} cannot fly this run's layout: {err}") from None
    assert start.trained_on is not None
    read = observation_layout(start.trained_on)
    differences = layout_differences(read, {k: spec for k, spec in run.layout.items() if k in read})
    if differences:
        raise ConfigError(
            f"--init-from={run.args.init_from!r} reads another observation than this run's env (start vs run): "
            + "; ".join(differences)
            + "; train that policy from scratch, or match its scenario's layout."
        )
    return start, trained_on


def _critic_input(state_dim: int | None, cfg: EnvConfig) -> str:
    """What a critic reads, in words: its own features, or the global state of a fleet and passenger count."""
    if state_dim is None:
        return "each taxi's own features"
    return f"the global state of {cfg.num_taxis} taxi(s) and {cfg.num_passengers} passenger(s) ({state_dim} values)"


def capture(run: Run, learner: Learner, counters: Counters) -> Checkpoint:
    """A checkpoint of the current state (copies: training goes on changing the live tensors)."""
    cuda = torch.cuda.get_rng_state(run.device) if run.device.type == "cuda" else None
    return Checkpoint(
        model=copy.deepcopy(learner.net.state_dict()), optimizer=copy.deepcopy(learner.optimizer.state_dict()),
        net_config=dataclasses.asdict(learner.net_cfg), args=plain_args(run.args),
        obs_shapes={k: list(v) for k, v in run.obs_shapes.items()}, obs_layout=layout_to_dict(run.layout),
        iteration=counters.iteration,
        global_step=counters.global_step, wall_s=counters.wall_offset + time.time() - run.start_time,
        obs_normalizer=learner.normalizer.state_dict() if learner.normalizer is not None else None,
        reward_scaler=learner.scaler.rms.state_dict() if learner.scaler is not None else None,
        best_eval=dict(counters.best_eval), best_step=counters.best_step, target_step=counters.target_step,
        target_s=counters.target_s, torch_rng=torch.get_rng_state(), numpy_rng=numpy_rng_state(), cuda_rng=cuda,
    )  # fmt: skip


def restore(ckpt: Checkpoint, run: Run, learner: Learner) -> Counters:
    ckpt.check_matches(run.args, run.obs_shapes, layout=run.layout)
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
            data = (run.folder / "last.pt").read_bytes() if run.args.resume else None
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
    obs, _ = run.venv.reset(seed=run.args.seed + run.env_offset)  # global env e gets seed + e
    run.obs = run.flat(obs)
    return counters, rows


# ---- one PPO iteration in named parts -----------------------------------------------------------------------


@dataclass
class RolloutStats:
    term_sums: np.ndarray  # [terms] reward term totals of this rank
    episodes: EpisodeSums


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
        learner.normalizer.update(obs, run.ranks)
    return learner.normalizer(obs)


def collect_rollout(run: Run, learner: Learner) -> RolloutStats:
    """num_steps steps of this rank's envs into ``run.buffer``; actions sampled from the current policy."""
    buf, net, dev = run.buffer, learner.net, run.device
    term_sums, episodes = np.zeros(len(REWARD_TERMS)), EpisodeSums()
    for step in range(run.args.num_steps):
        norm_obs = normalise(run, learner, run.obs, update=True)
        for key, value in norm_obs.items():
            buf.obs[key][step] = value
        state = run.global_state()
        if buf.state is not None and state is not None:
            buf.state[step] = state
        with torch.inference_mode():
            logits, value = net(obs_to_torch(norm_obs, dev), state=_tensor(state, dev))  # [N, 16], [N]
            action = sample_actions(logits, run.agent_offset, run.total_agents)  # [N]
            logprob = Categorical(logits=logits).log_prob(action)  # [N]
        buf.actions[step] = action.cpu().numpy()
        buf.logprobs[step] = logprob.cpu().numpy()
        buf.values[step] = value.cpu().numpy()
        next_obs, rewards, terminated, truncated, info = run.venv.step(run.env_actions(buf.actions[step]))
        term_sums += info["reward_terms"].sum(axis=(0, 1))  # (a mixture's padding taxis add zeros)
        done = terminated | truncated  # [E]
        buf.terminated[step] = run.per_agent(terminated)
        buf.truncated[step] = run.per_agent(truncated)
        buf.rewards[step] = run.per_agent(rewards)
        if learner.scaler is not None and not run.ranks.active:
            buf.rewards[step] = learner.scaler(buf.rewards[step], run.per_agent(done))
        if truncated.any():  # bootstrap a time limit from the real final observation
            final = normalise(run, learner, run.flat(info["final_obs"]), update=False)
            with torch.inference_mode():
                _, final_value = net(obs_to_torch(final, dev), state=_tensor(state, dev))
            buf.final_values[step] = final_value.cpu().numpy()
        for e in np.flatnonzero(done):
            episodes.add(run.finished_episode(info["episode"], int(e)), 0)
        run.obs = run.flat(next_obs)
    if learner.scaler is not None and run.ranks.active:  # all steps' statistics in one all-reduce
        buf.rewards[:] = learner.scaler.scale_rollout(buf.rewards, buf.terminated | buf.truncated, run.ranks)
    return RolloutStats(term_sums, episodes)


def compute_advantages(run: Run, learner: Learner) -> tuple[np.ndarray, np.ndarray]:
    """GAE over this rank's rollout: (advantages [T, N], returns [T, N])."""
    buf = run.buffer
    with torch.inference_mode():
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
    args, buf, dev, ranks = run.args, run.buffer, run.device, run.ranks
    minibatch_size = run.batch_size // args.num_minibatches
    adv = torch.as_tensor(advantages.reshape(-1), dtype=torch.float32, device=dev)
    ret = torch.as_tensor(returns.reshape(-1), dtype=torch.float32, device=dev)
    val = torch.as_tensor(buf.values.reshape(-1), dtype=torch.float32, device=dev)
    global_adv = torch.as_tensor(
        ranks.gather_agents(advantages, run.agent_offset, run.total_agents).reshape(-1),
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
            dist, new_value = learner.net.policy_and_value(mb_obs, state=mb_state)
            new_logprob, entropy = dist.log_prob(mb_actions.long()), dist.entropy()  # [B], [B]
            stats, denominator = None, None
            if ranks.active:
                stats, denominator = (global_adv[idx].mean(), global_adv[idx].std()), len(idx)
            loss, info = ppo_loss(
                new_logprob, mb_logprobs, entropy, new_value, val[local], adv[local], ret[local], args.clip_coef,
                args.vf_coef, args.ent_coef, args.clip_vloss, args.norm_adv, stats, denominator,
            )  # fmt: skip
            if learner.reference is not None:
                with torch.no_grad():
                    reference_logits = learner.reference.masked_logits(mb_obs)  # [B, 16]
                kl = categorical_kl(dist.logits, reference_logits)  # [B]
                kl_mean = kl.mean() if denominator is None else kl.sum() / denominator
                loss = loss + args.kl_to_init * kl_mean
                info = dataclasses.replace(info, kl_to_init=float(kl_mean.detach()))
            learner.optimizer.zero_grad()
            (loss * share).backward()
            summed = ranks.all_reduce_grads(params, share * np.array(dataclasses.astuple(info)))
            infos.append(PPOLossInfo(*(float(x) for x in summed)))
            torch.nn.utils.clip_grad_norm_(params, args.max_grad_norm)
            learner.optimizer.step()
        if args.target_kl is not None and infos[-1].approx_kl > args.target_kl:
            break
    return infos


def _local_indices(run: Run, idx: np.ndarray) -> tuple[np.ndarray, float]:
    """This rank's samples of a global minibatch as flat indices into its buffer, and 1.0; a rank with no
    sample in it takes sample 0 with weight 0.0 (it must still join the gradient all-reduce)."""
    if not run.ranks.active:
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


def evaluate_start(run: Run, learner: Learner, counters: Counters) -> dict[str, float]:
    """Rank 0, before a run from ``--init-from`` trains: the start's greedy evaluation becomes the best so far and
    best.pt, so fine-tuning keeps the start unless an evaluation beats it. Its row (iteration 0) goes to
    progress.csv."""
    row: dict[str, float] = {"iteration": 0, "global_step": 0, "wall_s": time.time() - run.start_time}
    evaluate_greedy(run, learner, counters, row)
    capture(run, learner, counters).save(run.folder / "best.pt")
    return row


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
    ranks, device = Ranks.from_env(args.device, args.backend)
    args = with_init_architecture(args)
    claim = claim_folder(args, ranks)  # before any env or table is built: a second run of the name fails at once
    try:
        run = make_run(args, env_config, ranks, device)
        try:
            return _train(run, on_iteration, claim)
        finally:
            if isinstance(run.venv, ShardedVectorEnv):
                run.venv.close()  # the env workers stop with the training, however it ends
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
            claim = claim_run(args.run_dir, args.name, resume=args.resume, overwrite=args.overwrite)
            if args.resume:
                read_progress(claim.folder / "progress.csv", required=("iteration",))
        except Exception as err:
            if claim is not None:
                claim.release()
            error = err
    if not ranks.broadcast_flag(error is None):
        if error is not None:
            raise error
        raise RankZeroError(f"rank 0 could not claim the run folder {args.run_dir / args.name}; its error says why.")
    return claim


def _train(
    run: Run, on_iteration: Callable[[int, torch.nn.Module], None] | None, claim: RunClaim | None
) -> TrainResult:
    args, ranks = run.args, run.ranks
    learner = make_learner(run)
    counters, rows = start(run, learner, claim)
    if args.init_from is not None and counters.iteration == 0 and ranks.is_main:
        rows.append(evaluate_start(run, learner, counters))
    if counters.iteration >= run.num_iterations:
        _say_finished(run, counters)
        return _result(run, counters, rows, interrupted=False)
    log = open_log(run, counters)
    snapshot = capture(run, learner, counters) if ranks.is_main else None
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
            stop, new_best = evaluate_and_decide(run, learner, counters, row, iteration)
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


def _say_finished(run: Run, counters: Counters) -> None:
    if run.ranks.is_main:
        print(f"{run.folder} is finished ({counters.iteration} of {run.num_iterations} iterations, "
              f"{counters.global_step:,} agent-steps); raise --total-timesteps to train it further")  # fmt: skip


def open_log(run: Run, counters: Counters) -> Logger | None:
    """Rank 0's logger (None on the other ranks); a resumed run says where it goes on."""
    if not run.ranks.is_main:
        return None
    resumed_at = counters.global_step if run.args.resume else None
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
    out_of_time = args.max_wall_s is not None and time.time() - run.start_time >= args.max_wall_s
    last = ranks.broadcast_flag(iteration == run.num_iterations - 1 or out_of_time)
    new_best = False
    if ranks.is_main and ((args.eval_every and (iteration + 1) % args.eval_every == 0) or last):
        new_best = evaluate_greedy(run, learner, counters, row)
    counters.iteration = iteration + 1
    stop = ranks.broadcast_flag(last or (counters.target_step is not None and args.stop_at_td_m is not None))
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
    if stop or counters.iteration % run.args.checkpoint_every == 0:
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
        rank=run.ranks.rank,
    )  # fmt: skip


def _tensor(x: np.ndarray | None, device: torch.device) -> torch.Tensor | None:
    return None if x is None else torch.as_tensor(x, dtype=torch.float32, device=device)


__all__ = [
    "ARCHITECTURE_FIELDS", "CHECKPOINT_FORMAT", "ENVIRONMENT_FIELDS", "RUN_FILES", "RUN_NAME", "Checkpoint",
    "CheckpointError", "GreedyPolicy", "Logger", "TrainArgs", "TrainResult", "checkpoint_args", "collect_rollout",
    "compute_advantages", "evaluate", "load_policy", "make_env_config", "ppo_update", "read_progress", "run_folder",
    "train", "upgrade_checkpoint",
]  # fmt: skip
