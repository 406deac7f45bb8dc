"""Evaluation on pre-segmented shapes (Liu et al. 2023, Table 1, GNN rows).

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

Per category, counts are pooled over the category's shapes (accuracies, precision, recall)
and errors averaged over its edges or joints; the ``mean`` row averages the categories
(every category weighs the same, as in the paper's table); the ``all`` row pools every test
shape (every edge or joint weighs the same).
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from kinmo.data.graph import PartGraph
from kinmo.data.labels import rigid_groups
from kinmo.data.model import FINE_TO_COARSE, FINE_TYPES, Joint, JointType, Link
from kinmo.io import write_text
from kinmo.metrics.axis import axis_angle_deg, line_distance, point_line_distance
from kinmo.mobility_tree import MobilityTree

__all__ = [
    "METRICS",
    "PAPER_MEANS",
    "EvalReport",
    "ShapeEval",
    "evaluate_graphs",
    "evaluate_shape",
    "gt_links",
    "match_links",
    "report_csv",
    "report_markdown",
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
)

#: Short column names of the printed (terminal) tables.
SHORT = {
    "edge_acc": "acc", "moving_edge_acc": "acc mov", "joint_type_acc": "acc jnt",
    "precision": "prec", "recall": "rec", "angle_edge": "ang e°", "dist_edge": "dist e",
    "angle_joint": "ang j°", "dist_joint": "dist j",
}

#: The paper's Table 1 means of its GNN (fine / coarse types): angle error (degrees) and
#: distance.
PAPER_MEANS = {
    "GNN_fine": {"angle": 8.93, "distance": 0.205},
    "GNN_coarse": {"angle": 12.23, "distance": 0.220},
    "OBB_fine": {"angle": 4.78, "distance": 0.112},
}

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


def _kind(j: Joint) -> str:
    if j.type is JointType.HINGE:
        return "R"
    return "PR" if j.rotates else "P"


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

    links_true = gt_links(graph)
    node_link = np.asarray(graph.node_link)
    leaves = np.flatnonzero(graph.is_leaf)
    true_groups = _moving_groups(links_true, {int(n): int(node_link[n]) for n in leaves})
    pred_groups = _moving_groups(tree.links, {int(n): int(tree.leaf_link[n]) for n in leaves})
    r.n_true, r.n_pred = len(true_groups), len(pred_groups)
    r.matches = match_links(pred_groups, true_groups)
    r.n_matched = len(r.matches)
    pj = {lk.id: lk.joint for lk in tree.links}
    tj = {lk.id: lk.joint for lk in links_true}
    for p, t, _ in r.matches:
        a, b = pj[p], tj[t]
        r.joint_type_correct += int(_kind(a) == _kind(b))
        r.angle_joint.append(float(axis_angle_deg(a.direction, b.direction)))
        if _kind(b) in ("R", "PR"):
            r.dist_joint.append(float(line_distance(a.origin, a.direction, b.origin, b.direction)) / scale)
    return r


def _nanmean(x: Sequence[float]) -> float:
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
        "angle_edge": _nanmean([a for r in rows for a in r.angle_edge]),
        "dist_edge": _nanmean([a for r in rows for a in r.dist_edge]),
        "angle_joint": _nanmean([a for r in rows for a in r.angle_joint]),
        "dist_joint": _nanmean([a for r in rows for a in r.dist_joint]),
    }
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


def _fmt(key: str, v: float) -> str:
    if isinstance(v, float) and math.isnan(v):
        return "–"
    if key.startswith("angle"):
        return f"{v:.2f}"
    if key.startswith("dist"):
        return f"{v:.3f}"
    return f"{v:.3f}"


def report_csv(report: EvalReport) -> str:
    """Long-format CSV: ``model, category, n_shapes, n_joints, <metrics>`` (empty for NaN)."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    keys = [k for k, _, _ in METRICS]
    w.writerow(["model", "category", "n_shapes", "n_joints", *keys])
    for m in report.models:
        for c in [*report.categories, "mean", "all"]:
            row = report.table.get((m, c))
            if row is None:
                continue
            vals = ["" if (isinstance(row[k], float) and math.isnan(row[k])) else f"{row[k]:.6g}"
                    for k in keys]
            w.writerow([m, c, int(row["n_shapes"]), int(row["n_joints"]), *vals])
    return buf.getvalue()


def report_markdown(report: EvalReport, paper: bool = True) -> str:
    """One Markdown table per metric: categories as rows, models as columns.

    With ``paper``, a final table sets the models' mean angle and distance errors next to
    the paper's (:data:`PAPER_MEANS`).
    """
    lines: list[str] = []
    cats = [*report.categories, "mean", "all"]
    for key, header, higher in METRICS:
        lines += [f"### {header} ({'higher' if higher else 'lower'} is better)", ""]
        lines.append("| category | n | " + " | ".join(report.models) + " |")
        lines.append("|---|---:|" + "---:|" * len(report.models))
        for c in cats:
            n = report.table.get((report.models[0], c), {}).get("n_shapes", 0)
            cells = [_fmt(key, report.table[(m, c)][key]) if (m, c) in report.table else "–"
                     for m in report.models]
            name = f"**{c}**" if c in ("mean", "all") else c
            lines.append(f"| {name} | {int(n)} | " + " | ".join(cells) + " |")
        lines.append("")
    if paper:
        lines += ["### Means next to the paper (Liu et al. 2023, Table 1)", "",
                  "| model | rows | angle err edges (deg) | angle err joints (deg) "
                  "| dist edges (/diag) | line dist joints (/diag) | paper angle (deg) "
                  "| paper distance |",
                  "|---|---|---:|---:|---:|---:|---:|---:|"]
        for m in report.models:
            ref = PAPER_MEANS.get(m, {})
            for agg in ("mean", "all"):
                row = report.table[(m, agg)]
                lines.append(
                    f"| {m} | {agg} | {_fmt('angle', row['angle_edge'])} "
                    f"| {_fmt('angle', row['angle_joint'])} | {_fmt('dist', row['dist_edge'])} "
                    f"| {_fmt('dist', row['dist_joint'])} | {ref.get('angle', '–')} "
                    f"| {ref.get('distance', '–')} |"
                )
        lines.append("")
    return "\n".join(lines)


def write_report(report: EvalReport, out: str | Path) -> dict[str, Path]:
    """Write ``table1.csv``, ``table1.md`` and ``shapes.csv`` (per shape) into ``out``."""
    out = Path(out)
    write_text(out / "table1.csv", report_csv(report))
    write_text(out / "table1.md", report_markdown(report))
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["model", "shape_id", "category", "n_edges", "edges_correct", "n_true", "n_pred",
                "n_matched", "angle_joint", "dist_joint"])
    for m, rows in report.shapes.items():
        for r in rows:
            w.writerow([m, r.shape_id, r.category, r.n_edges, r.edges_correct, r.n_true,
                        r.n_pred, r.n_matched, _fmt("angle", _nanmean(r.angle_joint)),
                        _fmt("dist", _nanmean(r.dist_joint))])
    write_text(out / "shapes.csv", buf.getvalue())
    return {"csv": out / "table1.csv", "markdown": out / "table1.md", "shapes": out / "shapes.csv"}


def _model_names(runs: Sequence) -> list[str]:
    names: list[str] = []
    for r in runs:
        base = f"GNN_{r.types}"
        names.append(base if base not in names else f"{base}_{r.path.name}")
    return names


def _load_graphs(data: Path, progress: bool) -> list[PartGraph]:
    from kinmo.train.gnn import load_cache

    if (data / "manifest.csv").is_file() or any(data.glob("*.npz")):
        return load_cache(data)
    from rich.progress import Progress

    from kinmo.data.build import build_graph
    from kinmo.data.readers import find_shapes, read_shape

    folders = find_shapes(data)
    out = []
    with Progress(disable=not progress) as bar:
        task = bar.add_task("build graphs", total=len(folders))
        for f in folders:
            out.append(build_graph(read_shape(f)))
            bar.advance(task)
    return out


def run_evaluation(
    models: Sequence[str | Path],
    data: str | Path,
    out: str | Path | None = None,
    split: str | Path | None = None,
    all_shapes: bool = False,
    render: bool = False,
    device: str = "auto",
    progress: bool = True,
    console=None,
    axis_model: str | Path | None = None,
    refine_config=None,
) -> tuple[EvalReport, dict[str, Path]]:
    """Evaluate trained motion GNNs on the test shapes of ``data`` (``kinmo eval pre-segmented``).

    Parameters
    ----------
    models : sequence of str or Path
        Run folders; a fine and a coarse run give the ``GNN_fine`` and ``GNN_coarse`` columns.
    data : str or Path
        A part-graph cache (``kinmo prepare``) or a PartNet-Mobility dataset folder.
    out : str or Path, optional
        Output folder (default ``<first run>/eval``).
    split : str or Path, optional
        Split file (default: the first run's ``split.json``): every labelled shape of ``data``
        that is not one of its ``train`` ids is evaluated, i.e. the test split on the models'
        own data and every new shape on another folder (as ``kinmo eval --category C --data
        DIR``).
    all_shapes : bool
        Evaluate every labelled graph of ``data``, training shapes included.
    render : bool
        Write ``out/renders/<model>/<id>.png`` per shape, and the predicted links as
        ``out/viewers/<model>/<id>/`` (:func:`kinmo.view.write_view_links`) for the
        report's interactive viewer.
    device : str
    progress : bool
    console : rich.console.Console, optional
        Where to print the per-model tables (not printed without one).
    axis_model : str or Path, optional
        Run folder of ``kinmo train axis``: adds, for every ``GNN_<types>`` column, an
        ``OBB_<types>`` column with the axes refined by the axis-selection network (the
        paper's Table 1 "OBB" rows; :func:`kinmo.refine.refine.refine_shape_prediction`).
    refine_config : kinmo.refine.refine.RefineConfig, optional
        Options of that refinement (default: the paper's weights 0.5 / 0.3 / 0.2;
        ``scoring.feasibility_only`` for the paper code's network-only selection).

    Returns
    -------
    (EvalReport, dict of str to Path)
        The report and the written files (:func:`write_report`).

    Raises
    ------
    KinmoDataError
        No model, unreadable runs or split, or no labelled test graph.
    """
    from kinmo.errors import KinmoDataError
    from kinmo.predict import predict_graphs
    from kinmo.train.gnn import load_run
    from kinmo.train.split import Split

    if not models:
        raise KinmoDataError("--model", "give at least one run folder")
    runs = [load_run(m, device) for m in models]
    data = Path(data)
    graphs = [g for g in _load_graphs(data, progress) if g.has_labels and g.meta.get("links")]
    if not all_shapes:  # every shape the models did not train on (on their data: the test split)
        sp = Path(split) if split is not None else runs[0].path / "split.json"
        train = set(Split.load(sp).train)
        refused = sorted(g.shape_id for g in graphs if g.shape_id in train)
        graphs = [g for g in graphs if g.shape_id not in train]
        if not graphs:
            raise KinmoDataError(data, f"no labelled shape the models did not train on ({len(refused)} training "
                                       "shapes of the split left out; --all evaluates them too)")
    if not graphs:
        raise KinmoDataError(data, "no labelled test shape to evaluate")
    names = _model_names(runs)
    preds = {n: predict_graphs(r, graphs) for n, r in zip(names, runs)}
    if axis_model is not None:
        from kinmo.refine.refine import refine_shape_prediction
        from kinmo.refine.train import load_axis_model

        net = None  # a folder with only a ranker.json: the learned selector needs no network
        if not (Path(axis_model).is_dir() and not (Path(axis_model) / "model.pt").is_file()
                and getattr(refine_config, "selector", "paper") == "ranker"):
            net = load_axis_model(axis_model,
                                  "cpu" if runs[0].device.type == "cpu" else str(runs[0].device))
        for n in list(preds):
            preds[n.replace("GNN_", "OBB_", 1)] = [refine_shape_prediction(p, net, refine_config)[0]
                                                  for p in preds[n]]
    report = evaluate_graphs(graphs, preds)
    out = Path(out) if out is not None else runs[0].path / "eval"
    paths = write_report(report, out)
    if render:
        from kinmo.viz import render_prediction

        from kinmo.view import write_view_links

        for n, plist in preds.items():
            for p in plist:
                render_prediction(p, out / "renders" / n / f"{p.shape_id}.png")
                if p.graph.meta.get("source") and Path(p.graph.meta["source"]).is_dir():
                    try:  # the interactive gallery of the report (kinmo.view.gallery_page)
                        write_view_links(out / "viewers" / n / p.shape_id, p.tree.links,
                                         p.graph.meta["source"])
                    except KinmoDataError:
                        pass  # the source changed since the cache was built: no viewer
    if console is not None:
        print_report(report, console)
    return report, paths


def print_report(report: EvalReport, console) -> None:
    """Print one rich table per model (categories as rows, metrics as columns)."""
    from rich.table import Table

    for m in report.models:
        t = Table(title=f"{m}: pre-segmented motion prediction (Table 1)",
                  caption="acc: type accuracy over sibling edges / moving edges / matched joints; "
                          "prec, rec: mobile-part detection (IoU >= 0.5); ang: axis angle error "
                          "(deg); dist: axis distance / bbox diagonal; e: edges, j: joints")
        t.add_column("category", no_wrap=True)
        t.add_column("n", justify="right")
        for key, _, _ in METRICS:
            t.add_column(SHORT[key], justify="right", no_wrap=True)
        for c in [*report.categories, "mean", "all"]:
            row = report.table.get((m, c))
            if row is None:
                continue
            t.add_row(c if c not in ("mean", "all") else f"[bold]{c}[/]", str(int(row["n_shapes"])),
                      *[_fmt(k, row[k]) for k, _, _ in METRICS])
        console.print(t)
