"""Training loop of the motion GNN (``kinmo train gnn``; Liu et al. 2023, Sec. 3.2).

:func:`train_gnn` reads a cache of part graphs (``kinmo prepare``), splits the labelled
(PartNet-Mobility) graphs into train and test sets by category (:mod:`kinmo.train.split`,
or a given split file), trains :class:`~kinmo.models.motion_gnn.MotionGNN` with the loss of
Eq. 1-4 (:mod:`kinmo.models.losses`) and writes a **run folder**:

- ``config.json``: the :class:`~kinmo.train.config.TrainConfig` (with the model's vocabulary
  size filled in);
- ``split.json``: the train/test split used;
- ``model.pt``: the checkpoint (state dict, config, semantic vocabulary, class weights);
- ``metrics.csv``: one row per epoch (:data:`METRIC_COLUMNS`): learning rate, training loss
  terms and edge accuracy, and the same on the test split when it is not empty (edge type
  accuracy, recall of moving edges, edge-level axis angle error in degrees and axis position
  error as a fraction of the shape's bounding-box diagonal; :mod:`kinmo.train.gnn_metrics`);
- ``recall.json``: per-class recall of the edge types on the training and test sets at the
  end, and the training time (wall clock and CPU seconds, torch threads, device).

Runs are reproducible: ``seed`` seeds torch, the batch order and the augmentation, and torch's
deterministic algorithms are switched on for the duration of the run.

Under ``torchrun`` (``torchrun --nproc-per-node N -m kinmo train gnn ...``) the run is
data-parallel (:mod:`kinmo.train.distributed`): the same global batches of ``batch_size``
graphs, each rank training on its shard, rank 0 writing the run folder.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np
import torch

from kinmo.data.augment import flat_variants
from kinmo.data.cache import load_cache
from kinmo.data.graph import PartGraph
from kinmo.data.model import FINE_TO_COARSE
from kinmo.errors import KinmoDataError
from kinmo.features import GraphTensors, SemanticVocab, collate, graph_tensors, yaw_rotation
from kinmo.io import write_json, write_text
from kinmo.models.losses import MotionLoss, class_weights
from kinmo.models.motion_gnn import ModelConfig, MotionGNN
from kinmo.runs import MEMBERS_DIR, member_folders
import kinmo.train.distributed as distributed
from kinmo.train.config import TrainConfig
from kinmo.train.loop import (
    build_or_refuse,
    load_checkpoint,
    optimizer_step,
    resolve_device,
    rows_csv,
    training_bar,
    training_session,
)
from kinmo.train.loop import save_checkpoint as _save
from kinmo.train.gnn_metrics import (
    edge_metrics,
    evaluate_edges,
    merge_metrics,
    per_class_recall,
    summarize_metrics,
)
from kinmo.train.split import Split, make_split

__all__ = [
    "METRIC_COLUMNS",
    "Run",
    "TrainResult",
    "edge_metrics",
    "labelled_graphs",
    "load_cache",
    "load_run",
    "train_gnn",
    "train_members",
]

METRIC_COLUMNS: tuple[str, ...] = (
    "epoch", "lr", "loss", "loss_type", "loss_dir", "loss_pos", "train_acc",
    "test_loss", "test_acc", "test_moving_recall", "test_angle_deg", "test_pos_dist", "seconds",
)


#: ``format`` tag of the checkpoints (:func:`kinmo.train.loop.save_checkpoint`).
CHECKPOINT_FORMAT = "kinmo-motion-gnn"

_COARSE_LUT = torch.tensor(FINE_TO_COARSE, dtype=torch.int64)


@dataclass
class Run:
    """A trained model loaded from a run folder.

    Attributes
    ----------
    model : MotionGNN
        In eval mode, on ``device``.
    config : TrainConfig
    vocab : SemanticVocab
    device : torch.device
    path : Path
        The run folder.
    members : tuple of Run
        Further models of the same type set and vocabulary, trained like this one with other
        seeds (``<run>/members/<k>/``, :data:`kinmo.runs.MEMBERS_DIR`): inference averages
        their answers with this one's (:func:`kinmo.inference.gnn.forward`). Empty for a
        single model.
    """

    model: MotionGNN
    config: TrainConfig
    vocab: SemanticVocab
    device: torch.device
    path: Path
    members: tuple[Run, ...] = ()

    @property
    def types(self) -> str:
        """``"fine"`` or ``"coarse"``."""
        return self.config.model.types


def save_checkpoint(path: Path, model: MotionGNN, config: TrainConfig, vocab: SemanticVocab,
                    weights: torch.Tensor | None, epoch: int) -> None:
    """Write ``model.pt`` atomically (state dict + config + vocabulary)."""
    _save(path, CHECKPOINT_FORMAT, model, config=config.model_dump(), vocab=vocab.names,
          class_weights=None if weights is None else weights.cpu(), epoch=epoch)


def load_run(run: str | Path, device: str = "auto") -> Run:
    """Load a trained motion GNN from a run folder (or a ``model.pt`` file).

    Parameters
    ----------
    run : str or Path
        Run folder written by :func:`train_gnn`, or its ``model.pt``.
    device : str
        See :func:`kinmo.train.loop.resolve_device`.

    Returns
    -------
    Run

    Raises
    ------
    KinmoDataError
        Missing or unreadable checkpoint, or one that is not a kinmo motion GNN.
    """
    payload, ckpt = load_checkpoint(run, CHECKPOINT_FORMAT, "motion-GNN", "kinmo train gnn")

    def build() -> tuple[TrainConfig, MotionGNN]:
        raw = payload["config"]
        # checkpoints written before the candidate direction head have no ``axis_mode``:
        # they regress the direction
        if isinstance(raw, dict) and "axis_mode" not in raw.get("model", {}):
            raw = {**raw, "model": {**raw.get("model", {}), "axis_mode": "regress"}}
        config = TrainConfig.model_validate(raw)
        model = MotionGNN(config.model)
        model.load_state_dict(payload["state_dict"])
        return config, model

    config, model = build_or_refuse(ckpt, build)
    dev = resolve_device(device)
    model.to(dev).eval()
    vocab = SemanticVocab(payload.get("vocab", []))
    members = []
    for folder in member_folders(ckpt.parent):
        m = load_run(folder, device)
        if m.members or m.types != config.model.types or m.vocab.names != vocab.names:
            raise KinmoDataError(folder, "an ensemble member must be a single motion GNN of the run's "
                                         "type set and vocabulary (trained on the same objects)")
        members.append(m)
    return Run(model, config, vocab, dev, ckpt.parent, tuple(members))


@dataclass
class TrainResult:
    """Outcome of :func:`train_gnn`.

    Attributes
    ----------
    run_dir : Path
    config : TrainConfig
    split : Split
    history : list of dict
        The rows of ``metrics.csv``.
    seconds : float
        Wall-clock training time (excluding data loading).
    cpu_seconds : float
        CPU time of the process over the same span (all threads; the fair measure on a shared
        machine).
    recall : dict
        Per-class recall on ``"train"`` and ``"test"``.
    """

    run_dir: Path
    config: TrainConfig
    split: Split
    history: list[dict[str, float]] = field(default_factory=list)
    seconds: float = 0.0
    recall: dict[str, Any] = field(default_factory=dict)
    cpu_seconds: float = 0.0


def _metrics_csv(rows: list[dict[str, float]]) -> str:
    """``metrics.csv`` text (NaN: empty cell)."""
    return rows_csv(rows, METRIC_COLUMNS)


def _subsample(members: list[GraphTensors], n_points: int | None,
               gen: torch.Generator) -> list[GraphTensors]:
    """The random point subsets of :func:`~kinmo.features.collate` drawn for a whole global
    batch (same draws, same order), so that a rank's shard of it holds the points a single
    process would have used."""
    from dataclasses import replace

    out = []
    for m in members:
        if n_points is not None and m.points.shape[1] > n_points:
            idx = torch.randperm(m.points.shape[1], generator=gen)[:n_points]
            m = replace(m, points=m.points[:, idx])
        out.append(m)
    return out


def labelled_graphs(graphs: Sequence[PartGraph]) -> list[PartGraph]:
    """The graphs the motion GNN and the axis network train on: with ground-truth labels and
    at least one sibling edge (in the given order)."""
    return [g for g in graphs if g.has_labels and len(g.sibling_edges) > 0]


def train_gnn(
    cache: str | Path | Sequence[PartGraph],
    out: str | Path,
    config: TrainConfig,
    split: Split | str | Path | None = None,
    progress: bool = True,
    on_epoch: Callable[[dict[str, float]], None] | None = None,
) -> TrainResult:
    """Train the motion GNN and write a run folder (module docstring).

    Parameters
    ----------
    cache : str, Path or sequence of PartGraph
        Cache folder of ``kinmo prepare`` (or graphs already loaded). Only graphs with
        ground-truth labels and at least one sibling edge are used.
    out : str or Path
        Run folder (created).
    config : TrainConfig
    split : Split, str or Path, optional
        A split (or its JSON file). By default one is made with
        :func:`~kinmo.train.split.make_split` (``config.test_fraction``, ``config.seed``).
        Ids of the split missing from the cache are ignored.
    progress : bool
        Show a rich progress bar.
    on_epoch : callable, optional
        Called with each epoch's metrics row.

    Returns
    -------
    TrainResult

    Raises
    ------
    KinmoDataError
        No labelled graphs, or a split leaving no training graph.
    """
    out = Path(out)
    graphs = list(cache) if not isinstance(cache, (str, Path)) else load_cache(cache)
    where = cache if isinstance(cache, (str, Path)) else out
    graphs = labelled_graphs(graphs)
    if not graphs:
        raise KinmoDataError(where, "no labelled (PartNet-Mobility) part graphs to train on")
    by_id = {g.shape_id: g for g in graphs}
    if split is None:
        split = make_split(list(by_id), [g.category for g in by_id.values()],
                           config.test_fraction, config.seed)
    elif not isinstance(split, Split):
        split = Split.load(split)
    train_g = [by_id[i] for i in split.train if i in by_id]
    test_g = [by_id[i] for i in split.test if i in by_id]
    if not train_g:
        raise KinmoDataError(where, "the split leaves no labelled graph for training")

    with training_session(config.device, config.seed, config.threads, deterministic=True) as (
            dist_info, device):
        return _train(train_g, test_g, out, config, split, progress, on_epoch, dist_info, device)


def train_members(cache: str | Path | Sequence[PartGraph], out: str | Path, config: TrainConfig,
                  members: int, progress: bool = True) -> list[TrainResult]:
    """Train the ensemble members of the run ``out`` (:attr:`Run.members`, kinmo extension): the
    models averaged with the run's own at inference (:func:`kinmo.inference.gnn.forward`).

    Member ``k`` (1 to ``members``) is :func:`train_gnn` of ``config`` with seed
    ``config.seed + k`` on the run's own split (``out/split.json``, so the same objects and
    vocabulary), into ``out/members/<k>/`` (:data:`kinmo.runs.MEMBERS_DIR`). Members already
    trained (their ``model.pt`` exists) are kept: an interrupted run resumes.

    Parameters
    ----------
    cache : str, Path or sequence of PartGraph
        As :func:`train_gnn`.
    out : str or Path
        A run folder of :func:`train_gnn` (its ``split.json`` is used).
    config : TrainConfig
        The run's configuration.
    members : int
        Further models (0: none).
    progress : bool

    Returns
    -------
    list of TrainResult
        The members trained by this call.

    Raises
    ------
    KinmoDataError
        ``out`` has no ``split.json`` (train the run first), or as :func:`train_gnn`.
    """
    out = Path(out)
    if members > 0 and not (out / "split.json").is_file():
        raise KinmoDataError(out / "split.json", "no split of the run: train its own model first")
    done = []
    for k in range(1, members + 1):
        folder = out / MEMBERS_DIR / str(k)
        if (folder / "model.pt").is_file():
            continue
        cfg = config.model_copy(update={"seed": config.seed + k})
        done.append(train_gnn(cache, folder, cfg, split=out / "split.json", progress=progress))
    return done


def _train(train_g: list[PartGraph], test_g: list[PartGraph], out: Path, config: TrainConfig,
           split: Split, progress: bool, on_epoch: Callable[[dict[str, float]], None] | None,
           dist_info: distributed.DistInfo, device: torch.device) -> TrainResult:
    main = dist_info.is_main
    vocab = SemanticVocab.from_graphs(train_g) if config.model.semantic_dim > 0 else SemanticVocab()
    if config.flatten_prob > 0 or config.drop_names_prob > 0:  # after the vocabulary: names kept
        train_g = flat_variants(train_g, config.flatten_prob, config.drop_names_prob, config.seed)
    mdata = config.model.model_dump()
    mdata["vocab_size"] = len(vocab)
    config = config.model_copy(update={"model": ModelConfig.model_validate(mdata)})
    if main:
        out.mkdir(parents=True, exist_ok=True)
        write_json(out / "config.json", config.model_dump())
        split.save(out / "split.json")

    train_t = [graph_tensors(g, vocab) for g in train_g]
    test_t = [graph_tensors(g, vocab) for g in test_g]
    k = len(config.model.type_names)
    counts = np.zeros(k, dtype=np.int64)
    for t in train_t:
        lab = t.edge_fine if config.model.types == "fine" else _COARSE_LUT[t.edge_fine]
        counts += np.bincount(lab.numpy(), minlength=k)
    weights = class_weights(counts) if config.class_weighting == "inv_sqrt" else None

    model = MotionGNN(config.model).to(device)
    ddp = distributed.wrap(model)  # the model itself in a single process
    loss_fn = MotionLoss(config.model.types, weights, config.focal_gamma, config.w_dir,
                         config.w_pos, config.balance).to(device)
    opt = torch.optim.Adam(model.parameters(), lr=config.lr, weight_decay=config.weight_decay)
    if config.schedule == "cosine":
        sched = torch.optim.lr_scheduler.CosineAnnealingLR(opt, T_max=max(config.epochs, 1))
    elif config.schedule == "step":
        sched = torch.optim.lr_scheduler.StepLR(opt, config.step_size, config.step_gamma)
    else:
        sched = torch.optim.lr_scheduler.LambdaLR(opt, lambda _: 1.0)
    gen = torch.Generator().manual_seed(config.seed)

    history: list[dict[str, float]] = []
    t0 = time.perf_counter()
    c0 = time.process_time()
    with training_bar(progress, "train gnn") as bar:
        task = bar.task("epochs", config.epochs)
        for epoch in range(1, config.epochs + 1):
            model.train()
            order = torch.randperm(len(train_t), generator=gen).tolist()
            sums = np.zeros(4)
            n_b = 0
            acc = None
            for start in range(0, len(order), config.batch_size):
                members = [train_t[i] for i in order[start:start + config.batch_size]]
                if config.augment_yaw:
                    angles = torch.rand(len(members), generator=gen) * (2 * math.pi)
                    members = [m.rotated(yaw_rotation(float(a))) for m, a in zip(members, angles)]
                if config.augment_turn > 0.0:
                    turn = torch.rand(len(members), generator=gen) < config.augment_turn
                    ks = torch.randint(1, 4, (len(members),), generator=gen)
                    members = [m.turned(int(k)) if t else m for m, t, k in zip(members, turn.tolist(), ks.tolist())]
                if dist_info.enabled:  # the global batch's point draws, then this rank's shard
                    members = _subsample(members, config.n_points, gen)
                members, weight = distributed.shard(members)
                batch = collate(members, n_points=config.n_points, generator=gen).to(device)
                outp = ddp(batch)
                terms = loss_fn(outp, batch)
                optimizer_step(opt, terms.total, model, weight, config.grad_clip)
                share = weight / dist_info.world_size  # n_rank / n_global (1: one process)
                sums += [share * float(terms.total.detach()), share * float(terms.type.detach()),
                         share * float(terms.direction.detach()),
                         share * float(terms.position.detach())]
                n_b += 1
                if weight > 0:
                    acc = merge_metrics(acc, edge_metrics(outp.logits.detach(), outp.direction.detach(),
                                                   outp.origin.detach(), batch, config.model.types))
            if dist_info.enabled:  # the epoch's figures over all ranks
                acc = acc or {"correct": 0, "n_edges": 0}
                tot = distributed.all_sum([*sums, acc["correct"], acc["n_edges"]])
                sums = np.asarray(tot[:4])
                acc["correct"], acc["n_edges"] = int(tot[4]), int(tot[5])
            lr = opt.param_groups[0]["lr"]
            sched.step()
            row: dict[str, float] = {
                "epoch": epoch, "lr": lr,
                "loss": sums[0] / n_b, "loss_type": sums[1] / n_b,
                "loss_dir": sums[2] / n_b, "loss_pos": sums[3] / n_b,
                "train_acc": summarize_metrics(acc)["acc"],
            }
            if test_t and main:  # the test split is evaluated by rank 0 only
                tacc, tloss = evaluate_edges(model, test_t, config, device, loss_fn)
                s = summarize_metrics(tacc)
                row.update(test_loss=tloss, test_acc=s["acc"],
                           test_moving_recall=s["moving_recall"], test_angle_deg=s["angle_deg"],
                           test_pos_dist=s["pos_dist"])
            else:
                row.update(test_loss=float("nan"), test_acc=float("nan"),
                           test_moving_recall=float("nan"), test_angle_deg=float("nan"),
                           test_pos_dist=float("nan"))
            row["seconds"] = time.perf_counter() - t0
            history.append(row)
            if main:
                write_text(out / "metrics.csv", _metrics_csv(history))
            info = f"loss {row['loss']:.3f} acc {row['train_acc']:.3f}"
            if test_t:
                info += f" | test acc {row['test_acc']:.3f} angle {row['test_angle_deg']:.1f}°"
            bar.advance(task, info=info)
            if on_epoch is not None:
                on_epoch(row)
    seconds = time.perf_counter() - t0
    cpu_seconds = time.process_time() - c0
    if not main:  # rank 0 evaluates and writes the run folder
        return TrainResult(out, config, split, history, seconds, {}, cpu_seconds)
    save_checkpoint(out / "model.pt", model, config, vocab, weights, config.epochs)
    names = config.model.type_names
    tr_acc, _ = evaluate_edges(model, train_t, config, device)
    recall: dict[str, Any] = {"train": per_class_recall(tr_acc["confusion"], names),
                              "train_seconds": seconds, "train_cpu_seconds": cpu_seconds,
                              "torch_threads": torch.get_num_threads(), "device": str(device),
                              "n_train": len(train_t), "n_test": len(test_t)}
    if test_t:
        te_acc, _ = evaluate_edges(model, test_t, config, device)
        recall["test"] = per_class_recall(te_acc["confusion"], names)
    write_json(out / "recall.json", _jsonable(recall))
    return TrainResult(out, config, split, history, seconds, recall, cpu_seconds)


def _jsonable(obj: Any) -> Any:
    if isinstance(obj, dict):
        return {k: _jsonable(v) for k, v in obj.items()}
    if isinstance(obj, float) and math.isnan(obj):
        return None
    return obj
