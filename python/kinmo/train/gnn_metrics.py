"""Edge-level metrics of the motion GNN on labelled part graphs (SWMP's test protocol).

:func:`edge_metrics` scores one batch (edge type accuracy and confusion, recall of moving
edges, axis angle and position errors); :func:`merge_metrics` / :func:`summarize_metrics`
accumulate batches into the figures of ``metrics.csv``; :func:`evaluate_edges` runs a model
over a set of graphs; :func:`per_class_recall` reads a confusion matrix
(:mod:`kinmo.train.gnn` writes them per epoch and in ``recall.json``).
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
import torch

from kinmo.features import GraphBatch, GraphTensors, collate, moving_fine_mask, rotating_fine_mask
from kinmo.models.losses import MotionLoss, position_loss
from kinmo.models.motion_gnn import MotionGNN
from kinmo.train.config import TrainConfig

__all__ = ["edge_metrics", "evaluate_edges", "merge_metrics", "per_class_recall", "summarize_metrics"]


def edge_metrics(logits: torch.Tensor, direction: torch.Tensor, origin: torch.Tensor,
                 batch: GraphBatch, types: str) -> dict[str, Any]:
    """Edge-level metrics of a labelled batch (SWMP's test protocol).

    Parameters
    ----------
    logits : (E, K) float
    direction : (E, 3) float
        Predicted unit axis directions (normalised frame).
    origin : (E, 3) float
        Predicted axis points (normalised frame).
    batch : GraphBatch
        Labelled.
    types : {"fine", "coarse"}

    Returns
    -------
    dict
        ``n_edges``, ``correct`` (edges with the right type), ``moving`` / ``moving_correct``
        (edges whose true type has an axis / and predicted right), ``confusion`` ``(K, K)``
        int64 (rows true, columns predicted), ``angles`` (degrees, ``min(θ, 180-θ)``, over
        edges whose true type has an axis), ``pos`` (distance of the predicted point to the
        true axis line over rotating edges, fraction of the shape's AABB diagonal, which is
        the unit of the normalised frame).
    """

    target = batch.edge_labels(types).cpu()
    pred = logits.argmax(dim=1).cpu()
    k = logits.shape[1]
    conf = torch.bincount(target * k + pred, minlength=k * k).reshape(k, k)
    fine = batch.edge_fine.cpu()
    has = (moving_fine_mask()[fine] & batch.has_axis.cpu())
    rot = (rotating_fine_mask()[fine] & batch.has_axis.cpu())
    d = direction.detach().cpu()
    o = origin.detach().cpu()
    td = batch.axis_direction.cpu()
    cos = (d[has] * td[has]).sum(1).abs().clamp(max=1.0)
    angles = torch.rad2deg(torch.acos(cos)).numpy()
    pos = position_loss(o[rot], batch.axis_origin.cpu()[rot], td[rot]).numpy()
    return {
        "n_edges": int(target.numel()),
        "correct": int((pred == target).sum()),
        "moving": int(has.sum()),
        "moving_correct": int(((pred == target) & has).sum()),
        "confusion": conf.numpy().astype(np.int64),
        "angles": angles,
        "pos": pos,
    }


def merge_metrics(acc: dict[str, Any] | None, m: dict[str, Any]) -> dict[str, Any]:
    """Add the :func:`edge_metrics` of a batch to an accumulator (``None``: start one)."""
    if acc is None:
        return {**m, "angles": [m["angles"]], "pos": [m["pos"]]}
    for key in ("n_edges", "correct", "moving", "moving_correct"):
        acc[key] += m[key]
    acc["confusion"] = acc["confusion"] + m["confusion"]
    acc["angles"].append(m["angles"])
    acc["pos"].append(m["pos"])
    return acc


def summarize_metrics(acc: dict[str, Any]) -> dict[str, float]:
    """``acc`` (edge type accuracy), ``moving_recall``, ``angle_deg`` and ``pos_dist`` (means;
    NaN without moving / rotating edges) of an accumulator of :func:`merge_metrics`."""
    ang = np.concatenate(acc["angles"]) if acc["angles"] else np.zeros(0)
    pos = np.concatenate(acc["pos"]) if acc["pos"] else np.zeros(0)
    return {
        "acc": acc["correct"] / max(acc["n_edges"], 1),
        "moving_recall": acc["moving_correct"] / acc["moving"] if acc["moving"] else float("nan"),
        "angle_deg": float(ang.mean()) if ang.size else float("nan"),
        "pos_dist": float(pos.mean()) if pos.size else float("nan"),
    }


def per_class_recall(confusion: np.ndarray, names: Sequence[str]) -> dict[str, dict[str, float]]:
    """Recall of every class from a ``(K, K)`` confusion matrix (rows true).

    Returns
    -------
    dict
        ``name -> {"recall": float or NaN when absent, "support": int}``.
    """
    out = {}
    for c, name in enumerate(names):
        n = int(confusion[c].sum())
        out[name] = {"recall": float(confusion[c, c] / n) if n else float("nan"), "support": n}
    return out


@torch.no_grad()
def evaluate_edges(model: MotionGNN, tensors: Sequence[GraphTensors], config: TrainConfig,
                   device: torch.device, loss_fn: MotionLoss | None = None) -> tuple[dict, float]:
    """Edge metrics (:func:`edge_metrics`, accumulated) and mean loss over labelled graphs."""
    model.eval()
    acc = None
    losses = []
    for start in range(0, len(tensors), max(config.batch_size, 1)):
        batch = collate(tensors[start:start + config.batch_size], n_points=config.n_points)
        batch = batch.to(device)
        out = model(batch)
        if loss_fn is not None:
            losses.append(float(loss_fn(out, batch).total))
        acc = merge_metrics(acc, edge_metrics(out.logits, out.direction, out.origin, batch,
                                       config.model.types))
    model.train()
    return acc or {}, float(np.mean(losses)) if losses else float("nan")
