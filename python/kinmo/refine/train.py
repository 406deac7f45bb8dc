"""Training of the axis-selection network (Liu et al. 2023, Sec. 3.3).

The training data (moving edges, the (rest, positive, negative) triples with articulated rest
states, the train / validation split) are built by :mod:`kinmo.refine.axis_data`; checkpoints
are written and read by :mod:`kinmo.refine.axis_io`; candidate lines are scored in batches by
:mod:`kinmo.refine.feasibility`; the configuration (:class:`AxisTrainConfig`,
:data:`PRESETS`) is :mod:`kinmo.refine.axis_config`; the run plumbing (session, optimisation
step, progress bar, metrics CSV, checkpoints) is :mod:`kinmo.train.loop`, shared with the other
trainers. This module holds the selection metric and the training loop (the per-category
fine-tuning shares the loop); the names of those modules used elsewhere are re-exported here.

Each epoch draws up to ``samples_per_shape`` moving edges per training shape (so a keyboard's
hundred keys do not drown the doors), with randomness from
``numpy.random.default_rng([seed, epoch])``: runs are reproducible.

**Loss and metrics.** Binary cross-entropy on the logits of (rest, positive) -> 1 and
(rest, negative) -> 0; accuracy at 0.5. The validation metric that matters is the
**selection accuracy**: on every validation edge, the candidates of its true fine type are
scored by feasibility alone (inference amounts ``angles_deg`` / ``translation_fraction``,
lines scored by ``sign_mode``) and the best must be equivalent to the true axis; shapes weigh
equally (:func:`selection_accuracy`; ``select_chance`` is a random choice's,
``select_coverage`` the share of edges where some candidate is right).

**Per-category networks** (``category_min_objects > 0``): after the global network, every
category with enough training objects gets a fine-tuned copy, kept only when it beats the
global network on the category's validation edges (:class:`AxisTrainConfig`).

**Outputs** of :func:`train_axis_model` in the run folder: ``config.json`` (the full
:class:`AxisTrainConfig` and the shape split), ``metrics.csv`` (one row per epoch),
``model.pt`` (best validation selection accuracy, ties broken by validation loss; the last
epoch without validation shapes) and ``last.pt``; with per-category networks also
``categories/<category>.pt``, ``categories.json`` (the kept ones) and ``categories.csv`` (every
tried category). All files are written atomically.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.errors import KinmoDataError
from kinmo.io import write_json, write_text
from kinmo.refine.axis_config import PRESETS, AxisTrainConfig, preset_config
from kinmo.progress import TrainingBar
from kinmo.train import distributed
from kinmo.train.loop import optimizer_step, rows_csv, training_bar, training_session
from kinmo.refine.axis_data import (
    MovingEdge,
    _diag,
    _obb,
    build_triples,
    equivalent_lines,
    load_graphs,
    moving_edges,
    split_graphs,
)
from kinmo.refine.axis_io import (
    CATEGORIES_FILE,
    AxisModelSet,
    load_axis_model,
    load_axis_models,
    save_axis_model,
)
from kinmo.refine.axis_net import AxisSelectionNet
from kinmo.refine.candidates import candidate_axes
from kinmo.refine.feasibility import LineRequest, score_lines
from kinmo.refine.motions import MotionAmounts

__all__ = [
    "PRESETS",
    "AxisModelSet",
    "AxisTrainConfig",
    "MovingEdge",
    "TrainResult",
    "build_triples",
    "equivalent_lines",
    "load_axis_model",
    "load_axis_models",
    "load_graphs",
    "moving_edges",
    "preset_config",
    "save_axis_model",
    "selection_accuracy",
    "selection_report",
    "split_graphs",
    "train_axis_model",
]

METRIC_COLUMNS: tuple[str, ...] = (
    "epoch", "train_loss", "train_acc", "val_loss", "val_acc", "val_select_acc",
    "val_select_chance", "val_select_coverage", "lr", "seconds",
)

#: Rows of ``categories.csv``: per-category fine-tuning of :func:`train_axis_model`.
CATEGORY_COLUMNS: tuple[str, ...] = (
    "category", "n_train_objects", "n_val_edges", "global_select_acc", "category_select_acc",
    "best_epoch", "kept", "seconds",
)



# --------------------------------------------------------------------------- metrics


def _edge_requests(graphs: Sequence[PartGraph], edges: Sequence[MovingEdge],
                   config: AxisTrainConfig, seed: int) -> tuple[list[LineRequest], list[np.ndarray]]:
    """Candidate lines of the true fine type of each edge and which of them match the truth."""
    reqs, matches = [], []
    for k, me in enumerate(edges):
        g = graphs[me.graph]
        cands = candidate_axes(_obb(g, me.moving), me.fine_type, g.points[me.moving],
                               g.points[me.reference], interaction_radius=config.interaction_radius)
        matches.append(equivalent_lines(cands.origins, cands.directions, me.origin, me.direction,
                                        cands.motion != "P", _diag(g, me.moving),
                                        config.match_angle_deg, config.match_distance))
        reqs.append(LineRequest(g, me.moving, me.reference, cands, seed=(seed, k)))
    return reqs, matches


def _per_shape_mean(edges: Sequence[MovingEdge], values: Sequence[tuple[float, ...]]
                    ) -> tuple[float, ...]:
    per_shape: dict[int, list[tuple[float, ...]]] = {}
    for me, v in zip(edges, values, strict=True):
        per_shape.setdefault(me.graph, []).append(v)
    if not per_shape:
        return (float("nan"),) * (len(values[0]) if values else 3)
    m = np.mean([np.mean(v, axis=0) for v in per_shape.values()], axis=0)
    return tuple(float(x) for x in m)


def selection_report(
    model: AxisSelectionNet | AxisModelSet,
    graphs: Sequence[PartGraph],
    edges: Sequence[MovingEdge],
    config: AxisTrainConfig,
    angle_sets: Sequence[Sequence[float]] = ((60.0,),),
    sign_modes: Sequence[str] = ("max", "mean"),
    seed: int = 0,
) -> dict[str, tuple[float, float, float]]:
    """Selection accuracy for several angle subsets and line scores from one scoring pass.

    All motions of the union of ``angle_sets`` are scored once (:func:`score_lines`), then
    each subset and sign mode selects. Per-shape means as in :func:`selection_accuracy`.

    Returns
    -------
    dict
        ``"<angles>|<mode>"`` (e.g. ``"30,45,60,80|mean"``) -> ``(accuracy, chance,
        coverage)``.
    """
    union = tuple(sorted({float(a) for s in angle_sets for a in s}))
    reqs, matches = _edge_requests(graphs, edges, config, seed)
    res = score_lines(model, reqs, MotionAmounts(union, config.translation_fraction))
    out: dict[str, tuple[float, float, float]] = {}
    for s in angle_sets:
        idx = [union.index(float(a)) for a in s]
        for mode in sign_modes:
            vals = []
            for lf, match in zip(res, matches, strict=True):
                sub = lf.subset(idx)
                score = sub.best if mode == "max" else sub.feasibility
                vals.append((float(match[int(np.argmax(score))]), float(match.mean()),
                             float(match.any())))
            key = ",".join(f"{a:g}" for a in s) + "|" + mode
            out[key] = _per_shape_mean(edges, vals)  # type: ignore[assignment]
    return out


def selection_accuracy(
    model: AxisSelectionNet | AxisModelSet,
    graphs: Sequence[PartGraph],
    edges: Sequence[MovingEdge],
    config: AxisTrainConfig,
    seed: int = 0,
) -> tuple[float, float, float]:
    """Share of edges whose most feasible candidate (true fine type) is the true axis.

    Every shape weighs the same (per-shape means, then their mean), so that one object with
    many identical joints (a keyboard, a table of drawers) does not decide the metric. Lines
    are scored with ``config.angles_deg`` and ``config.sign_mode`` in batched network calls
    (:func:`kinmo.refine.feasibility.score_lines`).

    Parameters
    ----------
    model : AxisSelectionNet or AxisModelSet
    graphs : sequence of PartGraph
    edges : sequence of MovingEdge
    config : AxisTrainConfig
        Gives the inference amounts, line score, interaction radius and matching thresholds.
    seed : int
        Point subsampling seed.

    Returns
    -------
    accuracy : float
        NaN without edges.
    chance : float
        Expected accuracy of a uniformly random choice among the candidates (the baseline).
    coverage : float
        Share of edges where some candidate matches the true axis (the accuracy's bound).
    """
    if not edges:
        return float("nan"), float("nan"), float("nan")
    rep = selection_report(model, graphs, edges, config, (config.angles_deg,),
                           (config.sign_mode,), seed)
    return next(iter(rep.values()))


# --------------------------------------------------------------------------- training


@dataclass
class TrainResult:
    """Outcome of :func:`train_axis_model`.

    Attributes
    ----------
    run_dir : Path
    metrics : list of dict
        One row per epoch (:data:`METRIC_COLUMNS`).
    best_epoch : int
    n_train_edges, n_val_edges : int
    categories_kept : list of str
        Categories that got their own network (``categories.json``).
    """

    run_dir: Path
    metrics: list[dict[str, float]]
    best_epoch: int
    n_train_edges: int
    n_val_edges: int
    categories_kept: list[str] = field(default_factory=list)


def _metrics_csv(rows: list[dict[str, float]]) -> str:
    """``metrics.csv`` text (NaN written ``nan``: epochs without validation)."""
    return rows_csv(rows, METRIC_COLUMNS, nan="nan")


def _run_batches(model, opt, graphs, edges, config, rng, device, train: bool,
                 on_batch: Callable[[], None] | None = None) -> tuple[float, float]:
    import torch
    import torch.nn.functional as F

    model.train(train)
    losses, accs, count = 0.0, 0.0, 0
    bs = config.batch_size
    for start in range(0, len(edges), bs):
        chunk = list(edges[start : start + bs])
        if train and len(chunk) < 2 and config.net.norm == "batch" and start > 0:
            continue  # a batch of one breaks batch norm; it is drawn again next epoch
        triples, weight = build_triples(graphs, chunk, config, rng), 1.0
        if train:  # torchrun: this rank's rows of the global batch (kinmo.train.distributed)
            rows, weight = distributed.shard(range(len(triples[0])))
            triples = tuple(a[rows] for a in triples)
        rest, pos, neg = (torch.from_numpy(a).to(device) for a in triples)
        b = rest.shape[0]
        with torch.set_grad_enabled(train):
            f = model.encode(torch.cat([rest, pos, neg]))
            fr, fp, fn = f[:b], f[b : 2 * b], f[2 * b :]
            logits = model.head(torch.cat([fr, fr]), torch.cat([fp, fn]))
            target = torch.cat([torch.ones(b), torch.zeros(b)]).to(device)
            loss = F.binary_cross_entropy_with_logits(logits, target)
        if train:  # sync: the mean gradient over the ranks
            optimizer_step(opt, loss, model, weight, sync=True)
        if weight > 0:
            losses += float(loss.detach()) * 2 * b
            accs += float(((logits > 0).float() == target).float().sum())
            count += 2 * b
        if on_batch is not None:
            on_batch()
    if train:  # the epoch's figures over all ranks
        losses, accs, count = distributed.all_sum([losses, accs, count])
    return losses / max(count, 1), accs / max(count, 1)


def _steps_per_epoch(edges: Sequence[MovingEdge], config: AxisTrainConfig) -> int:
    """Batches of one epoch of :func:`_fit` on ``edges`` (:func:`_epoch_edges`' count)."""
    per_graph: dict[int, int] = {}
    for e in edges:
        per_graph[e.graph] = per_graph.get(e.graph, 0) + 1
    return math.ceil(sum(min(config.samples_per_shape, n) for n in per_graph.values()) / config.batch_size)


def _epoch_edges(edges: Sequence[MovingEdge], per_shape: int, rng: np.random.Generator
                 ) -> list[MovingEdge]:
    by_graph: dict[int, list[MovingEdge]] = {}
    for me in edges:
        by_graph.setdefault(me.graph, []).append(me)
    out: list[MovingEdge] = []
    for g in sorted(by_graph):
        lst = by_graph[g]
        pick = rng.choice(len(lst), size=min(per_shape, len(lst)), replace=False)
        out += [lst[int(k)] for k in sorted(pick)]
    order = rng.permutation(len(out))
    return [out[int(k)] for k in order]


def _fit(
    model: AxisSelectionNet, graphs: Sequence[PartGraph], tr_edges: Sequence[MovingEdge],
    va_edges: Sequence[MovingEdge], config: AxisTrainConfig, epochs: int, lr: float,
    bar: TrainingBar, task: Any, label: str,
    on_epoch: Callable[[int, dict[str, float], bool], None], seed_offset: int = 0,
) -> tuple[list[dict[str, float]], int, dict[str, Any]]:
    """Train ``model`` in place; returns the epoch rows, the best epoch and its state dict."""
    import torch

    device = next(model.parameters()).device
    opt = torch.optim.Adam(model.parameters(), lr=lr, weight_decay=config.weight_decay)
    sched = torch.optim.lr_scheduler.StepLR(opt, step_size=config.lr_step, gamma=config.lr_gamma)
    rows: list[dict[str, float]] = []
    best_key: tuple[float, float] | None = None
    best_epoch, best_state = 0, copy.deepcopy(model.state_dict())
    for epoch in range(1, epochs + 1):
        t0 = time.perf_counter()
        rng = np.random.default_rng([config.seed, epoch + seed_offset])
        ep_edges = _epoch_edges(tr_edges, config.samples_per_shape, rng)
        bar.describe(task, f"{label} epoch {epoch}/{epochs}")
        tl, ta = _run_batches(model, opt, graphs, ep_edges, config, rng, device, True,
                              lambda: bar.advance(task))
        sched.step()
        vl = va = vs = vch = vc = float("nan")
        validate = bool(va_edges) and (epoch % config.val_every == 0 or epoch == epochs)
        if validate:
            vrng = np.random.default_rng([config.seed, 10**6])
            v_edges = [e for e in va_edges for _ in range(config.val_repeats)]
            with torch.no_grad():
                vl, va = _run_batches(model, None, graphs, v_edges, config, vrng, device, False)
            vs, vch, vc = selection_accuracy(model, graphs, va_edges, config, seed=config.seed)
        row = {"epoch": epoch, "train_loss": tl, "train_acc": ta, "val_loss": vl,
               "val_acc": va, "val_select_acc": vs, "val_select_chance": vch,
               "val_select_coverage": vc, "lr": float(opt.param_groups[0]["lr"]),
               "seconds": time.perf_counter() - t0}
        rows.append(row)
        # only what this epoch computed: validation every val_every epochs and at the last
        bar.log(f"{label} epoch {epoch}: loss {tl:.3f} acc {ta:.3f}" + (
            f" | val loss {vl:.3f} acc {va:.3f} select {vs:.3f} (chance {vch:.3f}, coverage {vc:.3f})"
            if validate else ""))
        key = (float(epoch), 0.0) if not va_edges else (vs, -vl)
        better = (validate or not va_edges) and (best_key is None or key > best_key)
        if better:
            best_key, best_epoch = key, epoch
            best_state = copy.deepcopy(model.state_dict())
        on_epoch(epoch, row, better)
    return rows, best_epoch, best_state


def _category_networks(
    base: AxisSelectionNet, graphs: Sequence[PartGraph], tr_edges: Sequence[MovingEdge],
    va_edges: Sequence[MovingEdge], config: AxisTrainConfig, out: Path, bar: TrainingBar,
) -> list[dict[str, Any]]:
    """Fine-tune per-category copies of ``base`` (rule: :class:`AxisTrainConfig`)."""
    objs: dict[str, set[int]] = {}
    for e in tr_edges:
        objs.setdefault(graphs[e.graph].category, set()).add(e.graph)
    rows: list[dict[str, Any]] = []
    kept: dict[str, dict[str, Any]] = {}
    fits = {}  # the categories fine-tuned: their (order, training edges, validation edges)
    for n_cat, cat in enumerate(sorted(objs)):
        cat_val = [e for e in va_edges if graphs[e.graph].category == cat]
        if len(objs[cat]) >= config.category_min_objects and cat_val:
            fits[cat] = (n_cat, [e for e in tr_edges if graphs[e.graph].category == cat], cat_val)
    # a task of their own, of the batches they will run (not more steps on the base net's)
    task = bar.task("category nets", sum(config.category_epochs * _steps_per_epoch(tr, config)
                                         for _, tr, _ in fits.values()))
    for cat, (n_cat, cat_tr, cat_val) in fits.items():
        t0 = time.perf_counter()
        g_acc = selection_accuracy(base, graphs, cat_val, config, seed=config.seed)[0]
        model = copy.deepcopy(base)
        _, best_epoch, best_state = _fit(
            model, graphs, cat_tr, cat_val, config, config.category_epochs,
            config.lr * config.category_lr_scale, bar, task, cat, lambda *_: None,
            seed_offset=10**4 * (n_cat + 1))
        model.load_state_dict(best_state)
        c_acc = selection_accuracy(model, graphs, cat_val, config, seed=config.seed)[0]
        keep = c_acc > g_acc
        row = {"category": cat, "n_train_objects": len(objs[cat]), "n_val_edges": len(cat_val),
               "global_select_acc": g_acc, "category_select_acc": c_acc,
               "best_epoch": best_epoch, "kept": keep, "seconds": time.perf_counter() - t0}
        rows.append(row)
        if keep:
            rel = f"categories/{cat}.pt"
            if distributed.info().is_main:
                save_axis_model(out / rel, model, epoch=best_epoch, category=cat,
                                train_config=config.model_dump(mode="json"))
            kept[cat] = {"file": rel, "global_select_acc": g_acc, "category_select_acc": c_acc}
    if not distributed.info().is_main:  # torchrun: rank 0 writes
        return rows
    write_json(out / CATEGORIES_FILE, {"rule": {
        "min_train_objects": config.category_min_objects, "min_val_objects": 1,
        "kept_when": "category_select_acc > global_select_acc"}, "categories": kept})
    write_text(out / "categories.csv", rows_csv(rows, CATEGORY_COLUMNS, nan="nan"))
    return rows


def train_axis_model(
    data: str | Path | Sequence[PartGraph],
    out: str | Path,
    config: AxisTrainConfig | None = None,
    split: Any = None,
    progress: bool = True,
) -> TrainResult:
    """Train the axis-selection network on labelled part graphs (module docstring).

    Parameters
    ----------
    data : str, Path or sequence of PartGraph
        A cache folder of ``kinmo prepare`` on PartNet-Mobility objects, or graphs.
    out : str or Path
        Run folder (created; existing files are overwritten).
    config : AxisTrainConfig, optional
        Default: the ``quick`` preset.
    split : Split, str or Path, optional
        The motion GNN's split (or its ``split.json``); its test shapes are never used
        (:func:`split_graphs`).
    progress : bool
        Show a rich progress bar.

    Returns
    -------
    TrainResult

    Raises
    ------
    KinmoDataError
        No labelled graphs with moving joints.
    """
    config = config or preset_config("quick")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if isinstance(data, (str, Path)):
        graphs = load_graphs(data)
    else:
        from kinmo.train.gnn import labelled_graphs

        graphs = sorted(labelled_graphs(data), key=lambda g: g.shape_id)
    tr_idx, va_idx, test_ids = split_graphs(graphs, config, split)
    all_edges = moving_edges(graphs)
    tr_set, va_set = set(tr_idx), set(va_idx)
    tr_edges = [e for e in all_edges if e.graph in tr_set]
    va_edges = [e for e in all_edges if e.graph in va_set]
    if config.val_edges_per_shape:
        va_edges = sorted(_epoch_edges(va_edges, config.val_edges_per_shape,
                                       np.random.default_rng([config.seed, 10**6 + 1])),
                          key=lambda e: (e.graph, e.edge))
    if not tr_edges:
        raise KinmoDataError(str(data), "no moving joints in the training graphs")
    with training_session(config.device, config.seed, config.threads) as (dist_info, device):
        model = AxisSelectionNet(config.net).to(device)  # torchrun: rank 0 writes
        if dist_info.is_main:
            write_json(out / "config.json", {
                "kind": "axis-selection",
                "config": config.model_dump(mode="json"),
                "data": str(data) if isinstance(data, (str, Path)) else None,
                "split": {"train": [graphs[k].shape_id for k in tr_idx],
                          "val": [graphs[k].shape_id for k in va_idx], "test": test_ids},
                "n_train_edges": len(tr_edges),
                "n_val_edges": len(va_edges),
            })
        steps = _steps_per_epoch(tr_edges, config)
        rows: list[dict[str, float]] = []

        def on_epoch(epoch: int, row: dict[str, float], better: bool) -> None:
            rows.append(row)
            if not dist_info.is_main:
                return
            extra = {"epoch": epoch, "metrics": row, "train_config": config.model_dump(mode="json")}
            save_axis_model(out / "last.pt", model, **extra)
            if better:
                save_axis_model(out / "model.pt", model, **extra)
            write_text(out / "metrics.csv", _metrics_csv(rows))

        with training_bar(progress, "train axis") as bar:
            task = bar.task("axis net", config.epochs * steps)
            _, best_epoch, best_state = _fit(model, graphs, tr_edges, va_edges, config,
                                             config.epochs, config.lr, bar, task, "axis net",
                                             on_epoch)
            kept: list[str] = []
            if dist_info.is_main:
                (out / CATEGORIES_FILE).unlink(missing_ok=True)  # a stale index of an earlier run
            if config.category_min_objects > 0:
                model.load_state_dict(best_state)
                cats = _category_networks(model, graphs, tr_edges, va_edges, config, out, bar)
                kept = [r["category"] for r in cats if r["kept"]]
    return TrainResult(out, rows, best_epoch, len(tr_edges), len(va_edges), kept)
