"""Data-parallel PPO on ``torch.distributed``: the process group, the collectives the trainer needs, and the
world-size-invariant action sampler.

``torchrun --nproc_per_node=N train/ppo.py ...`` starts N processes with ``RANK``, ``WORLD_SIZE``,
``LOCAL_RANK`` and a rendezvous in their environment; :meth:`Ranks.from_env` joins the group (gloo on CPU,
NCCL on GPU) with the *global* rank (CleanRL's ``ppo_atari_multigpu.py`` uses the local one, which repeats
across nodes). Without those variables the world is one process and every collective is the identity.

What makes 2 ranks x E/2 envs the same run as 1 rank x E envs (``tests/rl/test_distributed.py``):

- ``--num-envs`` and ``--total-timesteps`` are global. Rank r owns the global envs [r E/R, (r + 1) E/R),
  seeded ``seed + global env index``, and its agents are the matching slice of the global agent axis.
- Every rank seeds torch and NumPy alike and consumes their global generators identically, so the generator
  states stay equal across ranks: actions are drawn with Gumbel-style exponential noise of the GLOBAL shape
  ``[N_global, 16]`` and each rank keeps its own rows (:func:`sample_actions`; with one rank this is
  ``Categorical.sample()`` draw for draw), and the minibatch permutation of the global flat batch is the same
  on every rank, each keeping its own samples of each global minibatch.
- Normaliser statistics are updated with the moments of the global batch (an all-reduce of count, shifted sum
  and shifted sum of squares), so every rank holds identical normalisers equal to the single-process ones.
- Losses are sums over the rank's samples divided by the GLOBAL minibatch size, advantages are normalised with
  the mean and std of the global minibatch (advantages are all-reduced once per iteration), and the gradients
  are summed over ranks: the result is the gradient of the global minibatch mean, however the permutation
  splits a minibatch between ranks (with equal shares it is the average of the ranks' mean gradients).
  Gradient clipping and Adam then see identical gradients on every rank, so weights stay identical.
"""

from __future__ import annotations

import faulthandler
import logging
import os
import socket
import sys
from collections.abc import Callable
from dataclasses import dataclass
from datetime import timedelta
from typing import Any, NoReturn

import numpy as np
import torch
import torch.distributed as dist
import torch.multiprocessing as mp
from torch.distributions import Categorical


class RankZeroError(RuntimeError):
    """Raised on the other ranks when rank 0 fails a step that every rank waits for (claiming the run folder):
    rank 0 raises (and reports) the error itself, so a command line prints it once and these ranks leave quietly."""


def _backend(backend: str, use_cuda: bool, local_world: int) -> str:
    """ "auto": NCCL when every local rank has a GPU of its own, else gloo; NCCL only with CUDA."""
    if backend == "auto":
        backend = "nccl" if use_cuda and local_world <= torch.cuda.device_count() else "gloo"
    if backend == "nccl" and not use_cuda:
        raise ValueError("backend='nccl' needs --device cuda; use --backend gloo (or auto) on CPUs.")
    return backend


def _join_group(backend: str, rank: int, world_size: int, timeout_s: float) -> None:
    """Join torchrun's process group (once) and check it is the one the environment describes."""
    if not dist.is_initialized():
        dist.init_process_group(backend=backend, timeout=timedelta(seconds=timeout_s))
    if dist.get_rank() != rank or dist.get_world_size() != world_size:
        raise RuntimeError(f"process group has rank {dist.get_rank()}/{dist.get_world_size()}, env {rank}/{world_size}")


@dataclass(frozen=True)
class Ranks:
    """This process's place among the training ranks (possibly one process). Not the geometry
    (:class:`uamfleet.sim.world.World`); ``World`` is kept here as an alias of this class for old imports."""

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0
    active: bool = False
    """a torch.distributed process group is joined (also with one process under torchrun)"""
    comm_device: str = "cpu"
    """where collective buffers live: the CUDA device for NCCL, the CPU for gloo"""

    @property
    def is_main(self) -> bool:
        return self.rank == 0

    @staticmethod
    def from_env(device: str, backend: str = "auto", timeout_s: float = 600.0) -> tuple[Ranks, torch.device]:
        """Join the process group torchrun describes in the environment (or none) and pick this rank's device.

        ``device``: "cpu", "cuda" (``cuda:LOCAL_RANK``, wrapping when ranks outnumber GPUs) or "auto".
        ``backend``: "auto" takes NCCL when every local rank has a GPU of its own, else gloo (gloo also
        carries CUDA tensors, through host memory, so several ranks can share one GPU)."""
        if device == "cuda" and not torch.cuda.is_available():
            raise ValueError("device='cuda' but torch sees no CUDA device; use --device cpu or auto.")
        use_cuda = device == "cuda" or (device == "auto" and torch.cuda.is_available())
        if "RANK" not in os.environ or "WORLD_SIZE" not in os.environ:
            return Ranks(), torch.device("cuda" if use_cuda else "cpu")
        rank, world_size = int(os.environ["RANK"]), int(os.environ["WORLD_SIZE"])
        local_rank = int(os.environ.get("LOCAL_RANK", "0"))
        local_world = int(os.environ.get("LOCAL_WORLD_SIZE", str(world_size)))
        torch_device = torch.device("cpu")
        if use_cuda:
            torch_device = torch.device("cuda", local_rank % torch.cuda.device_count())
            torch.cuda.set_device(torch_device)
        backend = _backend(backend, use_cuda, local_world)
        _join_group(backend, rank, world_size, timeout_s)
        comm = str(torch_device) if backend == "nccl" else "cpu"
        return Ranks(rank, world_size, local_rank, True, comm), torch_device

    def shard(self, num_envs: int) -> tuple[int, int]:
        """(first global env index, env count) of this rank; ``num_envs`` is global."""
        if num_envs % self.world_size:
            raise ValueError(
                f"num_envs={num_envs} is the global env count and must divide among {self.world_size} ranks; "
                f"use a multiple of {self.world_size}."
            )
        per_rank = num_envs // self.world_size
        return self.rank * per_rank, per_rank

    # ---- collectives (identity in a one-process world) ------------------------------------------------

    def all_sum(self, x: np.ndarray) -> np.ndarray:
        """Element-wise sum over ranks of a float array (float64)."""
        x = np.asarray(x, dtype=np.float64)
        if not self.active:
            return x
        t = torch.as_tensor(x, device=self.comm_device).clone()
        dist.all_reduce(t, op=dist.ReduceOp.SUM)
        return t.cpu().numpy()

    def gather_agents(self, x: np.ndarray, offset: int, total: int) -> np.ndarray:
        """[T, N_local] per-rank slices -> [T, N_global] on every rank (a zero-padded all-reduce: exact)."""
        if not self.active:
            return x
        full = np.zeros((x.shape[0], total), dtype=np.float64)
        full[:, offset : offset + x.shape[1]] = x
        return self.all_sum(full)

    def broadcast_module(self, module: torch.nn.Module) -> None:
        """Rank 0's parameters and buffers to every rank (CleanRL's multi-GPU script leaves this out, #476)."""
        if not self.active:
            return
        with torch.no_grad():
            for tensor in [*module.parameters(), *module.buffers()]:
                buf = tensor.detach().to(self.comm_device).clone()
                dist.broadcast(buf, src=0)
                tensor.copy_(buf.to(tensor.device))

    def all_reduce_grads(self, params: list[torch.nn.Parameter], extra: np.ndarray) -> np.ndarray:
        """Sum the gradients of ``params`` (and a small float vector ``extra``) over ranks in one all-reduce."""
        if not self.active:
            return extra
        grads = [p.grad for p in params if p.grad is not None]
        flat = torch.cat([g.reshape(-1) for g in grads] + [torch.as_tensor(extra, dtype=grads[0].dtype,
                                                                          device=grads[0].device)])  # fmt: skip
        buf = flat.to(self.comm_device)
        dist.all_reduce(buf, op=dist.ReduceOp.SUM)
        flat = buf.to(grads[0].device)
        start = 0
        for g in grads:
            g.copy_(flat[start : start + g.numel()].view_as(g))
            start += g.numel()
        return flat[start:].double().cpu().numpy()

    def broadcast_flag(self, flag: bool) -> bool:
        """Rank 0's decision, on every rank (stop early, out of time)."""
        if not self.active:
            return flag
        t = torch.tensor([1.0 if flag else 0.0], device=self.comm_device)
        dist.broadcast(t, src=0)
        return bool(t.item())

    def broadcast_bytes(self, data: bytes | None) -> bytes | None:
        """Rank 0's bytes (a checkpoint file; None when rank 0 has none) on every rank, without pickling."""
        if not self.active:
            return data
        size = torch.tensor([-1 if data is None else len(data)], dtype=torch.int64, device=self.comm_device)
        dist.broadcast(size, src=0)
        n = int(size.item())
        if n < 0:
            return None
        buf = torch.zeros(n, dtype=torch.uint8, device=self.comm_device)
        if self.is_main and data is not None:
            buf.copy_(torch.frombuffer(bytearray(data), dtype=torch.uint8))
        dist.broadcast(buf, src=0)
        return buf.cpu().numpy().tobytes()

    def barrier(self) -> None:
        """Wait for every rank (the end of training: no rank tears the group down while rank 0 still saves)."""
        if self.active:
            dist.barrier()


def sample_actions(logits: torch.Tensor, offset: int, total: int) -> torch.Tensor:
    """Sample this rank's rows ``[offset, offset + B)`` of a global ``[total, 16]`` batch of masked logits.

    ``torch.multinomial`` draws one sample per row as ``argmax(p / q)`` with ``q ~ Exp(1)`` of the probability
    tensor's shape; drawing ``q`` for the global batch and keeping this rank's rows gives every rank its share
    of the one-process draw, and keeps the generator states of all ranks equal. With ``offset = 0`` and
    ``total = B`` this is ``Categorical(logits=logits).sample()`` draw for draw (tests/rl/test_distributed.py)."""
    probs = Categorical(logits=logits).probs  # [B, 16]
    noise = torch.empty((total, probs.shape[-1]), dtype=probs.dtype, device=probs.device).exponential_(1)
    return (probs / noise[offset : offset + probs.shape[0]]).argmax(-1)  # [B]


def free_port() -> int:
    with socket.socket(socket.AF_INET, socket.SOCK_STREAM) as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def _launched(local_rank: int, world_size: int, port: int, fn: Callable[..., None], args: tuple[Any, ...]) -> None:
    """One rank: ``fn(*args)``, then a teardown that never runs the interpreter's exit with gloo threads alive.

    A 2-rank run could end with a rank killed by SIGABRT ("terminate called without an active exception",
    raised while the interpreter was finalising: reports/2026-12-03-benchmarks-history/README.md, "Data-parallel PPO").
    After ``train()``, ``destroy_process_group()`` does not free the gloo group (its threads ``gloo_tcp_loop``,
    ``pt_gloo_runloop`` and rank 0's ``pt_tcpstore_uv`` still run: some object still holds it), so the C++ group was
    torn down during interpreter finalisation, possibly after the other rank, which hosts the store, had gone. So on
    success every rank waits for all (no rank leaves while another still uses the group), destroys the group and leaves
    with ``os._exit(0)`` once its output is flushed; a rank whose ``fn`` raises exits the usual way, so the
    launcher still reports its traceback (atexit handlers of a successful rank do not run). ``faulthandler``
    prints every thread's stack if a rank crashes."""
    os.environ.update(RANK=str(local_rank), WORLD_SIZE=str(world_size), LOCAL_RANK=str(local_rank),
                      LOCAL_WORLD_SIZE=str(world_size), MASTER_ADDR="127.0.0.1", MASTER_PORT=str(port))  # fmt: skip
    faulthandler.enable(file=sys.stderr, all_threads=True)
    try:
        fn(*args)
    except BaseException:
        if dist.is_initialized():
            dist.destroy_process_group()
        raise
    leave_rank(0)


def leave_rank(code: int) -> NoReturn:
    """End a successful rank (of :func:`launch_local` or torchrun): wait for every rank, destroy the process
    group, flush the output and ``os._exit(code)``, so the interpreter never finalises with gloo threads alive
    (see :func:`_launched`)."""
    if dist.is_initialized():
        dist.barrier()
        dist.destroy_process_group()
    logging.shutdown()
    sys.stdout.flush()
    sys.stderr.flush()
    os._exit(code)


def launch_local(world_size: int, fn: Callable[..., None], *args: Any) -> None:
    """Run ``fn(*args)`` in ``world_size`` fresh processes with torchrun's environment on this machine (tests and
    benchmarks; users run ``torchrun``). ``fn`` must be importable by name (a module-level function)."""
    mp.spawn(_launched, args=(world_size, free_port(), fn, args), nprocs=world_size, join=True)


World = Ranks
"""The old name of :class:`Ranks` (kept for imports that use it)."""

__all__ = ["RankZeroError", "Ranks", "World", "launch_local", "leave_rank", "sample_actions"]
