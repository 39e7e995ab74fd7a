"""Training checkpoints: saved atomically, loaded without running code, and checked before anything is built.

A :class:`Checkpoint` holds tensors, numbers, strings, lists and dicts only, so ``torch.load(weights_only=True)``
reads it and loading never runs code. A file is an input like any other, so before a network is built from it:

- :meth:`Checkpoint.from_bytes` refuses a file torch will not read safely, a file without the checkpoint's keys, a
  ``net_config`` of unknown fields or of sizes far beyond any trained policy (:data:`NET_LIMITS`: a crafted file
  asking for ``d_model=10**6`` is refused in milliseconds, before allocating anything), and NaN or infinite
  weights or normalisation statistics (they fly silently and deliver nobody);
- :func:`check_network` builds the network on PyTorch's ``meta`` device (shapes only, no memory) and compares
  every tensor's shape with the checkpoint's before ``load_state_dict``, so a mismatch is one line naming the
  tensor, not a RuntimeError listing them all.

Every refusal is a :class:`CheckpointError` (a ValueError: one line and exit status 2 on the command line).
Files of format 1 and the flat training arguments are read by :mod:`uamfleet.rl.legacy`.
"""

from __future__ import annotations

import dataclasses
import io
import re
import stat
from collections.abc import Iterator, Mapping
from dataclasses import dataclass
from importlib import resources
from pathlib import Path
from typing import Any

import numpy as np
import torch
from gymnasium import spaces

from uamfleet.config import EnvConfig, world_record
from uamfleet.observe.legacy import split_env_config
from uamfleet.observe.spec import Layout, ObserverSpec, layout_differences, layout_from_dict
from uamfleet.io import PathError, os_error_message, shown_path, write_bytes_atomic
from uamfleet.rl.networks import INPUT_FIELDS, MSHAActorCritic, NetConfig, observed_inputs
from uamfleet.rl.options import TrainArgs, make_env_config

CHECKPOINT_FORMAT = 3
"""3: as 2, plus what the policy reads (``observer``, :meth:`ObserverSpec.to_dict`) and the world it trained in
(``world``, :func:`world_record`), both plain values; 2: tensors, numbers, strings, lists and dicts only
(``torch.load(weights_only=True)``), what it reads rebuilt from its ``args`` (:func:`uamfleet.rl.legacy.
spec_of_checkpoint`); 1 (before): a pickled NumPy RNG state inside."""
ARCHITECTURE_FIELDS = (
    "variant", "d_model", "num_heads", "local_window", "readout", "centralised_critic", "action_head",
    "stop_free_move", "stop_prior",
)  # fmt: skip
ENVIRONMENT_FIELDS = (
    "scenario", "sinr_min_db", "thresholds", "num_taxis", "num_requests", "fleet_mixture", "feasibility", "norm_obs",
    "norm_reward",
)  # fmt: skip

NET_LIMITS: dict[str, int] = {"d_model": 4096, "num_heads": 256, "local_window": 256, "hidden": 16384,
                              "critic_state_dim": 1_000_000}  # fmt: skip
"""Largest size each integer field of a checkpoint's ``net_config`` may ask for: far above any policy trained here
(d_model 16 ... 128, hidden 128), low enough that a crafted file cannot make the loader allocate gigabytes."""


class CheckpointError(ValueError):
    """A file that is not a checkpoint uamfleet loads safely, or one that does not fit the network or env."""


class DeviceError(ValueError):
    """A torch device that is no device (``'bogus'``) or that this machine lacks (``'cuda:7'``)."""


def check_device(device: object) -> torch.device:
    """``device`` as a ``torch.device``, refused (:class:`DeviceError` naming it and the devices there are) when it
    names no device or one this machine lacks, before any file is read onto it."""
    if isinstance(device, torch.device):
        parsed = device
    else:
        try:
            parsed = torch.device(device)  # type: ignore[call-overload]
        except (RuntimeError, TypeError, ValueError):
            raise DeviceError(
                f"device={device!r} is not a torch device; use 'cpu', 'cuda' or 'cuda:<index>' ({_devices()})."
            ) from None
    if parsed.type == "cuda":
        count = torch.cuda.device_count() if torch.cuda.is_available() else 0
        if count == 0 or (parsed.index is not None and parsed.index >= count):
            raise DeviceError(f"device={str(device)!r} is not on this machine ({_devices()}); use one of those.")
    elif parsed.type not in ("cpu", "meta"):
        if parsed.type == "mps" and torch.backends.mps.is_available():
            return parsed
        raise DeviceError(f"device={str(device)!r}: uamfleet runs on 'cpu' or 'cuda' ({_devices()}).")
    return parsed


def _devices() -> str:
    count = torch.cuda.device_count() if torch.cuda.is_available() else 0
    if count == 0:
        return "this machine has the CPU and no CUDA device"
    return f"this machine has the CPU and CUDA devices cuda:0 ... cuda:{count - 1}"


def _unreadable(path: Path, err: OSError) -> PathError:
    return PathError(f"cannot read checkpoint {shown_path(path)}: {os_error_message(err, with_path=False)}", err, path)


def read_checkpoint_file(path: str | Path) -> bytes:
    """The bytes of the checkpoint file ``path``; an OSError with one line naming it when it is missing, a folder,
    a FIFO or another non-file, or unreadable (the file is never opened unless it is a regular file: a FIFO would
    block)."""
    path = Path(path)
    shown = shown_path(path)
    try:
        mode = path.stat().st_mode
    except FileNotFoundError:
        raise FileNotFoundError(
            f"checkpoint {shown} does not exist; train one with uamfleet-train (or python train/ppo.py)."
        ) from None
    except OSError as err:
        raise _unreadable(path, err) from None
    if stat.S_ISDIR(mode):
        raise PathError(
            f"checkpoint {shown} is a folder, not a file; give a checkpoint file in it (e.g. {shown}/best.pt).",
            path=path,
        )
    if not stat.S_ISREG(mode):
        raise PathError(
            f"checkpoint {shown} is not a regular file (a FIFO, socket or device); give a checkpoint file.", path=path
        )
    try:
        return path.read_bytes()
    except OSError as err:
        raise _unreadable(path, err) from None


@dataclass
class Checkpoint:
    """Everything to continue a run or fly its policy: tensors, numbers, strings, lists and dicts only, so
    ``torch.load(path, weights_only=True)`` loads it and loading never runs code."""

    model: dict[str, torch.Tensor]
    optimizer: dict[str, Any]
    net_config: dict[str, Any]
    args: dict[str, Any]
    obs_shapes: dict[str, list[int]]
    iteration: int  # iterations completed
    global_step: int  # agent-steps trained on (all ranks)
    wall_s: float
    obs_normalizer: dict[str, Any] | None
    reward_scaler: dict[str, Any] | None
    best_eval: dict[str, float]
    best_step: int
    target_step: int | None
    target_s: float | None
    torch_rng: torch.Tensor
    numpy_rng: dict[str, Any]
    cuda_rng: torch.Tensor | None = None
    format: int = CHECKPOINT_FORMAT
    obs_layout: dict[str, Any] | None = None  # layout_to_dict of the training env's spec; None: an older file
    observer: dict[str, Any] | None = None  # ObserverSpec.to_dict of what the policy reads; None: format 2 or older
    world: dict[str, Any] | None = None  # world_record of the world it trained in; None: format 2 or older

    def to_bytes(self) -> bytes:
        data = io.BytesIO()
        torch.save({f.name: getattr(self, f.name) for f in dataclasses.fields(self)}, data)
        return data.getvalue()

    def save(self, path: Path) -> None:
        write_bytes_atomic(path, self.to_bytes())

    @classmethod
    def load(cls, path: str | Path, map_location: str | torch.device = "cpu") -> Checkpoint:
        """The checkpoint file ``path`` (:meth:`from_bytes`). A path that is missing, a folder, a FIFO or another
        non-file, or that cannot be read is an OSError whose one-line message names it; a device that cannot take
        the tensors is a ValueError naming the device (:func:`check_device`)."""
        check_device(map_location)
        return cls.from_bytes(read_checkpoint_file(path), str(path), map_location)

    @classmethod
    def from_bytes(cls, data: bytes, source: str, map_location: str | torch.device = "cpu") -> Checkpoint:
        """The checkpoint in ``data`` (read from ``source``), checked: keys, net_config, finite values."""
        check_device(map_location)
        try:
            payload = torch.load(io.BytesIO(data), map_location=map_location, weights_only=True)
        except Exception as err:  # torch raises UnpicklingError, RuntimeError or ValueError by cause
            raise CheckpointError(f"{source} is not a checkpoint uamfleet loads safely ({_refusal(err)}).") from None
        names = [f.name for f in dataclasses.fields(cls)]
        required = [f.name for f in dataclasses.fields(cls) if f.default is dataclasses.MISSING]
        if not isinstance(payload, dict) or any(k not in payload for k in required):
            got = sorted(map(str, payload)) if isinstance(payload, dict) else type(payload).__name__
            raise CheckpointError(
                f"{source} is not a uamfleet training checkpoint (expected keys {required}, got {got})."
            )
        ckpt = cls(**{k: v for k, v in payload.items() if k in names})
        ckpt._check_parts(source)
        ckpt.net_config = with_input_flags(ckpt.net_config, ckpt.obs_shapes)
        ckpt.validate(source)
        return ckpt

    def layout(self, source: str) -> Layout | None:
        """The training env's observation spec (None for a file written before checkpoints stored it)."""
        if self.obs_layout is None:
            return None
        try:
            return layout_from_dict(self.obs_layout)
        except (ValueError, TypeError, AttributeError) as err:
            raise CheckpointError(f"{source}: its observation layout is not a spec: {err}") from None

    def spec(self, source: str) -> ObserverSpec | None:
        """What the policy reads, as stored (format 3); None for a file written before checkpoints stored it."""
        if self.observer is None:
            return None
        try:
            return ObserverSpec.from_dict(self.observer)
        except (ValueError, TypeError) as err:
            raise CheckpointError(f"{source}: its observer is not an observer spec: {err}") from None

    def validate(self, source: str) -> NetConfig:
        """Raise CheckpointError unless the parts are of the right types, the network config is known and
        bounded, and every weight and normalisation statistic is finite; the network's config."""
        self._check_parts(source)
        cfg = check_net_config(self.net_config, source)
        for name, value in self.model.items():
            if not isinstance(value, torch.Tensor):
                raise CheckpointError(f"{source}: model entry {name!r} is a {type(value).__name__}, not a tensor.")
        for name, value in self.statistics(source):
            if value.is_floating_point() and not bool(torch.isfinite(value).all()):
                bad = int((~torch.isfinite(value)).sum())
                raise CheckpointError(
                    f"{source}: {name} holds {bad} NaN or infinite value(s) of {value.numel()}; the run diverged or "
                    "the file is damaged: use an earlier checkpoint (best.pt) or train again."
                )
            if name.startswith("normaliser") and not name.endswith(" mean") and bool((value < 0).any()):
                raise CheckpointError(
                    f"{source}: {name} is negative; a variance or count never is: the file was altered."
                )
        return cfg

    def _check_parts(self, source: str) -> None:
        """The parts are dicts (the normalisers may be absent) and the observation shapes lists of sizes."""
        for name in ("model", "net_config", "args", "obs_shapes", "obs_normalizer", "reward_scaler"):
            value = getattr(self, name)
            if not isinstance(value, dict) and not (value is None and name in ("obs_normalizer", "reward_scaler")):
                raise CheckpointError(f"{source}: its {name} is a {type(value).__name__}, not a dict.")
        for key, shape in self.obs_shapes.items():
            if not (isinstance(shape, list | tuple) and all(_is_int(n) and 0 <= n <= 100_000 for n in shape)):
                raise CheckpointError(f"{source}: observation field {key!r} has no valid shape ({shape!r}).")
        for name in ("observer", "world"):
            value = getattr(self, name)
            if value is not None and not (isinstance(value, dict) and _is_plain(value)):
                raise CheckpointError(
                    f"{source}: its {name} holds something other than dicts, lists, strings and numbers: the file "
                    "was not written by uamfleet or was altered."
                )
        self.spec(source)
        self._check_layout(source)

    def _check_layout(self, source: str) -> None:
        """A stored spec is plain dicts, lists, strings and numbers, and agrees with ``obs_shapes``."""
        if self.obs_layout is None:
            return
        if not isinstance(self.obs_layout, dict) or not _is_plain(self.obs_layout):
            raise CheckpointError(
                f"{source}: its obs_layout holds something other than dicts, lists, strings and numbers: the file "
                "was not written by uamfleet or was altered."
            )
        layout = self.layout(source)
        assert layout is not None
        shapes = {k: list(spec.shape) for k, spec in layout.items()}
        if shapes != {k: list(v) for k, v in self.obs_shapes.items()}:
            raise CheckpointError(
                f"{source}: its obs_layout (shapes {shapes}) disagrees with its obs_shapes {self.obs_shapes}: the "
                "file was altered."
            )

    def statistics(self, source: str) -> Iterator[tuple[str, torch.Tensor]]:
        """(name, tensor) of every weight and normalisation statistic a policy flies with."""
        for name, value in self.model.items():
            yield f"model tensor {name!r}", value
        normalisers = {**(self.obs_normalizer or {}), **({"reward": self.reward_scaler} if self.reward_scaler else {})}
        for field_name, rms in normalisers.items():
            if not isinstance(rms, Mapping) or any(k not in rms for k in ("mean", "var", "count")):
                raise CheckpointError(f"{source}: normaliser {field_name!r} lacks mean, var or count.")
            for key in ("mean", "var", "count"):
                try:
                    value = torch.as_tensor(np.asarray(rms[key], dtype=np.float64))
                except (TypeError, ValueError, RuntimeError):
                    raise CheckpointError(f"{source}: normaliser {field_name!r} {key} is not numbers.") from None
                yield f"normaliser {field_name!r} {key}", value

    def check_matches(
        self, args: TrainArgs | None, obs_shapes: dict[str, tuple[int, ...]], extra_ok: bool = False,
        layout: Layout | None = None,
    ) -> None:  # fmt: skip
        """Raise ValueError naming every architecture, scenario or observation-layout field that differs (with
        ``layout``, the env's spec, also what a field of the same shape means: bounds, columns, kind, dtype);
        ``extra_ok``: fields only the env has are fine (a trained policy reads only the fields it knows)."""
        diffs = []
        if args is not None:
            run = args.flat()
            for key in (*ARCHITECTURE_FIELDS, *ENVIRONMENT_FIELDS):
                if key in self.args and self.args[key] != run[key]:
                    diffs.append(f"{key}: checkpoint {self.args[key]!r}, this run {run[key]!r}")
        for key in sorted(set(self.obs_shapes) | set(obs_shapes)):
            saved, now = self.obs_shapes.get(key), obs_shapes.get(key)
            if saved is None and extra_ok:
                continue
            if saved is None or now is None or tuple(saved) != tuple(now):
                diffs.append(f"observation field {key!r}: checkpoint shape {saved}, this env {now}")
        diffs += self._spec_differences(layout) if layout is not None else []
        if diffs:
            raise ValueError(
                "the checkpoint was trained with another setup: " + "; ".join(diffs) + ". Use the same options "
                "(or a new --run-name for a new run)."
            )

    def _spec_differences(self, layout: Layout) -> list[str]:
        """The fields of the same shape whose stored spec differs from ``layout``'s (none for an older file)."""
        trained = self.layout("the checkpoint")
        if trained is None:
            return []
        same = [k for k in trained if k in layout and layout[k].shape == trained[k].shape]
        lines = layout_differences({k: trained[k] for k in same}, {k: layout[k] for k in same})
        return [f"observation field {line} (checkpoint vs this env)" for line in lines]


def _is_int(value: object) -> bool:
    return isinstance(value, int) and not isinstance(value, bool)


def _is_plain(value: object, depth: int = 0) -> bool:
    """Dicts of string keys, lists, strings, numbers, booleans and None only, at most a few levels deep."""
    if value is None or isinstance(value, str | int | float | bool):
        return True
    if depth > 4:
        return False
    if isinstance(value, list):
        return all(_is_plain(v, depth + 1) for v in value)
    if isinstance(value, dict):
        return all(isinstance(k, str) and _is_plain(v, depth + 1) for k, v in value.items())
    return False


def plain_numpy_rng(state: tuple[Any, ...]) -> dict[str, Any]:
    """NumPy's global generator state (``np.random.get_state()``'s tuple) as the plain values a checkpoint stores
    (it loads with ``weights_only=True``)."""
    name, keys, pos, has_gauss, cached = state
    return {"name": str(name), "keys": [int(k) for k in keys], "pos": int(pos), "has_gauss": int(has_gauss),
            "cached_gaussian": float(cached)}  # fmt: skip


def trained_spec(
    cfg: EnvConfig, net_config: Mapping[str, Any], source: str = "the checkpoint", observer: ObserverSpec | None = None
) -> ObserverSpec:
    """What a network of ``net_config`` trained on ``cfg`` (its evaluation config) reads: ``observer`` (None: the
    observer of ``cfg``, :func:`~uamfleet.observe.legacy.split_env_config`) with, without a passenger window, the
    rows and time scale it read in ``cfg``'s world pinned where it leaves them to the world (``slots_per_taxi``:
    the world's passengers per taxi; ``time_scale_steps``: its time limit), ``hover`` whether its network takes the
    hover action (``net_config["hover_logit"]`` or ``["hover_anytime"]``, not the world's rule) and, for the linear
    encoder (variant ``"le"``), which reads the other taxis by position, ``fleet_rows`` its fleet's taxis less one."""
    hover = False
    for name in ("hover_logit", "hover_anytime"):
        flag = net_config.get(name, False)  # absent: written before the option existed
        if not isinstance(flag, bool):
            raise CheckpointError(f"{source}: net_config {name}={flag!r} must be a bool (e.g. False).")
        hover = hover or flag
    world, spec = split_env_config(cfg)
    if observer is not None:
        spec = observer
        if spec.passenger_window is None:
            spec = dataclasses.replace(
                spec,
                slots_per_taxi=world.num_passengers / world.num_taxis if spec.slots_per_taxi is None
                else spec.slots_per_taxi,
                time_scale_steps=world.time_limit_steps if spec.time_scale_steps is None else spec.time_scale_steps,
            )  # fmt: skip
    fleet_rows = world.num_taxis - 1 if net_config.get("variant") == "le" else None
    return dataclasses.replace(spec, hover=hover, fleet_rows=fleet_rows)


def with_input_flags(net_config: dict[str, Any], obs_shapes: Mapping[str, Any]) -> dict[str, Any]:
    """``net_config`` with the input flags of :class:`NetConfig` that a file written before them lacks, derived
    once, here, from the fields it was trained on (``obs_shapes``): the network it builds reads what it read then.
    A file that names the flags keeps them."""
    if not isinstance(net_config, dict) or all(name in net_config for name in INPUT_FIELDS):
        return net_config
    variant, head = net_config.get("variant", "full"), net_config.get("action_head", "headings")
    derived = observed_inputs(obs_shapes, str(variant), str(head))
    return {**net_config, **{k: v for k, v in derived.items() if k not in net_config}}


def check_net_config(net_config: Mapping[str, Any], source: str) -> NetConfig:
    """The :class:`NetConfig` of a checkpoint's ``net_config``, refused (CheckpointError) when a field is unknown,
    of the wrong type, or larger than :data:`NET_LIMITS` allows: nothing is allocated here."""
    fields = {f.name: f for f in dataclasses.fields(NetConfig)}
    unknown = sorted(set(map(str, net_config)) - set(fields))
    if unknown:
        raise CheckpointError(
            f"{source}: net_config has field(s) {unknown} this uamfleet does not know (it knows {sorted(fields)}); "
            "it was written by another version or altered."
        )
    for name, value in net_config.items():
        default = fields[name].default
        if name in NET_LIMITS:
            if value is None and default is None:
                continue
            if not _is_int(value) or not 1 <= value <= NET_LIMITS[name]:
                raise CheckpointError(
                    f"{source}: net_config {name}={value!r} must be an integer in 1 ... {NET_LIMITS[name]:,}; "
                    "the file was not written by a uamfleet training run (or was altered)."
                )
        elif not isinstance(value, type(default)):
            raise CheckpointError(
                f"{source}: net_config {name}={value!r} must be a {type(default).__name__} (e.g. {default!r})."
            )
    try:
        return NetConfig(**net_config)
    except ValueError as err:
        raise CheckpointError(f"{source}: net_config is not a valid network: {err}") from None


def check_network(ckpt: Checkpoint, space: spaces.Dict, source: str) -> NetConfig:
    """The network config of ``ckpt``, once its tensors fit the network it builds for ``space`` (one agent's
    observation space, the fields the policy reads) and its normaliser fits those fields. The network is built
    on the ``meta`` device: shapes only, nothing allocated. Raises CheckpointError naming the first tensor that
    is missing, extra or of another shape."""
    cfg = ckpt.validate(source)
    try:
        with torch.device("meta"):
            expected = {k: tuple(v.shape) for k, v in MSHAActorCritic(space, cfg).state_dict().items()}
    except (ValueError, RuntimeError) as err:
        raise CheckpointError(f"{source}: its network does not fit this observation layout: {err}") from None
    check_state_dict(ckpt.model, expected, source, cfg.variant)
    for field_name, rms in (ckpt.obs_normalizer or {}).items():
        shape = space.spaces[field_name].shape if field_name in space.spaces else None
        mean_shape = tuple(np.shape(rms["mean"]))
        if shape is None or mean_shape != tuple(shape) or tuple(np.shape(rms["var"])) != mean_shape:
            raise CheckpointError(
                f"{source}: the observation normaliser of {field_name!r} has shape {list(np.shape(rms['mean']))}; "
                f"the observation has {None if shape is None else list(shape)}: the file was altered."
            )
    return cfg


def check_state_dict(
    model: Mapping[str, torch.Tensor], expected: Mapping[str, tuple[int, ...]], source: str, variant: str
) -> None:
    """Raise CheckpointError naming the first tensor of ``model`` that is missing, extra or of another shape than
    ``expected`` (the network's), so ``load_state_dict`` never meets a mismatch."""
    saved = {k: tuple(v.shape) for k, v in model.items()}
    for name in sorted(set(expected) | set(saved)):
        want, got = expected.get(name), saved.get(name)
        if want == got:
            continue
        if got is None:
            why = f"lacks tensor {name!r} of shape {list(want or ())}"
        elif want is None:
            why = f"holds tensor {name!r} (shape {list(got)}) that its network ({variant!r}) does not have"
        else:
            why = f"tensor {name!r} has shape {list(got)}; its network needs {list(want)}"
        raise CheckpointError(
            f"{source}: {why} (of {len(expected)} tensors); the file does not match its own net_config: it was "
            "altered or written by another version."
        )


def _refusal(err: Exception) -> str:
    """Why torch refused a file, and what to do, in one line, never advising to unpickle it."""
    why = _load_error(err)
    found = re.search(r"GLOBAL (\S+)", why)
    if found and found.group(1).startswith("numpy"):
        return (
            f"torch.load(weights_only=True) refused it: {why}. It is a checkpoint of uamfleet before format "
            f"{CHECKPOINT_FORMAT}, with NumPy objects pickled inside: convert it with "
            "uamfleet.rl.checkpoint.upgrade_checkpoint(path), which reads only NumPy arrays and runs no code"
        )
    if found:
        return (
            f"torch.load(weights_only=True) refused it: {why}, an object no uamfleet checkpoint holds; the file "
            "was not written by uamfleet or was altered, and loading it otherwise could run code in it"
        )
    return f"torch.load(weights_only=True) refused it: {why}; it is damaged, truncated or not a torch file"


def _load_error(err: Exception) -> str:
    """The one line of torch's refusal that says why (it also advises weights_only=False: not for us)."""
    text = re.sub(r"\x1b\[[0-9;]*m", "", str(err))
    why = (
        r"Unsupported global: GLOBAL \S+|unsupported GLOBAL [^\n]*blocked|Unsupported operand \S+"
        r"|but got <class '[^']+'>"
    )
    found = re.search(f"({why})", text)
    if found:
        return found.group(1)
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    return lines[0].split(". ")[0] if lines else type(err).__name__


PRETRAINED: dict[str, str] = {
    "berlin": "berlin.pt",  # one taxi on the Berlin WinProp map, any threshold -7 ... -3 dB, up to 6 requests;
    # berlin_stops plus a correction of its flight learned from replan (DAgger, issue 20), reading each heading's
    # two-move look-ahead on the tour (EnvConfig.lookahead_depth=2)
    "berlin_lookahead1": "berlin_lookahead1.pt",  # the same from the one-move look-ahead (the "berlin" shipped
    # before it), for its results
    "berlin_stops": "berlin_stops.pt",  # the first generalist: stop head on the exact-tour prior, each stop flown
    # along its progress heading (issue 12); the look-ahead policy's prior and uamfleet-imitate's default start
    # The fleet names point at files by what the policy is, not by file name: every committed fleet command names
    # the file (--checkpoints uamfleet/data/pretrained/berlin_fleet.pt), so berlin_fleet.pt keeps the first
    # berlin_fleet's weights and those commands fly what they flew.
    "berlin_fleet": "berlin_fleet_hover.pt",  # a fleet sharing one policy on the Berlin map, any fleet size (it fits
    # itself at reset), any number of requests (it reads a 24-row passenger window, docs/rules.md "Passenger window"):
    # berlin_fleet_v1 fine-tuned on a mixture of 2-8 taxis, light and loaded, under the shield, waiting with the true
    # hover action (NetConfig.hover_logit; fly it with EnvConfig.hover_action=True, on in the *_fleet presets);
    # how it was trained: reports/2026-12-03-results-history/fleet_hover_finetune.md; its rows: docs/results.md "Fleets"
    "berlin_fleet_hover": "berlin_fleet_hover.pt",  # the same policy under the name its results were measured by
    "berlin_fleet_v1": "berlin_fleet.pt",  # the "berlin_fleet" shipped before it (trained
    # with 4 taxis): nearest-first claims, zig-zagging when idle, 6 requests per taxi; any number of requests through
    # learned:source=berlin_fleet_v1,passenger_window=24, its 24 trained slots; for its results
    "berlin_fleet4": "berlin_fleet4.pt",  # the first fleet policy (4 taxis, tour prior, no claims), for its results
}
"""The policies shipped in ``uamfleet/data/pretrained`` (``uamfleet.pretrained(name)``): name -> file."""


def pretrained_path(name: str = "berlin") -> Path:
    """The file of the shipped policy ``name`` (:data:`PRETRAINED`)."""
    if name not in PRETRAINED:
        raise ValueError(f"no pretrained policy {name!r}; the package ships {tuple(PRETRAINED)}.")
    path = Path(str(resources.files("uamfleet") / "data" / "pretrained" / PRETRAINED[name]))
    if not path.is_file():
        raise FileNotFoundError(f"the pretrained policy file {path} is missing from this install; reinstall uamfleet.")
    return path


def checkpoint_source(name_or_path: str | Path) -> Path:
    """A shipped policy's name (:data:`PRETRAINED`) or a checkpoint file, as a path (FileNotFoundError naming it
    when neither)."""
    if isinstance(name_or_path, str) and name_or_path in PRETRAINED:
        return pretrained_path(name_or_path)
    path = Path(name_or_path)
    if not path.is_file():
        raise FileNotFoundError(
            f"{str(name_or_path)!r} is neither a shipped policy {tuple(PRETRAINED)} nor a checkpoint file; give one "
            "of those names or the path of a best.pt / last.pt."
        )
    return path


def run_config(args: TrainArgs, scenario: str | EnvConfig | None = None, training: bool = True) -> EnvConfig:
    """The world a run trains (``training``) or is evaluated in, with its own observer fields:
    :func:`~uamfleet.rl.options.make_env_config` of ``scenario`` (default ``args.env.scenario``). A run from
    ``--init-from`` flies this world too; what it observes there is its observer spec (the start's, stored in its
    checkpoint), never a rewrite of the world."""
    return make_env_config(args.env.scenario if scenario is None else scenario, args, training=training)


__all__ = [
    "ARCHITECTURE_FIELDS",
    "CHECKPOINT_FORMAT",
    "ENVIRONMENT_FIELDS",
    "NET_LIMITS",
    "PRETRAINED",
    "Checkpoint",
    "CheckpointError",
    "DeviceError",
    "check_device",
    "check_net_config",
    "check_network",
    "check_state_dict",
    "checkpoint_source",
    "plain_numpy_rng",
    "pretrained_path",
    "read_checkpoint_file",
    "run_config",
    "trained_spec",
    "with_input_flags",
    "world_record",
]
