"""Learning from the search: DAgger with the online step-level search (``replan``'s solver) as the expert.

The stop head's prior fixes the order of the known stops; what it cannot do is fly differently from each stop's
single progress heading. ``replan`` can: it searches over the env's own moves, approaching a stop from the side of
the next one and using the pick-up radius. This module teaches a policy with a heading residual
(``NetConfig(heading_residual=True)``) to fly like it, on the states the policy itself visits (Ross et al. 2011):

1. **Roll out** a mixture: in round ``r`` each step's action is the expert's with probability
   ``beta0 * beta_decay ** r`` (round 0: the expert's own flights), else the policy's greedy heading.
2. **Label** every visited state that has a plan with the expert's heading. A plan is valid until a request is
   released, the episode ends or the executed heading leaves it, so one solve labels many steps
   (:class:`ReplanExpert`); the policy's own deviations are what cost solves.
3. **Fit** the network to the aggregated labels (cross-entropy on the masked logits), then score the greedy
   policy on the validation instances and keep the best checkpoint (``best.pt``), never the test ones.

The expert plans over the requests released so far, as ``replan`` does; it never sees the future. States with
no plan (every known passenger delivered, the next request not yet released) are not labelled: there the expert
only waits. The result is a checkpoint that :func:`uamfleet.rl.trainer.load_policy` and
:func:`uamfleet.zoo.export_policy` read like any other.
"""

from __future__ import annotations

import dataclasses
import time
from dataclasses import dataclass, field
from pathlib import Path
from collections.abc import Mapping
from typing import Annotated, Any, Literal

import numpy as np
import torch
import torch.nn.functional as F
from gymnasium import spaces

from uamfleet.baselines.anticipation import AnticipatingReplan, DemandPrior
from uamfleet.baselines.step_planner import SearchSettings
from uamfleet.config import ConfigError, EnvConfig, check_integer, check_number
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import BERLIN_THRESHOLDS_DB, FAMILIES, family_of, map_family, validation_metrics
from uamfleet.observe.legacy import observed_config
from uamfleet.io import write_csv_atomic
from uamfleet.paths import table_for
from uamfleet.radio.packaged import RADIO_MAPS
from uamfleet.rl.heads import PRIOR_FLOOR
from uamfleet.rl.networks import MSHAActorCritic, obs_to_torch
from uamfleet.rl.checkpoint import (
    CHECKPOINT_FORMAT,
    PRETRAINED,
    pretrained_path,
    run_config,
    trained_spec,
    world_record,
)
from uamfleet.rl.options import TrainArgs
from uamfleet.rl.option_groups import Flat, flat_options, grouped_from_flat, option_groups
from uamfleet.rl.experts import NO_LABEL, AnticipatingExpert, ReplanExpert, released_count
from uamfleet.rl.runs import RunClaim, check_run_name, claim_run
from uamfleet.rl.trainer import Checkpoint, GreedyPolicy, checkpoint_args, load_policy
from uamfleet.observe.spec import LookaheadSpec, ObserverSpec, layout_to_dict
from uamfleet.types import NUM_HEADINGS


@dataclass(frozen=True)
class ImitationEnvOptions:
    """The envs DAgger rolls out, and its rounds."""

    thresholds: tuple[float, ...] = (-7.0, -6.0, -5.0, -4.0, -3.0)
    """SINR thresholds to roll out on (dB), one group of envs each; with --map, Berlin's (the default) are read as
    the map family's"""
    map: str | None = None
    """roll out on this radio map (a packaged map's name or the path of a .npz / WinProp .txt map file) and validate
    on its instance family (uamfleet.instances.map_family); None: the start's own map and family"""
    also_maps: tuple[str, ...] = ()
    """with --map: more maps rolled out on at once (each at its family's thresholds, one group of envs per map and
    threshold); the validation metric is the mean over every map's validation instances"""
    envs_per_threshold: int = 8
    rounds: int = 6
    steps_per_round: int = 120
    """env steps per round, each over every env of every threshold"""


@dataclass(frozen=True)
class ImitationObserverOptions:
    """What the policy reads beyond its start's observation."""

    lookahead: bool = False
    """also observe each heading's one-step look-ahead on the exact tour (``EnvConfig.heading_lookahead``) and fit
    a learned correction of the flight from it (``NetConfig.lookahead_inputs``, zero at first)"""
    lookahead_depth: int = 1
    """with --lookahead: its depth (``EnvConfig.lookahead_depth``; 2: each heading's move, the best second move and
    the tour after both)"""


@dataclass(frozen=True)
class ImitationNetOptions:
    """The policy DAgger starts from, and what of it is fitted."""

    init: str = "berlin_stops"
    """checkpoint to start from: a shipped policy's name (uamfleet.zoo.PRETRAINED) or a file; its network,
    normaliser and training scenario are kept and a heading residual is added"""
    train: Literal["residual", "lookahead", "all"] = "residual"
    """parameters fitted: the heading residual alone (the prior and the encoders frozen: the order of the stops
    stays the prior's), only its look-ahead correction (with --lookahead), or the whole network"""
    lookahead_rule: float = 0.0
    """with --lookahead: fixed logits per move of look-ahead taken from each heading (``NetConfig.lookahead_rule``;
    100 makes the untrained policy fly the least look-ahead heading, the prior breaking near-ties, so DAgger fits
    corrections of that rule rather than of the prior)"""


@dataclass(frozen=True)
class ExpertOptions:
    """The teacher and how often its actions are flown."""

    beta0: float = 1.0
    """share of the expert's actions in round 0 (1: the expert's own flights)"""
    beta_decay: float = 0.5
    expert: Literal["replan", "futures"] = "replan"
    """the teacher: ``replan``'s search over the released requests, or ``replan_futures``' decisions (that plan
    and sampled futures' plans, scored on other sampled futures: it anticipates releases; seconds per decision)"""
    expert_beam: int = 32
    """beam of the expert's search (``replan`` runs 64 in the benchmark; smaller is cheaper and close)"""
    futures: int = 2
    """with --expert futures: sampled futures whose plans are candidates (``replan_futures`` flies 4)"""
    scored_futures: int = 4
    """with --expert futures: fresh futures each candidate is scored on (``replan_futures`` flies 8)"""
    future_beam: int = 8
    """with --expert futures: beam of a future's plan (``replan_futures`` flies 16)"""
    score_beam: int = 4
    """with --expert futures: beam of the search that finishes a scored future (``replan_futures`` flies 8)"""


@dataclass(frozen=True)
class FitOptions:
    """The fit to the aggregated labels, and the seed."""

    epochs: int = 3
    minibatch: int = 512
    learning_rate: float = 3e-4
    skip_ruled_out: bool = False
    """fit no label the stop head's prior rules out (log-probability at or below ``PRIOR_FLOOR``): a heading toward
    no known stop, e.g. the anticipating teacher's flight toward a sampled request, which the residual can only
    reach with a dozen logits"""
    correction_weight: float = 1.0
    """weight of a state whose label corrects the policy's own heading (the others weigh 1)"""
    max_samples: int = 300_000
    """the aggregated data set's size limit; the oldest samples go first"""
    seed: int = 0


@dataclass(frozen=True)
class ImitationEvalOptions:
    """The validation after each round, and when to stop."""

    eval_instances: int = 50
    max_wall_s: float | None = None


@dataclass(frozen=True)
class ImitationRunOptions:
    """The run folder and threads."""

    run_dir: Path = Path("runs")
    run_name: str = "berlin_imitation"
    overwrite: bool = False
    threads: int = 1


@dataclass(frozen=True)
class ImitationArgs:
    """DAgger from the online step-level search (every option is a flag of ``train/imitate.py``), in groups named
    as :class:`~uamfleet.rl.options.TrainArgs`' where they hold the same kind of option; flags flat."""

    env: Annotated[ImitationEnvOptions, Flat] = field(default_factory=ImitationEnvOptions)
    observer: Annotated[ImitationObserverOptions, Flat] = field(default_factory=ImitationObserverOptions)
    net: Annotated[ImitationNetOptions, Flat] = field(default_factory=ImitationNetOptions)
    expert: Annotated[ExpertOptions, Flat] = field(default_factory=ExpertOptions)
    fit: Annotated[FitOptions, Flat] = field(default_factory=FitOptions)
    eval: Annotated[ImitationEvalOptions, Flat] = field(default_factory=ImitationEvalOptions)
    run: Annotated[ImitationRunOptions, Flat] = field(default_factory=ImitationRunOptions)

    @classmethod
    def from_flat(cls, flat: Mapping[str, Any]) -> ImitationArgs:
        """The options of a flat dict (option name -> value; options it lacks take their defaults)."""
        return grouped_from_flat(cls, flat)

    def flat(self) -> dict[str, Any]:
        """Every option by name."""
        return flat_options(self)

    def _set(self, name: str, value: Any) -> None:
        """Store an option's checked value in its frozen group."""
        object.__setattr__(getattr(self, IMITATION_GROUP_OF[name]), name, value)

    def __post_init__(self) -> None:
        o = self.flat()
        for name in ("envs_per_threshold", "rounds", "steps_per_round", "expert_beam", "epochs", "minibatch",
                     "futures", "scored_futures", "future_beam", "score_beam"):  # fmt: skip
            self._set(name, check_integer(f"--{name.replace('_', '-')}", o[name], minimum=1))
        fit, net, observer = self.fit, self.net, self.observer
        self._set("max_samples", check_integer("--max-samples", fit.max_samples, minimum=fit.minibatch))
        self._set("eval_instances", check_integer("--eval-instances", o["eval_instances"], minimum=1, maximum=10_000))
        self._set("threads", check_integer("--threads", o["threads"], minimum=1, maximum=256))
        for name in ("beta0", "beta_decay"):
            value = check_number(f"--{name.replace('_', '-')}", o[name], minimum=0.0)
            if value > 1:
                raise ConfigError(f"--{name.replace('_', '-')}={value} is a probability: use a value in [0, 1].")
            self._set(name, value)
        self._set("learning_rate", check_number("--learning-rate", fit.learning_rate, positive=True))
        self._set("correction_weight", check_number("--correction-weight", fit.correction_weight, positive=True))
        thresholds = tuple(check_number("--thresholds", t) for t in self.env.thresholds)
        self._set("thresholds", thresholds)
        if not thresholds or len(set(thresholds)) != len(thresholds):
            raise ConfigError(f"--thresholds={list(thresholds)} must name one or more distinct dB values.")
        self._check_maps()
        self._set("run_dir", Path(self.run.run_dir))
        check_run_name(self.run.run_name, self.run.run_dir)  # the rule of every command that writes a run
        if net.train == "lookahead" and not observer.lookahead:
            raise ConfigError("--train lookahead fits the look-ahead correction: pass --lookahead too.")
        self._set("lookahead_rule", check_number("--lookahead-rule", net.lookahead_rule, minimum=0.0))
        if net.lookahead_rule > 0 and not observer.lookahead:
            raise ConfigError(f"--lookahead-rule={net.lookahead_rule} weighs the look-ahead: pass --lookahead too.")
        if observer.lookahead_depth != 1 and not observer.lookahead:  # its value is checked by EnvConfig
            raise ConfigError(
                f"--lookahead-depth={observer.lookahead_depth} is the look-ahead's depth: pass --lookahead."
            )

    def _check_maps(self) -> None:
        """--map and --also-maps name packaged maps or map files, distinct, --also-maps only beside --map."""
        also = tuple(self.env.also_maps)
        self._set("also_maps", also)
        if also and self.env.map is None:
            raise ConfigError(f"--also-maps={list(also)} adds maps to --map's: pass --map too (e.g. --map berlin).")
        maps = ([] if self.env.map is None else [self.env.map]) + list(also)
        for flag, name in [("--map", self.env.map)] + [("--also-maps", m) for m in also]:
            if name is not None and name not in FAMILIES:  # FAMILIES: a packaged map or a map file too
                raise ConfigError(
                    f"{flag}={name!r}: no packaged map of that name and no such map file; give one of "
                    f"{', '.join(RADIO_MAPS)} or the path of a map file (.npz of uamfleet-radio-map)."
                )
        if len(set(maps)) != len(maps):
            raise ConfigError(f"--map and --also-maps name {maps}: name each map once.")

    def maps(self) -> tuple[str, ...]:
        """The maps rolled out on (--map, then --also-maps); empty: the start's own map."""
        return () if self.env.map is None else (self.env.map, *self.env.also_maps)

    def beta(self, round_index: int) -> float:
        """Probability that a step of round ``round_index`` flies the expert's heading."""
        return self.expert.beta0 * self.expert.beta_decay**round_index


IMITATION_GROUP_OF: dict[str, str] = {
    f.name: name for name, group in option_groups(ImitationArgs).items() for f in dataclasses.fields(group)
}
"""The group of each option of :class:`ImitationArgs`, by its name."""


@dataclass
class Group:
    """One threshold's envs, its expert and the number of requests released in each env."""

    venv: VectorEnv
    expert: ReplanExpert | AnticipatingExpert
    obs: dict[str, np.ndarray]
    released: np.ndarray = field(default_factory=lambda: np.zeros(0, np.int64))


@dataclass
class Dataset:
    """The aggregated labelled states (normalised observations, as the network reads them)."""

    obs: list[dict[str, np.ndarray]] = field(default_factory=list)
    labels: list[np.ndarray] = field(default_factory=list)
    corrected: list[np.ndarray] = field(default_factory=list)  # the label differs from the policy's own heading

    def add(self, obs: dict[str, np.ndarray], labels: np.ndarray, corrected: np.ndarray) -> None:
        self.obs.append(obs)
        self.labels.append(labels)
        self.corrected.append(corrected)

    def __len__(self) -> int:
        return int(sum(len(x) for x in self.labels))

    def trim(self, limit: int) -> None:
        while len(self) - len(self.labels[0]) >= limit:
            self.obs.pop(0)
            self.labels.pop(0)
            self.corrected.pop(0)

    def arrays(self) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray]:
        """(observations {field: [N, ...]}, labels [N], corrected [N] bool)."""
        keys = self.obs[0].keys()
        obs = {k: np.concatenate([o[k] for o in self.obs]) for k in keys}
        return obs, np.concatenate(self.labels), np.concatenate(self.corrected)


RESIDUAL_PREFIX = "stop_head.residual_"
"""Names of the heading residual's parameters (and of its look-ahead correction's): what
:func:`with_heading_residual` adds, all zero at first."""


def with_heading_residual(
    policy: GreedyPolicy, lookahead: bool = False, lookahead_rule: float = 0.0, lookahead_depth: int = 1
) -> GreedyPolicy:
    """The policy with a zero heading residual added to its stop head (it still flies exactly as before), reading
    what it reads (its :attr:`~GreedyPolicy.spec`); with ``lookahead``, also a zero correction from the
    ``heading_lookahead`` field, which it then observes (at ``lookahead_depth``), and the rule term
    ``lookahead_rule`` (``NetConfig.lookahead_rule``; with it the policy flies the least look-ahead heading)."""
    net = policy.net
    shapes = dict(net.shapes)
    if lookahead:
        shapes["heading_lookahead"] = (NUM_HEADINGS,)
    space = spaces.Dict({k: spaces.Box(-np.inf, np.inf, shape, np.float32) for k, shape in shapes.items()})
    cfg = dataclasses.replace(net.cfg, heading_residual=True, lookahead_inputs=lookahead, lookahead_rule=lookahead_rule)
    new = MSHAActorCritic(space, cfg)
    missing, unexpected = new.load_state_dict(net.state_dict(), strict=False)
    if unexpected or any(not k.startswith(RESIDUAL_PREFIX) for k in missing):
        raise ValueError(f"the initial network does not carry over: missing {missing}, unexpected {unexpected}.")
    new.eval()
    trained_on, spec = policy.trained_on, policy.spec
    if lookahead and trained_on is not None:
        trained_on = trained_on.replace(heading_lookahead=True, lookahead_depth=lookahead_depth)
    if lookahead and spec is not None:
        spec = dataclasses.replace(spec, lookahead=LookaheadSpec(depth=lookahead_depth))
    return GreedyPolicy(
        new, policy.normalizer, policy.device, {**(policy.obs_shapes or {}), **shapes}, policy.num_taxis,
        policy.passenger_slots, trained_on, None, spec,
    )  # fmt: skip


def collect(
    groups: list[Group], policy: GreedyPolicy, beta: float, steps: int, rng: np.random.Generator,
    skip_ruled_out: bool = False,
) -> Dataset:  # fmt: skip
    """``steps`` steps of every group under the DAgger mixture; the labelled states of all of them (with
    ``skip_ruled_out``, not those whose label the stop head's prior rules out: ``ImitationArgs.skip_ruled_out``)."""
    data = Dataset()
    for _ in range(steps):
        for g in groups:
            E = g.venv.num_envs
            normalised = policy.network_input(g.obs)  # [E, ...] one taxi per env
            own = policy.logits_of(normalised).argmax(-1).numpy()  # [E] the policy's greedy heading
            labels = g.expert.labels(g.venv, own)  # [E]
            labelled = labels != NO_LABEL
            # a heading the rule forbids leaves the taxi in place: a plan's wait for a release (the anticipating
            # teacher's plans over sampled futures have them). It is flown, never fitted: the policy cannot wait.
            allowed = g.venv.state.action_mask[np.arange(E), 0, np.where(labelled, labels, 0)]
            fitted = labelled & allowed
            if skip_ruled_out and fitted.any():
                with torch.inference_mode():
                    prior = policy.net.prior_logits(obs_to_torch(normalised, policy.device)).numpy()  # [E, 16]
                fitted &= prior[np.arange(E), np.where(labelled, labels, 0)] > PRIOR_FLOOR
            if fitted.any():
                data.add(
                    {k: v[fitted].copy() for k, v in normalised.items()}, labels[fitted], (labels != own)[fitted],
                )  # fmt: skip
            take_expert = labelled & (rng.random(E) < beta)
            executed = np.where(take_expert, labels, own)
            g.obs, _, terminated, truncated, _ = g.venv.step(executed[:, None])
            ended = terminated | truncated
            released = released_count(g.venv)
            g.expert.advance(executed, (released != g.released) & ~ended, ended)
            g.released = released
    return data


def fitted_parameters(net: MSHAActorCritic, which: str) -> list[torch.nn.Parameter]:
    """The parameters DAgger fits: the stop head's heading residual, its look-ahead correction, or all of them."""
    if which == "all":
        return list(net.parameters())
    prefix = {"residual": RESIDUAL_PREFIX, "lookahead": RESIDUAL_PREFIX + "lookahead."}.get(which)
    if prefix is None:
        raise ValueError(f"train={which!r} is unknown; use 'residual', 'lookahead' or 'all'.")
    return [p for name, p in net.named_parameters() if name.startswith(prefix)]


def fit(net: MSHAActorCritic, data: Dataset, args: ImitationArgs, optimizer: torch.optim.Optimizer,
        rng: np.random.Generator) -> dict[str, float]:  # fmt: skip
    """``args.fit.epochs`` passes of cross-entropy between the masked logits and the expert's headings; a state where
    the expert corrected the policy weighs ``args.fit.correction_weight``."""
    obs, labels, corrected = data.arrays()
    weights = np.where(corrected, args.fit.correction_weight, 1.0).astype(np.float32)
    net.train()
    n, losses, hits = len(labels), [], []
    for _ in range(args.fit.epochs):
        order = rng.permutation(n)
        for start in range(0, n, args.fit.minibatch):
            idx = order[start : start + args.fit.minibatch]
            batch = obs_to_torch({k: v[idx] for k, v in obs.items()}, "cpu")
            target = torch.as_tensor(labels[idx])
            weight = torch.as_tensor(weights[idx])
            logits = net.masked_logits(batch)  # [b, 16]
            loss = (F.cross_entropy(logits, target, reduction="none") * weight).sum() / weight.sum()
            net.zero_grad(set_to_none=True)  # frozen parameters too: their gradients are never used
            loss.backward()
            torch.nn.utils.clip_grad_norm_([p for g in optimizer.param_groups for p in g["params"]], 0.5)
            optimizer.step()
            losses.append(float(loss.detach()))
            hits.append(float((logits.argmax(-1) == target).float().mean()))
    net.eval()
    tail = max(1, len(losses) // max(args.fit.epochs, 1))  # the last epoch
    return {"bc_loss": float(np.mean(losses[-tail:])), "bc_agreement": float(np.mean(hits[-tail:]))}


def imitate(args: ImitationArgs) -> dict[str, float]:
    """Run DAgger (module docstring); writes ``best.pt``, ``last.pt`` and ``progress.csv`` in the run folder and
    returns the best validation row. The folder is claimed first (:func:`~uamfleet.rl.runs.claim_run`): an existing
    run is refused without ``overwrite``, and so is a name another command is writing."""
    with claim_run(args.run.run_dir, args.run.run_name, overwrite=args.run.overwrite, resumable=False) as claim:
        return _imitate(args, claim)


def _imitate(args: ImitationArgs, claim: RunClaim) -> dict[str, float]:
    folder = claim.folder
    torch.set_num_threads(args.run.threads)
    torch.manual_seed(args.fit.seed)
    rng = np.random.default_rng(args.fit.seed)
    start = time.time()
    init = pretrained_path(args.net.init) if args.net.init in PRETRAINED else Path(args.net.init)
    ckpt = Checkpoint.load(init)
    source_args = checkpoint_args(ckpt)
    if args.observer.lookahead:
        source_args = source_args.with_options(heading_lookahead=True, lookahead_depth=args.observer.lookahead_depth)
    prior, _ = load_policy(init)
    policy = with_heading_residual(
        prior, lookahead=args.observer.lookahead, lookahead_rule=args.net.lookahead_rule,
        lookahead_depth=args.observer.lookahead_depth,
    )  # fmt: skip
    assert policy.spec is not None, "load_policy gives the spec the policy reads"
    worlds = _worlds(args, source_args, policy.spec)
    eval_like = worlds[0].eval_like  # the checkpoint's world: the first map's
    groups = [g for k, w in enumerate(worlds) for g in _groups(args, w.train_like, w.family, policy.spec, k)]
    optimizer = torch.optim.Adam(fitted_parameters(policy.net, args.net.train), lr=args.fit.learning_rate)
    claim.clear()  # every option checked: an earlier run replaced with --overwrite goes now
    first = _validate(policy, worlds, args.eval.eval_instances)
    rows: list[dict[str, float]] = [{"round": -1, "samples": 0, "wall_s": time.time() - start, **_val(first)}]
    best = dict(rows[-1])
    _save(folder / "best.pt", ckpt, policy, args, best, eval_like)
    data = Dataset()
    for r in range(args.env.rounds):
        if args.eval.max_wall_s is not None and time.time() - start > args.eval.max_wall_s:
            break
        counts, stats = _round(r, groups, policy, data, args, optimizer, rng)
        val = _validate(policy, worlds, args.eval.eval_instances)
        row = {**counts, "wall_s": time.time() - start, **stats, **_val(val)}  # progress.csv's column order
        rows.append(row)
        print(", ".join(f"{k}={v:.4g}" for k, v in row.items()), flush=True)
        _write_progress(folder, rows)
        _save(folder / "last.pt", ckpt, policy, args, row, eval_like)
        if (row["val_pr_pct"], -row["val_td_m"]) > (best["val_pr_pct"], -best["val_td_m"]):
            best = dict(row)
            _save(folder / "best.pt", ckpt, policy, args, best, eval_like)
    _write_progress(folder, rows)
    return best


@dataclass(frozen=True)
class World:
    """One map DAgger rolls out and validates on: its instance family and the start's worlds on it, observed as
    the policy reads them."""

    family: str
    train_like: EnvConfig
    eval_like: EnvConfig


def _worlds(args: ImitationArgs, source_args: TrainArgs, spec: ObserverSpec) -> list[World]:
    """The start's world on each of ``args.maps()`` (validated on the map's family), or its own world and family."""
    if not args.maps():
        family = family_of(source_args.env.scenario)
        return [World(family, run_config(source_args, training=True), _eval_like(source_args, spec))]
    worlds = []
    for name in args.maps():
        on_map = source_args.with_options(map=name, eval_instances=0)
        worlds.append(World(name, run_config(on_map, training=True), _eval_like(on_map, spec)))
    return worlds


def _eval_like(source_args: TrainArgs, spec: ObserverSpec) -> EnvConfig:
    return observed_config(run_config(source_args, training=False), spec)[0]


def _validate(policy: GreedyPolicy, worlds: list[World], count: int) -> dict[str, float]:
    """:func:`~uamfleet.instances.validation_metrics` on each world's first ``count`` validation instances, and
    their mean over the worlds (with one world: its own)."""
    per_map = [validation_metrics(policy, w.family, count, w.eval_like) for w in worlds]
    mean = {k: float(np.mean([m[k] for m in per_map])) for k in ("pr_pct", "solved_pct", "td_m")}
    if len(worlds) > 1:  # each map's figures too, in progress.csv
        for w, m in zip(worlds, per_map, strict=True):
            mean.update({f"{k}@{Path(w.family).stem}": m[k] for k in ("pr_pct", "td_m")})
    return mean


def _groups(args: ImitationArgs, base: EnvConfig, family: str, spec: ObserverSpec, map_index: int = 0) -> list[Group]:
    """One group of ``envs_per_threshold`` envs (tables filled), observed by ``spec``, and its expert per training
    threshold of ``family``'s map (the ``map_index``-th of ``args.maps()``)."""
    groups = []
    thresholds = args.env.thresholds
    if args.env.map is not None and thresholds == BERLIN_THRESHOLDS_DB:
        thresholds = map_family(family).thresholds_db
    for i, threshold in enumerate(thresholds):
        cfg = observed_config(base.replace(sinr_min_db=threshold), spec)[0]
        venv = VectorEnv(cfg, num_envs=args.env.envs_per_threshold, observer=spec)
        table_for(venv.world).fill()
        seed = args.fit.seed + 1000 * i + 100_000 * map_index  # map 0: the seeds of a one-map run
        obs, _ = venv.reset(seed=seed)
        expert: ReplanExpert | AnticipatingExpert
        teacher = args.expert
        if teacher.expert == "futures":  # the family's demand model on this threshold's flyable sites
            planner = AnticipatingReplan(
                DemandPrior.of_family(family, cfg), teacher.futures, teacher.scored_futures,
                SearchSettings(teacher.expert_beam, rank_slack=0.5), teacher.future_beam, teacher.score_beam,
            )  # fmt: skip
            expert = AnticipatingExpert(cfg, venv.num_envs, planner, seed=seed)
        else:
            expert = ReplanExpert(cfg, venv.num_envs, args.expert.expert_beam)
        groups.append(Group(venv, expert, obs, released_count(venv)))
    return groups


def _round(
    r: int, groups: list[Group], policy: GreedyPolicy, data: Dataset, args: ImitationArgs,
    optimizer: torch.optim.Optimizer, rng: np.random.Generator,
) -> tuple[dict[str, float], dict[str, float]]:  # fmt: skip
    """DAgger round r: collect under the mixture, add to ``data`` (trimmed), fit; the round's counts (samples,
    expert solves) and the fit's statistics."""
    solves_before = sum(g.expert.solves for g in groups)
    corrections_before = sum(g.expert.corrections for g in groups)
    new = collect(groups, policy, args.beta(r), args.env.steps_per_round, rng, args.fit.skip_ruled_out)
    for o, lab, cor in zip(new.obs, new.labels, new.corrected, strict=True):
        data.add(o, lab, cor)
    data.trim(args.fit.max_samples)
    stats = fit(policy.net, data, args, optimizer, rng)
    counts = {
        "round": r, "beta": args.beta(r), "samples": len(data), "new_samples": len(new),
        "solves": sum(g.expert.solves for g in groups) - solves_before,
        "corrections": sum(g.expert.corrections for g in groups) - corrections_before,
        "solve_s": sum(g.expert.solve_s for g in groups),
    }  # fmt: skip
    return counts, stats


def _val(m: dict[str, float]) -> dict[str, float]:
    per_map = {f"val_{k}": v for k, v in m.items() if "@" in k}
    return {"val_pr_pct": m["pr_pct"], "val_solved_pct": m["solved_pct"], "val_td_m": m["td_m"], **per_map}


def _save(
    path: Path, source: Checkpoint, policy: GreedyPolicy, args: ImitationArgs, row: dict[str, float], like: EnvConfig
) -> None:
    """The source checkpoint with this policy's network and what it reads (its spec, in ``like``, the world it is
    evaluated in): loads with load_policy like any trained checkpoint."""
    assert policy.spec is not None
    layout = policy.spec.layout(like)
    read = {k: spec for k, spec in layout.items() if k in policy.net.shapes}
    extra = (
        {"heading_lookahead": True, "lookahead_depth": args.observer.lookahead_depth} if args.observer.lookahead else {}
    )
    out = dataclasses.replace(
        source,
        model={k: v.detach().clone() for k, v in policy.net.state_dict().items()},
        net_config=dataclasses.asdict(policy.net.cfg),
        obs_shapes={k: list(spec.shape) for k, spec in read.items()},
        obs_layout=layout_to_dict(read),
        observer=trained_spec(like, dataclasses.asdict(policy.net.cfg), observer=policy.spec).to_dict(),
        world=world_record(like.world),
        format=CHECKPOINT_FORMAT,
        args={**source.args, **extra, "imitation": {k: _plain(v) for k, v in args.flat().items()}},
        best_eval={k: float(v) for k, v in row.items()},
        optimizer={}, reward_scaler=None, cuda_rng=None, numpy_rng={},
    )  # fmt: skip
    out.save(path)


def _plain(v: object) -> object:
    if isinstance(v, Path):
        return str(v)
    if isinstance(v, tuple):
        return list(v)
    return v


def _write_progress(folder: Path, rows: list[dict[str, float]]) -> None:
    """``progress.csv``: one row per round, the columns in their first appearance's order."""
    write_csv_atomic(folder / "progress.csv", rows, list(dict.fromkeys(k for r in rows for k in r)))


__all__ = ["RESIDUAL_PREFIX", "ImitationArgs", "collect", "fit", "imitate", "with_heading_residual"]
