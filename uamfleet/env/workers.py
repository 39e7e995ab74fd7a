"""The training envs stepped by worker processes, one core each: :class:`ShardedVectorEnv`.

A :class:`~uamfleet.env.vector_env.VectorEnv` steps all its envs on the calling thread, so a trainer whose network
runs on a GPU leaves every other CPU core idle while the envs step (issue 24: one GPU rank stepped 1,024 envs on
one core). :class:`ShardedVectorEnv` splits the same envs over ``workers`` processes. Each worker steps a
contiguous share of the envs and writes their observations, rewards and flags straight into shared memory; the
parent process sends the actions and reads the results, so one step costs one round trip per worker and no
copies through pipes (only a finished episode's statistics travel that way).

It is the same envs, not a look-alike: the envs are cut into the groups of
:class:`~uamfleet.env.mixture.MixtureVectorEnv` (one per config, the same sizes), each worker's share of a group is
a ``VectorEnv`` of that config reset with ``seed + e0`` for its first global env e0, and every env keeps its own
generator, so global env e runs the same episodes as in the in-process mixture, with any number of workers
(``tests/env/test_workers.py`` compares observations, rewards and episode statistics bit for bit).

Limits, with the reason: every config must have the same fleet size (the mixture's padding of smaller fleets is
not done here; mixed fleet sizes train in one process, as they already must without torchrun ranks), and the
envs' states live in the workers, so what reads ``venv.state`` (the imitation experts, the planners) takes the
in-process envs.

Workers are started with ``spawn`` (a fork of a process whose torch threads are running can deadlock), import
uamfleet afresh (the compiled kernels come from numba's cache: a few seconds), and are stopped by :meth:`close`, on
garbage collection, or when the parent exits. A worker that fails sends its traceback and the parent raises it as
a :class:`RuntimeError` naming the worker and its envs.
"""

from __future__ import annotations

import multiprocessing as mp
import traceback
import weakref
from collections.abc import Sequence
from dataclasses import dataclass
from multiprocessing import shared_memory
from multiprocessing.connection import Connection
from typing import Any

import numpy as np
from gymnasium import spaces

from uamfleet.config import REWARD_TERMS, EnvConfig, RewardConfig
from uamfleet.env.mixture import checked_configs, group_sizes
from uamfleet.observe.spec import ObserverSpec


@dataclass(frozen=True)
class _Piece:
    """A worker's share of one config's envs: global envs ``lo .. lo + num_envs - 1``, observed by ``observer``
    (None: the config's own)."""

    cfg: EnvConfig
    lo: int
    num_envs: int
    observer: ObserverSpec | None = None


@dataclass(frozen=True)
class _ArraySpec:
    """A shared array: its shared-memory block's name, shape and dtype."""

    block: str
    shape: tuple[int, ...]
    dtype: str


def shard_pieces(
    cfgs: Sequence[EnvConfig], num_envs: int, workers: int, observer: ObserverSpec | None = None
) -> list[list[_Piece]]:
    """Each worker's pieces: the envs cut into contiguous shares as equal as possible (``workers`` of them),
    each share cut again where a config's group ends; every piece observed by ``observer``."""
    sizes = group_sizes(len(cfgs), num_envs)
    bounds = np.concatenate([[0], np.cumsum(sizes)])
    shares = np.concatenate([[0], np.cumsum(group_sizes(workers, num_envs))])
    out: list[list[_Piece]] = []
    for w in range(workers):
        lo, hi = int(shares[w]), int(shares[w + 1])
        pieces = []
        for g, cfg in enumerate(cfgs):
            a, b = max(lo, int(bounds[g])), min(hi, int(bounds[g + 1]))
            if a < b:
                pieces.append(_Piece(cfg, a, b - a, observer))
        out.append(pieces)
    return out


class _Shared:
    """Named arrays in shared memory: created by the parent, attached by the workers."""

    def __init__(self, specs: dict[str, _ArraySpec], create: bool) -> None:
        self.blocks: dict[str, shared_memory.SharedMemory] = {}
        self.arrays: dict[str, np.ndarray] = {}
        for key, spec in specs.items():
            size = max(1, int(np.prod(spec.shape)) * np.dtype(spec.dtype).itemsize)
            if create:
                block = shared_memory.SharedMemory(create=True, size=size)
            else:
                # a worker attaches only: the parent owns the blocks and unlinks them. (A spawned worker shares the
                # parent's resource tracker, so its attaching registers nothing the parent's unlink does not clear.)
                block = shared_memory.SharedMemory(name=spec.block)
            self.blocks[key] = block
            self.arrays[key] = np.ndarray(spec.shape, np.dtype(spec.dtype), buffer=block.buf)
        self.specs = {
            key: _ArraySpec(self.blocks[key].name, spec.shape, spec.dtype) for key, spec in specs.items()
        }  # fmt: skip

    def close(self, unlink: bool) -> None:
        self.arrays.clear()
        for block in self.blocks.values():
            try:
                block.close()
                if unlink:
                    block.unlink()
            except (FileNotFoundError, BufferError):
                pass
        self.blocks.clear()


def _array_specs(obs_space: spaces.Dict, num_envs: int, num_taxis: int, state_dim: int | None) -> dict[str, _ArraySpec]:
    """Every array a step writes, for all envs: the observation fields (``obs/<key>``) and the last observation of
    a finished episode (``final/<key>``), rewards, flags, reward terms, actions, and the global state if asked."""
    specs: dict[str, _ArraySpec] = {}
    for key, space in obs_space.spaces.items():
        shape = (num_envs, num_taxis, *(space.shape or ()))
        specs[f"obs/{key}"] = _ArraySpec("", shape, np.dtype(space.dtype).str)
        specs[f"final/{key}"] = _ArraySpec("", shape, np.dtype(space.dtype).str)
    specs["rewards"] = _ArraySpec("", (num_envs, num_taxis), np.dtype(np.float64).str)
    specs["terminated"] = _ArraySpec("", (num_envs,), np.dtype(bool).str)
    specs["truncated"] = _ArraySpec("", (num_envs,), np.dtype(bool).str)
    specs["reward_terms"] = _ArraySpec("", (num_envs, num_taxis, len(REWARD_TERMS)), np.dtype(np.float64).str)
    specs["actions"] = _ArraySpec("", (num_envs, num_taxis), np.dtype(np.int64).str)
    if state_dim is not None:
        specs["state"] = _ArraySpec("", (num_envs, state_dim), np.dtype(np.float32).str)
    return specs


def _worker_main(conn: Connection, pieces: list[_Piece], fill_tables: bool) -> None:
    """A worker: builds its pieces' envs, reports their spaces, then serves the parent's commands until "close";
    an exception goes back to the parent as its traceback."""
    shared: list[_Shared] = []
    try:
        from uamfleet.env.vector_env import VectorEnv
        from uamfleet.paths.distance_table import table_for

        envs = [VectorEnv(p.cfg, num_envs=p.num_envs, observer=p.observer) for p in pieces]
        if fill_tables:
            for env in envs:
                if env.cfg.stop_features and env.cfg.requests is None:
                    table_for(env.world).fill()  # loads the table from the disk cache the parent filled
        conn.send(("ready", _describe(envs)))
        _serve(conn, pieces, envs, shared)
    except (KeyboardInterrupt, EOFError, BrokenPipeError):
        pass
    except BaseException:
        try:
            conn.send(("error", traceback.format_exc()))
        except (BrokenPipeError, OSError):
            pass
    finally:
        for block in shared:
            block.close(unlink=False)
        conn.close()


def _serve(conn: Connection, pieces: list[_Piece], envs: list[Any], shared: list[_Shared]) -> None:
    """The worker's command loop: attach the shared arrays, reset, step, set reward weights, close."""
    while True:
        command, argument = conn.recv()
        if command == "close":
            return
        if command == "attach":
            shared.append(_Shared(argument, create=False))
            conn.send(("ok", None))
            continue
        arrays = shared[0].arrays
        if command == "reset":
            for piece, env in zip(pieces, envs, strict=True):
                obs, _ = env.reset(seed=None if argument is None else int(argument) + piece.lo)
                _write(arrays, "obs/", obs, piece)
                _write_state(arrays, env, piece)
            conn.send(("ok", None))
        elif command == "step":
            conn.send(("ok", _step_pieces(arrays, pieces, envs)))
        elif command == "set_reward_weights":
            for env in envs:
                env.set_reward_weights(argument)
            conn.send(("ok", None))
        else:
            raise ValueError(f"unknown command {command!r}")


def _describe(envs: list[Any]) -> dict[str, Any]:
    first = envs[0]
    return {
        "observation_spaces": [env.single_observation_space for env in envs],
        "action_space": first.single_action_space,
        "state_space": first.state_space,
        "num_taxis": [env.num_taxis for env in envs],
    }


def _write(arrays: dict[str, np.ndarray], prefix: str, obs: dict[str, np.ndarray], piece: _Piece) -> None:
    rows = slice(piece.lo, piece.lo + piece.num_envs)
    for key, value in obs.items():
        arrays[prefix + key][rows] = value


def _write_state(arrays: dict[str, np.ndarray], env: Any, piece: _Piece) -> None:
    if "state" in arrays:
        arrays["state"][piece.lo : piece.lo + piece.num_envs] = env.global_state()


def _step_pieces(arrays: dict[str, np.ndarray], pieces: list[_Piece], envs: list[Any]) -> dict[int, Any]:
    """Step every piece on its actions; write the results; return each finished piece's episode statistics."""
    finished: dict[int, Any] = {}
    for piece, env in zip(pieces, envs, strict=True):
        rows = slice(piece.lo, piece.lo + piece.num_envs)
        obs, rewards, terminated, truncated, info = env.step(arrays["actions"][rows])
        _write(arrays, "obs/", obs, piece)
        arrays["rewards"][rows] = rewards
        arrays["terminated"][rows] = terminated
        arrays["truncated"][rows] = truncated
        arrays["reward_terms"][rows] = info["reward_terms"]
        _write_state(arrays, env, piece)
        if "_episode" in info:
            done = np.flatnonzero(info["_episode"])
            for key, value in info["final_obs"].items():
                arrays["final/" + key][piece.lo + done] = value[done]
            finished[piece.lo] = (done, {key: value[done] for key, value in info["episode"].items()})
    return finished


class ShardedVectorEnv:
    """``num_envs`` envs over ``cfgs`` (as :class:`~uamfleet.env.mixture.MixtureVectorEnv`; one config: as a
    :class:`~uamfleet.env.vector_env.VectorEnv`) stepped by ``workers`` processes (module docstring).

    The same interface as the mixture for a trainer: ``reset(seed)``, ``step(actions)`` (obs, rewards [E, A],
    terminated [E], truncated [E], info with ``reward_terms`` and, where an episode ended, ``_episode``,
    ``episode`` and ``final_obs`` for every env; read them where ``_episode``), ``global_state()`` (with
    ``global_state=True``), ``set_reward_weights``, ``close``, the spaces, ``num_envs``, ``num_taxis`` (one fleet
    size: ``taxis_per_env`` all ``num_taxis``, ``mixed_sizes`` False), and ``envs`` empty (the envs live in the
    workers): the backend interface of :mod:`uamfleet.env.backends`. ``observer``: every env observes by this spec
    (:class:`~uamfleet.env.vector_env.VectorEnv`'s ``observer``); None: each config's own.

    ``copy=True`` (as Gymnasium's ``AsyncVectorEnv``): the observations returned are copies. ``copy=False`` returns
    views of the shared buffers, which the next ``step`` or ``reset`` overwrites: for a caller that copies them on
    before it steps again (the trainer writes them into its rollout buffer), it saves a copy of every observation
    (at 1,020 envs, a third of a step's time on the 2-core machine; docs/benchmarks.md, "The environment")."""

    def __init__(
        self, cfgs: Sequence[EnvConfig], num_envs: int, workers: int, global_state: bool = False,
        fill_tables: bool = False, copy: bool = True, observer: ObserverSpec | None = None,
    ) -> None:  # fmt: skip
        cfgs = checked_configs("ShardedVectorEnv", cfgs, num_envs)
        self.num_taxis = _one_fleet_size(cfgs, num_envs, workers)
        self.cfgs, self.cfg, self.copy = cfgs, cfgs[0], bool(copy)
        self.num_envs, self.num_workers = int(num_envs), int(workers)
        self.taxis_per_env = np.full(self.num_envs, self.num_taxis)  # one fleet size: no padded taxis
        self.mixed_sizes = False
        self.envs: list[Any] = []  # the envs live in the workers: none here to fill tables of
        self.pieces = shard_pieces(cfgs, self.num_envs, self.num_workers, observer)
        self._closed = True
        self._finalizer: weakref.finalize[Any, Any]
        self._start_workers(fill_tables)
        self._read_spaces([self._receive(w) for w in range(self.num_workers)], global_state)
        state_dim = int(self.state_space.shape[0]) if global_state and self.state_space is not None else None
        self._shared = _Shared(
            _array_specs(self.single_observation_space, self.num_envs, self.num_taxis, state_dim), create=True
        )
        self._finalizer.detach()
        self._finalizer = weakref.finalize(self, _shutdown, self._conns, self._procs, self._shared)
        self._call_all("attach", self._shared.specs)
        self._keys = list(self.single_observation_space.spaces)
        self.needs_reset = True

    def _start_workers(self, fill_tables: bool) -> None:
        """One spawned process per share of the envs, stopped on garbage collection or at exit until closed."""
        context = mp.get_context("spawn")  # module docstring: not fork
        self._conns: list[Connection] = []
        self._procs: list[Any] = []
        for w, pieces in enumerate(self.pieces):
            parent, child = context.Pipe()
            proc = context.Process(
                target=_worker_main, args=(child, pieces, fill_tables), name=f"uamfleet-env-worker-{w}", daemon=True
            )
            proc.start()
            child.close()
            self._conns.append(parent)
            self._procs.append(proc)
        self._closed = False
        self._finalizer = weakref.finalize(self, _shutdown, self._conns, self._procs, None)

    def _read_spaces(self, described: list[dict[str, Any]], global_state: bool) -> None:
        """The spaces the workers report, refused (the workers closed, ValueError) when their observation layouts
        differ, or when ``global_state`` asks for one state the configs do not share."""
        obs_spaces = [space for d in described for space in d["observation_spaces"]]
        if any(space != obs_spaces[0] for space in obs_spaces):
            self.close()
            raise ValueError(
                "the configs give other observation layouts (max_passengers or passenger_window, patch_size, "
                "history_len, stop fields); env workers, like a mixture, step configs of one layout."
            )
        self.single_observation_space: spaces.Dict = obs_spaces[0]
        self.single_action_space = described[0]["action_space"]
        states = {None if d["state_space"] is None else d["state_space"].shape for d in described}
        self.state_space = described[0]["state_space"] if len(states) == 1 else None
        if global_state and self.state_space is None:
            self.close()
            raise ValueError(
                "global_state=True, but the configs' global states differ in size: no one [E, S] state holds them."
            )

    # ---- the interface ---------------------------------------------------------------------------------------
    def reset(self, seed: int | None = None) -> tuple[dict[str, np.ndarray], dict[str, Any]]:
        self._call_all("reset", seed)
        self.needs_reset = False
        return self._observation("obs/"), {}

    def step(
        self, actions: np.ndarray
    ) -> tuple[dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, dict[str, Any]]:
        if self.needs_reset:
            raise RuntimeError("step() called before reset().")
        actions = np.asarray(actions)
        if actions.shape != (self.num_envs, self.num_taxis):
            raise ValueError(f"actions has shape {actions.shape}, expected ({self.num_envs}, {self.num_taxis}).")
        self._shared.arrays["actions"][:] = actions
        replies = self._call_all("step", None)
        a = self._shared.arrays
        obs = self._observation("obs/")
        terminated, truncated = a["terminated"].copy(), a["truncated"].copy()
        info: dict[str, Any] = {"reward_terms": a["reward_terms"].copy()}
        finished = {lo: part for reply in replies for lo, part in reply.items()}
        if finished:
            done = terminated | truncated
            info["_episode"] = done
            final = {key: value.copy() for key, value in obs.items()}  # placeholders where no episode ended
            rows = np.flatnonzero(done)
            for key in self._keys:
                final[key][rows] = a["final/" + key][rows]
            info["final_obs"] = final
            info["episode"] = _gather_stats(finished, self.num_envs)
        return obs, a["rewards"].copy(), terminated, truncated, info

    def global_state(self) -> np.ndarray:
        if "state" not in self._shared.arrays:
            raise ValueError("this ShardedVectorEnv was built without global_state=True; build it with it.")
        return self._shared.arrays["state"].copy()

    def set_reward_weights(self, weights: RewardConfig) -> None:
        self._call_all("set_reward_weights", weights)
        self.cfg = self.cfg.replace(reward=weights)

    def close(self) -> None:
        """Stop the workers and free the shared memory (also done on garbage collection and at exit)."""
        if not self._closed:
            self._closed = True
            self._finalizer()

    def __enter__(self) -> ShardedVectorEnv:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()

    # ---- plumbing --------------------------------------------------------------------------------------------
    def _observation(self, prefix: str) -> dict[str, np.ndarray]:
        arrays = self._shared.arrays
        return {key: arrays[prefix + key].copy() if self.copy else arrays[prefix + key] for key in self._keys}

    def _call_all(self, command: str, argument: Any) -> list[Any]:
        if self._closed:
            raise RuntimeError("this ShardedVectorEnv is closed; build a new one.")
        for conn in self._conns:
            conn.send((command, argument))
        return [self._receive(w) for w in range(self.num_workers)]

    def _receive(self, w: int) -> Any:
        try:
            status, payload = self._conns[w].recv()
        except EOFError:
            status, payload = "error", f"the process exited (exit code {self._procs[w].exitcode})"
        if status == "error":
            envs = ", ".join(f"{p.lo}..{p.lo + p.num_envs - 1} ({p.cfg.scenario})" for p in self.pieces[w])
            self.close()
            raise RuntimeError(f"env worker {w} (envs {envs}) failed:\n{payload}")
        return payload


def _one_fleet_size(cfgs: list[EnvConfig], num_envs: int, workers: int) -> int:
    """The configs' one fleet size; ValueError naming the fix for a worker count out of 1 ... ``num_envs`` or for
    configs of several fleet sizes."""
    if int(workers) != workers or not 1 <= workers <= num_envs:
        raise ValueError(
            f"workers={workers!r} must be an integer from 1 to num_envs={num_envs} (each worker steps at "
            "least one env); 0 env workers means the in-process envs, which need no ShardedVectorEnv."
        )
    fleets = sorted({cfg.num_taxis for cfg in cfgs})
    if len(fleets) > 1:
        raise ValueError(
            f"the configs fly fleets of {fleets} taxis; env workers step configs of one fleet size (the "
            "mixture's padding of smaller fleets runs in one process): train mixed fleet sizes without "
            "env workers."
        )
    return fleets[0]


def _gather_stats(finished: dict[int, Any], num_envs: int) -> dict[str, np.ndarray]:
    """Every env's episode statistics (zeros where no episode ended) from each piece's finished rows."""
    template = next(iter(finished.values()))[1]
    out = {key: np.zeros((num_envs, *v.shape[1:]), v.dtype) for key, v in template.items()}
    for lo, (done, stats) in finished.items():
        for key, value in stats.items():
            out[key][lo + done] = value
    return out


def _shutdown(conns: list[Connection], procs: list[Any], shared: _Shared | None) -> None:
    for conn in conns:
        try:
            conn.send(("close", None))
        except (BrokenPipeError, OSError):
            pass
    for proc in procs:
        proc.join(timeout=5)
        if proc.is_alive():
            proc.terminate()
            proc.join(timeout=5)
    for conn in conns:
        conn.close()
    if shared is not None:
        shared.close(unlink=True)
