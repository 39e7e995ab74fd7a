"""Learned policies: the shipped ones (the model zoo) and any checkpoint, by name or file, in the registry.

    import uamfleet
    planner = uamfleet.pretrained("berlin")            # the Berlin generalist (one taxi, -7 ... -3 dB)
    cfg = uamfleet.make_config("berlin_p4", sinr_min_db=-5.0)   # or any start / requests / threshold
    traj = planner.fly(cfg)     # one episode; score it with uamfleet.metrics.episode_metrics(traj, cfg.radio)

    from uamfleet import policies
    fleet = policies.make("learned", source="berlin_fleet", taxis=4, passenger_window=24)

Each shipped file is a training checkpoint stripped of its optimiser and RNG state (:func:`export_policy`), loaded
with ``torch.load(weights_only=True)`` like every checkpoint.
"""

from __future__ import annotations

import copy
import dataclasses
import functools
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Literal

from uamfleet.baselines.assignment_value import CHOSEN_DISPATCHER
from uamfleet.checks import MAX_PASSENGERS, MAX_TAXIS, check_integer, check_number
from uamfleet.config import FLEET_ARRIVAL_WINDOW_S
from uamfleet.observe.spec import ObserverSpec
from uamfleet.policies.registry import PolicyNameError, register
from uamfleet.rl.checkpoint import PRETRAINED, Checkpoint, checkpoint_source, pretrained_path
from uamfleet.rl.fleet_claims import ClaimsFleetPolicy, check_claims_heading, with_dispatch_claims
from uamfleet.rl.idle_wait import IdleWait
from uamfleet.rl.legacy import with_stored_spec
from uamfleet.rl.loop_guard import LoopGuard
from uamfleet.rl.policy import GreedyPolicy, load_policy


def pretrained(name: str = "berlin", device: str = "cpu") -> GreedyPolicy:
    """The shipped policy ``name`` (:data:`PRETRAINED`) as a greedy planner: call it on observations, or
    ``.fly(cfg)`` any world of its map its observer spec reads (it fits itself at ``reset``). Flown at a
    threshold outside those it trained on (its training arguments' ``thresholds``, else ``sinr_min_db``), it
    warns once."""
    policy, args = load_policy(pretrained_path(name), device=device)
    assert policy.trained_on is not None  # load_policy always sets it
    single = args.env.sinr_min_db if args.env.sinr_min_db is not None else policy.trained_on.sinr_min_db
    trained = [float(t) for t in args.env.thresholds] if args.env.thresholds else [float(single)]
    policy.thresholds_db = (min(trained), max(trained))
    return policy


def export_policy(checkpoint: str | Path, out: str | Path) -> Path:
    """Write ``checkpoint`` without what only training needs (optimiser moments, RNG states): a few hundred
    kB that still loads with :func:`uamfleet.rl.policy.load_policy` (it cannot be resumed). It is written in the
    current format: what the policy reads (``observer``) and the world it trained in (``world``) are stored, for a
    file of format 2 rebuilt from its training arguments (:func:`uamfleet.rl.legacy.with_stored_spec`)."""
    ckpt = with_stored_spec(Checkpoint.load(checkpoint), str(checkpoint))
    ckpt.optimizer = {}
    ckpt.numpy_rng = {}
    ckpt.reward_scaler = None
    ckpt.cuda_rng = None
    out = Path(out)
    ckpt.save(out)
    return out


@functools.lru_cache(maxsize=8)
def learned_policy(checkpoint: Path) -> GreedyPolicy:
    """The greedy policy of a checkpoint file, loaded once per process (it keeps no state between episodes)."""
    return load_policy(checkpoint)[0]


@functools.lru_cache(maxsize=8)
def traced_policy(checkpoint: Path) -> GreedyPolicy:
    """A second copy of a checkpoint's greedy policy with its actor traced (the same actions, less overhead per
    call; ``GreedyPolicy.trace_actor``), for a search that calls the actor thousands of times per decision. A copy,
    so the eager policy's decision times stay its own."""
    policy = load_policy(checkpoint)[0]
    policy.trace_actor()
    return policy


@functools.lru_cache(maxsize=8)
def _shipped(name: str, device: str, traced: bool) -> GreedyPolicy:
    policy = pretrained(name, device=device)
    return policy.trace_actor() if traced else policy


@dataclass(frozen=True)
class LearnedOptions:
    """``learned``: the greedy policy of ``source`` (a :data:`PRETRAINED` name or a checkpoint file) on ``device``.
    ``taxis``, ``passenger_slots`` (rows of the passenger axis; ``"world"``: as many as the world has requests,
    resolved by :func:`for_world`) and ``passenger_window`` (K rows per taxi, any number of requests; exclusive
    with ``passenger_slots``) change the rows it reads (:func:`spec_of`); any fleet size its spec reads flies
    zero-shot, fitted at ``reset``; ``loop_guard``
    false: the argmax alone; ``idle_wait``: a taxi with nothing to do stays in place (:mod:`uamfleet.rl.idle_wait`);
    ``traced``: its actor traced (a copy, for searches)."""

    source: str = "berlin"
    device: str = "cpu"
    passenger_window: int | None = None
    passenger_slots: int | Literal["world"] | None = None
    taxis: int | None = None
    loop_guard: bool = True
    idle_wait: bool = False
    traced: bool = False

    def __post_init__(self) -> None:
        if self.passenger_window is not None and self.passenger_slots is not None:
            raise PolicyNameError(
                f"passenger_window={self.passenger_window} and passenger_slots={self.passenger_slots!r} both size "
                "the passenger axis; give one."
            )
        if self.passenger_window is not None:
            fix = " (the passenger rows each taxi reads, e.g. 24)"
            check_integer("passenger_window", self.passenger_window, 1, MAX_PASSENGERS, fix=fix)
        if self.passenger_slots is not None and self.passenger_slots != "world":
            fix = " (the passenger rows of the whole fleet; at most MAX_PASSENGERS)"
            check_integer("passenger_slots", self.passenger_slots, 1, MAX_PASSENGERS, fix=fix)
        if self.taxis is not None:
            check_integer("taxis", self.taxis, 1, MAX_TAXIS)


def for_world(options: dict[str, Any], taxis: int, requests: int) -> dict[str, Any]:
    """``learned`` options for a world of ``taxis`` and ``requests``: ``passenger_slots="world"`` becomes
    ``requests``, and the fleet size is ``taxis`` where the options size the passenger axis."""
    out = dict(options)
    if out.get("passenger_slots") == "world":
        out["passenger_slots"] = requests
    if out.get("passenger_slots") is not None or out.get("passenger_window") is not None:
        out.setdefault("taxis", taxis)
    return out


def spec_of(policy: GreedyPolicy, options: LearnedOptions) -> ObserverSpec:
    """What ``policy`` reads under ``options``: its own spec; with ``passenger_window=K`` a window of K rows (the
    time feature then over each world's own limit, as a windowed policy trains); with ``passenger_slots=S`` and no
    window, S rows for a fleet of ``taxis`` (the same number of rows per taxi in a fleet of another size)."""
    assert policy.spec is not None, "load_policy gives every policy its spec"
    spec = policy.spec
    if options.passenger_window is not None:
        return dataclasses.replace(spec, passenger_window=options.passenger_window, time_scale_steps=None)
    if isinstance(options.passenger_slots, int) and spec.passenger_window is None:
        taxis = options.taxis if options.taxis is not None else policy.num_taxis or 1
        return dataclasses.replace(spec, slots_per_taxi=options.passenger_slots / taxis)
    return spec


def load(options: LearnedOptions) -> GreedyPolicy:
    """The greedy policy ``options`` name: a copy of the one load per process and source (reading another spec when
    the options resize its passenger axis, :func:`spec_of`), with its own loop guard."""
    if options.source in PRETRAINED:
        policy = _shipped(options.source, options.device, options.traced)
    else:
        path = checkpoint_source(options.source)
        if options.device != "cpu":
            policy = load_policy(path, device=options.device)[0].trace_actor(options.traced)
        else:
            policy = (traced_policy if options.traced else learned_policy)(path)
    if options.passenger_slots == "world":
        raise PolicyNameError(
            "learned: passenger_slots='world' is read against a world; resolve it with "
            "uamfleet.policies.learned.for_world(options, taxis, requests) or give a number."
        )
    # a copy of the process's one load, with its own loop guard: the guard keeps the episode's moves, so two
    # policies of one source (two fleet_claims decodings, a search and its base) must not share one
    policy = copy.copy(policy.reading(spec_of(policy, options)))
    if options.idle_wait:
        policy.loop_guard = IdleWait(options.loop_guard)
    else:
        policy.loop_guard = LoopGuard() if options.loop_guard else None
    return policy


register("learned", "learned", LearnedOptions, lambda o, _b: load(o))


@dataclass(frozen=True)
class FleetClaimsOptions:
    """``fleet_claims``: the fleet policy of checkpoint ``source`` (trained with ``uamfleet fleet-imitate
    --dispatch-claims``) reading ``passenger_window`` rows per taxi and, on each, the claims of the chosen dispatcher
    (:data:`~uamfleet.baselines.assignment_value.CHOSEN_DISPATCHER`) that runs alongside for a service of
    ``arrival_window_s`` (:mod:`uamfleet.rl.fleet_claims`); the network decides every move. A fleet method that
    the fleet benchmark flies like a dispatcher (``--dispatchers fleet_claims:source=<file>``). A source that reads
    no claims (the default, the shipped ``berlin_fleet``) is converted with them at zero weight: it flies as
    itself. ``hover_when_idle``: a taxi with an open stop on the dispatcher's schedule never hovers (a decoding rule
    for a network that may hover at any step; :class:`~uamfleet.rl.fleet_claims.ClaimsFleetPolicy`). ``heading``:
    ``table`` (the env's stop heading marks) or ``onward`` (each taxi's next stop marked, on the move that makes it,
    with the move that ends nearest the stop after it on the dispatcher's schedule:
    :func:`~uamfleet.rl.fleet_claims.onward_marks`); unset, the marks the checkpoint was trained on (``uamfleet
    fleet-imitate --claims-heading``, recorded in it), else ``table``. ``make_way``: under the separation shield a
    hovering or idle taxi steps out of a moving taxi's way, as the dispatchers do
    (:func:`uamfleet.baselines.fleet_steering.make_way`; off by default, so the recorded names fly as they flew)."""

    source: str = "berlin_fleet"
    passenger_window: int = 24
    arrival_window_s: float = FLEET_ARRIVAL_WINDOW_S
    hover_when_idle: bool = False
    heading: str | None = None
    make_way: bool = False

    def __post_init__(self) -> None:
        check_integer("passenger_window", self.passenger_window, 1, MAX_PASSENGERS, fix=" (e.g. 24)")
        check_number("arrival_window_s", self.arrival_window_s, positive=True)
        if self.heading is not None:
            check_claims_heading(self.heading)


def fleet_claims(options: FleetClaimsOptions) -> ClaimsFleetPolicy:
    """The :class:`~uamfleet.rl.fleet_claims.ClaimsFleetPolicy` ``options`` names (a fresh dispatcher alongside)."""
    from uamfleet.policies.planners import make_flown  # here: importing it at the top registers planners first

    policy = load(LearnedOptions(source=options.source, passenger_window=options.passenger_window))
    policy = with_dispatch_claims(policy)  # a copy reading claims at zero weight, unless it reads them already
    teacher = make_flown(CHOSEN_DISPATCHER, arrival_window_s=options.arrival_window_s)
    heading = options.heading if options.heading is not None else trained_claims_heading(options.source)
    return ClaimsFleetPolicy(
        policy, teacher, hover_when_idle=options.hover_when_idle, heading=heading, make_way=options.make_way
    )


def trained_claims_heading(source: str) -> str:
    """The stop heading marks the fleet policy of ``source`` (a shipped name or a checkpoint file) was trained on:
    its last ``uamfleet fleet-imitate`` run's ``--claims-heading``, ``table`` for any other policy."""
    options = Checkpoint.load(checkpoint_source(source)).args.get("fleet_imitation") or {}
    return check_claims_heading(options.get("claims_heading", "table"))


register("fleet_claims", "dispatcher", FleetClaimsOptions, lambda o, _b: fleet_claims(o))

__all__ = [
    "PRETRAINED",
    "FleetClaimsOptions",
    "LearnedOptions",
    "export_policy",
    "fleet_claims",
    "for_world",
    "learned_policy",
    "load",
    "pretrained",
    "pretrained_path",
    "spec_of",
    "traced_policy",
    "trained_claims_heading",
]
