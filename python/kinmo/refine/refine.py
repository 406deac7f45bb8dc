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

Frames and units: mesh frame (y-up), mesh units.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, model_validator

from kinmo.data.graph import PartGraph
from kinmo.data.model import COARSE_TYPES, FINE_TYPES
from kinmo.refine.candidates import (
    Candidates,
    candidate_axes,
    canonical_direction,
    frame_box,
    merge_candidates,
)
from kinmo.refine.motions import (
    MotionAmounts,
    candidate_motions,
    network_inputs,
    pair_cloud,
    shape_context,
)
from kinmo.refine.scoring import (
    CandidateScores,
    ScoringConfig,
    line_feasibility,
    score_candidates,
)

__all__ = [
    "EdgePredictions",
    "EdgeRefinement",
    "RefineConfig",
    "RefinedPredictions",
    "as_edge_predictions",
    "refine_edge",
    "refine_predictions",
    "refine_shape_prediction",
    "select_edge",
]


class RefineConfig(BaseModel):
    """Options of the refinement.

    Attributes
    ----------
    scoring : ScoringConfig
        Weights (paper: 0.5 / 0.3 / 0.2) or ``feasibility_only``.
    angles_deg : tuple of float
        Rotation angles of the candidate motions (degrees).
    translation_fraction : float
        Translation of the candidate motions, fraction of the part's OBB extent.
    interaction_radius : float
        Interaction-region radius, fraction of the moving part's OBB diagonal.
    n_points : int or None
        Network input points (default: the network's ``n_points``).
    seed : int
        Point subsampling seed (results are reproducible).
    chunk : int
        Moved clouds per network call.
    min_agreement : float or None
        kinmo extension (None: off, the paper's behaviour): when the chosen candidate's
        direction agreement ``|cos|`` with the GNN's axis is below this value, the refinement
        abstains and keeps the GNN's axis (kind ``"gnn"``; the confidence stays the
        candidate's low score). A wrong orientation in the predicted type (a door predicted
        ``P_H`` whose regressed axis is vertical) then costs the GNN's error, not 90°.
    snap_angle_deg : float or None
        kinmo extension (None: off, the paper's behaviour): only candidates whose line is
        within this angle (degrees) of the GNN's axis direction compete, so the refinement
        fixes the axis position and the sign of motion but keeps the GNN's orientation. When
        no candidate is that close the refinement abstains (kind ``"gnn"``, the GNN's axis,
        confidence NaN, which no pseudo-label threshold accepts).
    keep_gnn : bool
        kinmo extension (False: off, the paper's behaviour): the GNN's own axis line joins the
        candidates (kind ``"gnn"``), judged by the network like the others; its agreement
        terms are 1 by construction, so a geometric candidate replaces it only when it scores
        better overall.
    box_frames : tuple of {"moving", "reference", "shape"}
        Boxes whose edges, centre lines and axes give the candidates. ``("moving",)`` (the
        paper): the moving part's OBB. kinmo extension: ``"reference"`` adds the moving part's
        bounding box in its reference part's OBB axes, ``"shape"`` its box in the shape frame
        (:func:`kinmo.refine.candidates.frame_box`), so a part whose own OBB is tilted from
        its hinge (an opened laptop lid, a faucet handle) still gets the hinge as a candidate;
        lines within ``merge_angle_deg`` and ``merge_distance`` (fraction of the moving OBB's
        diagonal) of an earlier box's line are merged into it.
    merge_angle_deg, merge_distance : float
        Tolerances of that merge.
    selector : {"paper", "ranker"}
        ``"paper"``: the weighted score of :mod:`kinmo.refine.scoring` over the candidates of
        the predicted type (the options above apply). ``"ranker"`` (kinmo extension,
        :mod:`kinmo.refine.selector`): candidates of every orientation in all three box
        frames plus the GNN's line, scored by the learned ranker at ``ranker`` from soft GNN
        priors and geometric terms; the confidence is the ranker's calibrated probability
        that the selected line is right. ``scoring``, ``snap_angle_deg``, ``keep_gnn``,
        ``box_frames`` and ``min_agreement`` do not apply to it.
    ranker : str or None
        Path of the ranker file (``ranker.json``, :func:`kinmo.refine.selector.load_ranker`);
        required by ``selector="ranker"``.
    """

    model_config = ConfigDict(extra="forbid")

    scoring: ScoringConfig = Field(default_factory=ScoringConfig)
    angles_deg: tuple[float, ...] = (60.0,)
    translation_fraction: float = Field(0.5, gt=0)
    interaction_radius: float = Field(0.1, gt=0)
    n_points: int | None = Field(None, ge=2)
    seed: int = 0
    chunk: int = Field(16, ge=1)
    min_agreement: float | None = Field(None, ge=0, le=1)
    snap_angle_deg: float | None = Field(None, gt=0, le=90)
    keep_gnn: bool = False
    box_frames: tuple[Literal["moving", "reference", "shape"], ...] = Field(("moving",), min_length=1)
    merge_angle_deg: float = Field(2.0, ge=0, le=90)
    merge_distance: float = Field(0.02, ge=0)
    selector: Literal["paper", "ranker"] = "paper"
    ranker: str | None = None

    @model_validator(mode="after")
    def _ranker_path(self) -> RefineConfig:
        if self.selector == "ranker" and not self.ranker:
            raise ValueError("refine: selector 'ranker' needs a ranker file (ranker=...)")
        return self

    @property
    def amounts(self) -> MotionAmounts:
        """The candidate motion amounts."""
        return MotionAmounts(tuple(self.angles_deg), self.translation_fraction)


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


@dataclass(frozen=True)
class EdgeRefinement:
    """The refinement of one moving edge.

    Attributes
    ----------
    candidates : Candidates
    scores : CandidateScores
    origin : (3,) float64
        Point of the chosen line nearest to the moving part's OBB centre.
    direction : (3,) float64
        Unit direction of the chosen line, signed by the feasible direction of motion.
    abstained : bool
        The best candidate disagreed with the GNN's direction
        (:attr:`RefineConfig.min_agreement`): ``origin`` and ``direction`` are the GNN's.
    """

    candidates: Candidates
    scores: CandidateScores
    origin: np.ndarray
    direction: np.ndarray
    abstained: bool = False
    calibrated: float | None = None

    @property
    def confidence(self) -> float:
        """Score of the chosen candidate (NaN without candidates).

        With the learned selector (:attr:`RefineConfig.selector` ``"ranker"``), the
        calibrated probability that the chosen line is right (``calibrated``).

        When the GNN's own line won (:attr:`RefineConfig.keep_gnn`), the best score of the
        geometric candidates instead: the line's agreement with itself is 1 by construction
        and says nothing, so the confidence keeps the paper's meaning (a feasible geometric
        axis agrees with the GNN) and keeping the GNN's axis never changes which joints pass
        a pseudo-label threshold.
        """
        if self.calibrated is not None:
            return float(self.calibrated)
        b = self.scores.best
        if b < 0 or self.candidates.kinds[b] != "gnn":
            return self.scores.confidence
        geo = [k for k, kind in enumerate(self.candidates.kinds) if kind != "gnn"]
        return float(np.max(self.scores.total[geo])) if geo else float("nan")

    @property
    def kind(self) -> str:
        """Kind of the chosen candidate (``"edge"``, ``"center"``, ``"interaction"``,
        ``"axis"``), ``"gnn"`` when the refinement abstained or the GNN's own line won
        (:attr:`RefineConfig.keep_gnn`)."""
        return "gnn" if self.abstained else self.candidates.kinds[self.scores.best]


def refine_edge(
    graph: PartGraph,
    moving: int,
    reference: int,
    motion_type: str,
    gnn_direction: np.ndarray,
    gnn_origin: np.ndarray,
    axis_model,
    config: RefineConfig | None = None,
    rng: np.random.Generator | int | None = None,
) -> EdgeRefinement:
    """Refine the axis of one edge ``(moving, reference)``.

    Parameters
    ----------
    graph : PartGraph
    moving, reference : int
        Node indices.
    motion_type : str
        Predicted fine or coarse type with an axis.
    gnn_direction, gnn_origin : (3,) float
        The GNN's axis (mesh frame).
    axis_model : AxisSelectionNet
    config : RefineConfig, optional
    rng : numpy Generator or int, optional
        Point subsampling (default: ``config.seed``).

    Returns
    -------
    EdgeRefinement
    """
    cfg = config or RefineConfig()
    rng = np.random.default_rng(cfg.seed if rng is None else rng)
    obb = (graph.obb_center[moving], graph.obb_axes[moving], graph.obb_half_extents[moving])
    diag = max(2.0 * float(np.linalg.norm(graph.obb_half_extents[moving])), 1e-12)
    cands = None
    for frame in dict.fromkeys(cfg.box_frames):  # in order, once each
        if frame == "moving":
            box = obb
        else:
            axes = graph.obb_axes[reference] if frame == "reference" else np.eye(3)
            box = frame_box(graph.points[moving], axes)
        c = candidate_axes(box, motion_type, graph.points[moving], graph.points[reference],
                           interaction_radius=cfg.interaction_radius)
        cands = c if cands is None else merge_candidates(
            cands, c, angle_deg=cfg.merge_angle_deg, distance=cfg.merge_distance * diag)
    assert cands is not None  # box_frames has at least one frame (RefineConfig)
    g = np.asarray(gnn_direction, dtype=np.float64)
    g = g / np.linalg.norm(g)
    if cfg.snap_angle_deg is not None:
        close = np.abs(cands.directions @ g) >= np.cos(np.radians(cfg.snap_angle_deg)) - 1e-12
        cands = cands.subset(close)
    if cfg.keep_gnn:
        cands = Candidates(np.vstack([cands.origins, np.asarray(gnn_origin, float)[None]]),
                           np.vstack([cands.directions, canonical_direction(g)[None]]),
                           (*cands.kinds, "gnn"), cands.motion_type)
    if len(cands) == 0:  # snap_angle_deg left nothing: keep the GNN's axis, no confidence
        z = np.zeros(0)
        empty = CandidateScores(z, z, z, z, np.zeros(0, dtype=np.int64), -1)
        return EdgeRefinement(cands, empty, np.asarray(gnn_origin, dtype=np.float64).copy(), g,
                              abstained=True)
    feas, sign = _network_feasibility(graph, moving, reference, cands, axis_model, cfg, rng)
    scores = score_candidates(cands.origins, cands.directions, feas, gnn_direction, gnn_origin,
                              diag, cands.motion != "P", cfg.scoring, sign)
    b = scores.best
    if cfg.min_agreement is not None and scores.direction[b] < cfg.min_agreement:
        return EdgeRefinement(cands, scores, np.asarray(gnn_origin, dtype=np.float64).copy(),
                              g, abstained=True)
    return EdgeRefinement(cands, scores, *_chosen_line(graph, moving, cands, b, scores.sign[b]))


def _chosen_line(graph: PartGraph, moving: int, cands: Candidates, b: int, sign: int
                 ) -> tuple[np.ndarray, np.ndarray]:
    """Origin (nearest the moving OBB's centre) and signed direction of candidate ``b``."""
    d = cands.directions[b] * sign
    c = graph.obb_center[moving]
    return cands.origins[b] + float(np.dot(c - cands.origins[b], d)) * d, d


def _network_feasibility(graph: PartGraph, moving: int, reference: int, cands: Candidates,
                         axis_model, cfg: RefineConfig, rng: np.random.Generator
                         ) -> tuple[np.ndarray, np.ndarray]:
    """Axis-network feasibility ``(C,)`` and better sign ``(C,)`` of each candidate line."""
    import torch

    obb = (graph.obb_center[moving], graph.obb_axes[moving], graph.obb_half_extents[moving])
    mot = candidate_motions(cands, obb, cfg.amounts)
    n = cfg.n_points or axis_model.config.n_points
    frac = axis_model.config.context_fraction
    ctx = shape_context(graph.points[0], graph.points[moving]) if frac > 0 else None
    pair = pair_cloud(graph.points[moving], graph.points[reference], n, rng, ctx, frac,
                      axis_model.config.crop)
    rest, moved = network_inputs(pair, mot.origins, mot.directions, mot.angles, mot.translations)
    device = next(axis_model.parameters()).device
    s = axis_model.feasibility(torch.from_numpy(rest).to(device),
                               torch.from_numpy(moved).to(device), chunk=cfg.chunk).cpu().numpy()
    return line_feasibility(s, mot.line, mot.sign, len(cands))


def select_edge(
    graph: PartGraph,
    edge: int,
    motion_type: str,
    gnn_direction: np.ndarray,
    gnn_origin: np.ndarray,
    priors,
    ranker,
    axis_model=None,
    config: RefineConfig | None = None,
    rng: np.random.Generator | int | None = None,
    meshes=None,
) -> EdgeRefinement:
    """Refine one edge with the learned selector (:mod:`kinmo.refine.selector`).

    Parameters
    ----------
    graph : PartGraph
    edge : int
        Row of ``graph.sibling_edges``.
    motion_type : str
        Predicted type (its coarse motion decides the candidates).
    gnn_direction, gnn_origin : (3,) float
        The GNN's axis (mesh frame).
    priors : kinmo.refine.selector.GNNPriors
    ranker : kinmo.refine.selector.Ranker
    axis_model : AxisSelectionNet, optional
        Queried only when the ranker uses the ``feasibility`` feature.
    config : RefineConfig, optional
    rng : numpy Generator or int, optional
    meshes : kinmo.refine.selector.ShapeMeshes, optional
        The shape's leaf meshes (swept-collision terms); see
        :func:`kinmo.refine.selector.shape_meshes`.

    Returns
    -------
    EdgeRefinement
        ``scores.total`` holds the ranker's probabilities, ``scores.direction`` the ``|cos|``
        with the GNN's axis, ``scores.position`` the position prior, ``calibrated`` the
        confidence; the direction's sign is the one the collision proxy (or the network)
        finds freer.
    """
    from kinmo.refine.selector import FEATURE_GROUPS, FEATURES, candidate_features, edge_candidates

    cfg = config or RefineConfig()
    rng = np.random.default_rng(cfg.seed if rng is None else rng)
    i, j = (int(x) for x in graph.sibling_edges[edge])
    cands, frames = edge_candidates(graph, i, j, motion_type, gnn_direction, gnn_origin,
                                    interaction_radius=cfg.interaction_radius,
                                    merge_angle_deg=cfg.merge_angle_deg,
                                    merge_distance=cfg.merge_distance)
    feas = None
    net_sign = None
    if "feasibility" in ranker.features and axis_model is not None:
        feas, net_sign = _network_feasibility(graph, i, j, cands, axis_model, cfg, rng)
    proxy = net_sign is not None or any(f in ranker.features for f in FEATURE_GROUPS["collision"])
    x, sign = candidate_features(graph, i, j, edge, cands, frames, priors, gnn_direction,
                                 gnn_origin, feas, meshes, seed=cfg.seed, semantic=ranker.semantic,
                                 proxy=proxy)
    p = ranker.probabilities(x)
    b = int(np.argmax(p))
    sg = sign if net_sign is None else np.where(x[:, FEATURES.index("collide_max")] > 0,
                                                sign, net_sign)
    scores = CandidateScores(x[:, FEATURES.index("feasibility")], x[:, FEATURES.index("cos_gnn")],
                             x[:, FEATURES.index("pos_prior")], p, np.asarray(sg, np.int64), b)
    o, d = _chosen_line(graph, i, cands, b, int(sg[b]))
    return EdgeRefinement(cands, scores, o, d, calibrated=ranker.confidence(float(p[b])))


@dataclass
class RefinedPredictions:
    """The GNN's predictions with refined axes (mesh frame).

    Attributes
    ----------
    edges : (E, 2) int64
    type_names : tuple of str
    type_prob : (E, T) float64
        As predicted (refinement keeps the types).
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


def refine_predictions(
    graph: PartGraph,
    edge_predictions: Any,
    axis_model,
    config: RefineConfig | None = None,
    only: Sequence[int] | None = None,
    priors=None,
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
    types = pred.types
    moving = np.array([t not in ("Fixed", "None") for t in types], dtype=bool)
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
    ranker = None
    if cfg.selector == "ranker":
        from kinmo.refine.selector import GNNPriors, load_ranker

        ranker = load_ranker(str(cfg.ranker))
        if priors is None:
            priors = GNNPriors(pred.type_prob, pred.type_names)
        meshes = None
        if moving.any() and any(f.startswith("sweep") or f == "attach_mesh"
                                for f in ranker.features):
            from kinmo.refine.selector import shape_meshes

            meshes = shape_meshes(graph)
    for k in np.flatnonzero(moving):
        i, j = (int(x) for x in pred.edges[k])
        if ranker is not None:
            r = select_edge(graph, int(k), types[k], pred.axis_direction[k], pred.axis_origin[k],
                            priors, ranker, axis_model, cfg,
                            rng=np.random.default_rng([cfg.seed, int(k)]), meshes=meshes)
        else:
            r = refine_edge(graph, i, j, types[k], pred.axis_direction[k], pred.axis_origin[k],
                            axis_model, cfg, rng=np.random.default_rng([cfg.seed, int(k)]))
        origin[k], direction[k] = r.origin, r.direction
        conf[k] = r.confidence
        feas[k] = r.scores.feasibility[r.scores.best] if r.scores.best >= 0 else np.nan
        kind[k] = r.kind
        n_c[k] = len(r.candidates)
        details[int(k)] = r
    return RefinedPredictions(pred.edges, pred.type_names, pred.type_prob, pred.type_index,
                              origin, direction, moving, conf, feas, kind, n_c, details)


def refine_shape_prediction(
    prediction,
    axis_model,
    config: RefineConfig | None = None,
    options=None,
):
    """Refine a :class:`kinmo.predict.ShapePrediction` and rebuild its mobility tree.

    The integration point of ``kinmo predict --refine``: the edges' axes are refined
    (:func:`refine_predictions`), the types and probabilities kept, and the mobility tree is
    rebuilt from the refined axes (:func:`kinmo.mobility_tree.build_mobility_tree`).

    Parameters
    ----------
    prediction : ShapePrediction
        From :func:`kinmo.predict.predict_graphs` (mesh frame).
    axis_model : AxisSelectionNet
    config : RefineConfig, optional
    options : kinmo.mobility_tree.TreeOptions, optional

    Returns
    -------
    (ShapePrediction, RefinedPredictions)
        The refined prediction (same graph and type names) and the refinement details
        (per-edge confidence, candidates and scores).
    """
    from kinmo.mobility_tree import (
        EdgePrediction,
        ShapePrediction,
        TreeOptions,
        build_mobility_tree,
        consistent_fine,
    )

    refined = refine_predictions(prediction.graph, prediction.edges, axis_model, config,
                                 priors=getattr(prediction, "priors", None))
    edges = EdgePrediction(np.asarray(prediction.edges.probs), refined.axis_direction.copy(),
                           refined.axis_origin.copy())
    if (config or RefineConfig()).selector == "ranker":
        # the fine type follows the selected axis: H/V from its direction, C/S from its pivot
        edges = consistent_fine(prediction.graph, edges)
    tree = build_mobility_tree(prediction.graph, edges, options or TreeOptions())
    return ShapePrediction(prediction.graph, edges, tree, prediction.type_names,
                           getattr(prediction, "priors", None)), refined
