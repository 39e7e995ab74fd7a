"""What reads a checkpoint's past: files of format 1 and the flat training arguments every checkpoint stores.

:func:`upgrade_checkpoint` converts a checkpoint of format 1 (NumPy objects pickled inside) to the safe format,
reading only NumPy arrays and scalars (:data:`NUMPY_GLOBALS`); unpickling anything else happens only with
``trust=True``, which warns what it means. :func:`checkpoint_args` reads the options a checkpoint was trained with
(stored flat, one key per option) as a :class:`~uamfleet.rl.options.TrainArgs`. :func:`spec_of_checkpoint` says what
a checkpoint of format 2 reads, as an :class:`~uamfleet.observe.spec.ObserverSpec`, from those arguments (for a run
fine-tuned from another, through the chain of start files it followed); :func:`spec_of` reads any checkpoint's.
"""

from __future__ import annotations

import dataclasses
import warnings
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np
import torch

from uamfleet.config import EnvConfig
from uamfleet.observe.spec import ObserverSpec, layout_differences, layout_from_dict, layout_to_dict, observation_layout
from uamfleet.presets import make_config
from uamfleet.rl.checkpoint import (
    CHECKPOINT_FORMAT,
    Checkpoint,
    CheckpointError,
    _load_error,
    checkpoint_source,
    plain_numpy_rng,
    trained_spec,
    with_input_flags,
    world_record,
)
from uamfleet.rl.options import TrainArgs, make_env_config

try:  # NumPy 2 renamed numpy.core to numpy._core
    from numpy._core import multiarray as _multiarray
except ImportError:  # pragma: no cover - NumPy 1
    from numpy.core import multiarray as _multiarray  # type: ignore[no-redef]

NUMPY_GLOBALS: list[Any] = [
    np.ndarray, np.dtype, _multiarray._reconstruct, _multiarray.scalar,
    *(type(np.dtype(kind)) for kind in "?bBhHiIlLqQefdg"),  # numeric dtypes only: never object arrays
    *((getattr(_multiarray, f), f"numpy.{core}.multiarray.{f}")  # the names files of either NumPy use
      for core in ("core", "_core") for f in ("_reconstruct", "scalar")),
]  # fmt: skip
"""What a format-1 checkpoint pickled besides tensors: NumPy arrays and scalars (the RNG state, the normaliser's
statistics). Rebuilding them runs no code of the file; :func:`upgrade_checkpoint` allows these and nothing else."""


TRUST_WARNING = (
    "upgrade_checkpoint(trust=True) unpickles {path} with torch.load(weights_only=False): any code the file holds "
    "runs now, with your permissions. Trust only a file you wrote yourself and kept where nobody else could "
    "change it."
)


def upgrade_checkpoint(path: str | Path, env_config: EnvConfig | None = None, *, trust: bool = False) -> Path:
    """Re-save a checkpoint of format 1 (NumPy RNG state and statistics pickled inside) in the current format, in
    place (pass the ``env_config`` it was trained on, if not its named scenario), with what it reads and the world
    it was evaluated in rebuilt from its training arguments.

    It reads the file with ``torch.load(weights_only=True)`` allowing NumPy arrays and scalars only
    (:data:`NUMPY_GLOBALS`): no code of the file runs, and a file holding anything else is refused. ``trust=True``
    unpickles the file fully instead, which runs any code in it (it warns): only for a file you wrote yourself.
    The result is checked like every checkpoint before it is saved."""
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"checkpoint {path} does not exist.")
    old = _read_format1(path, trust)
    if not isinstance(old, dict) or "numpy_rng" not in old or "args" not in old:
        raise CheckpointError(f"{path} is not a uamfleet training checkpoint (no numpy_rng or args).")
    _to_plain_values(old)
    cfg = _evaluation_config(old["args"], env_config)
    layout = observation_layout(cfg)  # the spec: no env is built
    old["obs_shapes"] = {k: list(spec.shape) for k, spec in layout.items()}
    old["obs_layout"] = layout_to_dict(layout)
    names = {f.name for f in dataclasses.fields(Checkpoint)} - {"format"}
    upgraded = Checkpoint(**{k: v for k, v in old.items() if k in names})
    upgraded.net_config = with_input_flags(upgraded.net_config, upgraded.obs_shapes)
    upgraded.observer = trained_spec(cfg, upgraded.net_config, str(path)).to_dict()
    upgraded.world = world_record(cfg.world)
    upgraded.validate(str(path))
    upgraded.save(path)
    return path


def _read_format1(path: Path, trust: bool) -> Any:
    """A format-1 file: NumPy arrays and scalars allowed and nothing else, or fully unpickled with ``trust``."""
    if trust:
        warnings.warn(TRUST_WARNING.format(path=path), UserWarning, stacklevel=3)
        return torch.load(path, map_location="cpu", weights_only=False)
    try:
        with torch.serialization.safe_globals(NUMPY_GLOBALS):  # torch >= 2.5
            return torch.load(path, map_location="cpu", weights_only=True)
    except AttributeError:  # pragma: no cover - older torch
        raise CheckpointError("upgrade_checkpoint needs torch >= 2.5 (torch.serialization.safe_globals).") from None
    except Exception as err:
        raise CheckpointError(
            f"{path} holds more than tensors and NumPy arrays, so upgrade_checkpoint will not read it "
            f"({_load_error(err)}): it is not a uamfleet checkpoint of format 1; train the run again."
        ) from None


def _to_plain_values(old: dict[str, Any]) -> None:
    """In place: the NumPy RNG state as plain values, the normalisers' statistics as tensors and floats."""
    if not isinstance(old["numpy_rng"], dict):
        old["numpy_rng"] = plain_numpy_rng(old["numpy_rng"])
    for key in ("obs_normalizer", "reward_scaler"):
        if old.get(key) is not None:
            fields = old[key] if key == "obs_normalizer" else {"_": old[key]}
            for rms in fields.values():
                rms["mean"], rms["var"] = (torch.as_tensor(np.asarray(rms[k], np.float64)) for k in ("mean", "var"))
                rms["count"] = float(rms["count"])
    old["best_eval"] = {k: float(v) for k, v in old.get("best_eval", {}).items()}


def _evaluation_config(args: Mapping[str, Any], env_config: EnvConfig | None) -> EnvConfig:
    """The config a run evaluated on, from its saved arguments (the observation layout is all that matters
    here: the same overrides as ``TrainArgs.env_overrides(training=False)``)."""
    overrides: dict[str, Any] = {"feasibility": args.get("feasibility", "endpoint_block")}
    for key in ("sinr_min_db", "num_taxis"):
        if args.get(key) is not None:
            overrides[key] = args[key]
    limit = args.get("eval_time_limit_steps") or args.get("time_limit_steps")
    if limit is not None:
        overrides["time_limit_steps"] = limit
    return make_config(env_config if env_config is not None else str(args["scenario"]), **overrides)


def checkpoint_args(ckpt: Checkpoint) -> TrainArgs:
    """The training arguments a checkpoint was written with, from its flat ``args`` (options added since take their
    defaults: :meth:`TrainArgs.from_saved`)."""
    return TrainArgs.from_saved(ckpt.args)


def with_stored_spec(ckpt: Checkpoint, source: str = "the checkpoint") -> Checkpoint:
    """``ckpt`` in the current format: a file of format 2 gains what it reads (:func:`spec_of_checkpoint`) and the
    world it was evaluated in (rebuilt from its ``args``), so that it no longer depends on the presets; a file that
    stores them is returned as it is."""
    if ckpt.observer is not None:
        return ckpt
    spec = spec_of_checkpoint(ckpt.args, ckpt.net_config, ckpt.obs_layout, source)
    world = _evaluated_config(TrainArgs.from_saved(ckpt.args), depth=0).world
    return dataclasses.replace(ckpt, observer=spec.to_dict(), world=world_record(world), format=CHECKPOINT_FORMAT)


def spec_of_checkpoint(
    args: Mapping[str, Any],
    net_config: Mapping[str, Any],
    obs_layout: Mapping[str, Any] | None = None,
    source: str = "the checkpoint",
) -> ObserverSpec:
    """What a checkpoint of format 2 reads, from its flat ``args``, its ``net_config`` and, when it has one, its
    ``obs_layout`` (the parts ``torch.load(weights_only=True)`` gives).

    The config it is evaluated on is rebuilt as it was when the file was written: its scenario through the presets
    with its options (:func:`~uamfleet.rl.options.make_env_config`), laid out as the policy its ``init_from`` names
    (a run fine-tuned then took its start's observation through a chain of files), then split
    (:func:`~uamfleet.observe.legacy.split_env_config`). ``hover`` is the network's hover logit
    (``net_config["hover_logit"]``), not the world's rule; a network of the linear encoder (variant ``"le"``) reads
    the other taxis by position, so ``fleet_rows`` is its fleet's taxis less one.

    A file with ``obs_layout`` must read what it stored: the spec's layout in the rebuilt world equals it field for
    field, else :class:`CheckpointError` naming the first field that differs. A file without one reads what its
    scenario's preset gives now (an edit of the preset changes it)."""
    cfg = _evaluated_config(TrainArgs.from_saved(args), depth=0)
    spec = trained_spec(cfg, net_config, source)
    world = cfg.world
    if obs_layout is not None:
        try:
            stored = layout_from_dict(obs_layout)
        except (ValueError, TypeError, AttributeError) as err:
            raise CheckpointError(f"{source}: its observation layout is not a spec: {err}") from None
        differences = layout_differences(stored, spec.layout(world))
        if differences:
            named = [line.replace("the first layout", "the stored layout") for line in differences]
            fields = "; ".join(f"observation field {line.replace('the second layout', 'the rebuilt layout')}"
                               for line in named)  # fmt: skip
            raise CheckpointError(
                f"{source}: the observer rebuilt from its args does not read what its obs_layout stores (stored vs "
                f"rebuilt): {fields}; the file's args or the preset they name changed since it was written."
            )
    return spec


def spec_of(ckpt: Checkpoint, source: str = "the checkpoint") -> ObserverSpec:
    """What the policy of ``ckpt`` reads: its stored spec (format 3), else the one rebuilt from its arguments
    (:func:`spec_of_checkpoint`)."""
    stored = ckpt.spec(source)
    if stored is not None:
        return stored
    return spec_of_checkpoint(ckpt.args, ckpt.net_config, ckpt.obs_layout, source)


_INIT_CHAIN_MAX = 8  # a run fine-tuned from a run fine-tuned from ...: deeper than this is a loop of files


def _evaluated_config(args: TrainArgs, depth: int) -> EnvConfig:
    """The config a run of format 2 was evaluated on: its scenario with its options and, with ``init_from``, the
    observation layout of the policy it started from, followed through the chain of start files
    (:func:`_followed`); the start's layout takes the run's own passenger window when it set one."""
    cfg = make_env_config(args.env.scenario, args, training=False)
    if args.net.init_from is None:
        return cfg
    if depth >= _INIT_CHAIN_MAX:
        raise CheckpointError(
            f"init_from={args.net.init_from!r} starts a chain of more than {_INIT_CHAIN_MAX} runs, each fine-tuned "
            "from the next: the files point at each other; load a run trained from scratch."
        )
    source = checkpoint_source(args.net.init_from)
    like = _evaluated_config(TrainArgs.from_saved(Checkpoint.load(source, map_location="cpu").args), depth + 1)
    window = args.observer.passenger_window
    return _followed(cfg, like if window is None else like.replace(passenger_window=window))


def _followed(cfg: EnvConfig, like: EnvConfig) -> EnvConfig:
    """``cfg`` laid out as a format-2 fine-tuned run read it: ``like``'s passenger axis, stop fields, patch and
    history, and, without a window in ``like``, its passenger rows and time limit written into the world (a
    windowed layout keeps ``cfg``'s own requests and time limit)."""
    windowed = like.passenger_window is not None
    return cfg.replace(
        max_passengers=cfg.max_passengers if windowed else like.num_passengers,
        passenger_window=like.passenger_window, stop_features=like.stop_features, stop_rivals=like.stop_rivals,
        stop_claims=like.stop_claims, heading_lookahead=like.heading_lookahead,
        lookahead_depth=like.lookahead_depth,
        time_limit_steps=cfg.time_limit_steps if windowed else like.time_limit_steps,
        patch_size=like.patch_size, history_len=like.history_len,
    )  # fmt: skip


__all__ = [
    "NUMPY_GLOBALS",
    "TRUST_WARNING",
    "checkpoint_args",
    "spec_of",
    "spec_of_checkpoint",
    "upgrade_checkpoint",
    "with_stored_spec",
]
