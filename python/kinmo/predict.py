"""Predict the motion of pre-segmented shapes with a trained motion GNN (``kinmo predict``).

For every shape (a PartNet or PartNet-Mobility folder with its part hierarchy), the part
graph is built (:func:`kinmo.data.build.build_graph`, or read from a ``kinmo prepare`` cache),
the motion GNN predicts every sibling edge's motion type and axis (Liu et al. 2023,
Sec. 3.2), :mod:`kinmo.mobility_tree` turns them into links and joints, and the result is
written as ``OUT/<id>/``:

- ``mobility_v2.json``: PartNet-Mobility's own format (links listing PartNet node ids,
  ``free``/``hinge``/``slider``/``static`` joints, axis origin and direction in the mesh
  frame, limits), readable by :func:`kinmo.data.readers.read_links`;
- ``semantics.txt``: ``link_<id> <joint> <name>`` per link;
- ``mobility.urdf``: the URDF (:mod:`kinmo.export.urdf`), meshes referenced relative to
  it, convex collision pieces in ``collision/``, loadable in PyBullet with the predicted
  joints moving;
- with ``formats``: any other format of :mod:`kinmo.export` (MJCF, USD, glTF);
- ``edges.json``: per sibling edge, the moving and reference node ids, the predicted type and
  probabilities of every type, and the predicted axis (mesh frame).

A summary ``OUT/predictions.csv`` lists every shape with its status (``ok``/``failed``
with the one-line reason) and the number of predicted moving links.

Shapes are independent: ``workers`` processes (``kinmo predict DIR -j N``, the local
``spawn`` pool or Ray through :mod:`kinmo.executor`) predict them at once, each with the
caller's predictor, and write the same files as one process.

Frames: every output coordinate is in the mesh frame of the input OBJ files (y-up), mesh units.
"""

from __future__ import annotations

import csv
import json
import io
from collections.abc import Callable, Iterator, Mapping, Sequence
from dataclasses import dataclass, field
from functools import partial
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.data.build import MeshesOnce, build_graph
from kinmo.data.cache import cached_graph, manifest_rows
from kinmo.data.graph import PartGraph
from kinmo.data.model import PartHierarchy, PartNode, Shape, ShapeFormat
from kinmo.data.readers import find_shapes, read_shape
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.executor import map_unordered, parse_executor
from kinmo.export import DEFAULT_FORMATS, export
from kinmo.export.collision import DEFAULT_COLLISION
from kinmo.inference.gnn import infer_edges, infer_edges_with_priors, predict_graphs
from kinmo.inference.predictor import Predictor
from kinmo.io import atomic_path, check_outputs_apart, output_dir, staged_folder, write_text
from kinmo.refine.selector import graph_meshes
from kinmo.mobility_tree import ShapePrediction, TreeOptions, consistent_fine
from kinmo.parallel import resolve_workers, single_threaded_worker, torch_threads
from kinmo.progress import CountingBar
from kinmo.stages import cache_key, worker_error
from kinmo.train.gnn import Run
from kinmo.viz import render_prediction

__all__ = [
    "PredictRow",
    "consistent_fine",
    "ShapePrediction",
    "edges_json",
    "write_edges_json",
    "hierarchy_from_graph",
    "infer_edges",
    "infer_edges_with_priors",
    "predict_dataset",
    "predict_graphs",
    "write_prediction",
]


def hierarchy_from_graph(graph: PartGraph) -> PartHierarchy:
    """The part hierarchy (ids, names, parent-child links) stored in a part graph.

    Leaves get no mesh names (a part graph does not keep them).
    """
    ids = [int(x) for x in graph.node_ids]
    kids: dict[int, list[int]] = {i: [] for i in ids}
    for n, p in enumerate(graph.parent):
        if p >= 0:
            kids[ids[int(p)]].append(ids[n])
    nodes = {}
    for n, nid in enumerate(ids):
        p = int(graph.parent[n])
        nodes[nid] = PartNode(nid, graph.node_names[n], graph.node_names[n], tuple(kids[nid]), (),
                              ids[p] if p >= 0 else None)
    roots = [ids[n] for n in range(len(ids)) if graph.parent[n] < 0]
    return PartHierarchy(nodes, roots[0] if roots else ids[0], ids)


def _edge_rows(pred: ShapePrediction) -> Iterator[dict]:
    """The ``edges`` rows of :func:`edges_json`, one at a time."""
    g = pred.graph
    e = np.asarray(g.sibling_edges, dtype=np.int64).reshape(-1, 2)
    names = pred.type_names
    for k, (i, j) in enumerate(e):
        p = pred.edges.probs[k]
        t = int(np.argmax(p))
        yield {
            "moving": int(g.node_ids[i]),
            "reference": int(g.node_ids[j]),
            "type": names[t],
            "confidence": round(float(p[t]), 6),
            "probs": {n: round(float(x), 6) for n, x in zip(names, p)},
            "axis": {
                "origin": [round(float(x), 6) for x in pred.edges.origin[k]],
                "direction": [round(float(x), 6) for x in pred.edges.direction[k]],
            },
        }


def edges_json(pred: ShapePrediction) -> dict:
    """The ``edges.json`` document of a prediction.

    Returns
    -------
    dict
        ``{"shape_id", "frame": "mesh (y-up)", "types": [...], "edges": [{"moving",
        "reference" (PartNet node ids), "type", "confidence", "probs" {type: p}, "axis"
        {"origin", "direction"}}]}``. ``confidence`` is the probability of the arg-max type.
    """
    g = pred.graph
    return {"shape_id": g.shape_id, "frame": "mesh (y-up)", "types": list(pred.type_names),
            "edges": list(_edge_rows(pred))}


def write_edges_json(pred: ShapePrediction, path: str | Path) -> Path:
    """Write :func:`edges_json` to ``path`` atomically, one edge row per line, streamed: a flat
    500-part asset has 249,500 sibling edges, whose rows never sit in memory at once
    (issue 21, finding 4)."""
    path = Path(path)
    head = {"shape_id": pred.graph.shape_id, "frame": "mesh (y-up)", "types": list(pred.type_names)}
    with atomic_path(path) as tmp, open(tmp, "w", encoding="utf-8") as f:
        f.write(json.dumps(head)[:-1] + ', "edges": [')
        for k, row in enumerate(_edge_rows(pred)):
            f.write(("\n" if k == 0 else ",\n") + json.dumps(row))
        f.write("\n]}\n")
    return path


def write_prediction(pred: ShapePrediction, out_dir: str | Path, shape: Shape | None = None,
                     formats: Sequence[str] | None = None, progress: bool = True,
                     collision: str = DEFAULT_COLLISION,
                     meshes: Mapping[str, tuple[np.ndarray, np.ndarray]]
                     | Callable[[], Mapping[str, tuple[np.ndarray, np.ndarray]]] | None = None,
                     ) -> dict[str, Path]:
    """Write one shape's outputs (module docstring) into ``out_dir``.

    Parameters
    ----------
    pred : ShapePrediction
    out_dir : str or Path
        Created if needed.
    shape : Shape, optional
        The shape as read (:func:`kinmo.data.readers.read_shape`); needed for the formats
        with geometry (URDF, MJCF, USD, glTF: its meshes) and gives the part names. Without
        it only ``mobility_v2`` and ``semantics`` are written.
    formats : sequence of str, optional
        Export formats (:mod:`kinmo.export`); default
        :data:`kinmo.export.DEFAULT_FORMATS` (``mobility_v2``, ``semantics``, ``urdf``).
    progress : bool
        Show the exporters' progress bars (convex decomposition of objects with many links).
    collision : str
        Collision geometry of URDF / MJCF (:mod:`kinmo.export.collision`).
    meshes : mapping of str to (vertices, faces), or a callable returning one, optional
        ``shape``'s meshes by name when the caller reads them (:func:`kinmo.export.export`).

    Returns
    -------
    dict of str to Path
        Format name -> its main file (``mobility_v2``, ``semantics``, ``urdf``, ``mjcf``,
        ``usd``, ``gltf`` as written) and ``edges``.
    """

    out_dir = Path(out_dir)
    out_dir.mkdir(parents=True, exist_ok=True)
    fmts = list(DEFAULT_FORMATS if formats is None else formats)
    if shape is None:
        fmts = [f for f in fmts if f in ("mobility_v2", "semantics")]
        shape = Shape(pred.shape_id, "unknown", ShapeFormat.PARTNET, out_dir, out_dir,
                      hierarchy_from_graph(pred.graph))
    files = export(shape, out_dir, fmts, links=pred.tree.links, name=shape.id, progress=progress,
                   collision=collision, meshes=meshes)
    paths = {f: written[0] for f, written in files.items()}
    write_edges_json(pred, out_dir / "edges.json")
    paths["edges"] = out_dir / "edges.json"
    return paths


@dataclass
class PredictRow:
    """One line of ``predictions.csv``."""

    id: str
    status: str
    n_links: int = 0
    n_moving: int = 0
    error: str = ""
    outputs: dict[str, Path] = field(default_factory=dict)


def _summary_csv(rows: list[PredictRow]) -> str:
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow(["id", "status", "n_links", "n_moving", "error"])
    for r in rows:
        w.writerow([r.id, r.status, r.n_links, r.n_moving, r.error])
    return buf.getvalue()


def predict_dataset(
    data: str | Path,
    run: str | Path | Run | Predictor,
    out: str | Path,
    cache: str | Path | None = None,
    device: str = "auto",
    options: TreeOptions = TreeOptions(),
    progress: bool = True,
    render: bool = False,
    axis_model: str | Path | None = None,
    refine_config=None,
    formats: Sequence[str] | None = None,
    collision: str = DEFAULT_COLLISION,
    workers: int = 1,
    executor: str = "local",
) -> list[PredictRow]:
    """Predict every shape folder below ``data`` and write ``out/<id>/`` (module docstring).

    Parameters
    ----------
    data : str or Path
        A dataset root (or one shape folder), PartNet or PartNet-Mobility format.
    run : str, Path, Run or Predictor
        Run folder of ``kinmo train gnn`` (or a loaded run), refined as ``axis_model`` and
        ``refine_config`` say (:meth:`kinmo.inference.predictor.Predictor.from_parts`); or a
        :class:`~kinmo.inference.predictor.Predictor` (then those are ignored).
    out : str or Path
        Output folder.
    cache : str or Path, optional
        A ``kinmo prepare`` cache of ``data``: graphs are read from it instead of being built
        (a shape missing from it is built).
    device : str
    options : TreeOptions
    progress : bool
    render : bool
        Also write ``out/<id>/prediction.png`` (:func:`kinmo.viz.render_prediction`).
    axis_model : str or Path, optional
        Run folder of ``kinmo train axis``: refine every moving edge's axis with the
        axis-selection network (Liu et al. 2023, Sec. 3.3;
        :func:`kinmo.refine.refine.refine_shape_prediction`) before writing.
    refine_config : kinmo.refine.refine.RefineConfig, optional
        Options of that refinement (default: the paper's scoring).
    formats : sequence of str, optional
        Export formats per shape (:func:`write_prediction`).
    collision : str
        Collision geometry of URDF / MJCF (:mod:`kinmo.export.collision`).
    workers : int
        Worker processes (1: in this process; 0: one per CPU). Each worker gets the
        predictor once (pickled: about 1 MB for the pretrained bundle) and runs torch and
        rayon on one thread; this process runs torch on one thread during the run too, so
        every worker count writes the same files.
    executor : str
        ``local``, ``ray``, ``ray:auto`` or ``ray:ADDRESS`` (:mod:`kinmo.executor`).

    Returns
    -------
    list of PredictRow
        One per shape folder, in the folders' order; failed shapes (and shapes whose worker
        died) are reported, not raised.

    Raises
    ------
    KinmoDataError
        ``data`` holds no shape folder, ``out`` is a file, or the run cannot be loaded.
    KinmoUsageError
        ``out`` is, or lies inside, ``data`` or ``cache``, or holds them where it would write
        (:func:`kinmo.io.check_outputs_apart`): outputs never overwrite inputs.
    """
    data = Path(data)
    folders = find_shapes(data)
    check_outputs_apart(out, [data, *([cache] if cache is not None else [])],
                        written=[*(f.name for f in folders), "predictions.csv"])
    out = output_dir(out)
    predictor = run if isinstance(run, Predictor) else Predictor.from_parts(
        run, axis_model, refine_config, options, device)
    if not folders:
        raise KinmoDataError(data, "no shape folder found")
    job = _Job(out, data, None if cache is None else Path(cache), formats, collision, render)
    # 0: one per CPU; never more processes than shapes
    workers = resolve_workers(workers, len(folders)) if workers >= 0 else 1
    in_process = workers == 1 and parse_executor(executor).kind == "local"
    found: dict[Path, PredictRow] = {}
    with CountingBar(len(folders), progress, "predict", "shapes") as bar:
        def record(folder: Path, row: PredictRow) -> None:
            found[folder] = row
            bar.advance(failed=int(row.status != "ok"))

        # one torch thread in this process too, as in every worker (_worker_init): torch's
        # reductions then add in the same order, and -j 1 writes the bytes -j N writes
        with torch_threads(1):
            if in_process:
                state = _worker_state(predictor, job.cache)
                for folder in folders:
                    record(folder, _predict_one(folder, job, progress, state))
            else:
                map_unordered(partial(_predict_one, job=job, progress=False), folders, workers,
                              record, _worker_failed, initializer=_worker_init,
                              initargs=(predictor, None if cache is None else str(cache)),
                              executor=executor)
    rows = [found[f] for f in folders]  # the folders' order, whatever the completion order
    write_text(out / "predictions.csv", _summary_csv(rows))
    return rows


@dataclass(frozen=True)
class _Job:
    """What every shape of one :func:`predict_dataset` run shares (picklable)."""

    out: Path
    root: Path
    cache: Path | None
    formats: Sequence[str] | None
    collision: str
    render: bool


#: The predictor (and the part-graph cache's manifest rows) of a worker process, set by
#: :func:`_worker_init`; a run in the calling process passes its own to :func:`_predict_one`.
_WORKER: dict[str, Any] = {}


def _worker_state(predictor: Predictor, cache: str | Path | None) -> dict[str, Any]:
    rows = None
    if cache is not None and Path(cache).is_dir():
        rows = manifest_rows(cache)
    return {"predictor": predictor, "cache_rows": rows}


def _worker_init(predictor: Predictor, cache: str | None) -> None:
    """A worker's start: one thread for torch and rayon, the predictor (sent once per
    worker, so every worker predicts with the same weights as the caller's)."""
    single_threaded_worker()
    _WORKER.update(_worker_state(predictor, cache))


def _worker_failed(folder: Path, e: Exception) -> PredictRow:
    # the worker raised or died (e.g. killed for memory)
    return PredictRow(folder.name, "failed", error=worker_error(folder, e))


def _predict_one(folder: Path, job: _Job, progress: bool,
                 state: Mapping[str, Any] | None = None) -> PredictRow:
    """Predict one shape folder and write ``job.out/<id>/`` (a staged folder, renamed into
    place whole); a :class:`~kinmo.errors.KinmoError` becomes a failed row. ``state``: the
    predictor and cache rows (:func:`_worker_state`); default this worker's."""
    state = _WORKER if state is None else state
    predictor: Predictor = state["predictor"]
    sid = folder.name
    try:
        shape = read_shape(folder)
        sid = shape.id
        named = MeshesOnce(shape)  # read once, shared by the graph, selector, exporters
        graph = _graph_for(folder, job.root, shape, job.cache, state["cache_rows"], named)
        pred = predictor.predict(graph, lambda g: graph_meshes(g, shape.hierarchy, named()))
        # written into a temporary sibling, renamed into place whole (issue 21,
        # finding 12: a reader never sees half an object)
        with staged_folder(job.out / sid) as tmp:
            paths = write_prediction(pred, tmp, shape, job.formats, progress, job.collision, named)
            if job.render:
                paths["png"] = render_prediction(pred, tmp / "prediction.png")
        paths = {k: job.out / sid / Path(v).relative_to(tmp) for k, v in paths.items()}
        return PredictRow(sid, "ok", len(pred.tree.links), len(pred.tree.moving_links), "", paths)
    except KinmoError as e:
        return PredictRow(sid, "failed", error=" ".join(str(e).split()))


def _graph_for(folder: Path, root: Path, shape: Shape, cache: str | Path | None,
               rows=None, named: MeshesOnce | None = None) -> PartGraph:
    """The shape's graph: from ``cache`` when its entry is current
    (:func:`kinmo.data.cache.cached_graph`: a stale or mismatched entry is rebuilt), else built."""
    if cache is not None:
        graph = cached_graph(cache, cache_key(folder, root), folder, rows)
        if graph is not None:
            return graph

    return build_graph(shape, meshes=None if named is None else named())
