"""Evaluation on pre-segmented shapes (Liu et al. 2023, Table 1, GNN rows): the run.

:func:`run_evaluation` (``kinmo eval pre-segmented``) predicts the test shapes with every
model (and, with an axis model, refines them: the "OBB" rows), evaluates them
(:mod:`kinmo.evaluate.shape_metrics`: edge- and joint-level metrics, per category, ``mean``
and ``all`` rows) and writes and prints the tables (:mod:`kinmo.evaluate.tables`). The names
of both modules are re-exported here.
"""

from __future__ import annotations

from collections.abc import Collection, Sequence
from pathlib import Path

from kinmo.data.build import build_graph
from kinmo.data.cache import load_cache
from kinmo.data.graph import PartGraph
from kinmo.data.readers import find_shapes, read_shape
from kinmo.errors import KinmoDataError
from kinmo.evaluate.shape_metrics import (
    EvalReport,
    METRICS,
    ShapeEval,
    aggregate,
    build_report,
    evaluate_graphs,
    evaluate_shape,
    gt_links,
    match_links,
)
from kinmo.evaluate.tables import (
    PAPER_MEANS,
    SHORT,
    print_report,
    report_csv,
    report_markdown,
    write_report,
)
from kinmo.inference.gnn import predict_graphs
from kinmo.inference.predictor import Predictor
from kinmo.train.gnn import load_run
from kinmo.train.split import Split

__all__ = [
    "METRICS",
    "PAPER_MEANS",
    "SHORT",
    "EvalReport",
    "ShapeEval",
    "aggregate",
    "build_report",
    "evaluate_graphs",
    "evaluate_shape",
    "gt_links",
    "match_links",
    "print_report",
    "report_csv",
    "report_markdown",
    "run_evaluation",
    "write_report",
]


def _model_names(runs: Sequence) -> list[str]:
    names: list[str] = []
    for r in runs:
        base = f"GNN_{r.types}"
        names.append(base if base not in names else f"{base}_{r.path.name}")
    return names


def _load_graphs(data: Path, progress: bool) -> list[PartGraph]:
    if (data / "manifest.csv").is_file() or any(data.glob("*.npz")):
        return load_cache(data)
    from rich.progress import Progress

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
    exclude: Collection[str] = (),
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
        Evaluate every labelled graph of ``data``, training shapes of the split included
        (never those of ``exclude``).
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

    exclude : collection of str
        Ids always left out, ``--all`` or not: a model bundle's ``trained_on``
        (:attr:`kinmo.inference.bundle.ModelBundle.trained_on`), so that no bundle is scored
        on its own training objects. Without ``split``, a run whose ``split.json`` is
        missing is then evaluated on every other labelled shape.

    Raises
    ------
    KinmoDataError
        No model, unreadable runs or split, or no labelled test graph.
    """

    if not models:
        raise KinmoDataError("--model", "give at least one run folder")
    runs = [load_run(m, device) for m in models]
    data = Path(data)
    graphs = [g for g in _load_graphs(data, progress) if g.has_labels and g.meta.get("links")]
    if exclude:
        n_all, excluded = len(graphs), set(exclude)
        graphs = [g for g in graphs if g.shape_id not in excluded]
        if not graphs:
            raise KinmoDataError(data, f"all {n_all} labelled shapes here are ones the model bundle was "
                                       "trained on: evaluate it on other objects")
        if console is not None and n_all > len(graphs):
            console.print(f"left out {n_all - len(graphs)} shape(s) the model bundle was trained on",
                          markup=False, highlight=False)
    sp = Path(split) if split is not None else runs[0].path / "split.json"
    if not all_shapes and (split is not None or sp.is_file() or not exclude):
        # every shape the models did not train on (on their data: the test split)
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
        refined = [Predictor.from_parts(r, axis_model, refine_config) for r in runs]
        for (n, plist), pr in zip(list(preds.items()), refined):
            preds[n.replace("GNN_", "OBB_", 1)] = [pr.refine_prediction(p) for p in plist]
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
