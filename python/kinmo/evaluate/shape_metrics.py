"""The metrics of the evaluation on pre-segmented shapes (Liu et al. 2023, Table 1, GNN rows).

For every test shape (PartNet-Mobility, ground truth from its part graph) and every model:

**Edge level** (the protocol of the paper's code, SWMP ``GnnMotion/test_struct.py``):

- ``edge_acc``: motion-type accuracy over all directed sibling edges (fine or coarse types,
  those of the model);
- ``moving_edge_acc``: the same over the edges whose true type has an axis (P, R, PR), i.e.
  over the joints as the hierarchy sees them;
- ``angle_edge``: axis angle error ``min(θ, 180° - θ)`` in degrees of those edges;
- ``dist_edge``: distance of the predicted axis point to the true axis line, over the edges
  whose true type rotates (R, PR), divided by the shape's scale (the diagonal of its
  axis-aligned bounding box). This is the paper's Table 1 "distance": SWMP measures it as
  ``|(p - o) x d|`` in the (roughly unit-sized) PartNet-Mobility mesh frame; kinmo divides
  by the diagonal so that numbers do not depend on the mesh units.

**Joint level** (the mobility tree, :mod:`kinmo.mobility_tree`, against the true links):

- mobile-part detection: predicted moving links (hinge/slider; a ``static`` link counts
  with the link it hangs from) are matched one-to-one to the true moving links (a moving
  link with the ``static``/``heavy``/``junk`` links attached to it, the rigid groups of
  :mod:`kinmo.data.labels`) by their leaf sets, maximising the total IoU (Hungarian) and
  keeping pairs with IoU >= 0.5: ``precision`` = matched / predicted, ``recall`` = matched /
  true;
- ``joint_type_acc``: share of matched joints with the right kind (revolute, prismatic,
  cylindrical);
- ``angle_joint``: axis angle error (degrees) of all matched joints;
- ``dist_joint``: minimum **line-to-line** distance between the predicted and the true axis
  (ANCSH, Li et al. 2020: the length of the common perpendicular of the two lines, the
  point-to-line distance when they are parallel), for matched joints whose true joint
  rotates, divided by the shape's scale.

**Ranges** (kinmo, issue 35; :mod:`kinmo.metrics.motion_range`), for matched joints of the
right kind whose axis is within 20° of the truth: ``range_iou_hinge`` / ``range_iou_slider``
(mean range IoU; a continuous prediction of a limited hinge counts as the full turn
``[-180, 180]``), ``range_ok_*`` (share with IoU >= 0.5), ``range_end_hinge`` (median worst
end-point error, degrees) and ``range_end_slider`` (the same as a fraction of the true
travel; cylindrical joints by their translation), ``range_cont_acc`` (hinges: continuous or
not, as the truth; the only score of a true ``noLimit`` hinge).

Per category, counts are pooled over the category's shapes (accuracies, precision, recall)
and errors averaged over its edges or joints; the ``mean`` row averages the categories
(every category weighs the same, as in the paper's table); the ``all`` row pools every test
shape (every edge or joint weighs the same).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.data.labels import rigid_groups
from kinmo.data.model import FINE_TO_COARSE, FINE_TYPES, Joint, JointType, Link
from kinmo.metrics.axis import axis_angle_deg, line_distance, point_line_distance
from kinmo.metrics.motion_range import RangeScore, joint_kind, score_range, summarise_ranges
from kinmo.mobility_tree import MobilityTree

__all__ = [
    "METRICS",
    "EvalReport",
    "ShapeEval",
    "aggregate",
    "build_report",
    "evaluate_graphs",
    "evaluate_shape",
    "gt_links",
    "leaf_link_map",
    "match_joints",
    "match_links",
    "nanmean",
]

#: Reported metrics, in table order: (key, header, higher is better).
METRICS: tuple[tuple[str, str, bool], ...] = (
    ("edge_acc", "type acc (edges)", True),
    ("moving_edge_acc", "type acc (moving edges)", True),
    ("joint_type_acc", "type acc (joints)", True),
    ("precision", "mobile-part precision", True),
    ("recall", "mobile-part recall", True),
    ("angle_edge", "angle err edges (deg)", False),
    ("dist_edge", "dist edges (/diag)", False),
    ("angle_joint", "angle err joints (deg)", False),
    ("dist_joint", "line dist joints (/diag)", False),
    ("range_iou_hinge", "hinge range IoU", True),
    ("range_ok_hinge", "hinge ranges with IoU >= 0.5", True),
    ("range_end_hinge", "hinge range worst end-point err (deg, median)", False),
    ("range_iou_slider", "slider range IoU", True),
    ("range_ok_slider", "slider ranges with IoU >= 0.5", True),
    ("range_end_slider", "slider range worst end-point err (/travel, median)", False),
    ("range_cont_acc", "hinge continuous-or-not acc", True),
)


_MOVING_FINE = np.array([t not in ("Fixed", "None") for t in FINE_TYPES])
_ROT_FINE = np.array([t.startswith("R") or t.startswith("PR") for t in FINE_TYPES])


def _joint_from_json(d: dict) -> Joint:
    jt = JointType(d["joint"])
    o = None if d.get("origin") is None else np.asarray(d["origin"], dtype=np.float64)
    dr = None if d.get("direction") is None else np.asarray(d["direction"], dtype=np.float64)
    lim = None if d.get("limit") is None else tuple(float(x) for x in d["limit"])
    return Joint(jt, o, dr, lim, bool(d.get("rotates", False)), d.get("rotation_limit"))


def gt_links(graph: PartGraph) -> list[Link]:
    """The true links stored in a part graph's ``meta["links"]`` (PartNet-Mobility caches).

    Raises
    ------
    ValueError
        The graph has no links (not a PartNet-Mobility graph) or they are malformed.
    """
    raw = graph.meta.get("links")
    if not raw:
        raise ValueError(f"{graph.shape_id}: part graph has no ground-truth links")
    try:
        return [Link(int(d["id"]), int(d["parent"]), str(d.get("name", "")),
                     tuple(int(p) for p in d.get("parts", [])), _joint_from_json(d)) for d in raw]
    except (KeyError, TypeError, ValueError) as e:
        raise ValueError(f"{graph.shape_id}: malformed ground-truth links: {e}") from None


def _moving_groups(links: Sequence[Link], leaf_link: dict[int, int]) -> dict[int, set[int]]:
    """Leaf sets of the moving rigid groups: group head id -> leaf node indices."""
    groups = rigid_groups(list(links))
    by_id = {lk.id: lk for lk in links}
    out: dict[int, set[int]] = {lk.id: set() for lk in links if lk.joint.is_moving}
    for leaf, lid in leaf_link.items():
        if lid in groups:
            g = groups[lid]
            if g in out and by_id[g].joint.is_moving:
                out[g].add(leaf)
    return out


def match_links(pred: dict[int, set[int]], true: dict[int, set[int]],
                threshold: float = 0.5) -> list[tuple[int, int, float]]:
    """One-to-one matching of leaf sets maximising total IoU, keeping IoU >= ``threshold``.

    Parameters
    ----------
    pred, true : dict of int to set of int
        Link id -> leaf node indices.
    threshold : float

    Returns
    -------
    list of (pred id, true id, IoU)
        Sorted by predicted id.
    """
    from scipy.optimize import linear_sum_assignment

    pk, tk = sorted(pred), sorted(true)
    if not pk or not tk:
        return []
    iou = np.zeros((len(pk), len(tk)))
    for a, p in enumerate(pk):
        for b, t in enumerate(tk):
            u = len(pred[p] | true[t])
            iou[a, b] = len(pred[p] & true[t]) / u if u else 0.0
    rows, cols = linear_sum_assignment(-iou)
    out = [(pk[r], tk[c], float(iou[r, c])) for r, c in zip(rows, cols) if iou[r, c] >= threshold]
    return sorted(out)


def leaf_link_map(graph: PartGraph, links: Sequence[Link]) -> dict[int, int]:
    """Leaf node index -> id of the link that holds it, from the links' ``parts`` (PartNet
    node ids; a listed inner node holds every leaf below it); -1 for a leaf of no link.

    The map :func:`match_joints` needs for links read back without their tree (a
    pseudo-label's, a ``mobility_v2.json``'s)."""
    owner = {int(p): lk.id for lk in links for p in lk.parts}
    ids = np.asarray(graph.node_ids)
    parent = np.asarray(graph.parent)
    out: dict[int, int] = {}
    for n in np.flatnonzero(np.asarray(graph.is_leaf, bool)):
        k = int(n)
        while k >= 0 and int(ids[k]) not in owner:
            k = int(parent[k])
        out[int(n)] = owner[int(ids[k])] if k >= 0 else -1
    return out


def match_joints(graph: PartGraph, links: Sequence[Link], leaf_link: dict[int, int] | None = None
                 ) -> tuple[int, int, list[tuple[Link, Link, float]]]:
    """Predicted moving links matched to the graph's true ones, as Table 1 matches them
    (:func:`evaluate_shape`): each link's moved leaf set (its rigid group's), one to one,
    IoU >= 0.5 (:func:`match_links`).

    Parameters
    ----------
    graph : PartGraph
        Labelled (``meta["links"]``, ``node_link``).
    links : sequence of Link
        The predicted links (a mobility tree's, or a pseudo-label's).
    leaf_link : dict of int to int, optional
        Leaf node index -> predicted link id; by default :func:`leaf_link_map` of ``links``.

    Returns
    -------
    (int, int, list of (Link, Link, float))
        The numbers of predicted and true moving rigid groups, and the matched (predicted,
        true, IoU) pairs, sorted by predicted id.

    Raises
    ------
    ValueError
        The graph has no ground-truth links.
    """
    true = gt_links(graph)
    node_link = np.asarray(graph.node_link)
    leaves = np.flatnonzero(np.asarray(graph.is_leaf, bool))
    pred_groups = _moving_groups(links, leaf_link if leaf_link is not None else leaf_link_map(graph, links))
    true_groups = _moving_groups(true, {int(n): int(node_link[n]) for n in leaves})
    by_p, by_t = {lk.id: lk for lk in links}, {lk.id: lk for lk in true}
    return len(pred_groups), len(true_groups), [(by_p[a], by_t[b], iou)
                                                for a, b, iou in match_links(pred_groups, true_groups)]


@dataclass
class ShapeEval:
    """Raw evaluation counts and errors of one shape under one model."""

    shape_id: str
    category: str
    n_edges: int = 0
    edges_correct: int = 0
    n_moving_edges: int = 0
    moving_edges_correct: int = 0
    angle_edge: list[float] = field(default_factory=list)
    dist_edge: list[float] = field(default_factory=list)
    n_pred: int = 0
    n_true: int = 0
    n_matched: int = 0
    joint_type_correct: int = 0
    angle_joint: list[float] = field(default_factory=list)
    dist_joint: list[float] = field(default_factory=list)
    matches: list[tuple[int, int, float]] = field(default_factory=list)
    ranges: list[RangeScore] = field(default_factory=list)


def evaluate_shape(graph: PartGraph, probs: np.ndarray, direction: np.ndarray,
                   origin: np.ndarray, tree: MobilityTree, types: str) -> ShapeEval:
    """Evaluate one shape's predictions against its ground truth (module docstring).

    Parameters
    ----------
    graph : PartGraph
        Labelled (PartNet-Mobility) part graph.
    probs : (E, K) float
        Type probabilities (fine ``K=10`` or coarse ``K=5``).
    direction, origin : (E, 3) float
        Predicted axes, mesh frame.
    tree : MobilityTree
        The mobility tree built from these predictions.
    types : {"fine", "coarse"}

    Returns
    -------
    ShapeEval

    Raises
    ------
    ValueError
        The graph has no labels.
    """
    if not graph.has_labels:
        raise ValueError(f"{graph.shape_id}: part graph has no ground-truth labels")
    scale = float(graph.scale)
    r = ShapeEval(graph.shape_id, graph.category)
    fine = np.asarray(graph.edge_fine, dtype=np.int64)
    true = fine if types == "fine" else np.asarray(FINE_TO_COARSE)[fine]
    pred = np.argmax(probs, axis=1)
    ok = pred == true
    r.n_edges = int(len(fine))
    r.edges_correct = int(ok.sum())
    mv = _MOVING_FINE[fine]
    r.n_moving_edges = int(mv.sum())
    r.moving_edges_correct = int((ok & mv).sum())
    if mv.any():
        td = np.asarray(graph.edge_axis_direction)[mv]
        r.angle_edge = list(np.atleast_1d(axis_angle_deg(direction[mv], td)))
    rot = _ROT_FINE[fine]
    if rot.any():
        d = point_line_distance(origin[rot], np.asarray(graph.edge_axis_origin)[rot],
                                np.asarray(graph.edge_axis_direction)[rot])
        r.dist_edge = list(np.atleast_1d(d) / scale)

    leaves = np.flatnonzero(graph.is_leaf)
    r.n_pred, r.n_true, pairs = match_joints(graph, tree.links,
                                             {int(n): int(tree.leaf_link[n]) for n in leaves})
    r.matches = [(p.id, t.id, iou) for p, t, iou in pairs]
    r.n_matched = len(r.matches)
    for p, t, _ in pairs:
        a, b = p.joint, t.joint
        r.joint_type_correct += int(joint_kind(a) == joint_kind(b))
        r.angle_joint.append(float(axis_angle_deg(a.direction, b.direction)))
        if joint_kind(b) in ("R", "PR"):
            r.dist_joint.append(float(line_distance(a.origin, a.direction, b.origin, b.direction)) / scale)
        rs = score_range(a, b)
        if rs is not None:
            r.ranges.append(rs)
    return r


def nanmean(x: Sequence[float]) -> float:
    """Mean of the non-NaN values of ``x`` (NaN when there is none)."""
    return float(np.mean(x)) if len(x) else float("nan")


def aggregate(rows: Sequence[ShapeEval]) -> dict[str, float]:
    """Pool shape evaluations into the metrics of :data:`METRICS` (plus ``n_shapes`` etc.)."""
    n_e = sum(r.n_edges for r in rows)
    n_m = sum(r.n_moving_edges for r in rows)
    n_p = sum(r.n_pred for r in rows)
    n_t = sum(r.n_true for r in rows)
    n_x = sum(r.n_matched for r in rows)
    out = {
        "n_shapes": len(rows),
        "n_joints": n_t,
        "edge_acc": sum(r.edges_correct for r in rows) / n_e if n_e else float("nan"),
        "moving_edge_acc": sum(r.moving_edges_correct for r in rows) / n_m if n_m else float("nan"),
        "joint_type_acc": sum(r.joint_type_correct for r in rows) / n_x if n_x else float("nan"),
        "precision": n_x / n_p if n_p else float("nan"),
        "recall": n_x / n_t if n_t else float("nan"),
        "angle_edge": nanmean([a for r in rows for a in r.angle_edge]),
        "dist_edge": nanmean([a for r in rows for a in r.dist_edge]),
        "angle_joint": nanmean([a for r in rows for a in r.angle_joint]),
        "dist_joint": nanmean([a for r in rows for a in r.dist_joint]),
    }
    out.update(summarise_ranges(x for r in rows for x in r.ranges))
    return out


@dataclass
class EvalReport:
    """Per-category metrics of one or more models.

    Attributes
    ----------
    models : list of str
        Column names (``GNN_fine``, ``GNN_coarse``...).
    categories : list of str
        Sorted; the tables add ``mean`` (over categories) and ``all`` (pooled) rows.
    table : dict of (str, str) to dict
        ``(model, category, "mean" or "all") -> metrics`` (:func:`aggregate`).
    shapes : dict of str to list of ShapeEval
        Per model.
    """

    models: list[str]
    categories: list[str]
    table: dict[tuple[str, str], dict[str, float]]
    shapes: dict[str, list[ShapeEval]]


def build_report(shapes: dict[str, list[ShapeEval]]) -> EvalReport:
    """Aggregate shape evaluations per model and category; ``mean`` averages categories."""
    models = list(shapes)
    cats = sorted({r.category for rows in shapes.values() for r in rows})
    table: dict[tuple[str, str], dict[str, float]] = {}
    for m, rows in shapes.items():
        per = []
        for c in cats:
            sub = [r for r in rows if r.category == c]
            if sub:
                table[(m, c)] = aggregate(sub)
                per.append(table[(m, c)])
        mean: dict[str, float] = {"n_shapes": sum(p["n_shapes"] for p in per),
                                  "n_joints": sum(p["n_joints"] for p in per)}
        for key, _, _ in METRICS:
            vals = [p[key] for p in per if not math.isnan(p[key])]
            mean[key] = float(np.mean(vals)) if vals else float("nan")
        table[(m, "mean")] = mean
        table[(m, "all")] = aggregate(rows)
    return EvalReport(models, cats, table, shapes)


def evaluate_graphs(graphs: Sequence[PartGraph], predictions: dict[str, Sequence]) -> EvalReport:
    """Evaluate several models' predictions on the same labelled graphs.

    Parameters
    ----------
    graphs : sequence of PartGraph
        Labelled test graphs.
    predictions : dict of str to sequence of ShapePrediction
        Per model name, one :class:`~kinmo.predict.ShapePrediction` per graph (same order).

    Returns
    -------
    EvalReport
    """
    shapes: dict[str, list[ShapeEval]] = {}
    for name, preds in predictions.items():
        rows = []
        for g, p in zip(graphs, preds):
            types = "fine" if p.edges.probs.shape[1] == len(FINE_TYPES) else "coarse"
            rows.append(evaluate_shape(g, p.edges.probs, p.edges.direction, p.edges.origin,
                                       p.tree, types))
        shapes[name] = rows
    return build_report(shapes)
