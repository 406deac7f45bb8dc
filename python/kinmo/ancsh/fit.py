"""The ANCSH training loop: Adam with the configured schedule over seeded batches of scans.

:func:`fit` trains an :class:`~kinmo.ancsh.model.ANCSH` on an
:class:`~kinmo.ancsh.dataset.ANCSHFrames` for a number of epochs of ``steps_per_epoch``
batches (one pass over the scans when ``None``), with the loss of
:func:`kinmo.ancsh.model.ancsh_loss` (Li et al. CVPR 2020, Sec. 4). The batch order comes from
``numpy.random.default_rng([seed, stage_index])`` and the learning rate follows
``config.schedule`` per step (:func:`lr_at`). Each batch's PointNet++ neighbourhoods (its
:class:`~kinmo.ancsh.plan.GeometryPlan`: farthest point sampling, ball query, nearest
neighbours of every level) are computed for the whole batch by the Rust core before the
forward pass (:func:`train_step`), so the step is bound by the network. Under ``torchrun`` every rank draws the whole
global batch and keeps its shard (:mod:`kinmo.train.distributed`). Each epoch gives one row
of ``metrics.csv`` (:data:`METRIC_COLUMNS`, :func:`metrics_csv`). The run set-up around it
(data, rendering, stages, checkpoints) is :func:`kinmo.ancsh.train.train_ancsh`.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ThreadPoolExecutor
from typing import Any, TypeVar

import numpy as np
import torch
from torch.utils.data import default_collate

from kinmo.ancsh.config import ANCSHConfig
from kinmo.ancsh.dataset import ANCSHFrames
from kinmo.ancsh.model import ANCSH, ancsh_loss
from kinmo.ancsh.plan import GeometryPlan
from kinmo.train import distributed
from kinmo.parallel import torch_threads
from kinmo.train.loop import optimizer_step, rows_csv, training_bar

__all__ = ["METRIC_COLUMNS", "batch_stream", "fit", "lr_at", "metrics_csv", "prepare_batch", "train_step"]

T = TypeVar("T")

#: Columns of ``metrics.csv``: one row per epoch of each stage.
METRIC_COLUMNS: tuple[str, ...] = (
    "stage", "epoch", "lr", "loss", "loss_seg", "loss_npcs", "loss_naocs", "loss_heatmap",
    "loss_unitvec", "loss_axis", "loss_joint_cls", "seg_acc", "scans", "seconds",
)
_TERMS = ("seg", "npcs", "naocs", "heatmap", "unitvec", "axis", "joint_cls")


def metrics_csv(rows: list[dict[str, Any]]) -> str:
    """``metrics.csv`` text (values as rounded by the loop, NaN written ``nan``)."""
    return rows_csv(rows, METRIC_COLUMNS, digits=None, nan="nan")


def lr_at(config: ANCSHConfig, step: int, total: int, epoch: int) -> float:
    """Learning rate at optimisation ``step`` of ``total`` (``epoch`` 0-based) for ``config.schedule``:
    ``cosine`` (per step, to 0), ``step`` (x ``step_gamma`` every ``step_size`` epochs) or
    ``constant``."""
    if config.schedule == "cosine":
        return config.lr * 0.5 * (1.0 + math.cos(math.pi * step / max(1, total)))
    if config.schedule == "step":
        return config.lr * config.step_gamma ** (epoch // config.step_size)
    return config.lr


def train_step(
    model: ANCSH,
    optimizer: torch.optim.Optimizer,
    items: list[dict[str, torch.Tensor]],
    device: torch.device,
    grad_clip: float = 0.0,
    weight: float = 1.0,
    module: torch.nn.Module | None = None,
    reference: bool = False,
    prepared: tuple[dict[str, torch.Tensor], GeometryPlan | None] | None = None,
) -> tuple[dict[str, torch.Tensor], dict[str, torch.Tensor], dict[str, torch.Tensor]]:
    """One optimisation step of ANCSH on a batch of :class:`~kinmo.ancsh.dataset.ANCSHFrames`
    items.

    The items are collated, the batch's neighbourhoods planned on the CPU by the Rust core
    (``model.backbone.plan``) and moved to ``device`` with the batch; then forward, loss
    (:func:`~kinmo.ancsh.model.ancsh_loss`), backward and ``optimizer``'s step
    (:func:`kinmo.train.loop.optimizer_step`).

    Parameters
    ----------
    model : ANCSH
        On ``device``.
    optimizer : torch.optim.Optimizer
    items : list of dict
        Dataset items (:meth:`ANCSHFrames.sample`).
    device : torch.device
    grad_clip : float
        Gradient norm clip (0: off).
    weight : float
        This rank's loss weight (:func:`kinmo.train.distributed.shard`; 1 in one process).
    module : torch.nn.Module, optional
        What runs the forward pass (``DistributedDataParallel`` of ``model``); default
        ``model``.
    reference : bool
        Run the computation before geometry plans instead (:meth:`ANCSH.forward_reference
        <kinmo.ancsh.model.ANCSH.forward_reference>`, no plan; ``module`` is not used): the
        "before" of ``bench/bench_ancsh.py`` and the tests.
    prepared : (dict, GeometryPlan or None), optional
        :func:`prepare_batch` of ``items`` made beforehand (on the CPU, e.g. while the
        previous step ran); default: made here.

    Returns
    -------
    terms : dict of scalar tensors
        The loss terms and ``total``.
    pred : dict of tensors
        The network's output.
    batch : dict of tensors
        The collated batch on ``device``.
    """
    batch, plan = prepared if prepared is not None else prepare_batch(model, items, reference)
    batch = {k: v.to(device) for k, v in batch.items()}
    if reference:
        pred = model.forward_reference(batch["xyz"])
    else:
        pred = (module or model)(batch["xyz"], plan.to(device))
    terms = ancsh_loss(pred, batch)
    optimizer_step(optimizer, terms["total"], model, weight, grad_clip)
    return terms, pred, batch


def prepare_batch(model: ANCSH, items: list[dict[str, torch.Tensor]],
                  reference: bool = False) -> tuple[dict[str, torch.Tensor], GeometryPlan | None]:
    """The CPU side of a training step: ``items`` collated (leading B) and the batch's
    PointNet++ neighbourhoods planned by the Rust core (``model.backbone.plan``; None with
    ``reference``). It reads only the points and the backbone's fixed sizes, never the
    weights, so it can run in another thread while the previous step trains."""
    batch = default_collate(items)
    if reference:
        return batch, None
    with torch.no_grad():
        return batch, model.backbone.plan(batch["xyz"])


def batch_stream(draw: Callable[[], T], total: int, overlap: bool = True) -> Iterator[T]:
    """``total`` results of ``draw()``, in call order; with ``overlap`` the next one is made
    in a background thread while the caller uses the current one.

    ``draw`` runs sequentially either way (one thread, one call at a time, in the same
    order), so a seeded ``draw`` yields the same sequence: overlapping changes timing, never
    results. Made for :func:`fit`, whose ``draw`` samples a batch and plans it
    (:func:`prepare_batch`): the Rust planning and the sampling then overlap the network's
    step, on the CPU (the Rust core releases the GIL) as in front of a GPU.

    Raises
    ------
    Exception
        Whatever ``draw`` raised, when its result is reached.
    """
    if not overlap:
        for _ in range(total):
            yield draw()
        return
    with ThreadPoolExecutor(max_workers=1, thread_name_prefix="kinmo-ancsh-batches") as pool:
        nxt = pool.submit(draw) if total > 0 else None
        for k in range(total):
            cur = nxt.result()  # type: ignore[union-attr]
            nxt = pool.submit(draw) if k + 1 < total else None
            yield cur


def overlap_helps(device: torch.device, threads: int) -> bool:
    """Whether :func:`fit` should prepare batches in a background thread by default.

    True on an accelerator (the CPU prepares while the GPU steps) and on the CPU when torch
    runs on fewer threads than there are cores (``threads`` >= 1, the ``train all`` default
    of 1); False when a CPU step already uses every core (``threads`` 0: torch's default,
    or as many as the cores), where the preparing thread only competes with the step.
    """
    if device.type != "cpu":
        return True
    cores = os.cpu_count() or 1
    return 0 < threads < cores


def fit(
    model: ANCSH,
    dataset: ANCSHFrames,
    config: ANCSHConfig,
    epochs: int,
    device: torch.device,
    stage: str = "train",
    stage_index: int = 0,
    on_epoch: Callable[[dict[str, Any]], None] | None = None,
    progress: bool = True,
    overlap: bool | None = None,
) -> list[dict[str, Any]]:
    """Train ``model`` on ``dataset`` for ``epochs`` epochs (Adam, ``config`` schedule).

    Each step's batch is sampled and planned (:func:`prepare_batch`) one step ahead in a
    background thread (:func:`batch_stream`), in the same order from the same random stream
    as without, so ``overlap`` changes the step time, not the result. By default
    (:func:`overlap_helps`) it overlaps unless torch already uses every CPU core for a CPU
    step, where the thread only competes with it (``bench/bench_ancsh.py --scans``, paper
    preset on 2 cores: 0.95x).

    Parameters
    ----------
    model : ANCSH
        Trained in place (on ``device``).
    dataset : ANCSHFrames
    config : ANCSHConfig
        ``steps_per_epoch``, ``batch_size``, ``lr``, ``weight_decay``, ``schedule``,
        ``grad_clip``, ``seed``.
    epochs : int
    device : torch.device
    stage : str
        Label of the rows (``"train"``, ``"semi"``).
    stage_index : int
        Seeds the batch order of this stage (``[seed, stage_index]``).
    on_epoch : callable, optional
        Called with each epoch's metrics row.
    progress : bool
    overlap : bool, optional
        Prepare the next batch while the current one trains; False: in turn; None (default):
        :func:`overlap_helps`.

    Returns
    -------
    list of dict
        One row per epoch (:data:`METRIC_COLUMNS`).
    """
    if overlap is None:
        overlap = overlap_helps(device, config.threads)
    with torch_threads(config.threads):
        return _fit(model, dataset, config, epochs, device, stage, stage_index, on_epoch, progress, overlap)


def _fit(model: ANCSH, dataset: ANCSHFrames, config: ANCSHConfig, epochs: int, device: torch.device,
         stage: str, stage_index: int, on_epoch: Callable[[dict[str, Any]], None] | None,
         progress: bool, overlap: bool) -> list[dict[str, Any]]:
    steps = config.steps_per_epoch or max(1, math.ceil(len(dataset) / config.batch_size))
    total = steps * epochs
    opt = torch.optim.Adam(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    rng = np.random.default_rng([config.seed, stage_index])
    order: list[int] = []
    rows: list[dict[str, Any]] = []
    step = 0
    model.to(device)
    ddp = distributed.wrap(model)  # torchrun: DistributedDataParallel (kinmo.train.distributed)
    dist_info = distributed.info()

    def draw() -> tuple[list[dict[str, torch.Tensor]], float, Any]:
        # the next batch: indices from the seeded order, its items, collated and planned
        idx: list[int] = []
        while len(idx) < config.batch_size:
            if not order:
                order.extend(int(i) for i in rng.permutation(len(dataset)))
            idx.append(order.pop())
        # every rank draws the whole global batch (same random stream), keeps its shard
        items, weight = distributed.shard([dataset.sample(i, rng) for i in idx])
        return items, weight, prepare_batch(model, items)

    batches = batch_stream(draw, total, overlap)
    with training_bar(progress, "ancsh") as bar:
        task = bar.task(f"{config.category} {config.setting} [{stage}]", total)
        for epoch in range(epochs):
            model.train()
            t0 = time.perf_counter()
            sums = dict.fromkeys(("total", *_TERMS), 0.0)
            correct = seen = 0
            lr = config.lr
            for _ in range(steps):
                lr = lr_at(config, step, total, epoch)
                for g in opt.param_groups:
                    g["lr"] = lr
                items, weight, prepared = next(batches)
                terms, pred, batch = train_step(model, opt, items, device, config.grad_clip, weight, ddp,
                                                prepared=prepared)
                step += 1
                share = weight / dist_info.world_size  # this rank's share of the global batch
                for k in sums:
                    sums[k] += share * float(terms[k].detach())
                if weight > 0:
                    with torch.no_grad():
                        correct += int((pred["seg_logits"].argmax(-1) == batch["seg"]).sum())
                        seen += batch["seg"].numel()
                bar.advance(task, info=f"loss {float(terms['total'].detach()):.3f}")
            if dist_info.enabled:  # the epoch's figures over all ranks
                *totals, correct, seen = distributed.all_sum([*sums.values(), correct, seen])
                sums = dict(zip(sums, totals))
            row = {"stage": stage, "epoch": epoch + 1, "lr": round(lr, 8),
                   "loss": round(sums["total"] / steps, 6),
                   **{f"loss_{k}": round(sums[k] / steps, 6) for k in _TERMS},
                   "seg_acc": round(correct / max(1, seen), 6), "scans": len(dataset),
                   "seconds": round(time.perf_counter() - t0, 3)}
            rows.append(row)
            if on_epoch is not None:
                on_epoch(row)
    return rows
