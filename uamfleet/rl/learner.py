"""The learner of PPO: the network, its optimiser and statistics (:class:`Learner`), and the update.

:func:`make_learner` builds it for a run (afresh, or from an ``--init-from`` policy fitted to the run's world);
:func:`set_schedules` sets the iteration's learning rate and shaping weight, :func:`compute_advantages` computes
GAE over the collected rollout (bootstrapping truncated episodes from their real final observation) and
:func:`ppo_update` runs the clipped PPO loss (:mod:`uamfleet.rl.ppo`) over its minibatches, data-parallel under
``torchrun`` (:mod:`uamfleet.rl.distributed`).
"""

from __future__ import annotations

import copy
import dataclasses
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import torch

from uamfleet.config import ConfigError, EnvConfig
from uamfleet.observe.spec import layout_differences
from uamfleet.rl.buffer import ObservationNormalizer, RewardScaler, compute_gae
from uamfleet.rl.checkpoint import ARCHITECTURE_FIELDS, Checkpoint, checkpoint_source
from uamfleet.rl.collector import HOVER_WITHOUT_ACTION, Run, _critic_input, _tensor, normalise
from uamfleet.rl.legacy import checkpoint_args
from uamfleet.rl.networks import MSHAActorCritic, NetConfig, obs_to_torch, observed_inputs
from uamfleet.rl.options import TrainArgs
from uamfleet.rl.policy import GreedyPolicy, load_policy
from uamfleet.rl.ppo import PPOLossInfo, categorical_kl, ppo_loss


@dataclass
class Learner:
    """What PPO trains and keeps between iterations, identical on every rank."""

    net: MSHAActorCritic
    optimizer: torch.optim.Optimizer
    net_cfg: NetConfig
    normalizer: ObservationNormalizer | None
    scaler: RewardScaler | None
    reference: MSHAActorCritic | None = None  # the --init-from policy, frozen, for the --kl-to-init term


def make_learner(run: Run) -> Learner:
    args = run.args
    np.random.seed(args.ppo.seed)
    torch.manual_seed(args.ppo.seed)
    if args.net.init_from is not None:
        return _learner_from(run, checkpoint_source(args.net.init_from))
    options = args.net
    net_cfg = NetConfig(
        variant=options.variant, d_model=options.d_model, num_heads=options.num_heads,
        local_window=options.local_window, readout=options.readout, critic_state_dim=run.state_dim or None,
        action_head=options.action_head, stop_free_move=options.stop_free_move, stop_prior=options.stop_prior,
        hover_logit=options.hover_logit,
        **observed_inputs(run.layout, options.variant, options.action_head),  # from the env's spec
    )  # fmt: skip
    _check_hover_logit(net_cfg, run.cfg)
    net = MSHAActorCritic(run.venv.single_observation_space, net_cfg).to(run.device)
    return Learner(
        net=net, optimizer=torch.optim.Adam(net.parameters(), lr=args.ppo.learning_rate, eps=1e-5), net_cfg=net_cfg,
        normalizer=ObservationNormalizer(run.obs_shapes) if args.ppo.norm_obs else None,
        scaler=RewardScaler(run.num_agents, args.ppo.gamma) if args.ppo.norm_reward else None,
    )  # fmt: skip


def _learner_from(run: Run, source: Path) -> Learner:
    """A learner whose network and observation statistics are the policy at ``source`` (``--init-from``): the
    reward scaler starts afresh (the new task's rewards), and with ``--kl-to-init`` a frozen copy is the
    reference.

    The start reads the run's spec (:attr:`Run.spec`: its own, with the run's window) and fits itself to the run's
    world (:meth:`GreedyPolicy.fit`: the same weights; the network reads the other taxis and the passengers as sets,
    their normaliser statistics pooled over the rows when their number differs). Its actor and torso are always
    loaded; its critic when it reads this run's input (own features, or a global state of the same fleet and
    passenger count), else only with ``--reinit-critic``, which starts it afresh and says so."""
    args = run.args
    start, trained_on = _fitted_start(run, source)
    start_net, normalizer, shapes = start.fitted()
    if set(shapes or {}) != set(run.obs_shapes):
        unread = sorted(set(run.obs_shapes) - set(shapes or {}))
        raise ConfigError(
            f"--init-from={args.net.init_from!r} reads {sorted(shapes or {})}, but this run's env also "
            f"observes {unread}, which its network has no weights for; train that policy from scratch, or use a "
            "scenario without those fields."
        )
    hover_logit = start_net.cfg.hover_logit or args.net.hover_logit  # an untrained switch keeps every weight
    net_cfg = dataclasses.replace(start_net.cfg, critic_state_dim=run.state_dim or None, hover_logit=hover_logit)
    _check_hover_logit(net_cfg, run.cfg)
    net = MSHAActorCritic(run.venv.single_observation_space, net_cfg).to(run.device)
    _load_start(run, net, start_net, trained_on)
    net.train()
    reference = None
    if args.net.kl_to_init > 0:
        reference = copy.deepcopy(net).eval().requires_grad_(False)
    return Learner(
        net=net, optimizer=torch.optim.Adam(net.parameters(), lr=args.ppo.learning_rate, eps=1e-5), net_cfg=net_cfg,
        normalizer=normalizer if args.ppo.norm_obs else None,
        scaler=RewardScaler(run.num_agents, args.ppo.gamma) if args.ppo.norm_reward else None, reference=reference,
    )  # fmt: skip


def _load_start(run: Run, net: MSHAActorCritic, start: MSHAActorCritic, trained_on: EnvConfig) -> None:
    """Load the start's weights into ``net``: all of them when its critic reads this run's input, else (with
    ``--reinit-critic``) all but the critic's, which start afresh; ConfigError without ``--reinit-critic``."""
    init_from, reinit = run.args.net.init_from, run.args.net.reinit_critic
    critic_reads = _critic_input(start.cfg.critic_state_dim, trained_on)
    run_reads = _critic_input(net.cfg.critic_state_dim, run.cfg)
    weights = start.state_dict()
    if critic_reads == run_reads and not reinit:
        net.load_state_dict(weights)
        return
    if not reinit:
        raise ConfigError(
            f"--init-from={init_from!r}: its critic reads {critic_reads}, this run's would read {run_reads}; add "
            "--reinit-critic to start the critic afresh (the actor and its torso are still the start's), or train "
            "at the start's fleet size and load."
        )
    missing, unexpected = net.load_state_dict(
        {k: v for k, v in weights.items() if not k.startswith("critic.")}, strict=False
    )
    assert all(k.startswith("critic.") for k in missing) and not unexpected, (missing, unexpected)
    if run.ranks.is_main:
        print(f"--init-from={init_from!r}: actor and torso loaded; critic re-initialised (--reinit-critic): "
              f"the start's read {critic_reads}, this run's reads {run_reads}")  # fmt: skip


def with_init_architecture(args: TrainArgs) -> TrainArgs:
    """``args`` with the architecture options of the ``--init-from`` policy (its network is what trains), so the
    run's checkpoints state what they hold; unchanged without ``init_from``. With ``--reinit-critic`` the critic
    starts afresh, so ``--centralised-critic`` stays the run's own. ConfigError when the start lies in the run's own
    folder (replacing the run would delete the file its checkpoints point at)."""
    if args.net.init_from is None:
        return args
    source = checkpoint_source(args.net.init_from)
    folder = (args.run.run_dir / args.name).resolve()
    if folder in source.resolve().parents:
        raise ConfigError(
            f"--init-from={args.net.init_from!r} lies inside this run's own folder {folder}; copy it elsewhere or "
            "choose another --run-name."
        )
    start = checkpoint_args(Checkpoint.load(source, map_location="cpu"))
    if args.net.centralised_critic != start.net.centralised_critic and not args.net.reinit_critic:
        reads = "the global state" if start.net.centralised_critic else "its own features"
        raise ConfigError(
            f"--centralised-critic={args.net.centralised_critic} differs from the --init-from policy's "
            f"({start.net.centralised_critic}): its critic reads {reads}; set --centralised-critic "
            f"{start.net.centralised_critic}, or add --reinit-critic to start the critic afresh."
        )
    # (what the run observes, look-ahead included, is the start's spec (collector.run_observer), not these flags)
    taken = [name for name in ARCHITECTURE_FIELDS if not (args.net.reinit_critic and name == "centralised_critic")]
    return dataclasses.replace(
        args, net=dataclasses.replace(args.net, **{name: getattr(start.net, name) for name in taken})
    )


def _check_hover_logit(net_cfg: NetConfig, cfg: EnvConfig) -> None:
    """ConfigError when the network takes the hover action (``NetConfig.hover_logit`` or ``hover_anytime``) but the
    run's env has none."""
    if net_cfg.hover_logit and not cfg.hover_action:
        raise ConfigError(HOVER_WITHOUT_ACTION)
    if net_cfg.hover_anytime and not cfg.hover_action:
        raise ConfigError(
            "the start's network takes the hover action (16) at any step (NetConfig.hover_anytime), which this "
            "run's env lacks: train on a scenario with EnvConfig.hover_action (a *_fleet preset), or start from a "
            "policy without it."
        )


def _fitted_start(run: Run, source: Path) -> tuple[GreedyPolicy, EnvConfig]:
    """The ``--init-from`` policy reading this run's spec, fitted to its world (the largest fleet of a mixture;
    :meth:`GreedyPolicy._acting` gives the network, normaliser and shapes it flies there), and the config it
    trained on; ConfigError naming every field whose meaning differs from this run's."""
    start, _ = load_policy(source, device=str(run.device))
    assert start.trained_on is not None and start.spec is not None, "load_policy gives its config and spec"
    trained_on, start_spec = start.trained_on, start.spec
    try:
        # the hover logit a run switches on (--hover-logit) is the run's, not what the start's network takes
        start = start.reading(dataclasses.replace(run.spec, hover=start_spec.hover))
        start.fit(run.cfg)
    except ValueError as err:
        raise ConfigError(f"--init-from={run.args.net.init_from!r} cannot fly this run's layout: {err}") from None
    shapes = start.fitted()[2] or {}
    trained = start_spec.layout(trained_on)  # what its weights read, as they trained
    read = {k: dataclasses.replace(trained[k], shape=shape) for k, shape in shapes.items() if k in trained}
    differences = layout_differences(read, {k: spec for k, spec in run.layout.items() if k in read})
    if differences:
        raise ConfigError(
            f"--init-from={run.args.net.init_from!r} reads another observation than this run's env (start vs run): "
            + "; ".join(differences)
            + "; train that policy from scratch, or match its scenario's layout."
        )
    return start, trained_on


def schedule(
    args: TrainArgs, num_iterations: int, iteration: int, clock_start: int | None = None
) -> tuple[float, float]:
    """The (learning rate, shaping weight) of ``iteration`` (0-based) of a run of ``num_iterations``.

    With ``--schedule-clock steps`` the learning rate decays linearly from ``--learning-rate`` to 0 over the run
    (constant without ``--anneal-lr``) and the shaping weight decays linearly to 0 over the last
    ``--shaping-anneal-frac`` of it. With ``first_delivery`` both stay at their start values until
    ``clock_start``, the first iteration after the first greedy evaluation that delivered everyone (None: none
    has yet), and from there follow the same shapes over the ``num_iterations - clock_start`` iterations left. The
    shaping weight never falls below 1e-6, so the env's shaping stays on (its metric is fixed)."""
    n, lr0, shaping, frac = num_iterations, args.ppo.learning_rate, args.env.shaping, args.env.shaping_anneal_frac
    if args.ppo.schedule_clock == "steps":
        begin, span = 0, n
    elif clock_start is None:
        return lr0, (shaping if shaping <= 0 or frac <= 0 else max(shaping, 1e-6))
    else:
        begin, span = clock_start, n - clock_start
    lr = lr0 * (1.0 - (iteration - begin) / span) if args.ppo.anneal_lr else lr0
    if shaping <= 0 or frac <= 0:
        return lr, shaping
    anneal_begin = begin + (1.0 - frac) * span
    decay = min(1.0, max(0.0, 1.0 - (iteration - anneal_begin) / (frac * span)))
    return lr, max(shaping * decay, 1e-6)


def set_schedules(run: Run, learner: Learner, iteration: int, clock_start: int | None = None) -> float:
    """Set the iteration's learning rate and shaping weight (:func:`schedule`); returns the shaping weight."""
    args = run.args
    lr, weight = schedule(args, run.num_iterations, iteration, clock_start)
    if args.ppo.anneal_lr:
        learner.optimizer.param_groups[0]["lr"] = lr
    if args.env.shaping <= 0 or args.env.shaping_anneal_frac <= 0:
        return args.env.shaping
    run.venv.set_reward_weights(dataclasses.replace(run.cfg.reward, shaping=weight))
    return weight


def compute_advantages(run: Run, learner: Learner) -> tuple[np.ndarray, np.ndarray]:
    """GAE over this rank's rollout: (advantages [T, N], returns [T, N])."""
    buf = run.buffer
    with torch.inference_mode():
        norm_obs = normalise(run, learner.normalizer, run.obs, update=False)
        _, next_value = learner.net(obs_to_torch(norm_obs, run.device), state=_tensor(run.global_state(), run.device))
    return compute_gae(
        buf.rewards, buf.values, buf.terminated, buf.truncated, buf.final_values, next_value.cpu().numpy(),
        run.args.ppo.gamma, run.args.ppo.gae_lambda,
    )  # fmt: skip


def ppo_update(run: Run, learner: Learner, advantages: np.ndarray, returns: np.ndarray) -> list[PPOLossInfo]:
    """update_epochs passes of minibatch Adam steps on the clipped PPO loss.

    The permutation is of the GLOBAL flat batch [T * N_global] (the same on every rank: the NumPy generator
    is); each rank takes its own samples of each global minibatch (see uamfleet.rl.distributed)."""
    args, buf, dev, ranks = run.args, run.buffer, run.device, run.ranks
    ppo = args.ppo
    minibatch_size = run.batch_size // ppo.num_minibatches
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
    for _epoch in range(args.ppo.update_epochs):
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
                new_logprob, mb_logprobs, entropy, new_value, val[local], adv[local], ret[local], ppo.clip_coef,
                ppo.vf_coef, ppo.ent_coef, ppo.clip_vloss, ppo.norm_adv, stats, denominator,
            )  # fmt: skip
            if learner.reference is not None:
                with torch.no_grad():
                    reference_logits = learner.reference.masked_logits(mb_obs)  # [B, 16]
                kl = categorical_kl(dist.logits, reference_logits)  # [B]
                kl_mean = kl.mean() if denominator is None else kl.sum() / denominator
                loss = loss + args.net.kl_to_init * kl_mean
                info = dataclasses.replace(info, kl_to_init=float(kl_mean.detach()))
            learner.optimizer.zero_grad()
            (loss * share).backward()
            summed = ranks.all_reduce_grads(params, share * np.array(dataclasses.astuple(info)))
            infos.append(PPOLossInfo(*(float(x) for x in summed)))
            torch.nn.utils.clip_grad_norm_(params, args.ppo.max_grad_norm)
            learner.optimizer.step()
        if args.ppo.target_kl is not None and infos[-1].approx_kl > args.ppo.target_kl:
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


__all__ = [
    "Learner", "compute_advantages", "make_learner", "ppo_update", "schedule", "set_schedules",
    "with_init_architecture",
]  # fmt: skip
