"""Data-parallel training with ``torch.distributed`` (``torchrun``), shared by kinmo's trainers.

``torchrun --nproc-per-node N -m kinmo train gnn|axis|ancsh ...`` starts N processes that
each run the same command; torchrun sets ``RANK``, ``WORLD_SIZE``, ``LOCAL_RANK``,
``MASTER_ADDR`` and ``MASTER_PORT``. The trainers call :func:`setup` at their start, which
joins the process group from those variables (backend ``gloo`` on CPU, ``nccl`` when the
training device is CUDA) and is a no-op in a plain single process, so single-process use is
unchanged. The scheme, the same in every trainer:

- **same global batch**: every rank draws the batch order and the random augmentation of the
  *whole* global batch from the same seeded generator (so the random streams stay identical
  on every rank and equal to a single process's), then keeps its shard, items
  ``rank::world_size`` (:func:`shard`). This is a distributed sampler over the global batch:
  a run on N processes sees exactly the samples of the single-process run with the same
  ``batch_size``, each sample on one rank;
- **gradients**: the model is wrapped in
  :class:`~torch.nn.parallel.DistributedDataParallel` (:func:`wrap`), which averages the
  gradients over the ranks; each rank's loss is weighted by
  ``world_size * n_rank / n_global`` (:func:`loss_weight`), so the averaged gradient is the
  gradient of the global batch's mean over samples (a rank whose shard is empty, at the end of
  an epoch, runs one sample with weight 0 so that it still takes part in the all-reduce);
- **what differs from one process**: per-sample means inside a loss that averages over edges
  or points rather than samples are taken per rank, and batch-norm layers normalise with the
  statistics of the rank's shard (CPU has no :class:`~torch.nn.SyncBatchNorm`; on CUDA
  :func:`wrap` converts them, ``sync_batchnorm=True``), so loss curves agree within a
  tolerance, not bit for bit (measured in ``tests/train/test_distributed.py``);
- **metrics**: each rank sums its share of the epoch's metrics and :func:`all_sum` adds them
  up, so every rank holds the global figures;
- **writes**: only rank 0 (:attr:`DistInfo.is_main`) writes checkpoints, metrics and configs;
  shared preparation that writes files (rendering scans) runs on rank 0 first
  (:func:`main_first`).

Seeded runs are reproducible for a given number of processes.
"""

from __future__ import annotations

import atexit
import gc
import os
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import timedelta
from typing import TypeVar

import torch

__all__ = [
    "DistInfo",
    "all_sum",
    "barrier",
    "info",
    "loss_weight",
    "main_first",
    "setup",
    "shard",
    "sync_gradients",
    "unwrap",
    "wrap",
]

T = TypeVar("T")


@dataclass(frozen=True)
class DistInfo:
    """Where this process stands in a distributed run.

    Attributes
    ----------
    rank : int
        0 .. world_size - 1.
    world_size : int
        Number of processes; 1 outside ``torchrun``.
    local_rank : int
        Rank on this node (the CUDA device index with NCCL).
    """

    rank: int = 0
    world_size: int = 1
    local_rank: int = 0

    @property
    def enabled(self) -> bool:
        """True when more than one process trains."""
        return self.world_size > 1

    @property
    def is_main(self) -> bool:
        """True on rank 0, the one that writes files."""
        return self.rank == 0


def info() -> DistInfo:
    """This process's :class:`DistInfo` (from the process group, else ``DistInfo()``)."""
    import torch.distributed as dist

    if dist.is_available() and dist.is_initialized():
        return DistInfo(dist.get_rank(), dist.get_world_size(),
                        int(os.environ.get("LOCAL_RANK", dist.get_rank())))
    return DistInfo()


def setup(device: torch.device | str | None = None) -> tuple[DistInfo, torch.device | None]:
    """Join the ``torchrun`` process group, if this process was started by torchrun.

    Parameters
    ----------
    device : torch.device or str, optional
        The training device. CUDA selects the NCCL backend and this rank's GPU
        (``cuda:LOCAL_RANK``); anything else gloo.

    Returns
    -------
    (DistInfo, torch.device or None)
        The process's place, and ``device`` (with the local rank's index on CUDA).

    Raises
    ------
    RuntimeError
        torch.distributed cannot initialise (e.g. the rendezvous times out).

    Notes
    -----
    Does nothing when ``WORLD_SIZE`` is unset or 1 (single process) or the group is already
    initialised; safe to call from every trainer. The group is destroyed at exit.
    """
    import torch.distributed as dist

    dev = torch.device(device) if isinstance(device, str) else device
    world = int(os.environ.get("WORLD_SIZE", "1"))
    if world <= 1 or not dist.is_available():
        return info(), dev
    local = int(os.environ.get("LOCAL_RANK", "0"))
    cuda = dev is not None and dev.type == "cuda"
    if cuda:
        torch.cuda.set_device(local)
        dev = torch.device("cuda", local)
    if not dist.is_initialized():
        dist.init_process_group(backend="nccl" if cuda else "gloo")
        atexit.register(_destroy)
    return info(), dev


#: How long a rank waits at exit for the others before it tears the group down anyway (a
#: rank that failed leaves the others inside a collective; torchrun then stops them).
EXIT_BARRIER_S = 120.0


def _destroy() -> None:
    """Tear the process group down at exit, in an order that cannot abort the process.

    Without it, a rank could abort at exit (``terminate called without an active exception``,
    SIGABRT, seen on one ``torchrun`` run in about fifteen on 2 loaded cores, after training had
    finished): a :class:`~torch.nn.parallel.DistributedDataParallel` kept alive by a reference
    cycle holds the gloo group, whose worker threads were then destroyed during interpreter
    finalisation while a peer was still closing its connections. So: collect such cycles,
    wait for every rank at a barrier (bounded by :data:`EXIT_BARRIER_S`), then destroy.
    """
    import torch.distributed as dist

    if not dist.is_initialized():
        return
    gc.collect()
    try:
        dist.barrier(async_op=True).wait(timeout=timedelta(seconds=EXIT_BARRIER_S))
    except RuntimeError:  # a peer is gone or stuck: tear down regardless
        pass
    dist.destroy_process_group()


def wrap(model: torch.nn.Module, sync_batchnorm: bool = True,
         find_unused_parameters: bool = False) -> torch.nn.Module:
    """``model`` in :class:`~torch.nn.parallel.DistributedDataParallel` when distributed.

    Parameters
    ----------
    model : torch.nn.Module
        Already on its device; its parameters are broadcast from rank 0.
    sync_batchnorm : bool
        On CUDA, convert batch-norm layers to :class:`~torch.nn.SyncBatchNorm` (CPU has none:
        batch norm then uses per-rank statistics).
    find_unused_parameters : bool
        For models whose forward leaves some parameters without gradient.

    Returns
    -------
    torch.nn.Module
        ``model`` itself in a single process.
    """
    if not info().enabled:
        return model
    from torch.nn.parallel import DistributedDataParallel

    dev = next(model.parameters()).device
    if sync_batchnorm and dev.type == "cuda":
        model = torch.nn.SyncBatchNorm.convert_sync_batchnorm(model)
    ids = [dev.index] if dev.type == "cuda" else None
    return DistributedDataParallel(model, device_ids=ids,
                                   find_unused_parameters=find_unused_parameters)


def sync_gradients(model: torch.nn.Module) -> None:
    """Average the gradients of ``model``'s parameters over the ranks (after ``backward``).

    What :class:`~torch.nn.parallel.DistributedDataParallel` does during ``backward``, for
    trainers whose step calls several sub-modules rather than one ``forward`` (DDP only
    synchronises through ``forward``). Parameters without a gradient on this rank count as
    zero. A no-op in one process.
    """
    if not info().enabled:
        return
    import torch.distributed as dist

    params = [p for p in model.parameters() if p.requires_grad]
    grads = [p.grad if p.grad is not None else torch.zeros_like(p) for p in params]
    flat = torch.cat([g.reshape(-1) for g in grads])
    dist.all_reduce(flat, op=dist.ReduceOp.SUM)
    flat /= info().world_size
    i = 0
    for p, g in zip(params, grads):
        n = g.numel()
        p.grad = flat[i:i + n].view_as(p).clone()
        i += n


def unwrap(model: torch.nn.Module) -> torch.nn.Module:
    """The plain model inside a :func:`wrap` (for checkpoints and evaluation)."""
    return getattr(model, "module", model)


def shard(items: Sequence[T]) -> tuple[list[T], float]:
    """This rank's share of a global batch, and the weight of its loss.

    Parameters
    ----------
    items : sequence
        The whole global batch, identical on every rank.

    Returns
    -------
    (list, float)
        ``items[rank::world_size]`` and :func:`loss_weight` of it. A rank whose share is
        empty gets ``[items[0]]`` with weight 0 (it must still run a backward pass for the
        gradient all-reduce). In a single process: ``(list(items), 1.0)``.
    """
    d = info()
    if not d.enabled:
        return list(items), 1.0
    mine = list(items[d.rank::d.world_size])
    if not mine:
        return [items[0]], 0.0
    return mine, loss_weight(len(mine), len(items))


def loss_weight(n_rank: int, n_global: int) -> float:
    """``world_size * n_rank / n_global``: the factor that makes DDP's gradient average the
    gradient of the global batch's per-sample mean (1 in a single process)."""
    d = info()
    return d.world_size * n_rank / max(n_global, 1) if d.enabled else 1.0


def all_sum(values: Sequence[float]) -> list[float]:
    """Element-wise sum of ``values`` over the ranks (float64; the values in one process)."""
    d = info()
    if not d.enabled:
        return [float(v) for v in values]
    import torch.distributed as dist

    t = torch.tensor([float(v) for v in values], dtype=torch.float64)
    if dist.get_backend() == "nccl":
        t = t.cuda()
    dist.all_reduce(t, op=dist.ReduceOp.SUM)
    return [float(v) for v in t.cpu()]


def barrier() -> None:
    """Wait for every rank (no-op in one process)."""
    if info().enabled:
        import torch.distributed as dist

        dist.barrier()


@contextmanager
def main_first() -> Iterator[None]:
    """Run the block on rank 0 first, then on the other ranks (which then find its outputs,
    e.g. rendered scans, up to date and only read them). A no-op in one process."""
    d = info()
    if d.enabled and not d.is_main:
        barrier()
    try:
        yield
    finally:
        if d.enabled and d.is_main:
            barrier()

