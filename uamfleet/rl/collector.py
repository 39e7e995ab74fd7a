"""The collector of PPO's rollouts: the run's envs and buffer (:class:`Run`), and :func:`collect_rollout`.

:func:`make_run` builds one rank's share of a run from its options: its world, what it observes there (its observer
spec: :func:`run_observer`), the training envs (one config, a mixture over ``--thresholds`` and ``--fleet-mixture``,
or env workers, all observed by that spec), the rollout buffer and the agents' rows.
:func:`collect_rollout` flies the acting network (with its observation normaliser and reward scaler) for
``num_steps`` steps of those envs into the buffer; it never sees the optimiser, so the learner
(:mod:`uamfleet.rl.learner`) and the loop (:mod:`uamfleet.rl.trainer`) build on it, never it on them.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch
from torch.distributions import Categorical

from uamfleet.config import REWARD_TERMS, ConfigError, EnvConfig
from uamfleet.env.backends import VectorBackend, make_vector
from uamfleet.observe.legacy import observed_config, split_env_config
from uamfleet.observe.spec import Layout, ObserverSpec, layout_shapes
from uamfleet.rl.buffer import EpisodeSums, ObservationNormalizer, RewardScaler, RolloutBuffer
from uamfleet.rl.checkpoint import Checkpoint, checkpoint_source, run_config
from uamfleet.rl.legacy import spec_of
from uamfleet.rl.distributed import Ranks, sample_actions
from uamfleet.rl.networks import VARIANTS, MSHAActorCritic, obs_to_torch
from uamfleet.rl.options import TrainArgs


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
    cfg: EnvConfig  # the run's world (its largest fleet in a mixture), joined with the fields its spec observes
    eval_cfg: EnvConfig  # the world of its greedy evaluation, joined likewise
    spec: ObserverSpec  # what every env of the run observes (run_observer)
    venv: VectorBackend  # inline, a mixture or env workers (uamfleet.env.backends)
    obs_shapes: dict[str, tuple[int, ...]]
    layout: Layout  # one taxi's observation in the run's world: spec.layout(cfg) (stored in checkpoints)
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
    obs_stats_frozen: bool = False  # after a search warm start: its network was fitted on these statistics

    @property
    def batch_size(self) -> int:  # global
        return self.args.ppo.num_steps * self.total_agents

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
        taxis = int(self.venv.taxis_per_env[e])
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
    if args.net.variant not in VARIANTS:
        raise ValueError(f"variant={args.net.variant!r} is unknown; use one of {VARIANTS}.")
    env_offset, local_envs = ranks.shard(args.env.num_envs)
    base: str | EnvConfig = env_config if env_config is not None else args.env.scenario
    own = run_config(args, base, training=True)
    spec = run_observer(args, own)
    cfg = observed(args, own, spec)
    eval_cfg = observed(args, run_config(args, base, training=False), spec)
    venv = _training_envs(args, cfg, spec, base, local_envs)
    taxis = cfg.num_taxis  # taxis per env (a mixture of fleet sizes: its largest, padded; --num-taxis)
    shapes = {k: tuple(s.shape or ()) for k, s in venv.single_observation_space.spaces.items()}
    layout = spec.layout(cfg)
    assert layout_shapes(layout) == shapes, "the env's observation is built from its spec"
    state_dim = _critic_state_dim(args, venv)
    rows = None
    if venv.mixed_sizes:
        if ranks.active:
            raise ConfigError(
                f"--fleet-mixture={list(args.env.fleet_mixture)} mixes fleet sizes, whose agents do not split evenly "
                "among torchrun ranks; train it in one process."
            )
        real = np.arange(venv.num_taxis)[None, :] < venv.taxis_per_env[:, None]  # [E, A_max]
        rows = np.flatnonzero(real.reshape(-1))
    local_agents = local_envs * taxis if rows is None else len(rows)
    total_agents = args.env.num_envs * taxis if rows is None else len(rows)
    batch = args.ppo.num_steps * total_agents
    _check_batch(args, batch, taxis)
    return Run(
        args=args, ranks=ranks, device=device, folder=args.run.run_dir / args.name, cfg=cfg, eval_cfg=eval_cfg,
        spec=spec, venv=venv, obs_shapes=shapes, layout=layout,
        buffer=RolloutBuffer(args.ppo.num_steps, local_agents, shapes, state_dim), env_offset=env_offset,
        num_agents=local_agents, agent_offset=env_offset * taxis, total_agents=total_agents,
        num_iterations=max(1, args.ppo.total_timesteps // batch), state_dim=state_dim, agent_rows=rows,
    )  # fmt: skip


def run_observer(args: TrainArgs, cfg: EnvConfig) -> ObserverSpec:
    """What a run's envs observe, ``cfg`` being its own config (:func:`~uamfleet.rl.checkpoint.run_config`).

    Without ``--init-from``: the observer fields of ``cfg`` (:func:`~uamfleet.observe.legacy.split_env_config`),
    each world read with its own passenger rows and time limit, as every env of the run always read them. With it:
    the spec the start reads (stored in its checkpoint; rebuilt for a file of format 2,
    :func:`~uamfleet.rl.legacy.spec_of`), with the run's own ``--passenger-window`` K when given
    (``passenger_window=K``, ``time_scale_steps=None``). ``hover`` is the network's: ``--hover-logit``, or the
    start's hover logit."""
    if args.net.init_from is None:
        own = split_env_config(cfg)[1]
        return dataclasses.replace(own, slots_per_taxi=None, time_scale_steps=None, hover=args.net.hover_logit)
    source = checkpoint_source(args.net.init_from)
    spec = spec_of(Checkpoint.load(source, map_location="cpu"), str(source))
    window = args.observer.passenger_window
    if window is not None:
        spec = dataclasses.replace(spec, passenger_window=window, time_scale_steps=None)
    return dataclasses.replace(spec, hover=spec.hover or args.net.hover_logit)


def observed(args: TrainArgs, world: EnvConfig, spec: ObserverSpec) -> EnvConfig:
    """``world`` (a config of the run: its world is kept) joined with the fields ``spec`` observes
    (:func:`~uamfleet.observe.legacy.observed_config`); ConfigError in one line naming the flag when ``spec``
    cannot read the world (:meth:`~uamfleet.observe.spec.ObserverSpec.reads`)."""
    if spec.hover and not world.hover_action:
        raise ConfigError(HOVER_WITHOUT_ACTION)
    refusal = spec.reads(world)
    if refusal is not None:
        start = f"--init-from={args.net.init_from!r}" if args.net.init_from is not None else "the run's observer"
        raise ConfigError(f"{start} cannot read this run's world: {refusal}.")
    return observed_config(world, spec)[0]


HOVER_WITHOUT_ACTION = (
    "--hover-logit makes the network take the hover action (16), which this run's env lacks: train on a scenario "
    "with EnvConfig.hover_action (a *_fleet preset), or drop --hover-logit (and start from a policy without it)."
)
"""The refusal of a network that takes the hover action in a world without it."""


def _critic_state_dim(args: TrainArgs, venv: VectorBackend) -> int:
    """Size of the centralised critic's state (the env state and a one-hot of the taxi); 0 without one.
    ConfigError for a mixture whose settings' global states differ in size (no one critic input holds them)."""
    if not args.net.centralised_critic:
        return 0
    if venv.state_space is None:
        raise ConfigError(
            f"--centralised-critic reads one global state, but the settings of --fleet-mixture="
            f"{list(args.env.fleet_mixture)} have states of different sizes (taxis and passengers); train with "
            "--no-centralised-critic (the critic reads each taxi's own features, of any fleet), and with an "
            "--init-from policy whose critic is centralised add --reinit-critic."
        )
    return int(venv.state_space.shape[0]) + venv.num_taxis


def _training_envs(
    args: TrainArgs, cfg: EnvConfig, spec: ObserverSpec, base: str | EnvConfig, local_envs: int
) -> VectorBackend:
    """This rank's training envs, observed by ``spec``: one config, or a mixture over ``--thresholds`` and
    ``--fleet-mixture``, stepped by ``--vector-backend`` (auto: env workers with ``--env-workers``, else a mixture
    with either option, else one config's envs); tables filled if asked."""
    cfgs = [observed(args, c, spec) for c in training_configs(args, cfg, base)]
    # Random demand reads every row of the distance tables within minutes: compute them now (or load them from the
    # disk cache), instead of a few Dijkstras in every new episode's reset.
    fill = args.env.fill_tables and cfg.stop_features and cfg.requests is None
    backend = args.chosen_backend()
    if backend != "workers":
        return make_vector(cfgs, local_envs, backend, fill_tables=fill, observer=spec)
    if args.env.env_workers > local_envs:
        raise ConfigError(
            f"--env-workers={args.env.env_workers} exceeds this rank's {local_envs} envs; give at most "
            f"{local_envs} (each worker steps one env at least), or more --num-envs."
        )
    try:
        # copy=False: collect_rollout copies each observation into its buffer before it steps again
        return make_vector(
            cfgs, local_envs, backend, workers=args.env.env_workers, global_state=args.net.centralised_critic,
            fill_tables=fill, copy=False, observer=spec,
        )  # fmt: skip
    except ValueError as err:
        raise ConfigError(f"--env-workers={args.env.env_workers}: {err}") from err


def training_configs(args: TrainArgs, cfg: EnvConfig, base: str | EnvConfig) -> list[EnvConfig]:
    """The worlds of the training envs' groups: ``cfg`` (the run's) at each ``--thresholds`` value, in each
    ``--fleet-mixture`` setting (threshold-major); ``[cfg]`` without either. The run's observer reads them all."""
    settings = [cfg]
    if args.env.fleet_mixture:
        if not isinstance(base, str):
            raise ConfigError(
                f"--fleet-mixture={list(args.env.fleet_mixture)} draws each setting from a *_fleet scenario by name; "
                "it cannot vary a config given as an EnvConfig (train one setting, or name the scenario)."
            )
        settings = [
            run_config(args.with_options(num_taxis=taxis, num_requests=requests, fleet_mixture=()), base)
            for taxis, requests in args.fleet_settings()
        ]  # the run's own options (window, time limit, reward) in each setting
    if not args.env.thresholds:
        return settings
    return [c.replace(sinr_min_db=t) for t in args.env.thresholds for c in settings]


def _check_batch(args: TrainArgs, batch: int, taxis: int) -> None:
    """ConfigError unless an iteration's ``batch`` of agent-steps fits the run and splits into the minibatches."""
    ppo = args.ppo
    if ppo.total_timesteps < batch or ppo.num_minibatches > batch:
        raise ConfigError(
            f"--total-timesteps={ppo.total_timesteps} and --num-minibatches={ppo.num_minibatches} need at least "
            f"one iteration's batch of {batch} agent-steps (--num-steps {ppo.num_steps} x --num-envs "
            f"{args.env.num_envs} x {taxis} taxi(s)) to split; raise --total-timesteps to >= {batch} or lower "
            "--num-envs / --num-steps."
        )
    if batch % ppo.num_minibatches:  # else the last minibatch would be a silent extra, smaller update
        divisor = max(d for d in range(1, ppo.num_minibatches) if batch % d == 0)
        raise ConfigError(
            f"--num-minibatches={ppo.num_minibatches} does not divide the batch of {batch} agent-steps (--num-steps "
            f"x --num-envs x taxis); choose a divisor of {batch}, e.g. {divisor}."
        )


@dataclass
class RolloutStats:
    term_sums: np.ndarray  # [terms] reward term totals of this rank
    episodes: EpisodeSums


def normalise(
    run: Run, normalizer: ObservationNormalizer | None, obs: dict[str, np.ndarray], update: bool
) -> dict[str, np.ndarray]:
    """``obs`` standardised by ``normalizer`` (unchanged without one); with ``update`` its statistics first take
    ``obs`` in, pooled over the run's ranks, unless the run's statistics are frozen (:attr:`Run.obs_stats_frozen`)."""
    if normalizer is None:
        return obs
    if update and not run.obs_stats_frozen:
        normalizer.update(obs, run.ranks)
    return normalizer(obs)


def collect_rollout(
    run: Run, net: MSHAActorCritic, normalizer: ObservationNormalizer | None, scaler: RewardScaler | None
) -> RolloutStats:
    """num_steps steps of this rank's envs into ``run.buffer``; actions sampled from ``net`` on the observations
    ``normalizer`` standardises (and updates), rewards scaled by ``scaler`` when given."""
    buf, dev = run.buffer, run.device
    term_sums, episodes = np.zeros(len(REWARD_TERMS)), EpisodeSums()
    for step in range(run.args.ppo.num_steps):
        norm_obs = normalise(run, normalizer, run.obs, update=True)
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
        if scaler is not None and not run.ranks.active:
            buf.rewards[step] = scaler(buf.rewards[step], run.per_agent(done))
        if truncated.any():  # bootstrap a time limit from the real final observation
            final = normalise(run, normalizer, run.flat(info["final_obs"]), update=False)
            with torch.inference_mode():
                _, final_value = net(obs_to_torch(final, dev), state=_tensor(state, dev))
            buf.final_values[step] = final_value.cpu().numpy()
        for e in np.flatnonzero(done):
            episodes.add(run.finished_episode(info["episode"], int(e)), 0)
        run.obs = run.flat(next_obs)
    if scaler is not None and run.ranks.active:  # all steps' statistics in one all-reduce
        buf.rewards[:] = scaler.scale_rollout(buf.rewards, buf.terminated | buf.truncated, run.ranks)
    return RolloutStats(term_sums, episodes)


def _critic_input(state_dim: int | None, cfg: EnvConfig) -> str:
    """What a critic reads, in words: its own features, or the global state of a fleet and passenger count."""
    if state_dim is None:
        return "each taxi's own features"
    return f"the global state of {cfg.num_taxis} taxi(s) and {cfg.num_passengers} passenger(s) ({state_dim} values)"


def _tensor(x: np.ndarray | None, device: torch.device) -> torch.Tensor | None:
    return None if x is None else torch.as_tensor(x, dtype=torch.float32, device=device)


def restore_counters(ckpt: Checkpoint) -> Counters:
    best = {k: float(v) for k, v in ckpt.best_eval.items()}
    return Counters(
        ckpt.iteration, ckpt.global_step, ckpt.wall_s, best, ckpt.best_step, ckpt.target_step, ckpt.target_s
    )


__all__ = [
    "HOVER_WITHOUT_ACTION", "Counters", "RolloutStats", "Run", "collect_rollout", "make_run", "normalise",
    "observed", "restore_counters", "run_observer", "training_configs",
]  # fmt: skip
