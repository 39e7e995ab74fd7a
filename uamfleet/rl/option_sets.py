"""The training options by group: env, observer, net, ppo, eval and run (frozen dataclasses whose fields are the flags
of ``train/ppo.py``, each documented where it is declared, which is what ``--help`` prints in those sections).
:class:`~uamfleet.rl.options.TrainArgs` holds one of each and checks them (:mod:`uamfleet.rl.option_checks`).
"""

from __future__ import annotations

import dataclasses
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from uamfleet.config import FEASIBILITY_RULES
from uamfleet.presets import SCENARIOS
from uamfleet.rl.networks import VARIANTS

# The known names as Literal types built from the package's tuples (tyro offers them as choices); mypy sees str.
if TYPE_CHECKING:
    ScenarioName = str
    FeasibilityRule = str
    VariantName = str
else:
    ScenarioName, FeasibilityRule, VariantName = Literal[SCENARIOS], Literal[FEASIBILITY_RULES], Literal[VARIANTS]


@dataclass(frozen=True)
class EnvOptions:
    """The world a run trains on: scenario, threshold(s), fleet and demand, rules, shaping, and its envs."""

    scenario: ScenarioName = "berlin_p4"
    """scenario name"""
    map: str | None = None
    """fly the scenario's world on this radio map: a packaged map's name (berlin, detroit_estimate, detroit_3gpp,
    munich, munich_3km: uamfleet.radio.packaged.RADIO_MAPS) or the path of a map file (.npz of uamfleet-radio-map,
    or WinProp ASCII .txt), at the strictest threshold of the map's family (uamfleet.instances.map_family) unless
    --sinr-min-db says otherwise; --curve-instances then fly that family's validation instances. A scenario of
    random demand (e.g. berlin_instances); None: its own map"""
    sinr_min_db: float | None = None
    """SINR threshold in dB; None: the scenario's"""
    num_taxis: int | None = None
    """fleet size; None: the scenario's (with --fleet-mixture: its largest fleet)"""
    num_requests: int | None = None
    """requests per episode of a *_fleet scenario, released over its arrival window (e.g. 48 with 4 taxis: the
    loaded regime); None: the preset's 6 per taxi"""
    fleet_mixture: tuple[str, ...] = ()
    """train on several fleet settings at once, each <taxis>x<requests> (a *_fleet scenario; e.g. 2x12 2x24 4x24
    4x48 8x48 8x96: fleet sizes and loads): the envs split into one group per setting (and --thresholds value),
    smaller fleets padded to the largest (uamfleet.env.mixture). The run's own config (its evaluation, its
    checkpoints' layout) is --num-taxis, which must be the largest fleet of the mixture, with --num-requests"""
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
    num_envs: int = 32
    """parallel envs of the batched core (agents per step = num_envs x taxis); under torchrun the global count,
    split evenly among the ranks"""
    env_workers: int = 0
    """step this rank's training envs in this many worker processes, one core each (uamfleet.env.workers), while
    the network runs here (e.g. on a GPU); 0: in this process. Same episodes either way; configs of one fleet size"""
    vector_backend: Literal["auto", "inline", "mixture", "workers"] = "auto"
    """what steps this rank's training envs (uamfleet.env.backends): inline (one config, in this process), mixture
    (a group of envs per --thresholds value and --fleet-mixture setting, in this process), workers (the mixture's
    envs in --env-workers processes); auto: workers with --env-workers, else mixture with --thresholds or
    --fleet-mixture, else inline. Same episodes with any"""
    fill_tables: bool = True
    """with stop features on random demand: compute the feasible-path distance tables before training (or load
    them from the disk cache, uamfleet.paths.distance_table), ~30 s per threshold on Berlin the first time"""


@dataclass(frozen=True)
class ObserverOptions:
    """What the policy reads beyond the scenario's own observation."""

    passenger_window: int | None = None
    """each taxi observes at most this many passenger rows: its riders, then the nearest waiting requests
    (EnvConfig.passenger_window, docs/rules.md "Passenger window"), so the policy flies any number of requests and
    any shift length; None: a row per request of the episode"""
    heading_lookahead: bool = False
    """observe each heading's move plus the shortest tour after it (EnvConfig.heading_lookahead; needs a scenario
    with stop features); a stop-head network then reads it as a learned correction of its flight"""
    lookahead_depth: int = 1
    """the look-ahead's depth (EnvConfig.lookahead_depth): 2 costs each heading by its move, the best second move
    and the tour after both"""


@dataclass(frozen=True)
class NetOptions:
    """The network, and the policy a fine-tuning run starts from."""

    variant: VariantName = "de_msfea"
    """MSHA ablation variant: linear encoders / designed encoders / + multi-source features / + hybrid attention.
    Default de_msfea: on Berlin P4 it came within 5 % of raster_opt (a raster planner, not an optimum of the env's
    moves) in 40-140k agent-steps in 8 of 10 runs, at 3x the full model's speed per step; the full model learned
    slower per step too (reports/2026-12-03-results-history/README.md, "The recipe, and what made the difference")"""
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
    hover_logit: bool = False
    """with --action-head stops and a hover component (a *_fleet scenario: EnvConfig.hover_action): the hover
    component is the logit of the hover action (16, stay in place) instead of mass on the heading back to where the
    taxi was (NetConfig.hover_logit); also switches it on for an --init-from policy, whose weights are kept"""
    init_from: str | None = None
    """start from this policy's weights and observation statistics: a shipped name (e.g. berlin, see
    uamfleet.zoo.PRETRAINED) or a checkpoint file. Its network options replace --variant, --d-model and the other
    architecture flags, and the run's envs observe what it reads (its observer spec, stored in its checkpoint:
    passenger rows, stop fields, look-ahead, patch, history and time scale; --passenger-window replaces its
    window) in the run's own world, so e.g. the Berlin generalist is fine-tuned on Berlin P4 with --scenario
    berlin_p4 --init-from berlin. A greedy evaluation of the start comes first, so best.pt is never worse than it
    on the evaluation"""
    reinit_critic: bool = False
    """with --init-from: start the critic afresh, the actor and its torso from the start. Needed when the start's
    critic cannot read this run's input: a centralised critic (MAPPO) reads the global state, whose size is set by
    the number of taxis and passengers, so it does not fit another fleet size or load, and no one state holds a
    --fleet-mixture of them. With it, --centralised-critic is this run's own choice (without it, the start's)"""
    kl_to_init: float = 0.0
    """weight of KL(pi || pi_init), the new policy's divergence from the --init-from policy averaged over each
    minibatch, in the loss: PPO may leave the start where the return pays for it, not drift where it does not
    (0: no such term; from scratch it needs --warm-start-rounds, whose network is then the start)"""
    warm_start_rounds: int = 0
    """from scratch: rounds of DAgger from replan's search on the run's world before PPO (uamfleet.rl.warm_start;
    a lone taxi, one process); 0: none"""


@dataclass(frozen=True)
class PPOOptions:
    """The PPO update: budget, batch, optimiser, losses, normalisation and the seed."""

    total_timesteps: int = 200_000
    """agent-steps (env steps x taxis) to train for (under torchrun: of all ranks together); rounded down to whole
    iterations of num_steps x num_envs x taxis, at least one"""
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
    5,200-5,300 m in 150k agent-steps (reports/2026-12-03-results-history/README.md, "The recipe, and what made
    the difference"). Raise it for sparse rewards (shaping 0)"""
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
    seed: int = 1
    """seed of torch, numpy and the envs (env e gets seed + e)"""
    schedule_clock: Literal["steps", "first_delivery"] = "steps"
    """what the learning-rate decay and the shaping anneal count: steps, the run's iterations from the first; or
    first_delivery, the iterations after the first greedy evaluation that delivers everyone (PR 100 %): until then
    the learning rate and the shaping weight stay at their start values, after it both follow the steps schedule
    compressed into the iterations left (needs greedy evaluations: --eval-every >= 1)"""


@dataclass(frozen=True)
class EvalOptions:
    """Greedy evaluations during training, and when training stops."""

    eval_every: int = 5
    """greedy evaluation every this many iterations (0: only at the end)"""
    eval_instances: int = 0
    """evaluate on this many held-out validation instances of the scenario's family (uamfleet.instances;
    *_instances scenarios), flown in one batch, and keep the best on them; 0: one episode of the training
    scenario. Never the test instances: those are for the final report"""
    eval_time_limit_steps: int | None = None
    """time limit of the greedy evaluation episodes; None: the training one (the observation's time
    features are fractions of the time limit, so a different one shifts them)"""
    stop_at_td_m: float | None = None
    """stop once a greedy evaluation delivers everyone with TD at or below this (measures time-to-target)"""
    max_wall_s: float | None = None
    """stop (after a final evaluation and checkpoint) once training has run this many seconds"""
    curve_instances: int = 0
    """after each greedy evaluation, also fly the greedy policy on the first this many validation instances of
    --curve-family (one batch; uamfleet.instances.validation_metrics) and log their mean distance and delivered
    share as progress.csv's val_td_m and val_pr_pct (the learning curve's validation panel); never used to keep a
    checkpoint. 0: none"""
    curve_every: int = 1
    """with --curve-instances, fly them at every this-many-th evaluation (its progress.csv row's iteration a
    multiple of it) and at the last one; the rows between carry no val_td_m / val_pr_pct. 1: at every evaluation"""
    curve_family: str | None = None
    """instance family of --curve-instances (uamfleet.instances.FAMILIES, e.g. berlin); None: the scenario's own
    (a *_instances, *_fleet or *_random scenario)"""


@dataclass(frozen=True)
class RunOptions:
    """The run folder, resuming, device, threads and logs."""

    checkpoint_every: int = 5
    """iterations between checkpoints"""
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


GROUPS: dict[str, type] = {
    "env": EnvOptions, "observer": ObserverOptions, "net": NetOptions, "ppo": PPOOptions, "eval": EvalOptions,
    "run": RunOptions,
}  # fmt: skip
"""The option groups of :class:`TrainArgs`, by attribute: each option belongs to exactly one."""
GROUP_OF: dict[str, str] = {f.name: group for group, cls in GROUPS.items() for f in dataclasses.fields(cls)}
"""The group of each option, by its name (the key of the flat dict a checkpoint stores)."""


__all__ = [
    "GROUPS",
    "GROUP_OF",
    "EnvOptions",
    "EvalOptions",
    "NetOptions",
    "ObserverOptions",
    "PPOOptions",
    "RunOptions",
]
