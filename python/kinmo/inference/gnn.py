"""Motion-GNN inference on part graphs (Liu et al. 2023, Sec. 3.2): edge types and axes,
with the GNN's raw outputs kept as priors of the learned selector, and mobility trees.

Moved out of :mod:`kinmo.predict` (issue 22) so that every caller (``predict``, ``eval``,
``pseudo-label``, the pipeline, the ranker's out-of-fold fit) shares one implementation,
through :class:`kinmo.inference.predictor.Predictor` where a refinement follows.

**Quarter turns for unnamed objects** (issue 36). A user's asset faces any way, and without
part names the GNN's types and axes lean on PartNet's facing (drawers out along ``+z``): the
same cabinet facing ``+x`` (the ROS convention) lost a quarter of its right joints. For a graph
none of whose nodes has a name the vocabulary knows (``part_<k>``, the names of a GLB exporter),
:func:`infer_edges_with_priors` runs the GNN on the object turned 0, 1, 2 and 3 quarter turns
about the vertical (:meth:`kinmo.features.GraphTensors.turned`) and averages the four answers
once turned back (:func:`average_turns`): type probabilities and axis points are averaged,
directions by their mean axis, and each axis candidate's probability summed over
the turns' nearest candidates; the object and its turned copies go through the GNN in one
forward pass. The priors say so (``GNNPriors.turned``), and the learned selector then
averages its semantic direction prior over the same turns
(:meth:`kinmo.refine.semantic_prior.SemanticPrior.probability`). The prediction then no
longer depends on which quarter the object faces (up to its own point samples and OBB fits).
A named object (PartNet format, URDF links with known names) gets one pass, as before: there
the names and PartNet's facing are the better cue (docs/results/foreign_assets.md, "Quarter
turns for unnamed objects").

**Ensemble members** (kinmo extension, issue 34). A run folder may hold further models of the
same type set and vocabulary trained with other seeds (``members/<k>/``,
:func:`kinmo.train.gnn.train_members`, ``kinmo train all --gnn-members N``); :func:`forward` then
runs each and averages their answers as the turns are averaged (:func:`average_members`). Out
of fold on the 235 labelled objects, one single fine GNN's selector gain over it was −23.5 % and
another seed's −32.4 % per category, the two averaged −46.0 % (docs/results/table1_four_settings.md).
Two models whose directions are perpendicular tie in the mean axis (the answer is either, or
between them); an even ensemble is the weakest there, and three models let the majority
decide. As ``kinmo train all`` runs it, neither one nor two members beat the single GNN on
every figure (session 29), so members stay opt-in.

Frames: axes in each graph's mesh frame (PartNet is y-up), mesh units.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Literal

import numpy as np
import torch

from kinmo.data.graph import PartGraph
from kinmo.features import GraphTensors, collate, graph_tensors, quarter_turn
from kinmo.mobility_tree import (
    EdgePrediction,
    ShapePrediction,
    TreeOptions,
    build_mobility_tree,
    consistent_fine,
)
from kinmo.refine.selector import GNNPriors
from kinmo.train.gnn import Run

__all__ = ["TURNS", "TurnPolicy", "average_members", "average_turns", "forward", "infer_edges",
           "infer_edges_with_priors", "predict_graphs"]

#: When :func:`infer_edges_with_priors` averages over quarter turns (module docs): ``"unnamed"``
#: (the default: graphs without a known node name), ``"always"`` or ``"never"``.
TurnPolicy = Literal["unnamed", "always", "never"]
TURNS: tuple[str, ...] = ("unnamed", "always", "never")


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
def infer_edges_with_priors(run: Run, graphs: Sequence[PartGraph], batch_size: int = 8,
                            turns: TurnPolicy = "unnamed") -> tuple[list[EdgePrediction], list]:
    """Run the motion GNN on part graphs; also return its raw outputs as refinement priors.

    Parameters
    ----------
    run : Run
        A loaded model (:func:`kinmo.train.gnn.load_run`).
    graphs : sequence of PartGraph
        Labels, if present, are ignored.
    batch_size : int
        Graphs per forward pass.
    turns : {"unnamed", "always", "never"}
        Which graphs are predicted as the average over four quarter turns about the vertical
        (:func:`average_turns`, module docs): those without a node name in the model's
        vocabulary (default), every graph, or none.

    Returns
    -------
    (list of EdgePrediction, list of kinmo.refine.selector.GNNPriors)
        One per graph, rows in ``graph.sibling_edges`` order; probabilities over the run's
        type set; axes mapped back to each graph's mesh frame. The priors hold the type
        probabilities as predicted (before :func:`consistent_fine`) and the softmax of the
        axis-candidate logits with the 10 candidate directions (``None`` for a model without
        them).

    Raises
    ------
    ValueError
        ``turns`` is not one of :data:`TURNS`.
    """
    if turns not in TURNS:
        raise ValueError(f"turns must be one of {', '.join(TURNS)}, got {turns!r}")
    run.model.eval()
    out: list[EdgePrediction] = []
    priors: list[GNNPriors] = []
    tensors = [graph_tensors(g, run.vocab) for g in graphs]
    for t in tensors:  # labels are not needed at inference
        t.edge_fine = t.axis_origin = t.axis_direction = t.has_axis = None
    turned = [turns == "always" or (turns == "unnamed" and not bool((t.semantic != 0).any()))
              for t in tensors]
    for start in range(0, len(tensors), max(1, batch_size)):
        chunk = tensors[start:start + batch_size]
        extra = [t.turned(q) for t, on in zip(chunk, turned[start:start + batch_size]) if on
                 for q in (1, 2, 3)]
        o, p = forward(run, chunk + extra)  # one pass: the graphs, then their turned copies
        b = len(chunk)
        for n, t in enumerate(chunk):
            if turned[start + n]:
                out_n, prior_n = average_turns(t, o[n], p[n], o[b:b + 3], p[b:b + 3])
                b += 3
            else:
                out_n, prior_n = o[n], p[n]
            out.append(out_n)
            priors.append(prior_n)
    return out, priors


@torch.no_grad()
def forward(run: Run, tensors: Sequence[GraphTensors]) -> tuple[list[EdgePrediction], list[GNNPriors]]:
    """One forward pass of the motion GNN over graph tensors (labels unset), batched; for a
    run with ensemble members (:attr:`kinmo.train.gnn.Run.members`), one pass of each model,
    averaged (:func:`average_members`).

    Returns
    -------
    (list of EdgePrediction, list of GNNPriors)
        One per graph, as :func:`infer_edges_with_priors` gives them: probabilities
        ``(E, K)``, unit directions ``(E, 3)`` (``+y`` where the network gives none) and axis
        points ``(E, 3)`` in the mesh frame of each tensors' ``center``/``scale``; the
        axis-candidate softmax ``(E, 10)`` and directions ``(E, 10, 3)`` (normalised-frame
        orientation), or None. float64.
    """
    first = _forward_one(run, tensors)
    if not run.members or not tensors:
        return first
    answers = [first] + [_forward_one(m, tensors) for m in run.members]
    out: list[EdgePrediction] = []
    priors: list[GNNPriors] = []
    for b in range(len(tensors)):
        pred, prior = average_members([a[0][b] for a in answers], [a[1][b] for a in answers])
        out.append(pred)
        priors.append(prior)
    return out, priors


def _forward_one(run: Run, tensors: Sequence[GraphTensors]) -> tuple[list[EdgePrediction], list[GNNPriors]]:
    """:func:`forward` of one model (``run.members`` not used)."""
    if not tensors:
        return [], []
    names = tuple(run.config.model.type_names)
    batch = collate(list(tensors), n_points=run.config.n_points).to(run.device)
    res = run.model(batch)
    probs = torch.softmax(res.logits, dim=1).double().cpu().numpy()
    d = res.direction.double().cpu().numpy()
    o = res.origin.double().cpu().numpy()
    eo = batch.edge_offsets.tolist()
    out: list[EdgePrediction] = []
    priors: list[GNNPriors] = []
    for b, t in enumerate(tensors):
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


def _add_axis_mass(total: np.ndarray, dirs: np.ndarray, prob: np.ndarray, prob_dirs: np.ndarray,
                   same_first: bool = False) -> None:
    """Add the axis-candidate probabilities ``prob`` ``(E, C)`` of candidates ``prob_dirs``
    ``(E, C, 3)`` to ``total`` ``(E, C)``, each onto the candidate of ``dirs`` ``(E, C, 3)``
    nearest to it (largest ``|cos|``; the first of equals, or with ``same_first`` the
    candidate of the same index when it is one of them: duplicate candidates, such as a part's
    and its reference's equal OBB axes, keep their own mass), in place."""
    cos = np.abs(np.einsum("eci,edi->ecd", prob_dirs, dirs))
    nearest = np.argmax(cos, axis=2)  # (E, C): the candidate of ``dirs`` of each candidate
    if same_first:
        own = np.diagonal(cos, axis1=1, axis2=2)  # (E, C): |cos| with the same index
        best = np.take_along_axis(cos, nearest[:, :, None], axis=2)[:, :, 0]
        nearest = np.where(own >= best - 1e-12, np.arange(cos.shape[1])[None, :], nearest)
    rows = np.repeat(np.arange(total.shape[0]), nearest.shape[1])
    np.add.at(total, (rows, nearest.ravel()), prob.ravel())


def _mean_axis(directions: Sequence[np.ndarray], reference: np.ndarray) -> np.ndarray:
    """The mean axis of unit directions ``(E, 3)`` each: the principal eigenvector of the sum of
    ``d d^T`` (signs do not matter), signed to agree with ``reference`` ``(E, 3)``."""
    scatter = sum(np.einsum("ei,ej->eij", d, d) for d in directions)
    mean = np.linalg.eigh(scatter)[1][:, :, -1]
    return mean * np.where(np.sum(mean * reference, axis=1, keepdims=True) < 0, -1.0, 1.0)


def average_members(preds: Sequence[EdgePrediction], priors: Sequence[GNNPriors]
                    ) -> tuple[EdgePrediction, GNNPriors]:
    """One graph's answers of an ensemble's models (:attr:`kinmo.train.gnn.Run.members`),
    averaged as :func:`average_turns` averages turns, with nothing turned back.

    Parameters
    ----------
    preds, priors : sequence of EdgePrediction, sequence of GNNPriors
        Each model's answer (:func:`forward` of one model), the run's own first; mesh frame.

    Returns
    -------
    (EdgePrediction, GNNPriors)
        Type probabilities ``(E, K)`` and axis points ``(E, 3)`` the models' means; unit
        directions ``(E, 3)`` their mean axis, signed to agree with the first model's; the
        axis-candidate probabilities ``(E, 10)`` over the first model's candidate directions
        (the nine fixed ones are every model's; the tenth, the regressed direction, is each
        model's own), each model's mass added to the first's candidate of the same index, or
        the nearest one where that one is not among the nearest, then normalised. float64.
    """
    first, prior = preds[0], priors[0]
    if first.probs.shape[0] == 0 or len(preds) == 1:
        return first, prior
    m = float(len(preds))
    probs = sum(np.asarray(p.probs, dtype=np.float64) for p in preds) / m
    direction = _mean_axis([np.asarray(p.direction, dtype=np.float64) for p in preds],
                           np.asarray(first.direction, dtype=np.float64))
    origin = sum(np.asarray(p.origin, dtype=np.float64) for p in preds) / m
    ap = None
    if all(q.axis_prob is not None and q.axis_dirs is not None for q in priors):
        base = np.asarray(prior.axis_dirs, dtype=np.float64)
        ap = np.zeros_like(np.asarray(prior.axis_prob, dtype=np.float64))
        for q in priors:
            _add_axis_mass(ap, base, np.asarray(q.axis_prob, dtype=np.float64),
                           np.asarray(q.axis_dirs, dtype=np.float64), same_first=True)
        ap = ap / ap.sum(axis=1, keepdims=True)
    return (EdgePrediction(probs, direction, origin),
            GNNPriors(probs.copy(), prior.type_names, ap, prior.axis_dirs, turned=prior.turned))


def average_turns(tensors: GraphTensors, pred: EdgePrediction, prior: GNNPriors,
                  preds: Sequence[EdgePrediction], pris: Sequence[GNNPriors]
                  ) -> tuple[EdgePrediction, GNNPriors]:
    """One graph's GNN answer averaged over the four quarter turns about the vertical.

    Parameters
    ----------
    tensors : GraphTensors
        The graph's tensors, as given.
    pred, prior : EdgePrediction, GNNPriors
        The GNN's answer for the graph as given (turn 0, mesh frame).
    preds, pris : sequence of EdgePrediction, sequence of GNNPriors
        Its answers for ``tensors.turned(q)``, ``q`` = 1, 2, 3 in that order, as
        :func:`forward` gives them (:func:`infer_edges_with_priors` runs them in the graph's
        own forward pass).

    Returns
    -------
    (EdgePrediction, GNNPriors)
        Type probabilities ``(E, K)`` and axis points ``(E, 3)`` the means of the four turns'
        (each turned back); unit directions ``(E, 3)`` the mean axis of the turns' (the
        principal eigenvector of the sum of ``d d^T``, so signs do not matter), signed to
        agree with turn 0's; the axis-candidate probabilities ``(E, 10)`` over
        turn 0's candidate directions, each turn's mass added to the turn-0 candidate nearest
        (largest ``|cos|``), then normalised; ``GNNPriors.turned`` set. Mesh frame, float64.
    """
    e = pred.probs.shape[0]
    if e == 0:
        return pred, prior
    p_sum = np.array(pred.probs, dtype=np.float64, copy=True)
    d0 = np.asarray(pred.direction, dtype=np.float64)
    dirs = [d0]
    o_sum = np.array(pred.origin, dtype=np.float64, copy=True)
    has_axes = prior.axis_prob is not None and prior.axis_dirs is not None
    ap = np.array(prior.axis_prob, dtype=np.float64, copy=True) if has_axes else None
    centre = np.asarray(tensors.center, dtype=np.float64)
    for q, pq, prq in zip((1, 2, 3), preds, pris):
        back = quarter_turn(q)  # row vectors v turned back: v @ R (= R^T v)
        p_sum += pq.probs
        dirs.append(pq.direction @ back)
        o_sum += (pq.origin - centre) @ back + centre  # turned about the frame's centre
        if ap is not None and prq.axis_prob is not None and prq.axis_dirs is not None:
            _add_axis_mass(ap, np.asarray(prior.axis_dirs), prq.axis_prob, prq.axis_dirs @ back)
    direction = _mean_axis(dirs, d0)  # the mean axis, whatever the signs
    probs_avg = p_sum / 4.0
    if ap is not None:
        ap = ap / ap.sum(axis=1, keepdims=True)
    return (EdgePrediction(probs_avg, direction, o_sum / 4.0),
            GNNPriors(probs_avg.copy(), prior.type_names, ap, prior.axis_dirs, turned=True))


def predict_graphs(run: Run, graphs: Sequence[PartGraph], options: TreeOptions = TreeOptions(),
                   batch_size: int = 8, consistent: bool = True,
                   turns: TurnPolicy = "unnamed") -> list[ShapePrediction]:
    """Edge predictions and mobility trees of part graphs (see :func:`infer_edges`; ``turns``:
    :func:`infer_edges_with_priors`'s).

    With ``consistent`` (default) fine types are made to agree with the predicted axes
    (:func:`consistent_fine`).
    """
    preds, priors = infer_edges_with_priors(run, graphs, batch_size, turns)
    if consistent:
        preds = [consistent_fine(g, p) for g, p in zip(graphs, preds)]
    names = run.config.model.type_names
    return [ShapePrediction(g, p, build_mobility_tree(g, p, options), names, pr)
            for g, p, pr in zip(graphs, preds, priors)]
