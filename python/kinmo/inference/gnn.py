"""Motion-GNN inference on part graphs (Liu et al. 2023, Sec. 3.2): edge types and axes,
with the GNN's raw outputs kept as priors of the learned selector, and mobility trees.

Moved out of :mod:`kinmo.predict` (issue 22) so that every caller (``predict``, ``eval``,
``pseudo-label``, the pipeline, the ranker's out-of-fold fit) shares one implementation,
through :class:`kinmo.inference.predictor.Predictor` where a refinement follows.

Frames: axes in each graph's mesh frame (PartNet is y-up), mesh units.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
import torch

from kinmo.data.graph import PartGraph
from kinmo.features import collate, graph_tensors
from kinmo.mobility_tree import (
    EdgePrediction,
    ShapePrediction,
    TreeOptions,
    build_mobility_tree,
    consistent_fine,
)
from kinmo.refine.selector import GNNPriors
from kinmo.train.gnn import Run

__all__ = ["infer_edges", "infer_edges_with_priors", "predict_graphs"]


@torch.no_grad()
def infer_edges(run: Run, graphs: Sequence[PartGraph], batch_size: int = 8) -> list[EdgePrediction]:
    """Run the motion GNN on part graphs: the edge predictions of
    :func:`infer_edges_with_priors` (same parameters), without the priors.

    Returns
    -------
    list of EdgePrediction
        One per graph (mesh frame).
    """
    return infer_edges_with_priors(run, graphs, batch_size)[0]


@torch.no_grad()
def infer_edges_with_priors(run: Run, graphs: Sequence[PartGraph], batch_size: int = 8
                            ) -> tuple[list[EdgePrediction], list]:
    """Run the motion GNN on part graphs; also return its raw outputs as refinement priors.

    Parameters
    ----------
    run : Run
        A loaded model (:func:`kinmo.train.gnn.load_run`).
    graphs : sequence of PartGraph
        Labels, if present, are ignored.
    batch_size : int
        Graphs per forward pass.

    Returns
    -------
    (list of EdgePrediction, list of kinmo.refine.selector.GNNPriors)
        One per graph, rows in ``graph.sibling_edges`` order; probabilities over the run's
        type set; axes mapped back to each graph's mesh frame. The priors hold the type
        probabilities as predicted (before :func:`consistent_fine`) and the softmax of the
        axis-candidate logits with the 10 candidate directions (``None`` for a model without
        them).
    """
    run.model.eval()
    out: list[EdgePrediction] = []
    priors: list[GNNPriors] = []
    names = tuple(run.config.model.type_names)
    tensors = [graph_tensors(g, run.vocab) for g in graphs]
    for t in tensors:  # labels are not needed at inference
        t.edge_fine = t.axis_origin = t.axis_direction = t.has_axis = None
    for start in range(0, len(tensors), max(1, batch_size)):
        chunk = tensors[start:start + batch_size]
        batch = collate(chunk, n_points=run.config.n_points).to(run.device)
        res = run.model(batch)
        probs = torch.softmax(res.logits, dim=1).double().cpu().numpy()
        d = res.direction.double().cpu().numpy()
        o = res.origin.double().cpu().numpy()
        eo = batch.edge_offsets.tolist()
        for b, t in enumerate(chunk):
            s = slice(eo[b], eo[b + 1])
            dd = d[s]
            n = np.linalg.norm(dd, axis=1, keepdims=True)
            dd = np.where(n > 0, dd / np.where(n > 0, n, 1.0), np.array([0.0, 1.0, 0.0]))
            out.append(EdgePrediction(probs[s], dd, t.to_mesh(o[s])))
            ap = ad = None
            if getattr(res, "axis_logits", None) is not None:
                ap = torch.softmax(res.axis_logits[s].double(), dim=1).cpu().numpy()
                ad = res.axis_candidates[s].double().cpu().numpy()
            priors.append(GNNPriors(probs[s].copy(), names, ap, ad))
    return out, priors


def predict_graphs(run: Run, graphs: Sequence[PartGraph], options: TreeOptions = TreeOptions(),
                   batch_size: int = 8, consistent: bool = True) -> list[ShapePrediction]:
    """Edge predictions and mobility trees of part graphs (see :func:`infer_edges`).

    With ``consistent`` (default) fine types are made to agree with the predicted axes
    (:func:`consistent_fine`).
    """
    preds, priors = infer_edges_with_priors(run, graphs, batch_size)
    if consistent:
        preds = [consistent_fine(g, p) for g, p in zip(graphs, preds)]
    names = run.config.model.type_names
    return [ShapePrediction(g, p, build_mobility_tree(g, p, options), names, pr)
            for g, p, pr in zip(graphs, preds, priors)]
