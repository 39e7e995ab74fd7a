"""The training options: :class:`TrainArgs` (every flag of ``train/ppo.py``, checked on construction), in groups
(env, observer, net, ppo, eval, run: frozen dataclasses, flags flat, ``--help`` in those sections), and the env
config a run trains and evaluates on (:func:`make_env_config`). A checkpoint's options are read back by
:func:`uamfleet.rl.legacy.checkpoint_args`, without importing the training loop.
"""

from __future__ import annotations

import dataclasses
import math
import os
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Annotated, Any, Literal

from uamfleet.config import FEASIBILITY_RULES, MAX_TAXIS, ConfigError, EnvConfig, check_integer, check_number
from uamfleet.instances import FAMILIES, VALIDATION_SEEDS, family_of, is_map_name, map_family, map_family_name
from uamfleet.presets import SCENARIOS, make_config
from uamfleet.radio.packaged import RADIO_MAPS
from uamfleet.rl.networks import VARIANTS
from uamfleet.rl.option_groups import Flat, flat_options, grouped_from_flat

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
    munich) or the path of a map file (.npz of uamfleet-radio-map, or WinProp ASCII .txt), at the strictest threshold of
    the map's family (uamfleet.instances.map_family) unless --sinr-min-db says otherwise; --curve-instances then fly
    that family's validation instances. A scenario of random demand (e.g. berlin_instances); None: its own map"""
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


@dataclass(frozen=True)
class TrainArgs:
    """PPO training of the shared MSHA policy (every option is a command-line flag of ``train/ppo.py``), in groups.

    A checkpoint stores the options flat (:meth:`flat`, one key per option, plain values), and
    :meth:`from_flat` reads such a dict back; ``args.ppo.learning_rate`` is ``args.flat()["learning_rate"]``."""

    env: Annotated[EnvOptions, Flat] = field(default_factory=EnvOptions)
    observer: Annotated[ObserverOptions, Flat] = field(default_factory=ObserverOptions)
    net: Annotated[NetOptions, Flat] = field(default_factory=NetOptions)
    ppo: Annotated[PPOOptions, Flat] = field(default_factory=PPOOptions)
    eval: Annotated[EvalOptions, Flat] = field(default_factory=EvalOptions)
    run: Annotated[RunOptions, Flat] = field(default_factory=RunOptions)

    @classmethod
    def from_flat(cls, flat: Mapping[str, Any]) -> TrainArgs:
        """The options of a flat dict (as :meth:`flat` gives and a checkpoint stores; options it lacks take their
        defaults); ConfigError naming any key that is no option."""
        return grouped_from_flat(cls, flat)

    @classmethod
    def from_saved(cls, saved: Mapping[str, Any]) -> TrainArgs:
        """The options of a checkpoint's flat ``args``: keys that are no option (an imitation run's ``imitation``)
        are left out, options added since the checkpoint was written take their defaults."""
        return cls.from_flat({name: value for name, value in saved.items() if name in GROUP_OF})

    def flat(self) -> dict[str, Any]:
        """Every option by name, as plain values (paths as strings): what a checkpoint stores as its ``args``."""
        return {name: (str(v) if isinstance(v, Path) else v) for name, v in self._values().items()}

    def with_options(self, **options: Any) -> TrainArgs:
        """These options with ``options`` (flat names, e.g. ``num_taxis=4``) replaced; checked like any."""
        return TrainArgs.from_flat({**self._values(), **options})

    def _values(self) -> dict[str, Any]:
        return flat_options(self)

    def _get(self, name: str) -> Any:
        return getattr(getattr(self, GROUP_OF[name]), name)

    def _set(self, name: str, value: Any) -> None:
        """Store an option's normalised value (a tuple for a list) in its frozen group."""
        object.__setattr__(getattr(self, GROUP_OF[name]), name, value)

    def __post_init__(self) -> None:
        """Every numeric option in its range (:class:`~uamfleet.config.ConfigError` naming the flag otherwise),
        so a typo fails before any env is built, not after training (``checkpoint_every=0``)."""
        for group, cls in GROUPS.items():
            if not isinstance(getattr(self, group), cls):
                raise ConfigError(f"TrainArgs.{group}={getattr(self, group)!r} must be a {cls.__name__}.")
        self._check_numbers()
        self._check_thresholds()
        env, evaluation = self.env, self.eval
        if evaluation.eval_instances > len(VALIDATION_SEEDS):
            raise ConfigError(
                f"--eval-instances={evaluation.eval_instances} exceeds the {len(VALIDATION_SEEDS):,} seeds of the "
                f"validation split; give at most {len(VALIDATION_SEEDS):,} (e.g. 50)."
            )
        if evaluation.eval_instances and not env.scenario.endswith(("_instances", "_fleet")):
            raise ConfigError(
                f"--eval-instances={evaluation.eval_instances} flies held-out instances of a family; it needs a "
                f"*_instances or *_fleet scenario (not {env.scenario!r}), e.g. --scenario berlin_instances."
            )
        self._check_map()
        self._check_curve()
        self._check_fleet_mixture()
        self._check_vector_backend()
        self._check_start()
        for name in ("scenario", "run_name", "init_from"):
            value = self._get(name)
            if value is not None and not isinstance(value, str):
                raise ConfigError(f"{_flag(name)}={value!r} must be a string.")
        self._set("run_dir", Path(self.run.run_dir))

    def _check_start(self) -> None:
        """What a run starts from: --kl-to-init, --reinit-critic and --warm-start-rounds need (or refuse) a start."""
        net = self.net
        if net.kl_to_init > 0 and net.init_from is None and not net.warm_start_rounds:
            raise ConfigError(
                f"--kl-to-init={net.kl_to_init:g} pulls the policy toward the one it starts from; give that policy "
                "with --init-from (a shipped name such as berlin, or a checkpoint file) or build it with "
                "--warm-start-rounds, or drop --kl-to-init."
            )
        if net.warm_start_rounds and net.init_from is not None:
            raise ConfigError(f"--warm-start-rounds={net.warm_start_rounds} warm-starts a network from scratch; drop "
                              f"it or --init-from={net.init_from!r}.")  # fmt: skip
        if net.reinit_critic and net.init_from is None:
            raise ConfigError(
                "--reinit-critic starts the critic of an --init-from policy afresh; give that policy with "
                "--init-from, or drop --reinit-critic (a run from scratch starts every weight afresh)."
            )

    def _check_numbers(self) -> None:
        """The integer options against their lower bounds, the float options against their intervals."""
        for name, minimum in _COUNTS.items():
            check_integer(_flag(name), self._get(name), minimum)
        most = 4 * (os.cpu_count() or 1)
        check_integer("--threads", self.run.threads, 0, most, fix=" (4 per CPU core at most; 0: torch's default)")
        for name in ("num_taxis", "eval_time_limit_steps", "passenger_window"):
            if self._get(name) is not None:
                check_integer(_flag(name), self._get(name), 1)
        for name, (low, high, low_open) in _RANGES.items():
            value = self._get(name)
            if value is None:
                continue
            check_number(_flag(name), value)
            if (value <= low if low_open else value < low) or (high is not None and value > high):
                interval = f"{'(' if low_open else '['}{low:g}, {'inf)' if high is None else f'{high:g}]'}"
                raise ConfigError(f"{_flag(name)}={value!r} is out of range: it must lie in {interval}.")

    def _check_curve(self) -> None:
        """--curve-instances within the validation split, and a family to draw them from; --schedule-clock known,
        and with first_delivery, evaluations during the run to start it."""
        if self.ppo.schedule_clock not in ("steps", "first_delivery"):
            raise ConfigError(f"--schedule-clock={self.ppo.schedule_clock!r} is unknown; use steps or first_delivery.")
        if self.ppo.schedule_clock == "first_delivery" and self.eval.eval_every == 0:
            raise ConfigError(
                "--schedule-clock first_delivery starts the schedules at the first greedy evaluation that delivers "
                "everyone, but --eval-every 0 evaluates only at the end; give --eval-every >= 1."
            )
        count, family = self.eval.curve_instances, self.eval.curve_family
        if count > len(VALIDATION_SEEDS):
            raise ConfigError(
                f"--curve-instances={count} exceeds the {len(VALIDATION_SEEDS):,} seeds of the validation split; "
                "give at most that (e.g. 10)."
            )
        if family is not None and family not in FAMILIES:
            raise ConfigError(f"--curve-family={family!r} is unknown; use one of {sorted(FAMILIES)}.")
        if count and family is None and isinstance(self.env.scenario, str):
            try:
                family_of(self.env.scenario)
            except ValueError:
                raise ConfigError(
                    f"--curve-instances={count} flies validation instances, but scenario {self.env.scenario!r} "
                    f"belongs to no instance family; name one with --curve-family (e.g. berlin)."
                ) from None

    def curve_family_name(self) -> str:
        """The family of the --curve-instances flights: --curve-family, else --map's, else the scenario's own."""
        return self.eval.curve_family or self.env.map or family_of(self.env.scenario)

    def _check_map(self) -> None:
        """--map names a map (a packaged one or a file), on a scenario of random demand, without --eval-instances
        (the trainer draws those from the scenario's own family)."""
        env = self.env
        if env.map is None:
            return
        if not (env.map in RADIO_MAPS or is_map_name(env.map)):
            raise ConfigError(
                f"--map={env.map!r}: no packaged map of that name and no such map file; give one of berlin, "
                "detroit_estimate, detroit_3gpp, munich or the path of a map file (.npz of uamfleet-radio-map)."
            )
        if env.scenario in ("berlin_p4", "detroit_p5", "detroit3gpp_p5"):
            raise ConfigError(
                f"--map={env.map!r} with --scenario {env.scenario}: a fixed scenario's stops lie on its own map; "
                "give a scenario of random demand, e.g. --scenario berlin_instances."
            )
        if self.eval.eval_instances:
            raise ConfigError(
                f"--eval-instances={self.eval.eval_instances} with --map: the trainer draws them from the scenario's "
                "own family and map; fly the map's validation instances with --curve-instances N, --eval-instances 0."
            )
        map_family(env.map)  # a file that is no map, or too small a map, is refused now

    def _check_thresholds(self) -> None:
        """--thresholds: a list of distinct dB values, not given together with --sinr-min-db (stored as a tuple)."""
        given = self.env.thresholds
        if isinstance(given, str | bytes) or not hasattr(given, "__iter__"):
            raise ConfigError(f"--thresholds={given!r} must be a list of dB values, e.g. -7 -6 -5.")
        thresholds = tuple(check_number("--thresholds", t) for t in given)
        self._set("thresholds", thresholds)
        repeated = sorted({t for t in thresholds if thresholds.count(t) > 1})
        if repeated:
            raise ConfigError(
                f"--thresholds={list(thresholds)} repeats {repeated}: each threshold is one share of the envs; "
                "give each once."
            )
        if thresholds and self.env.sinr_min_db is not None:
            raise ConfigError(
                f"--sinr-min-db={self.env.sinr_min_db} and --thresholds={list(thresholds)} both set the threshold; "
                "give one of them."
            )

    def _check_fleet_mixture(self) -> None:
        """--num-requests and --fleet-mixture: a *_fleet scenario, settings <taxis>x<requests>, each given once,
        --num-taxis the largest fleet (stored as a tuple of strings)."""
        env = self.env
        fleet = env.scenario.endswith("_fleet") if isinstance(env.scenario, str) else False
        if env.num_requests is not None:
            check_integer("--num-requests", env.num_requests, 1)
            if not fleet:
                raise ConfigError(
                    f"--num-requests={env.num_requests} sets a fleet scenario's demand; it needs a *_fleet scenario "
                    f"(not {env.scenario!r}), e.g. --scenario berlin_fleet."
                )
        if isinstance(env.fleet_mixture, str | bytes) or not hasattr(env.fleet_mixture, "__iter__"):
            raise ConfigError(f"--fleet-mixture={env.fleet_mixture!r} must be a list of settings, e.g. 2x12 4x48.")
        mixture = tuple(str(s) for s in env.fleet_mixture)
        self._set("fleet_mixture", mixture)
        if not mixture:
            return
        if not fleet:
            raise ConfigError(
                f"--fleet-mixture={list(mixture)} mixes fleet settings; it needs a *_fleet scenario "
                f"(not {env.scenario!r}), e.g. --scenario berlin_fleet."
            )
        settings = self.fleet_settings()
        repeated = sorted({s for s in mixture if mixture.count(s) > 1})
        if repeated:
            raise ConfigError(f"--fleet-mixture={list(mixture)} repeats {repeated}; give each setting once.")
        largest = max(taxis for taxis, _ in settings)
        if env.num_taxis is not None and env.num_taxis != largest:
            raise ConfigError(
                f"--num-taxis={env.num_taxis} is not the largest fleet of --fleet-mixture={list(mixture)} "
                f"({largest}): the run's observation holds the largest fleet's other taxis; set --num-taxis {largest} "
                "or leave it out."
            )

    def _check_vector_backend(self) -> None:
        """--vector-backend: a known name that agrees with --env-workers, --thresholds and --fleet-mixture."""
        env = self.env
        backend, workers = env.vector_backend, env.env_workers
        if backend not in ("auto", "inline", "mixture", "workers"):
            raise ConfigError(f"--vector-backend={backend!r} is unknown; use auto, inline, mixture or workers.")
        if backend == "workers" and not workers:
            raise ConfigError(
                "--vector-backend workers steps the envs in worker processes; give --env-workers >= 1 (or use auto)."
            )
        if backend in ("inline", "mixture") and workers:
            raise ConfigError(
                f"--vector-backend {backend} steps the envs in this process, but --env-workers={workers} asks for "
                "worker processes; use --vector-backend workers (or auto), or drop --env-workers."
            )
        configs = max(1, len(env.thresholds)) * max(1, len(env.fleet_mixture))
        if backend == "inline" and configs > 1:
            raise ConfigError(
                f"--vector-backend inline steps one config, but --thresholds and --fleet-mixture give {configs}; use "
                "--vector-backend mixture (or auto)."
            )

    def chosen_backend(self) -> str:
        """The backend that steps the training envs: --vector-backend, with auto resolved (workers with
        --env-workers, else mixture with --thresholds or --fleet-mixture, else inline)."""
        env = self.env
        if env.vector_backend != "auto":
            return env.vector_backend
        if env.env_workers:
            return "workers"
        return "mixture" if env.thresholds or env.fleet_mixture else "inline"

    def fleet_settings(self) -> list[tuple[int, int]]:
        """(taxis, requests) of each --fleet-mixture setting, in the order given (ConfigError for a malformed one)."""
        out = []
        for setting in self.env.fleet_mixture:
            taxis, sep, requests = setting.partition("x")
            if not (sep and taxis.isdigit() and requests.isdigit() and int(taxis) >= 1 and int(requests) >= 1):
                raise ConfigError(
                    f"--fleet-mixture setting {setting!r} is not <taxis>x<requests> with both >= 1 (e.g. 4x48)."
                )
            out.append((check_integer("--fleet-mixture taxis", int(taxis), 1, MAX_TAXIS), int(requests)))
        return out

    @property
    def name(self) -> str:
        if self.run.run_name:
            return self.run.run_name
        sinr = "default" if self.env.sinr_min_db is None else f"{self.env.sinr_min_db:g}"
        place = "" if self.env.map is None else f"{map_family_name(self.env.map)}_"
        return f"{place}{self.env.scenario}_{sinr}dB_{self.net.variant}_s{self.ppo.seed}"

    def env_overrides(self, training: bool = True) -> dict[str, Any]:
        env, observer = self.env, self.observer
        overrides: dict[str, Any] = {"feasibility": env.feasibility}
        if env.map is not None:  # the map, at its family's strictest threshold unless one is given
            overrides["radio"] = env.map
            overrides["sinr_min_db"] = map_family(env.map).thresholds_db[-1]
        if env.sinr_min_db is not None:
            overrides["sinr_min_db"] = env.sinr_min_db
        taxis = env.num_taxis
        if taxis is None and env.fleet_mixture:
            taxis = max(n for n, _ in self.fleet_settings())
        if taxis is not None:
            overrides["num_taxis"] = taxis
        evaluation_limit = self.eval.eval_time_limit_steps
        overrides["time_limit_steps"] = (
            env.time_limit_steps if training or evaluation_limit is None else evaluation_limit
        )
        if observer.heading_lookahead:
            overrides["heading_lookahead"] = True
        if observer.lookahead_depth != 1:
            overrides["lookahead_depth"] = observer.lookahead_depth
        if observer.passenger_window is not None:
            overrides["passenger_window"] = observer.passenger_window
        return overrides


# Lower bounds of TrainArgs' integer options.
_COUNTS: dict[str, int] = {
    "time_limit_steps": 1, "d_model": 1, "num_heads": 1, "local_window": 1, "seed": 0, "total_timesteps": 1,
    "num_envs": 1, "num_steps": 1, "num_minibatches": 1, "update_epochs": 1, "eval_every": 0,
    "checkpoint_every": 1, "threads": 0, "eval_instances": 0, "env_workers": 0, "curve_instances": 0,
    "warm_start_rounds": 0,
}  # fmt: skip
# (low, high or None, low excluded) of TrainArgs' float options; None values (unset options) are skipped.
_RANGES: dict[str, tuple[float, float | None, bool]] = {
    "sinr_min_db": (-math.inf, None, True), "shaping": (0.0, None, False), "shaping_gamma": (0.0, 1.0, True),
    "shaping_anneal_frac": (0.0, 1.0, False), "learning_rate": (0.0, None, True), "gamma": (0.0, 1.0, True),
    "gae_lambda": (0.0, 1.0, False), "clip_coef": (0.0, None, True), "ent_coef": (0.0, None, False),
    "vf_coef": (0.0, None, False), "max_grad_norm": (0.0, None, True), "target_kl": (0.0, None, True),
    "stop_at_td_m": (0.0, None, False), "max_wall_s": (0.0, None, True), "kl_to_init": (0.0, None, False),
}  # fmt: skip


def _flag(name: str) -> str:
    return "--" + name.replace("_", "-")


def make_env_config(scenario: str | EnvConfig, args: TrainArgs, training: bool = True) -> EnvConfig:
    """The env config a run trains (or evaluates) on: the scenario with the run's overrides and shaping.

    The shaping term uses the trainer's discount unless ``args.env.shaping_gamma`` is set, so by default it stays
    potential-based for the return PPO maximises (Ng et al. 1999: F = gamma * Phi(s') - Phi(s) with the MDP's own
    gamma)."""
    cfg = make_config(scenario, **args.env_overrides(training=training))
    env = args.env
    if env.num_requests is not None:
        cfg = with_num_requests(cfg, env.num_requests)
    reward = dataclasses.replace(
        cfg.reward,
        shaping=env.shaping,
        shaping_metric=env.shaping_metric,
        shaping_gamma=args.ppo.gamma if env.shaping_gamma is None else env.shaping_gamma,
    )
    return cfg.replace(reward=reward)


def with_num_requests(cfg: EnvConfig, requests: int) -> EnvConfig:
    """A random-demand config with exactly ``requests`` per episode (its arrival law and window kept) and a
    passenger axis that holds them (a passenger window, when set, still decides the rows observed)."""
    demand = dataclasses.replace(
        cfg.demand, min_requests=requests, max_requests=requests, num_initial=min(cfg.demand.num_initial, requests)
    )
    return cfg.replace(demand=demand, max_passengers=requests)
