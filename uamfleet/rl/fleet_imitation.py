"""A fleet policy taught by a fleet dispatcher: DAgger on the fleet policy's own states (Ross et al. 2011).

The teacher is a schedule dispatcher (by default the chosen one, :data:`TEACHER`). It keeps commitments: each
taxi's stop schedule, repaired every step and re-assigned at releases. So its label at a state is only the
dispatcher's own action where the dispatcher has watched the whole episode up to that state. Every episode is
therefore flown with the teacher **observing every step** (its ``act`` is called on the env's simulator at every
step, exactly as when it flies), while the step flown is, with probability β (:attr:`FleetImitationArgs.beta`),
the teacher's joint move and otherwise the policy's greedy joint move. The label of every taxi at every step is
the teacher's action for it there (a heading toward its next stop along feasible paths, the hover where it has
nothing to do, a step aside under the shield): what the dispatcher itself would fly from that state, given the
schedules it would hold after watching those steps.

One network for every taxi and every fleet size: each taxi's observation row is one sample, read as the policy
reads it at that fleet size (its window of passenger rows, its normaliser fitted to the world), and the other-taxi
rows are padded to the largest fleet the network reads with masked rows (a masked mean ignores them, as in
:mod:`uamfleet.env.mixture`). The fit is :func:`uamfleet.rl.imitation.fit` (cross-entropy on the masked logits,
data aggregated over rounds in :class:`~uamfleet.rl.imitation.Dataset`). A label the policy gives a
log-probability at or below :data:`~uamfleet.rl.heads.PRIOR_FLOOR` is flown but never fitted (with
``fit_improbable``, only a masked one, :data:`MASKED_LOG_PROB`).

The network decides which stop each taxi flies for, and flies the stop's progress heading of its observation; the
dispatcher steers by its own path fields, which rank the moves differently: most labels the shipped network
rules out are such headings (``reports/2026-12-04-fleet-labels/``). ``labels="stop"`` labels each taxi with the
network's heading for the dispatcher's stop instead (:func:`stop_labels`), and ``hover_anytime`` opens the hover at
every step, so that the dispatcher's hover while the taxi reads a stop can be fitted too.
"""

from __future__ import annotations

import copy
import dataclasses
import time
from dataclasses import dataclass
from pathlib import Path
from collections.abc import Callable, Sequence
from typing import Any, Literal

import numpy as np
import torch

from uamfleet.baselines.assignment_value import CHOSEN_DISPATCHER
from uamfleet.baselines.fleet_dispatch import ScheduleFleetPolicy
from uamfleet.checks import ConfigError, check_integer, check_number
from uamfleet.config import FLEET_ARRIVAL_WINDOW_S, EnvConfig
from uamfleet.env.mixture import OTHER_TAXI_FIELDS
from uamfleet.env.protocol import PolicyBase
from uamfleet.env.vector_env import VectorEnv
from uamfleet.instances import fleet_setting, make_fleet_instance, split_seeds
from uamfleet.io import write_csv_atomic
from uamfleet.policies import kind_of, make_flown
from uamfleet.policies.learned import LearnedOptions, spec_of
from uamfleet.rl.checkpoint import Checkpoint, checkpoint_source
from uamfleet.rl.expert_iteration import ExItOptions, LabelSet
from uamfleet.rl.expert_iteration import fit as exit_fit
from uamfleet.rl.fleet_claims import (
    CLAIM_SCORE, check_claims_heading, claims_view, dispatch_claims, with_dispatch_claims,
)  # fmt: skip
from uamfleet.rl.heads import NOT_THIS, PRIOR_FLOOR
from uamfleet.rl.hover import NEW_PARAMETERS, with_hover_anytime
from uamfleet.rl.imitation import RESIDUAL_PREFIX, Dataset, FitOptions, ImitationArgs, fit, with_heading_residual
from uamfleet.rl.networks import MSHAActorCritic
from uamfleet.rl.policy import GreedyPolicy, load_policy
from uamfleet.rl.runs import RunClaim, check_run_name, claim_run
from uamfleet.rollout import observer_of
from uamfleet.types import HOVER_ACTION, NUM_HEADINGS, WAITING

TEACHER = CHOSEN_DISPATCHER
"""The chosen dispatcher (docs/results.md "Fleets"): the default teacher."""

MASKED_LOG_PROB = NOT_THIS / 2
"""A label the network gives a log-probability at or below this is masked (a heading toward no stop it reads, the
hover while a stop is open without ``hover_anytime``): no gradient reaches it, so it can never be fitted."""

CONVERSIONS: tuple[str, ...] = ("hover_anytime", "dispatch_claim_inputs", "heading_residual")
"""The ``NetConfig`` flags a conversion of the start may set (:func:`fleet_policy`): a saved round records them."""

MIXTURE: tuple[str, ...] = ("2x12", "2x24", "4x24", "4x48", "8x48", "8x96")
"""The fleet settings (taxis x requests) of the training episodes: 2 to 8 taxis, light and loaded, as the shipped
fleet policy's fine-tune flew."""


@dataclass(frozen=True)
class FleetImitationArgs:
    """DAgger from a fleet dispatcher (every option is a flag of ``uamfleet fleet-imitate``)."""

    init: str = "berlin_fleet"
    """the policy to start from: a shipped policy's name (uamfleet.zoo.PRETRAINED) or a checkpoint file"""
    teacher: str = TEACHER
    """the dispatcher whose actions are the labels (a fleet dispatcher's name, uamfleet.policies)"""
    family: str = "berlin"
    """instance family of the training episodes (its training seeds; uamfleet.instances.FAMILIES)"""
    mixture: tuple[str, ...] = MIXTURE
    """fleet settings of the training episodes (<taxis>x<requests>), ``episodes_per_setting`` of each per round"""
    passenger_window: int = 24
    """passenger rows each taxi reads (the shipped fleet policy flies 24)"""
    rounds: int = 6
    episodes_per_setting: int = 1
    """episodes of each mixture setting per round (fresh training seeds every round)"""
    labels: Literal["heading", "stop"] = "heading"
    """what a taxi is labelled with: the teacher's heading, or (``stop``) the heading the network's stop head flies to
    the stop the teacher flies for (:func:`stop_labels`: the level the network decides at)"""
    hover_anytime: bool = False
    """start from the policy with the hover action open at every step (:func:`uamfleet.rl.hover.with_hover_anytime`):
    the teacher's hover where the taxi reads a stop becomes a label the network can take"""
    hover_learning_rate: float = 0.01
    """with --hover-anytime: learning rate of the new hover logit (its bias starts at -12, out of reach at 1e-4)"""
    fit_improbable: bool = False
    """also fit labels the policy gives at most e^-12 but does not mask (a stop its nearness prior weighs out; with
    --hover-anytime, the hover where a stop is open); else only labels above e^-12 are fitted"""
    dispatch_claims: bool = False
    """start from the policy converted to read the teacher's claims (:func:`uamfleet.rl.fleet_claims.
    with_dispatch_claims`: each passenger row's stop on my schedule, another taxi's, my next stop, my schedule's
    order; zero weights at first); flown with the dispatcher alongside (``fleet_claims`` in uamfleet.policies)"""
    claims_heading: Literal["table", "onward"] = "table"
    """with --dispatch-claims: the stop heading marks the network reads and is labelled by: the env's (``table``), or
    with each taxi's next stop marked as the teacher's ``heading=onward`` makes it (``onward``,
    :func:`uamfleet.rl.fleet_claims.onward_marks`; fly the result as ``fleet_claims:heading=onward``)"""
    claims_learning_rate: float = 0.03
    """with --dispatch-claims: learning rate of the claims' term in each stop's score (from zero; at 1e-4 it would
    move about 0.01 logits per round)"""
    heading_residual: bool = False
    """start from the policy with a zero heading residual on its stop head
    (:func:`uamfleet.rl.imitation.with_heading_residual`): the teacher's heading toward a stop where the stop head
    would fly another becomes a label the network can take (with --labels heading and --fit-improbable)"""
    residual_learning_rate: float = 0.01
    """with --heading-residual: learning rate of the residual's layers (from zero; a heading the stop head rules out
    needs a dozen logits, out of reach at 1e-4)"""
    kl_anchor: float = 0.0
    """weight of the KL divergence from the round's start network over the headings in each round's fit (the fit of
    :func:`uamfleet.rl.expert_iteration.fit`); 0: the plain cross-entropy of :func:`uamfleet.rl.imitation.fit`"""
    beta0: float = 1.0
    """share of steps flown by the teacher in round 0 (1: the teacher's own episodes)"""
    beta_decay: float = 0.5
    epochs: int = 2
    minibatch: int = 512
    learning_rate: float = 1e-4
    max_samples: int = 300_000
    seed: int = 0
    run_dir: Path = Path("runs")
    run_name: str = "fleet_dagger"
    overwrite: bool = False
    threads: int = 1
    max_wall_s: float | None = None
    """stop starting rounds after this many seconds"""

    def __post_init__(self) -> None:
        for name in ("passenger_window", "rounds", "episodes_per_setting", "epochs", "minibatch", "threads"):
            check_integer(f"--{name.replace('_', '-')}", getattr(self, name), 1)
        check_integer("--max-samples", self.max_samples, self.minibatch)
        check_number("--learning-rate", self.learning_rate, positive=True)
        check_number("--hover-learning-rate", self.hover_learning_rate, positive=True)
        check_number("--claims-learning-rate", self.claims_learning_rate, positive=True)
        check_number("--residual-learning-rate", self.residual_learning_rate, positive=True)
        check_number("--kl-anchor", self.kl_anchor, minimum=0.0)
        check_claims_heading(self.claims_heading)
        if self.claims_heading != "table" and not self.dispatch_claims:
            raise ConfigError(
                f"--claims-heading={self.claims_heading} marks the dispatcher's next stop: add --dispatch-claims."
            )
        if self.labels not in ("heading", "stop"):
            raise ConfigError(f"--labels={self.labels!r} is unknown; use 'heading' or 'stop'.")
        for name in ("beta0", "beta_decay"):
            value = check_number(f"--{name.replace('_', '-')}", getattr(self, name), minimum=0.0)
            if value > 1:
                raise ConfigError(f"--{name.replace('_', '-')}={value} is a probability: use a value in [0, 1].")
        check_mixture(self.mixture)
        check_run_name(self.run_name, self.run_dir)

    def beta(self, round_index: int) -> float:
        """Probability that a step of round ``round_index`` flies the teacher's joint move."""
        return self.beta0 * self.beta_decay**round_index

    def fit_floor(self) -> float:
        """Labels the policy gives a log-probability at or below this are flown, never fitted."""
        return MASKED_LOG_PROB if self.fit_improbable else PRIOR_FLOOR

    def fit_args(self) -> ImitationArgs:
        """The options :func:`uamfleet.rl.imitation.fit` reads (its fit group)."""
        options = FitOptions(self.epochs, self.minibatch, self.learning_rate, max_samples=self.max_samples)
        return ImitationArgs(fit=dataclasses.replace(options, seed=self.seed))


def check_mixture(mixture: Sequence[str], extra: Sequence[str] = ()) -> None:
    """ConfigError in one line for an empty ``--mixture`` or a setting (of it or ``extra``) not <taxis>x<requests>."""
    if not mixture:
        raise ConfigError(f"--mixture is empty: give fleet settings <taxis>x<requests>, e.g. {' '.join(MIXTURE)}.")
    for setting in (*mixture, *extra):
        setting_size(setting)


def setting_size(setting: str) -> tuple[int, int]:
    """(taxis, requests) of a --mixture setting ``<taxis>x<requests>`` (e.g. ``8x96``): :func:`fleet_setting`."""
    return fleet_setting(setting, "--mixture")


def fleet_policy(
    init: str, passenger_window: int, hover_anytime: bool = False, dispatch_claims: bool = False,
    heading_residual: bool = False,
) -> GreedyPolicy:  # fmt: skip
    """A fresh copy of the greedy policy ``init`` (a shipped name or a file) reading ``passenger_window`` rows per
    taxi: one network for every fleet size (fitted to each world at reset); with ``hover_anytime``, converted by
    :func:`~uamfleet.rl.hover.with_hover_anytime`, with ``dispatch_claims`` by
    :func:`~uamfleet.rl.fleet_claims.with_dispatch_claims`, with ``heading_residual`` by
    :func:`~uamfleet.rl.imitation.with_heading_residual`. Fresh, so that fitting it never changes the process's
    cached shipped policy. Each conversion leaves a start that already has it as it is (its trained weights kept)."""
    policy = load_policy(checkpoint_source(init))[0]
    if hover_anytime:
        policy = with_hover_anytime(policy)
    if dispatch_claims:
        policy = with_dispatch_claims(policy)
    if heading_residual:
        policy = with_heading_residual(policy)
    return policy.reading(spec_of(policy, LearnedOptions(passenger_window=passenger_window)))


def padded_rows(policy: GreedyPolicy, rows: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
    """Each taxi's normalised observation row as the network reads it (``rows``: :meth:`GreedyPolicy.network_input`,
    ``[A, ...]``), its other-taxi rows padded with masked rows to the largest fleet the network reads (its
    ``shapes``), so rows of any fleet size stack."""
    out = {}
    for key, value in rows.items():
        if key in OTHER_TAXI_FIELDS:
            if value.shape[1] > policy.net.shapes[key][0]:
                raise ConfigError(
                    f"a fleet of {value.shape[1] + 1} taxis: this network reads at most {policy.net.shapes[key][0] + 1}"
                    "; train on fleets no larger (--mixture)."
                )
            full = np.zeros((value.shape[0], *policy.net.shapes[key]), value.dtype)
            full[:, : value.shape[1]] = value
            value = full
        out[key] = value
    return out


@dataclass
class EpisodeLabels:
    """One labelled episode: its rows and labels (:class:`~uamfleet.rl.imitation.Dataset`'s parts) and counts."""

    obs: dict[str, np.ndarray]
    labels: np.ndarray
    corrected: np.ndarray
    teacher_actions: np.ndarray  # [T, A] the teacher's action for every taxi at every step, fitted or not
    flown: np.ndarray  # [T, A] the joint move flown at every step (the teacher's or the policy's)
    steps: int
    teacher_steps: int
    ruled_out: int  # labels the policy's stop head rules out (log-probability <= PRIOR_FLOOR): flown, never fitted
    ruled_out_hovers: int  # of them, hovers (the teacher waits where the policy's stop head sees a stop)


StepWatch = Callable[[VectorEnv, dict[str, np.ndarray], PolicyBase, np.ndarray, np.ndarray], None]
"""Called at every step of :func:`label_episode` before the step is flown, with the env, its observation, the
teacher, the teacher's actions [A] and the policy's log-probabilities [A, 16 or 17]: a look at the labels."""


def label_episode(
    cfg: EnvConfig, policy: GreedyPolicy, teacher: PolicyBase, beta: float, rng: np.random.Generator,
    labels: Literal["heading", "stop"] = "heading", fit_floor: float = PRIOR_FLOOR, watch: StepWatch | None = None,
    claims_heading: str = "table",
) -> EpisodeLabels:  # fmt: skip
    """Fly one episode of ``cfg`` with ``teacher`` observing every step (module docstring): each step is the
    teacher's joint move with probability ``beta``, else the policy's greedy one; every taxi's state is labelled
    with the teacher's action there (``labels="stop"``: at the level the network decides at, :func:`stop_labels`).
    Labels the policy gives a log-probability at or below ``fit_floor`` are flown, never fitted. A policy that reads
    the teacher's claims reads them, and with ``claims_heading="onward"`` its next stop's mark, as
    :class:`~uamfleet.rl.fleet_claims.ClaimsFleetPolicy` gives them in flight; its own moves are its greedy ones,
    without that policy's decoding rules (``hover_when_idle``, ``make_way``)."""
    env = VectorEnv(cfg, num_envs=1, autoreset=False, observer=observer_of(policy))
    obs, _ = env.reset(seed=0)
    policy.reset(env.sim)
    teacher.reset(env.sim)
    parts: list[dict[str, np.ndarray]] = []
    taught, corrected, teacher_actions, flown = [], [], [], []
    steps = teacher_steps = 0
    while True:
        action = np.asarray(teacher.act(obs), np.int64)  # [1, A]: its schedules advance by this step too
        if policy.net.cfg.dispatch_claim_inputs:  # the teacher's claims after its act: as ClaimsFleetPolicy reads them
            claims = teacher_claims(env, teacher)
            assert isinstance(teacher, ScheduleFleetPolicy)  # teacher_claims refuses any other
            obs, inputs = claims_view(policy, obs, claims, teacher, claims_heading)
        else:
            inputs = policy.network_input(obs)
        logits = policy.logits_of(inputs)  # [A, 16 or 17]
        own = policy.choose(obs, logits)  # [1, A] greedy, with the loop guard (as it flies)
        log_probs = torch.log_softmax(logits, -1).numpy()
        if watch is not None:
            watch(env, obs, teacher, action[0], log_probs)
        label = stop_labels(env, obs, teacher, action[0]) if labels == "stop" else action[0]
        fitted = log_probs[np.arange(len(label)), label] > fit_floor
        parts.append({k: v[fitted] for k, v in padded_rows(policy, inputs).items()})
        taught.append(label[fitted])
        corrected.append((label != own[0])[fitted])
        by_teacher = bool(rng.random() < beta)
        teacher_steps += by_teacher
        teacher_actions.append(action[0])
        flown.append((action if by_teacher else own)[0])
        obs, _, terminated, truncated, _ = env.step(action if by_teacher else own)
        steps += 1
        if terminated[0] or truncated[0]:
            break
    stacked = {k: np.concatenate([p[k] for p in parts]) for k in parts[0]}
    fitted_labels, all_actions = np.concatenate(taught), np.stack(teacher_actions)
    ruled_out = all_actions.size - len(fitted_labels)
    hovers = int((all_actions == HOVER_ACTION).sum() - (fitted_labels == HOVER_ACTION).sum())
    return EpisodeLabels(stacked, fitted_labels, np.concatenate(corrected), all_actions, np.stack(flown), steps,
                         teacher_steps, ruled_out, hovers)  # fmt: skip


def teacher_claims(env: VectorEnv, teacher: PolicyBase) -> np.ndarray:
    """[A, K, 4] the claims of the teacher's schedules on each taxi's window rows in env 0
    (:func:`~uamfleet.rl.fleet_claims.dispatch_claims`)."""
    if not isinstance(teacher, ScheduleFleetPolicy):
        raise ConfigError(f"dispatch claims read a schedule dispatcher's schedules, not a {type(teacher).__name__}.")
    return dispatch_claims(env.observer.window_rows(env.state)[0], teacher)


def stop_points(env: VectorEnv) -> tuple[np.ndarray, np.ndarray]:
    """(rows [A, K]: the state's passenger in each slot of each taxi's window, -1 where empty; points [A, K, 2]: the
    stop each slot's row stands for, its origin while it waits, else its destination) of env 0."""
    s = env.state
    rows = env.observer.window_rows(s)[0]  # [A, K]
    p = np.maximum(rows, 0)
    waiting = (s.pax_status[0, p] == WAITING)[..., None]  # [A, K, 1]
    return rows, np.where(waiting, s.pax_origin_m[0, p], s.pax_dest_m[0, p])


def stop_labels(env: VectorEnv, obs: dict[str, np.ndarray], teacher: PolicyBase, actions: np.ndarray) -> np.ndarray:
    """[A] the teacher's ``actions`` [A] of env 0 at the level the network decides at: a taxi heading for a stop of
    its schedule that it reads (a row of its window whose stop is there, ``stop_heading_mask`` set) is labelled with
    the heading its stop head flies to that stop; a hover, a step aside (no stop to fly to) and a heading for a stop
    outside its window keep the teacher's action. The two headings differ where the teacher's path fields and the
    observation's distance table rank the moves differently (ties included): which stop the taxi flies for is the
    teacher's either way."""
    if not isinstance(teacher, ScheduleFleetPolicy):
        raise ConfigError(f"stop labels read a schedule dispatcher's targets, not a {type(teacher).__name__}.")
    rows, points = stop_points(env)
    heading_of = obs["stop_heading_mask"][0]  # [A, K, 16] one-hot where the row is actionable
    out = actions.copy()
    for a in range(len(actions)):
        target = teacher.target(a)
        if target is None or actions[a] >= NUM_HEADINGS:
            continue
        serves = (rows[a] >= 0) & heading_of[a].any(-1) & np.all(np.abs(points[a] - target) < 1e-6, axis=-1)
        if serves.any():
            out[a] = int(np.argmax(heading_of[a, np.argmax(serves)]))
    return out


def training_episodes(args: FleetImitationArgs, round_index: int) -> list[EnvConfig]:
    """Round ``round_index``'s episodes: ``episodes_per_setting`` of each mixture setting, on training seeds no
    other round or setting uses, under the shield with the hover action (as the fleet benchmark flies)."""
    per_round = len(args.mixture) * args.episodes_per_setting
    seeds = split_seeds("train", per_round, first=args.seed * 100_000 + round_index * per_round)
    cfgs = []
    for i, setting in enumerate(args.mixture):
        taxis, requests = setting_size(setting)
        for j in range(args.episodes_per_setting):
            seed = seeds[i * args.episodes_per_setting + j]
            cfgs.append(make_fleet_instance(args.family, seed, taxis, requests, separation="shield", hover_action=True))
    return cfgs


def fleet_imitate(args: FleetImitationArgs) -> list[dict[str, float]]:
    """Run DAgger from the teacher (module docstring); writes ``round<r>.pt`` after every round's fit, ``last.pt``
    and ``progress.csv`` in the run folder, and returns the progress rows. Checkpoints are chosen afterwards on
    validation episodes (``uamfleet fleet-bench --split validation``), never here."""
    with claim_run(args.run_dir, args.run_name, overwrite=args.overwrite, resumable=False) as claim:
        return _fleet_imitate(args, claim)


def _fleet_imitate(args: FleetImitationArgs, claim: RunClaim) -> list[dict[str, float]]:
    torch.set_num_threads(args.threads)
    torch.manual_seed(args.seed)
    rng = np.random.default_rng(args.seed)
    start = time.time()
    initial = Checkpoint.load(checkpoint_source(args.init))  # what every saved round keeps but its weights
    policy = fleet_policy(
        args.init, args.passenger_window, args.hover_anytime, args.dispatch_claims, args.heading_residual
    )  # one set of weights, any fleet size
    net = policy.net
    optimizer = torch.optim.Adam(parameter_groups(net, args))
    fit_args = args.fit_args()
    claim.clear()
    data, rows = Dataset(), []
    for r in range(args.rounds):
        if args.max_wall_s is not None and time.time() - start > args.max_wall_s:
            break
        counts = _collect_round(args, r, policy, data, rng)
        data.trim(args.max_samples)
        stats = (
            anchored_fit(policy, data, args, rng) if args.kl_anchor > 0 else fit(net, data, fit_args, optimizer, rng)
        )
        rows.append({"round": r, "beta": args.beta(r), **counts, "samples": len(data), **stats,
                     "wall_s": time.time() - start})  # fmt: skip
        print(", ".join(f"{k}={v:.4g}" for k, v in rows[-1].items()), flush=True)
        save_fleet_checkpoint(claim.folder / f"round{r}.pt", initial, net, args, rows[-1])
        save_fleet_checkpoint(claim.folder / "last.pt", initial, net, args, rows[-1])
        write_csv_atomic(claim.folder / "progress.csv", rows, list(rows[0]))
    return rows


def _collect_round(
    args: FleetImitationArgs, r: int, policy: GreedyPolicy, data: Dataset, rng: np.random.Generator
) -> dict[str, float]:
    """Label round ``r``'s episodes (flown by ``policy`` and the teacher) into ``data``; the round's counts."""
    counts: dict[str, float] = {"new_samples": 0, "corrections": 0, "ruled_out": 0, "ruled_out_hovers": 0, "steps": 0,
              "teacher_steps": 0}  # fmt: skip
    for cfg in training_episodes(args, r):
        teacher = make_teacher(args.teacher, cfg.num_taxis)
        episode = label_episode(
            cfg, policy, teacher, args.beta(r), rng, args.labels, args.fit_floor(), claims_heading=args.claims_heading
        )
        data.add(episode.obs, episode.labels, episode.corrected)
        counts["new_samples"] += len(episode.labels)
        counts["corrections"] += int(episode.corrected.sum())
        counts["ruled_out"] += episode.ruled_out
        counts["ruled_out_hovers"] += episode.ruled_out_hovers
        counts["steps"] += episode.steps
        counts["teacher_steps"] += episode.teacher_steps
    return counts


def anchored_fit(
    policy: GreedyPolicy, data: Dataset, args: FleetImitationArgs, rng: np.random.Generator
) -> dict[str, float]:
    """Fit ``policy`` to the aggregated labels with ``args.kl_anchor`` times the KL divergence from its network as
    the round starts (:func:`uamfleet.rl.expert_iteration.fit`, one-hot targets, a fresh optimiser per round); the
    fit's statistics under :func:`~uamfleet.rl.imitation.fit`'s names, and the mean KL."""
    obs, labels, _ = data.arrays()
    target = np.zeros((len(labels), policy.net.num_actions), np.float32)
    target[np.arange(len(labels)), labels] = 1.0
    options = ExItOptions(
        init=args.init, epochs=args.epochs, learning_rate=args.learning_rate, minibatch=args.minibatch,
        kl_anchor=args.kl_anchor, hover_lr_scale=args.hover_learning_rate / args.learning_rate,
    )  # fmt: skip
    stats = exit_fit(policy, copy.deepcopy(policy), LabelSet(obs, target, np.ones(len(labels))), options, rng)
    return {"bc_loss": stats["fit_loss"], "bc_agreement": stats["fit_agreement"], "fit_kl": stats["fit_kl"]}


def parameter_groups(net: torch.nn.Module, args: FleetImitationArgs) -> list[dict[str, Any]]:
    """The optimiser's parameter groups: every parameter at ``learning_rate``, the hover logit that
    ``--hover-anytime`` adds at ``hover_learning_rate``, the claims' score term of ``--dispatch-claims`` at
    ``claims_learning_rate``, the heading residual of ``--heading-residual`` at ``residual_learning_rate`` (each
    wherever the network has it, converted by this run or by the one that wrote ``--init``)."""

    def group_of(name: str) -> str:
        if name.startswith(NEW_PARAMETERS):
            return "hover"
        if name == CLAIM_SCORE:
            return "claims"
        return "residual" if name.startswith(RESIDUAL_PREFIX) else "rest"

    rates = {"rest": args.learning_rate, "hover": args.hover_learning_rate, "claims": args.claims_learning_rate,
             "residual": args.residual_learning_rate}  # fmt: skip
    params: dict[str, list[torch.nn.Parameter]] = {group: [] for group in rates}
    for name, p in net.named_parameters():
        params[group_of(name)].append(p)
    return [{"params": params[g], "lr": rates[g]} for g in rates if params[g] or g == "rest"]


def make_teacher(name: str, taxis: int) -> PolicyBase:
    """The fleet dispatcher ``name`` (uamfleet.policies' grammar, e.g. :data:`TEACHER`) for ``taxis`` taxis, built
    as the fleet benchmark flies it (a valued one for the benchmark's arrival window); another kind of policy is
    refused in one line."""
    if kind_of(name) != "dispatcher":
        raise ConfigError(f"--teacher={name!r} is not a fleet dispatcher; give one such as {TEACHER!r}.")
    return make_flown(name, num_taxis=taxis, arrival_window_s=FLEET_ARRIVAL_WINDOW_S)


def save_fleet_checkpoint(
    path: Path, ckpt: Checkpoint, net: MSHAActorCritic, args: Any, row: dict[str, Any], key: str = "fleet_imitation"
) -> None:
    """The start's checkpoint ``ckpt`` with the trained weights (the same network, normaliser and spec: it loads and
    flies like the start, any fleet size, its conversions recorded), the run's options ``args`` (a dataclass:
    :class:`FleetImitationArgs`, or fleet_finetune's with ``key="fleet_finetune"``) under ``args[key]`` and this
    round's row recorded, without optimiser state."""
    options = {k: (str(v) if isinstance(v, Path) else list(v) if isinstance(v, tuple) else v)
               for k, v in dataclasses.asdict(args).items()}  # fmt: skip
    out = dataclasses.replace(
        ckpt,
        model={k: v.detach().clone() for k, v in net.state_dict().items()},
        net_config={**ckpt.net_config, **{k: True for k in CONVERSIONS if getattr(net.cfg, k)}},
        args={**ckpt.args, key: options},
        best_eval={k: float(v) for k, v in row.items()},
        optimizer={}, reward_scaler=None, cuda_rng=None, numpy_rng={},
    )  # fmt: skip
    out.save(path)


__all__ = [
    "CONVERSIONS",
    "MASKED_LOG_PROB",
    "MIXTURE",
    "TEACHER",
    "EpisodeLabels",
    "FleetImitationArgs",
    "StepWatch",
    "anchored_fit",
    "fleet_imitate",
    "label_episode",
    "make_teacher",
    "padded_rows",
    "parameter_groups",
    "save_fleet_checkpoint",
    "stop_labels",
    "stop_points",
    "teacher_claims",
    "training_episodes",
]
