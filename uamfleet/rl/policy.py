"""The trained policy at inference: :class:`GreedyPolicy` (greedy actions, the observer spec it reads, fitted at
``reset`` to the world it flies, the same weights for another fleet size). Its shapes come from the observation
spec (:class:`uamfleet.observe.spec.ObserverSpec`), never from a built env. Loading one from a checkpoint:
:func:`load_policy` (no env is built, the training loop is not imported).
"""

from __future__ import annotations

import copy
import math
import warnings
from pathlib import Path
from collections.abc import Callable
from typing import Any

import numpy as np
import torch
from gymnasium import spaces

from uamfleet.checks import ConfigError
from uamfleet.config import EnvConfig, WorldConfig
from uamfleet.env.protocol import PolicyBase
from uamfleet.observe.spec import (
    PASSENGER_AXIS_FIELDS,
    Layout,
    ObserverSpec,
    layout_differences,
    layout_shapes,
    observation_layout,
    observation_space,
)
from uamfleet.presets import PRESETS
from uamfleet.rl.buffer import ObservationNormalizer
from uamfleet.rl.checkpoint import Checkpoint, check_network, run_config, trained_spec
from uamfleet.rl.legacy import checkpoint_args, spec_of
from uamfleet.rl.loop_guard import LoopGuard
from uamfleet.rl.networks import DesignedTorso, MSHAActorCritic, NetConfig, obs_to_torch
from uamfleet.rl.options import TrainArgs
from uamfleet.rollout import Trajectory, fly
from uamfleet.sim.core import Simulator


class GreedyPolicy(PolicyBase):
    """The trained policy acting greedily (argmax of the masked logits) on a core's ``[E, A, ...]`` obs.

    ``spec`` (:class:`~uamfleet.observe.spec.ObserverSpec`, the protocol's :attr:`~uamfleet.env.protocol.Policy.spec`)
    is what it reads, as its checkpoint stores it; ``obs_shapes`` (one agent's observation shapes, the fields its
    network takes) are checked on every observation; ``num_taxis`` and ``passenger_slots`` (the
    training env's fleet size and passenger axis) let it refuse, with a message, an env of another layout;
    ``trained_on`` is the config it was evaluated on while training; ``thresholds_db`` (lowest, highest threshold it
    trained on), when given, makes :meth:`fit` warn once about a threshold outside them. It flies any world its spec
    reads (:meth:`fit` at ``reset``); :meth:`reading` gives a copy that reads another spec (a passenger window).

    Greedy decoding keeps one rule besides the argmax (:class:`uamfleet.rl.loop_guard.LoopGuard`, docs/rules.md
    "Greedy decoding of a trained policy"): a taxi does not fly back to a point it stood on since its last event
    while another allowed heading is left. :attr:`loop_guard` = None turns it off (the argmax alone)."""

    def __init__(
        self,
        net: MSHAActorCritic,
        normalizer: ObservationNormalizer | None,
        device: torch.device,
        obs_shapes: dict[str, tuple[int, ...]] | None = None,
        num_taxis: int | None = None,
        passenger_slots: int | None = None,
        trained_on: EnvConfig | None = None,
        thresholds_db: tuple[float, float] | None = None,
        spec: ObserverSpec | None = None,
    ) -> None:
        if spec is not None and net.cfg.hover_anytime and not spec.hover:
            raise ConfigError(
                "this policy's network takes the hover action at every step (NetConfig.hover_anytime), but its "
                "observer spec has hover=False: give it dataclasses.replace(spec, hover=True) (it flies hover worlds)."
            )
        self.net, self.normalizer, self.device = net, normalizer, device
        self.spec = spec
        self.obs_shapes, self.num_taxis, self.passenger_slots = obs_shapes, num_taxis, passenger_slots
        self.trained_on, self.thresholds_db = trained_on, thresholds_db
        # the window it trained with: its spec's as loaded (a copy reading another spec keeps it)
        self._trained_window = (
            spec.passenger_window if spec is not None else trained_on.passenger_window if trained_on else None
        )
        # fitted to the world of the last reset (None: as built): the network, normaliser and shapes it acts with,
        # and the fits to each world shape met (per network, so a network swapped in is fitted afresh)
        self._fitted: tuple[MSHAActorCritic, ObservationNormalizer | None, dict[str, tuple[int, ...]]] | None = None
        self._fits: dict[tuple[object, ...], tuple[Any, ...]] = {}
        self._warned_threshold = False
        self.loop_guard: LoopGuard | None = LoopGuard()
        self.traced = False  # see trace_actor
        self._traces: dict[tuple[object, ...], torch.jit.ScriptModule] = {}

    def reset(self, sim: Simulator | None = None) -> None:
        """A new episode (:meth:`Policy.reset <uamfleet.env.protocol.Policy.reset>`): the loop guard forgets every
        taxi's points, and a policy with a :attr:`spec` fits itself to the simulator's world (:meth:`fit`)."""
        if self.loop_guard is not None:
            self.loop_guard.reset()
        if sim is not None and self.spec is not None:
            self.fit(sim.cfg)

    def fit(self, world: WorldConfig) -> None:
        """Read ``world`` with this policy's :attr:`spec`, never changing the world: :class:`ConfigError` with the
        spec's one line when it cannot (:meth:`ObserverSpec.reads`); else the shapes it checks follow the rows the
        spec reads there (``slots_per_taxi`` times the world's taxis, or the window) and its fleet, and the
        normaliser's statistics of the set fields are pooled over their rows when the row count differs from the
        one it trained on (:meth:`ObservationNormalizer.resized`), also when it reads a window it did not train
        with. Fitted once per world shape; :attr:`net`, :attr:`normalizer`, :attr:`obs_shapes`, :attr:`num_taxis`
        and :attr:`passenger_slots` stay those it was built with. Warns once when the world's threshold lies outside
        :attr:`thresholds_db`."""
        assert self.spec is not None
        refusal = self.spec.reads(world)
        if refusal is not None:
            raise ConfigError(refusal + ".")
        self._warn_threshold(world.sinr_min_db)
        self._fitted = None
        shapes = self.obs_shapes
        if shapes is None:
            return
        layout = self.spec.layout(world)
        missing = sorted(set(shapes) - set(layout))
        if missing:
            raise ConfigError(
                f"this policy reads {missing}, which its spec lacks: give it the spec its checkpoint stores."
            )
        fitted = {k: layout[k].shape for k in shapes}
        window, trained_window = self.spec.passenger_window, self.passenger_window
        if fitted == shapes and window == trained_window:
            return
        if not isinstance(self.net.torso, DesignedTorso):
            raise ConfigError(
                "only a policy of a designed variant ('de', 'de_msfea', 'full') flies another fleet size or passenger "
                f"window; this one flies num_taxis={self.num_taxis} and {self.passenger_slots} passenger slots only."
            )
        key = (id(self.net), id(self.normalizer), tuple(sorted(fitted.items())), window)
        if key not in self._fits:
            resized = copy.copy(self.net)  # the same modules and weights; only the shapes it checks differ
            resized.shapes = fitted
            pooled = self.normalizer
            if pooled is not None and window is not None and trained_window is None:
                pooled = pooled.resized(_one_row(fitted))  # rows no longer mean request indices: pool them
            # the network and normaliser fitted are kept alive with their fit, so that their ids stay theirs
            self._fits[key] = (
                resized,
                pooled.resized(fitted) if pooled is not None else None,
                self.net,
                self.normalizer,
            )
        net, normalizer = self._fits[key][:2]
        self._fitted = (net, normalizer, fitted)

    def fitted(self) -> tuple[MSHAActorCritic, ObservationNormalizer | None, dict[str, tuple[int, ...]] | None]:
        """The network, normaliser and field shapes it acts with: fitted to the world of the last reset, else as
        built."""
        return self._fitted if self._fitted is not None else (self.net, self.normalizer, self.obs_shapes)

    def _warn_threshold(self, sinr_min_db: float) -> None:
        """Warn once when ``sinr_min_db`` lies outside :attr:`thresholds_db`."""
        low, high = self.thresholds_db or (-math.inf, math.inf)
        if not low <= sinr_min_db <= high and not self._warned_threshold:
            self._warned_threshold = True  # once: a sweep over thresholds would otherwise repeat it per episode
            warnings.warn(
                f"sinr_min_db={sinr_min_db:g} dB lies outside the thresholds this policy trained on "
                f"({low:g} ... {high:g} dB); it flies, but nothing was measured there (docs/results.md).",
                UserWarning,
                stacklevel=4,
            )

    @property
    def passenger_window(self) -> int | None:
        """The passenger window it trained with (``ObserverSpec.passenger_window`` of its checkpoint): None: it
        trained on a fixed passenger axis, row p read as request p."""
        return self._trained_window

    def reading(self, spec: ObserverSpec) -> GreedyPolicy:
        """A copy of this policy (the same network, weights and normaliser) that reads ``spec`` instead of its own,
        fitted at each ``reset`` like it (:meth:`fit`): e.g. a passenger window it did not train with,
        ``policy.reading(dataclasses.replace(policy.spec, passenger_window=24, time_scale_steps=None))``. The
        network's own needs stay its own: ConfigError when ``spec`` drops the hover action it takes or reads the
        other taxis otherwise than it does (``hover``, ``fleet_rows``)."""
        if self.spec is None:
            raise ConfigError("this policy has no observer spec to replace: load it with load_policy.")
        if (spec.hover, spec.fleet_rows) != (self.spec.hover, self.spec.fleet_rows):
            raise ConfigError(
                f"hover={spec.hover}, fleet_rows={spec.fleet_rows}: this policy's network takes hover="
                f"{self.spec.hover} and fleet_rows={self.spec.fleet_rows}; keep them: "
                "dataclasses.replace(policy.spec, ...)."
            )
        if spec == self.spec:
            return self
        other = copy.copy(self)
        other.spec = spec
        other._fitted, other._fits = None, {}
        other.loop_guard = LoopGuard() if self.loop_guard is not None else None
        return other

    def with_network(
        self, cfg: NetConfig, load: Callable[[MSHAActorCritic], None], spec: ObserverSpec | None = None
    ) -> GreedyPolicy:  # fmt: skip
        """A copy of this policy (normaliser, device, shapes, training config, thresholds, loop guard, tracing) whose
        network is a new :class:`MSHAActorCritic` of ``cfg`` on the same input shapes, its weights set by
        ``load(network)`` and its training mode this one's; reading ``spec`` (None: this policy's). For converters
        that widen a trained network with new inputs or logits at zero weight (:mod:`uamfleet.rl.hover`,
        :mod:`uamfleet.rl.fleet_claims`)."""
        net = self.net
        space = spaces.Dict({k: spaces.Box(-np.inf, np.inf, shape, np.float32) for k, shape in net.shapes.items()})
        with torch.random.fork_rng(devices=[]):  # the initial weights drawn here are replaced: leave the caller's RNG
            new = MSHAActorCritic(space, cfg).to(self.device)
        load(new)
        new.train(net.training)
        converted = type(self)(
            new, self.normalizer, self.device, self.obs_shapes, self.num_taxis, self.passenger_slots,
            self.trained_on, self.thresholds_db, self.spec if spec is None else spec,
        )  # fmt: skip
        converted.loop_guard = LoopGuard() if self.loop_guard is not None else None
        return converted.trace_actor(self.traced)

    def fly(self, cfg: EnvConfig, seed: int | None = 0) -> Trajectory:
        """One recorded episode of this policy on the world ``cfg`` as given (observed by its :attr:`spec`); score
        it with :func:`uamfleet.metrics.episode_metrics`."""
        return fly(cfg, self, seed=seed)

    def check_layout(self, obs: dict[str, np.ndarray]) -> None:
        """ValueError naming every observation field whose shape differs from the training env's."""
        shapes = self.fitted()[2]
        if shapes is None:
            return
        diffs = [
            f"{k!r} {tuple(obs[k].shape[2:]) if k in obs else None} (trained on {shape})"
            for k, shape in shapes.items()
            if k not in obs or tuple(obs[k].shape[2:]) != tuple(shape)
        ]
        if diffs:
            window = self.spec.passenger_window if self.spec is not None else self.passenger_window
            axis = (
                f"passenger_window={window}" if window is not None else
                f"max_passengers={self.passenger_slots} (a smaller instance is padded by max_passengers)"
            )  # fmt: skip
            raise ValueError(
                f"this env's observations differ from the policy's training env ({self.num_taxis} taxi(s), "
                f"{self.passenger_slots} passenger slot(s)): " + ", ".join(diffs) + ". Fly it on an env with "
                f"num_taxis={self.num_taxis} and {axis} (reset the policy with the simulator: it fits itself to the "
                "world its spec reads), or train a policy for this one."
            )

    def network_input(self, obs: dict[str, np.ndarray]) -> dict[str, np.ndarray]:
        """What the network reads of a core's ``[E, A, ...]`` observation: one row per taxi (``[E * A, ...]``), the
        fields it was trained on, normalised."""
        self.check_layout(obs)
        E, A = obs["action_mask"].shape[:2]
        _, normalizer, shapes = self.fitted()
        known = shapes or obs  # a field the policy was not trained on is not read
        flat = {k: v.reshape(E * A, *v.shape[2:]) for k, v in obs.items() if k in known}
        return normalizer(flat) if normalizer is not None else flat

    def trace_actor(self, enabled: bool = True) -> GreedyPolicy:
        """Run the network's actor as TorchScript traces (``torch.jit.trace``), one per set of input shapes, made
        at its first call: the same logits bit for bit (the actor branches on shapes only, never on values), in
        less than half the time of the eager call for a lone taxi (reports/2026-12-03-benchmarks-history/README.md, "the
        actor as TorchScript traces"), which is mostly Python overhead per operation. The traces share the network's
        parameters, so later weight updates are seen. For deployment and benchmarks; training and its evaluations run
        eagerly. Returns this policy."""
        self.traced = enabled
        self._traces.clear()
        return self

    @torch.inference_mode()
    def logits_of(self, inputs: dict[str, np.ndarray]) -> torch.Tensor:
        """Masked logits [B, 16] (17 with the hover action's, ``NetConfig.hover_logit`` / ``hover_anytime``) for
        :meth:`network_input` rows (needs no critic state). Under inference mode, not only no_grad: less overhead per
        call, which a lone taxi's decision is mostly (docs/benchmarks.md, "Decision time"); with :meth:`trace_actor`,
        through a trace."""
        return self._logits(obs_to_torch(inputs, self.device))

    @torch.inference_mode()
    def _logits(self, x: dict[str, torch.Tensor]) -> torch.Tensor:
        """:meth:`logits_of` of inputs already converted to tensors (``obs_to_torch``)."""
        net = self.fitted()[0]
        if not self.traced:
            return net.masked_logits(x)
        keys = tuple(sorted(x))
        signature = _signature(x)
        trace = self._traces.get(signature)
        if trace is None:
            # The shape checks become constants of the trace, so there is one per set of shapes. torch 2.13 calls
            # torch.jit deprecated in favour of torch.export / torch.compile; here torch.export's module ran slower
            # than eager (1.06 against 0.71 ms) and torch.compile took minutes, so the trace stays while it exists.
            with warnings.catch_warnings():
                warnings.simplefilter("ignore", torch.jit.TracerWarning)
                warnings.simplefilter("ignore", DeprecationWarning)
                try:
                    trace = torch.jit.trace(_Actor(net, keys).eval(), tuple(x[k] for k in keys), check_trace=False)
                except Exception as err:  # a torch without torch.jit, or a network it cannot trace: run eagerly
                    warnings.warn(f"trace_actor: tracing failed ({err!r}); the actor runs eagerly.", stacklevel=2)
                    self.traced = False
                    return net.masked_logits(x)
            self._traces[signature] = trace
        return trace(*(x[k] for k in keys))

    def trace_for(self, inputs: dict[str, np.ndarray]) -> None:
        """With :meth:`trace_actor`, make the trace of ``inputs``' shapes unless it exists (one forward pass, whose
        logits are dropped); nothing otherwise. A search calls it at reset for every batch shape it will feed."""
        if self.traced:
            x = obs_to_torch(inputs, self.device)  # converted once: the signature and the forward pass share it
            if _signature(x) not in self._traces:
                self._logits(x)

    def act(self, obs: dict[str, np.ndarray]) -> np.ndarray:
        return self.choose(obs, self.logits_of(self.network_input(obs)))

    def choose(self, obs: dict[str, np.ndarray], logits: torch.Tensor) -> np.ndarray:
        """The greedy actions ``[E, A]`` for ``obs`` given its :meth:`logits_of` (through the loop guard, which
        records the step: call it once per step, as :meth:`act` does)."""
        E, A = obs["action_mask"].shape[:2]
        if self.loop_guard is None:
            return logits.argmax(-1).cpu().numpy().reshape(E, A)
        return self.loop_guard.choose(obs, logits.cpu().numpy()).reshape(E, A)


def _signature(x: dict[str, torch.Tensor]) -> tuple[tuple[object, ...], ...]:
    """The key of a trace: each input's name, shape and dtype (a trace's shape checks are constants)."""
    return tuple((k, tuple(x[k].shape), x[k].dtype) for k in sorted(x))


class _Actor(torch.nn.Module):
    """``net.masked_logits`` with the observation's fields as positional tensors (in ``keys`` order), as
    ``torch.jit.trace`` takes them."""

    def __init__(self, net: MSHAActorCritic, keys: tuple[str, ...]) -> None:
        super().__init__()
        self.net, self.keys = net, keys

    def forward(self, *fields: torch.Tensor) -> torch.Tensor:
        return self.net.masked_logits(dict(zip(self.keys, fields, strict=True)))


__all__ = ["GreedyPolicy"]


def load_policy(
    path: str | Path, device: str = "cpu", env_config: EnvConfig | None = None
) -> tuple[GreedyPolicy, TrainArgs]:
    """A greedy policy and the training arguments from a checkpoint written by :func:`train` (pass the same
    ``env_config`` when it was trained on one). Loads with ``weights_only=True``: a foreign or pickle-only
    file is refused with a ValueError, a checkpoint of another observation layout says what differs. The policy
    reads the observer spec its checkpoint stores (format 3), else the one rebuilt from the config it was
    evaluated on (format 2: :func:`~uamfleet.rl.legacy.spec_of`)."""
    ckpt = Checkpoint.load(path, map_location=device)
    args = checkpoint_args(ckpt)
    cfg = env_config if env_config is not None else run_config(args, training=False)
    # what it reads: stored (format 3), else rebuilt from its arguments (format 2, a fine-tune through its start's
    # files) or from the config it was trained on when one is given
    if env_config is None:
        spec = spec_of(ckpt, str(path))
    else:
        spec = ckpt.spec(str(path)) or trained_spec(cfg, ckpt.net_config, str(path))
    layout = spec.layout(cfg.world)  # the spec: no env is built
    _check_layout(ckpt, layout, str(path), args)
    if env_config is not None:  # the config it trained on, as given, must observe what the weights read
        _check_layout(ckpt, observation_layout(env_config), str(path), args)
    read = {k: field for k, field in layout.items() if k in ckpt.obs_shapes}  # fields added since are not read
    space, shapes = observation_space(read), layout_shapes(read)
    net = MSHAActorCritic(space, check_network(ckpt, space, str(path))).to(device)
    net.load_state_dict(ckpt.model)
    net.eval()
    normalizer = None
    if ckpt.obs_normalizer is not None:
        normalizer = ObservationNormalizer(shapes)
        normalizer.load_state_dict(ckpt.obs_normalizer)
    trained_on = env_config if env_config is not None else cfg
    if env_config is not None and args.env.scenario in PRESETS:
        trained_on = run_config(args, training=False)
    return GreedyPolicy(
        net, normalizer, torch.device(device), shapes, cfg.num_taxis, spec.rows(cfg.world), trained_on, spec=spec
    ), args


def _one_row(shapes: dict[str, tuple[int, ...]]) -> dict[str, tuple[int, ...]]:
    """``shapes`` with one row in each passenger-axis field: a normaliser resized to it has its passenger rows'
    statistics pooled (:meth:`ObservationNormalizer.resized`), to be resized again to any row count."""
    return {k: (1, *v[1:]) if k in PASSENGER_AXIS_FIELDS else v for k, v in shapes.items()}


def _check_layout(ckpt: Checkpoint, layout: Layout, source: str, args: TrainArgs) -> None:
    """ValueError naming every field of the checkpoint's training spec that ``layout`` (the env's) lacks or
    describes otherwise (shape, dtype, bounds, columns, kind); fields only the env has are not read. A file written
    before checkpoints stored the spec is compared by shapes."""
    trained = ckpt.layout(source)
    if trained is None:
        try:
            ckpt.check_matches(None, layout_shapes(layout), extra_ok=True)
            return
        except ValueError as err:
            why = str(err)
    else:
        diffs = layout_differences(trained, {k: spec for k, spec in layout.items() if k in trained})
        if not diffs:
            return
        lines = [line.replace("only in the first layout", "not observed by this env") for line in diffs]
        why = "its observation spec differs from this env's (checkpoint vs env): " + "; ".join(
            f"observation field {line}" for line in lines
        )
        why += "."
    fields = ckpt.obs_shapes
    raise ValueError(
        f"{source}: {why} The policy flies any config of its observation layout (any threshold, instance or "
        f"fewer passengers): num_taxis={args.env.num_taxis or 'as trained'}, max_passengers="
        f"{fields.get('passengers', ['?'])[0]}, stop_features={'stop_paths' in fields}, "
        f"stop_rivals={'stop_rivals' in fields}, stop_claims={'stop_claims' in fields}."
    ) from None
