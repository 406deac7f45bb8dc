"""Refine the motion GNN's axes of one shape (Liu et al. 2023, Sec. 3.3; Table 1 settings).

For every sibling edge ``(i, j)`` the GNN predicts moving (its most probable type is P, R or
PR, fine or coarse), the refinement

1. builds the candidate lines of part ``i`` for the predicted type
   (:func:`kinmo.refine.candidates.candidate_axes`, with the interaction region of ``i`` and
   ``j``),
2. moves part ``i`` about / along each line in both directions by the inference amounts
   (:func:`kinmo.refine.motions.candidate_motions`, Rust
   :func:`~kinmo.geometry.apply_motions`) and lets the axis-selection network judge each
   motion (:class:`~kinmo.refine.axis_net.AxisSelectionNet`),
3. scores every line by feasibility and agreement with the GNN's axis
   (:func:`kinmo.refine.scoring.score_candidates`) and keeps the best: its line (origin moved
   to the point nearest the centre of ``i``'s OBB, like the labels of
   :mod:`kinmo.data.labels`), its feasible direction, and its score as the joint's
   confidence.

The paper's Table 1 compares four settings: ``GNN_coarse`` and ``GNN_fine`` (the GNN's axes
as predicted by a GNN trained on coarse or fine types) and ``OBB_coarse`` and ``OBB_fine``
(the same types with refined axes). A fine-type model's predictions refined here give
``OBB_fine``; a coarse-type model's give ``OBB_coarse`` (its candidates cover every
orientation and pivot kind).

Input contract (:class:`EdgePredictions`, built by :func:`as_edge_predictions` from any object
or mapping with the same fields): per sibling edge, type probabilities over
:data:`~kinmo.data.model.FINE_TYPES` (10) or :data:`~kinmo.data.model.COARSE_TYPES` (5), a unit
axis direction and an axis point, **in the mesh frame** of the graph.

This module holds the input contract and the dispatch over a shape's edges
(:func:`refine_predictions`, :func:`refine_shape_prediction`); the refinement of one edge
(:func:`refine_edge`, :func:`select_edge`, :class:`EdgeRefinement`) is in
:mod:`kinmo.refine.edge` and the options (:class:`RefineConfig`) in :mod:`kinmo.refine.config`,
both re-exported here.

Frames and units: mesh frame (y-up), mesh units.
"""

from __future__ import annotations

import logging
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.data.model import COARSE_TYPES, FINE_TYPES
from kinmo.metrics.axis import axis_angle_deg
from kinmo.mobility_tree import (
    EdgePrediction,
    ShapePrediction,
    TreeOptions,
    build_mobility_tree,
    consistent_fine,
)
from kinmo.refine.config import RefineConfig
from kinmo.refine.edge import (OPEN_FREE, SLIDE_ALONG_DEG, EdgeRefinement, fixed_parts_slide_veto,
                               hinge_blocked, pressable, pressed_into_face, refine_edge,
                               select_edge, spin_blocked)
from kinmo.refine.paired import open_from_the_middle
from kinmo.refine.repeated import vote_repeated
from kinmo.refine.ranker import DIRECTION_TOL_DEG
from kinmo.refine.selector import fixed_leaves

logger = logging.getLogger(__name__)

__all__ = [
    "EdgePredictions",
    "EdgeRefinement",
    "RefineConfig",
    "RefinedPredictions",
    "as_edge_predictions",
    "ranker_needs_meshes",
    "refine_edge",
    "refine_predictions",
    "refine_shape_prediction",
    "select_edge",
]


@dataclass
class EdgePredictions:
    """Motion GNN predictions of ``E`` directed sibling edges of one shape (mesh frame).

    Attributes
    ----------
    edges : (E, 2) int64
        ``(i, j)`` node indices of the graph ("i moves relative to j").
    type_prob : (E, T) float64
        Probabilities over ``type_names``.
    axis_direction : (E, 3) float64
        Predicted axis directions (unit; any finite value for non-moving edges).
    axis_origin : (E, 3) float64
        Predicted axis points.
    type_names : tuple of str
        :data:`~kinmo.data.model.FINE_TYPES` or :data:`~kinmo.data.model.COARSE_TYPES`.
    """

    edges: np.ndarray
    type_prob: np.ndarray
    axis_direction: np.ndarray
    axis_origin: np.ndarray
    type_names: tuple[str, ...] = FINE_TYPES

    def __post_init__(self) -> None:
        self.edges = np.asarray(self.edges, dtype=np.int64).reshape(-1, 2)
        e = self.edges.shape[0]
        self.type_prob = np.asarray(self.type_prob, dtype=np.float64)
        self.axis_direction = np.asarray(self.axis_direction, dtype=np.float64).reshape(-1, 3)
        self.axis_origin = np.asarray(self.axis_origin, dtype=np.float64).reshape(-1, 3)
        self.type_names = tuple(self.type_names)
        if self.type_names not in (FINE_TYPES, COARSE_TYPES):
            raise ValueError(f"edge_predictions.type_names: expected FINE_TYPES or COARSE_TYPES, "
                             f"got {self.type_names}")
        if self.type_prob.shape != (e, len(self.type_names)):
            raise ValueError(f"edge_predictions.type_prob: expected shape ({e}, "
                             f"{len(self.type_names)}), got {self.type_prob.shape}")
        for name in ("axis_direction", "axis_origin"):
            if getattr(self, name).shape[0] != e:
                raise ValueError(f"edge_predictions.{name}: expected {e} rows, "
                                 f"got {getattr(self, name).shape[0]}")

    @property
    def type_index(self) -> np.ndarray:
        """``(E,) int64``: most probable type."""
        return np.argmax(self.type_prob, axis=1).astype(np.int64)

    @property
    def types(self) -> list[str]:
        """Most probable type name of each edge."""
        return [self.type_names[k] for k in self.type_index]


_ALIASES = {
    "edges": ("edges", "sibling_edges", "edge_index"),
    "type_prob": ("type_prob", "type_probs", "fine_prob", "coarse_prob", "probs", "prob"),
    "axis_direction": ("axis_direction", "direction", "axis_dir"),
    "axis_origin": ("axis_origin", "axis_point", "origin", "point"),
    "type_names": ("type_names",),
}


def as_edge_predictions(obj: Any, graph: PartGraph | None = None) -> EdgePredictions:
    """An :class:`EdgePredictions` from an object or mapping with the same fields.

    Field names are looked up as attributes or keys, with aliases (``sibling_edges``,
    ``fine_prob`` / ``probs``, ``axis_point``, ...). Without ``edges`` the graph's
    ``sibling_edges`` are used; without ``type_names`` they are inferred from the number of
    type columns (10: fine, 5: coarse). Torch tensors are converted.

    Raises
    ------
    ValueError
        A required field is missing or has the wrong shape.
    """
    if isinstance(obj, EdgePredictions):
        return obj

    def get(key: str) -> Any:
        for name in _ALIASES[key]:
            if isinstance(obj, Mapping) and name in obj:
                v = obj[name]
            elif not isinstance(obj, Mapping) and hasattr(obj, name):
                v = getattr(obj, name)
            else:
                continue
            if hasattr(v, "detach"):
                v = v.detach().cpu().numpy()
            return v
        return None

    values = {k: get(k) for k in _ALIASES}
    if values["edges"] is None and graph is not None:
        values["edges"] = graph.sibling_edges
    for key in ("edges", "type_prob", "axis_direction", "axis_origin"):
        if values[key] is None:
            raise ValueError(f"edge_predictions: missing field {key!r} (aliases: "
                             f"{', '.join(_ALIASES[key])})")
    if values["type_names"] is None:
        t = np.asarray(values["type_prob"]).shape[-1]
        values["type_names"] = FINE_TYPES if t == len(FINE_TYPES) else COARSE_TYPES
    return EdgePredictions(**values)


@dataclass
class RefinedPredictions:
    """The GNN's predictions with refined axes (mesh frame).

    Attributes
    ----------
    edges : (E, 2) int64
    type_names : tuple of str
    type_prob : (E, T) float64
        As predicted (refinement keeps the types), except edges the blocked-hinge veto
        made sliders (:attr:`RefineConfig.sweep_vetoes`, :func:`as_slider`).
    type_index : (E,) int64
        Most probable type.
    axis_origin, axis_direction : (E, 3) float64
        Refined axes where ``refined``, the GNN's elsewhere.
    refined : (E,) bool
        Edges predicted moving (and selected), whose axes were refined.
    confidence : (E,) float64
        Score of the chosen candidate; NaN where not refined.
    feasibility : (E,) float64
        Network feasibility of the chosen candidate; NaN where not refined.
    kind : list of str
        Kind of the chosen candidate, ``""`` where not refined.
    n_candidates : (E,) int64
    details : dict of int to EdgeRefinement
        Per refined edge index: all candidates and scores.
    """

    edges: np.ndarray
    type_names: tuple[str, ...]
    type_prob: np.ndarray
    type_index: np.ndarray
    axis_origin: np.ndarray
    axis_direction: np.ndarray
    refined: np.ndarray
    confidence: np.ndarray
    feasibility: np.ndarray
    kind: list[str]
    n_candidates: np.ndarray
    details: dict[int, EdgeRefinement] = field(default_factory=dict)

    @property
    def types(self) -> list[str]:
        """Most probable type name of each edge."""
        return [self.type_names[k] for k in self.type_index]

    def to_json(self) -> dict[str, Any]:
        """JSON-ready summary of the refined edges (``edges``, types, axes, scores)."""
        rows = []
        for e in np.flatnonzero(self.refined):
            r = self.details[int(e)]
            rows.append({
                "edge": int(e),
                "moving": int(self.edges[e, 0]),
                "reference": int(self.edges[e, 1]),
                "type": self.type_names[int(self.type_index[e])],
                "origin": [float(x) for x in self.axis_origin[e]],
                "direction": [float(x) for x in self.axis_direction[e]],
                "confidence": float(self.confidence[e]),
                "feasibility": float(self.feasibility[e]),
                "direction_agreement": (float(r.scores.direction[r.scores.best])
                                        if r.scores.best >= 0 else float("nan")),
                "position_agreement": (float(r.scores.position[r.scores.best])
                                       if r.scores.best >= 0 else float("nan")),
                "kind": self.kind[e],
                "n_candidates": int(self.n_candidates[e]),
            })
        return {"edges": rows}


def ranker_needs_meshes(ranker) -> bool:
    """True when a ranker (:class:`kinmo.refine.ranker.Ranker`) uses mesh features (the
    swept-collision terms, ``attach_mesh``)."""
    return any(f.startswith("sweep") or f == "attach_mesh" for f in ranker.features)


def as_slider(type_prob: np.ndarray, type_names: Sequence[str], rows: Sequence[int]) -> np.ndarray:
    """Type probabilities with the revolute mass of ``rows`` moved to the prismatic type.

    Parameters
    ----------
    type_prob : (E, T) float
        Over ``type_names`` (fine: the ``R_*`` columns go to ``P_H``, which
        :func:`kinmo.mobility_tree.consistent_fine` then splits by the chosen axis; coarse:
        ``R`` goes to ``P``).
    type_names : sequence of str
    rows : sequence of int
        Edges switched from hinge to slider (:func:`refine_predictions`).

    Returns
    -------
    (E, T) float64
        A copy; the rows' sums are kept.
    """
    out = np.array(type_prob, dtype=np.float64, copy=True)
    if len(rows):
        names = list(type_names)
        to = names.index("P_H") if "P_H" in names else names.index("P")
        rcols = [c for c, n in enumerate(names) if n.split("_")[0] == "R"]
        idx = np.asarray(list(rows), dtype=np.int64)
        out[idx, to] += out[np.ix_(idx, rcols)].sum(axis=1)
        out[np.ix_(idx, rcols)] = 0.0
    return out


def refine_predictions(
    graph: PartGraph,
    edge_predictions: Any,
    axis_model,
    config: RefineConfig | None = None,
    only: Sequence[int] | None = None,
    priors=None,
    meshes=None,
) -> RefinedPredictions:
    """Refine the axes of every edge the GNN predicts moving (``OBB_fine`` / ``OBB_coarse``).

    Parameters
    ----------
    graph : PartGraph
        The shape's part graph (points, OBBs).
    edge_predictions : EdgePredictions or compatible
        See :func:`as_edge_predictions`; mesh frame.
    axis_model : AxisSelectionNet
        A trained network (:func:`kinmo.refine.train.load_axis_model`).
    config : RefineConfig, optional
    only : sequence of int, optional
        Refine only these edge indices (e.g. the joints of the final mobility tree); others
        keep the GNN's axes.
    priors : kinmo.refine.selector.GNNPriors, optional
        The GNN's raw outputs (:func:`kinmo.predict.infer_edges_with_priors`), used by the
        learned selector; without them it takes the types of ``edge_predictions`` as type
        priors and no axis-candidate prior.
    meshes : kinmo.refine.selector.ShapeMeshes, optional
        The shape's leaf meshes, for a ranker with swept-collision / mesh features. Without
        them they are read from the graph's source folder
        (:func:`kinmo.refine.selector.shape_meshes`); when that fails too, a warning names
        the shape and the point terms stand in (never silently).

    Returns
    -------
    RefinedPredictions

    Raises
    ------
    ValueError
        Malformed predictions or an edge index outside the graph.
    """
    cfg = config or RefineConfig()
    pred = as_edge_predictions(edge_predictions, graph)
    e = pred.edges.shape[0]
    if e and (pred.edges.min() < 0 or pred.edges.max() >= graph.n_nodes):
        raise ValueError(f"edge_predictions.edges: node index out of range 0..{graph.n_nodes - 1}")
    types = list(pred.types)
    moving = np.array([t not in ("Fixed", "None") for t in types], dtype=bool)
    movers = pred.edges[moving, 0]  # every part predicted to move, refined (``only``) or not
    mover_set = {int(n) for n in movers}
    # parts touching a part predicted to move: a handle on a drawer moves with the drawer
    touch = np.asarray(graph.sibling_edges, dtype=np.int64).reshape(-1, 2)[
        np.asarray(graph.sibling_contact, dtype=bool).reshape(-1)]
    carried = {int(a) for a, b in touch.tolist() if b in mover_set} | \
        {int(b) for a, b in touch.tolist() if a in mover_set}
    if only is not None:
        sel = np.zeros(e, dtype=bool)
        sel[np.asarray(list(only), dtype=np.int64)] = True
        moving &= sel
    origin = pred.axis_origin.copy()
    direction = pred.axis_direction.copy()
    conf = np.full(e, np.nan)
    feas = np.full(e, np.nan)
    kind = [""] * e
    n_c = np.zeros(e, dtype=np.int64)
    details: dict[int, EdgeRefinement] = {}
    switched: set[int] = set()
    ranker = None
    if cfg.selector == "ranker":
        from kinmo.refine.ranker import load_ranker
        from kinmo.refine.selector import GNNPriors

        ranker = load_ranker(str(cfg.ranker)).for_types(pred.type_names)
        if priors is None:
            priors = GNNPriors(pred.type_prob, pred.type_names)
        if meshes is None and moving.any() and ranker_needs_meshes(ranker):
            from kinmo.refine.selector import shape_meshes

            meshes = shape_meshes(graph)
            if meshes is None:
                logger.warning("%s: no meshes (source folder %s unreadable or not matching the "
                               "graph): the ranker's sweep features use the point proxy",
                               graph.shape_id, graph.meta.get("source", "unknown"))
    # the fixed-parts slide veto's obstacle: a door predicted to open is no obstacle to its
    # drawer, whether or not the door's own edge is refined
    fixed = fixed_leaves(graph, movers) if ranker is not None and cfg.sweep_vetoes and meshes is not None \
        else None
    for k in np.flatnonzero(moving):
        i, j = (int(x) for x in pred.edges[k])
        if ranker is not None:
            r = select_edge(graph, int(k), types[k], pred.axis_direction[k], pred.axis_origin[k],
                            priors, ranker, axis_model, cfg,
                            rng=np.random.default_rng([cfg.seed, int(k)]), meshes=meshes)
        else:
            r = refine_edge(graph, i, j, types[k], pred.axis_direction[k], pred.axis_origin[k],
                            axis_model, cfg, rng=np.random.default_rng([cfg.seed, int(k)]))
        revolute = ranker is not None and cfg.sweep_vetoes and types[k].split("_")[0] == "R"
        every = revolute and hinge_blocked(r)
        if every or (revolute and spin_blocked(r, types[k])):
            # no hinge line, or not the chosen one, turns the part: does it slide out? (issue
            # 36, module docs) With only the chosen line blocked, it must slide along that line
            rp = select_edge(graph, int(k), "P_H", pred.axis_direction[k], pred.axis_origin[k],
                             priors, ranker, axis_model, cfg,
                             rng=np.random.default_rng([cfg.seed, int(k)]), meshes=meshes)
            if rp.free is not None and rp.scores.best >= 0 and float(rp.free[rp.scores.best]) >= OPEN_FREE \
                    and (every or axis_angle_deg(rp.direction, r.direction) <= SLIDE_ALONG_DEG):
                r = rp
                switched.add(int(k))
                types[k] = "P_H"
        if fixed is not None:
            r = fixed_parts_slide_veto(graph, int(k), r, meshes, fixed, ranker.confidence)
        if ranker is not None and cfg.sweep_vetoes and j not in mover_set and i not in carried \
                and pressable(graph.node_names[i] if i < len(graph.node_names) else "", priors.turned):
            # a button (unnamed, or named so) on a part predicted not to move, carried by none
            # that moves (edge module docs)
            r = pressed_into_face(graph, int(k), r, ranker.confidence)
        details[int(k)] = r
    if ranker is not None and cfg.vote_repeated and details:
        details.update(vote_repeated(graph, pred.edges, types, details, ranker.confidence,
                                     mass=DIRECTION_TOL_DEG if ranker.choice == "direction" else None,
                                     slide_veto=cfg.sweep_vetoes))
    if ranker is not None and cfg.pair_doors and details:
        details.update(open_from_the_middle(graph, pred.edges, types, details))
    for k, r in details.items():
        origin[k], direction[k] = r.origin, r.direction
        conf[k] = r.confidence
        feas[k] = r.scores.feasibility[r.scores.best] if r.scores.best >= 0 else np.nan
        kind[k] = r.kind
        n_c[k] = len(r.candidates)
    type_prob = as_slider(pred.type_prob, pred.type_names, sorted(switched))
    return RefinedPredictions(pred.edges, pred.type_names, type_prob,
                              np.argmax(type_prob, axis=1).astype(np.int64),
                              origin, direction, moving, conf, feas, kind, n_c, details)


def refine_shape_prediction(
    prediction,
    axis_model,
    config: RefineConfig | None = None,
    options=None,
    meshes=None,
):
    """Refine a :class:`kinmo.predict.ShapePrediction` and rebuild its mobility tree.

    The integration point of ``kinmo predict --refine``: the edges' axes are refined
    (:func:`refine_predictions`), the types and probabilities kept (but for edges the
    blocked-hinge veto made sliders), and the mobility tree is
    rebuilt from the refined axes (:func:`kinmo.mobility_tree.build_mobility_tree`).

    Parameters
    ----------
    prediction : ShapePrediction
        From :func:`kinmo.predict.predict_graphs` (mesh frame).
    axis_model : AxisSelectionNet
    config : RefineConfig, optional
    options : kinmo.mobility_tree.TreeOptions, optional
    meshes : kinmo.refine.selector.ShapeMeshes, optional
        The shape's leaf meshes (see :func:`refine_predictions`).

    Returns
    -------
    (ShapePrediction, RefinedPredictions)
        The refined prediction (same graph and type names) and the refinement details
        (per-edge confidence, candidates and scores).
    """

    refined = refine_predictions(prediction.graph, prediction.edges, axis_model, config,
                                 priors=getattr(prediction, "priors", None), meshes=meshes)
    edges = EdgePrediction(refined.type_prob, refined.axis_direction.copy(),
                           refined.axis_origin.copy())
    if (config or RefineConfig()).selector == "ranker":
        # the fine type follows the selected axis: H/V from its direction, C/S from its pivot
        edges = consistent_fine(prediction.graph, edges)
    tree = build_mobility_tree(prediction.graph, edges, options or TreeOptions())
    return ShapePrediction(prediction.graph, edges, tree, prediction.type_names,
                           getattr(prediction, "priors", None)), refined
