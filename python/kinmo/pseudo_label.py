"""Pseudo-labels: PartNet shapes turned into PartNet-Mobility objects (Liu et al. 2023, Sec. 3).

The semi-weakly supervised part of the paper: a motion GNN trained on the few labelled
PartNet-Mobility objects predicts the motions of the many unlabelled PartNet shapes, the
refinement stage (:mod:`kinmo.refine`) snaps every predicted axis to a geometric candidate and
scores it, and the shapes whose every joint is confident enough become new training objects.

For every shape folder below ``DIR`` (:func:`kinmo.data.readers.find_shapes`):

1. read the shape and build its part graph (:func:`kinmo.data.build.build_graph`, or read it
   from a ``kinmo prepare`` cache);
2. predict every sibling edge's motion (:func:`kinmo.predict.infer_edges`), make the fine
   types agree with the predicted axes only with ``consistent=True``
   (:func:`kinmo.mobility_tree.consistent_fine`, as ``kinmo predict`` and ``kinmo eval
   pre-segmented`` do; off by default, see :class:`PseudoLabelConfig`) and refine the axes
   of the moving ones (:func:`kinmo.refine.refine.refine_predictions`);
3. build the mobility tree from the refined predictions
   (:func:`kinmo.mobility_tree.build_mobility_tree`; default limits: hinges 0–90°, sliders
   0–0.3 × part size);
4. keep the shape when it has at least one moving joint and the score of every moving joint
   is at least ``threshold``: the confidence of its refined line (its representative edge's,
   :mod:`kinmo.refine.scoring`) times the probability of its predicted type
   (:attr:`PseudoLabelConfig.score`);
5. with a second motion GNN (``check_run``; ``kinmo train all`` passes its coarse-type GNN),
   keep it only when that model agrees on every joint: it gives the joint's motion (``R``,
   ``P``, ``PR``) a probability of at least ``agree_prob`` and its refined axis lies within
   ``agree_deg`` of the joint's (:class:`PseudoLabelConfig`).

A kept shape becomes ``OUT/<id>/`` in the PartNet-Mobility format, read by kinmo (and by
PartNet-Mobility tools) exactly like a real object:

- ``result.json`` (the hierarchy file used, copied byte for byte; ``result_after_merging.json``
  too when present), ``meta.json`` (copied; written with ``model_cat`` and ``anno_id`` when the
  source has none);
- ``textured_objs/<name>.obj``: the shape's meshes, hard links to the source files (copies
  where the file system cannot link, or with ``link="copy"``; symbolic links with
  ``link="symlink"``, for a source dataset that stays in place): the folder is
  self-contained;
- ``mobility_v2.json``, ``semantics.txt`` (:mod:`kinmo.data.writers`), ``mobility.urdf``
  (meshes relative to it, convex collision pieces in ``collision/``) and any other format of
  :mod:`kinmo.export` chosen with ``formats`` (through :func:`kinmo.export.export`);
- ``scores.json``: the per-joint scores (refinement confidence, feasibility, direction and
  position agreement, type probability, candidate kind), the threshold and the models used.

Every shape's folder is assembled in ``OUT/.staging/`` and renamed into place, so ``OUT/<id>/``
is complete or absent. Each processed shape leaves a record ``OUT/.records/<id>.json``
(status, reason, scores, fingerprint of the source folder, models, the refinement's ranker and
range prior files, and options): a re-run skips shapes whose record is current, so an
interrupted run resumes, and a model or prior trained again at the same path makes every record
stale. ``OUT/shapes.csv`` lists every
shape (status ``kept``, ``no_moving_joint``, ``below_threshold``, ``disagreement`` or ``failed``
with the reason)
and ``OUT/summary.csv`` counts them per category. Shapes run in parallel worker processes
(``spawn`` or Ray; each loads the models once) through the stage machinery of
:mod:`kinmo.stages` (lock, resume, progress bar, worker-failure records).

Frames and units: mesh frame (y-up), mesh units; hinge limits in degrees.

Length: over 500 lines, about 30 % of them docstrings: the judgement of one shape
(:func:`pseudo_label_shape`), the folder it becomes, and its record and tables are one
topic; the run itself is :mod:`kinmo.stages`.
"""

from __future__ import annotations

import csv
import io
import json
import logging
import os
import shutil
import time
import uuid
from collections.abc import Callable, Mapping, Sequence
from dataclasses import asdict, dataclass, field, replace
from functools import partial
from pathlib import Path
from typing import TYPE_CHECKING, Any, Literal

import numpy as np
from pydantic import BaseModel, ConfigDict, Field, field_validator

from kinmo import stages
from kinmo.data.build import MeshesOnce, build_graph
from kinmo.data.cache import cached_graph
from kinmo.data.model import COARSE_INDEX
from kinmo.data.readers import HIERARCHY_FILES, read_shape
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.executor import parse_executor
from kinmo.export import export
from kinmo.export.collision import COLLISION_METHODS, DEFAULT_COLLISION
from kinmo.io import check_outputs_apart, write_json, write_text
from kinmo.metrics.axis import axis_angle_deg
from kinmo.mobility_tree import TreeOptions
from kinmo.parallel import resolve_workers, single_threaded_worker, torch_threads
from kinmo.refine.refine import RefineConfig
from kinmo.refine.selector import graph_meshes
from kinmo.stages import ShapeStage, cache_key, one_line, source_fingerprint

if TYPE_CHECKING:
    from kinmo.data.graph import PartGraph

logger = logging.getLogger(__name__)

__all__ = [
    "STATUSES",
    "PseudoLabelConfig",
    "PseudoLabelResult",
    "ShapeRecord",
    "judge",
    "pseudo_label_dataset",
    "pseudo_label_shape",
    "score_graph",
    "score_joints",
    "summary_rows",
]

#: Status of a processed shape.
STATUSES: tuple[str, ...] = ("kept", "no_moving_joint", "below_threshold", "disagreement", "failed")
SHAPE_COLUMNS: tuple[str, ...] = (
    "id", "category", "status", "reason", "n_moving", "min_score", "seconds", "source",
)
SUMMARY_COLUMNS: tuple[str, ...] = ("category", "shapes") + STATUSES
_RECORD_VERSION = 1


class PseudoLabelConfig(BaseModel):
    """Options of a pseudo-labelling run (part of every record's fingerprint).

    Attributes
    ----------
    threshold : float
        Minimum score of every moving joint of a kept shape.
    score : {"joint", "line"}
        A joint's score. ``joint`` (default): the refinement confidence of its line times the
        GNN's probability of its type, the chance that both are right when the two are taken
        as independent. ``line``: the refinement confidence alone (the rule before; it lets
        through parts wrongly predicted to move, whose type probability is low). On the 69
        labelled test objects of the shared data's split at 0.6 (``docs/results/
        pseudo_labels.md``): ``line`` keeps 67 with joint precision 0.856, type accuracy
        0.923 and axis error 9.09°; ``joint`` keeps 60 with 0.969, 0.930 and 8.79°.
    refine : RefineConfig
        Candidate, motion and scoring options.
    hinge_limit : (float, float)
        Fallback limits of predicted hinges (degrees), used where no range is predicted: the
        refinement has no range prior (``refine.ranges``), or the prior no group for the
        joint (issue 35, :mod:`kinmo.ranges`).
    slider_fraction : float
        Fallback of predicted sliders, likewise: ``0 .. slider_fraction * size`` (``size``:
        longest OBB side).
    sign : {"tree", "feasibility"}
        Direction of motion of a joint: the mobility tree's rule (away from the reference
        part) or the direction the axis-selection network found feasible.
    consistent : bool
        Make the fine types agree with the GNN's own axes before refining
        (:func:`kinmo.mobility_tree.consistent_fine`, as the evaluated predictor does). Default
        False (the paper's pipeline): the raw arg-max types, whose candidates may all be
        perpendicular to the GNN's axis (a ``P_V`` drawer with a horizontal axis scores
        direction agreement 0 and is rejected). That disagreement between the type and axis
        heads is what makes the threshold useful: on the 36 labelled test objects of
        ``docs/results/pseudo_labels.md`` the raw types keep 25 shapes whose joints err by
        8.9° on average and reject 11 at 27.3°, while consistent types keep 35 of 36 (11.9°).
    link : {"hardlink", "copy", "symlink"}
        How meshes get into ``textured_objs/``: ``hardlink`` (default; a copy where the file
        system cannot link, e.g. across devices) and ``copy`` make a self-contained folder
        that can be moved or sent; ``symlink`` links to the source files by absolute path, for
        datasets that stay in place (moving or deleting the source breaks the folder, and
        kinmo's own readers refuse meshes that resolve outside an object folder, so such a
        folder serves other tools, not ``kinmo prepare``/``render``).
    device : str
        Torch device of both networks.
    formats : tuple of str
        Export formats of a kept shape (:mod:`kinmo.export`); ``mobility_v2.json`` is always
        written (it makes the folder a PartNet-Mobility object).
    collision : str
        Collision geometry of URDF / MJCF (:mod:`kinmo.export.collision`; default ``parts``).
    agree_prob : float
        With a second model (``check_run`` of :func:`pseudo_label_dataset`): the least
        probability it gives a joint's motion (``R``, ``P``, ``PR``: the prefix of the
        joint's fine type; a fine-type model's probabilities are summed per motion).
    agree_deg : float
        With a second model: the largest angle (degrees, sign-free) between the joint's
        refined axis and the second model's refined axis of the same sibling edge.

        Why (issue 34): the confidence and the type probability cover one model's doubt, not
        its confident mistakes. Out of fold on the 235 labelled objects of the shared data
        (``docs/results/pseudo_labels.md``, session 23), at 0.6 the rule alone keeps 77 % with
        per-edge joint precision 0.955, type accuracy 0.931 and axis error 4.58°; with the
        coarse GNN's agreement (0.5, 20°) it keeps 66 % with 0.977, 0.965 and 3.77°. 0.5 asks
        that the second model's most likely motion be the joint's (0.5 to 0.8 keep the same
        objects but one there); the two refined axes are either within 1° or 90° apart, so
        any ``agree_deg`` from 10° to 30° keeps the same shapes there.
    """

    model_config = ConfigDict(extra="forbid")

    threshold: float = Field(0.6, ge=0.0, le=1.0)
    score: Literal["joint", "line"] = "joint"
    refine: RefineConfig = Field(default_factory=RefineConfig)
    hinge_limit: tuple[float, float] = (0.0, 90.0)
    slider_fraction: float = Field(0.3, gt=0)
    sign: Literal["tree", "feasibility"] = "tree"
    consistent: bool = False
    link: Literal["hardlink", "copy", "symlink"] = "hardlink"
    device: str = "cpu"
    formats: tuple[str, ...] = ("mobility_v2", "semantics", "urdf")
    collision: str = DEFAULT_COLLISION
    agree_prob: float = Field(0.5, ge=0.0, le=1.0)
    agree_deg: float = Field(20.0, ge=0.0, le=90.0)

    @field_validator("collision")
    @classmethod
    def _known_collision(cls, v: str) -> str:
        if v not in COLLISION_METHODS:
            raise ValueError(f"unknown collision method {v!r}; known: {', '.join(COLLISION_METHODS)}")
        return v


@dataclass
class ShapeRecord:
    """The outcome of one shape (a row of ``shapes.csv``, the content of its record).

    Attributes
    ----------
    id, category : str
    status : str
        One of :data:`STATUSES`.
    reason : str
        Why a shape was not kept (one line); empty when kept.
    n_moving : int
        Moving joints of the predicted mobility tree.
    min_score : float
        Lowest joint score (NaN without moving joints).
    seconds : float
    source : str
        The shape folder.
    joints : list of dict
        Per moving joint: link id, name, joint type, score and its terms.
    fingerprint : str
        Of the source folder, the models and the options.
    """

    id: str
    category: str
    status: str
    reason: str = ""
    n_moving: int = 0
    min_score: float = float("nan")
    seconds: float = 0.0
    source: str = ""
    joints: list[dict[str, Any]] = field(default_factory=list)
    fingerprint: str = ""


@dataclass
class PseudoLabelResult:
    """Outcome of :func:`pseudo_label_dataset`.

    Attributes
    ----------
    out : Path
    records : list of ShapeRecord
        Sorted by id.
    n_skipped : int
        Shapes whose record was current (not recomputed).
    seconds : float
    """

    out: Path
    records: list[ShapeRecord]
    n_skipped: int
    seconds: float

    def count(self, status: str) -> int:
        """Number of shapes with ``status``."""
        return sum(r.status == status for r in self.records)


# ----------------------------------------------------------------------------- fingerprints


def _models_fingerprint(gnn_run: Path, axis_run: Path, check_run: Path | None = None,
                        refine: Any = None) -> str:
    """Digest of the files that decide a shape's pseudo-label: the GNN, the axis network (or
    the ranker standing for it), the check model, and the refinement's ranker and range prior
    files (``refine.ranker`` / ``refine.ranges``), so that a record goes stale when any of them
    is trained again, even at the same path."""
    gnn = gnn_run / "model.pt" if gnn_run.is_dir() else gnn_run
    axis = axis_run / "model.pt" if axis_run.is_dir() else axis_run
    if axis_run.is_dir() and not axis.is_file() and (axis_run / "ranker.json").is_file():
        axis = axis_run / "ranker.json"  # a learned selector alone needs no axis network
    check = [] if check_run is None else [check_run / "model.pt" if check_run.is_dir() else check_run]
    for p in (gnn, axis, *check):
        if not p.is_file():
            raise KinmoDataError(p, "checkpoint is missing")
    files = [Path(f) for f in (getattr(refine, "ranker", None), getattr(refine, "ranges", None)) if f]
    return stages.digest(stages.file_fingerprint(gnn), stages.file_fingerprint(axis),
                         *(stages.file_fingerprint(p) for p in check),
                         *(stages.file_fingerprint(f) if f.is_file() else str(f) for f in files))


def _fingerprint(source_fp: str, models_fp: str, config: PseudoLabelConfig) -> str:
    return stages.json_digest([_RECORD_VERSION, source_fp, models_fp,
                               config.model_dump(mode="json")])


# ----------------------------------------------------------------------------- one shape


@dataclass
class _Models:
    predictor: Any
    models_fp: str
    gnn_path: str
    axis_path: str
    check: Any = None  # the second model's Predictor (PseudoLabelConfig.agree_prob), or None
    check_path: str = ""


_WORKER_MODELS: _Models | None = None


def _load_models(gnn_run: Path, axis_run: Path, device: str, refine: Any = None,
                 check_run: Path | None = None) -> _Models:
    """The models of one process that judges shapes (this one with ``-j 1``, else each
    worker): the only place this module reaches torch, so that the process which hands the
    shapes to a pool of workers starts them without importing it (issue 24). The second
    model (``check_run``) refines with the same axis network, selector and range prior."""
    from kinmo.inference.predictor import Predictor  # torch: in the processes that run models

    fp = _models_fingerprint(gnn_run, axis_run, check_run, refine)
    predictor = Predictor.from_parts(gnn_run, axis_run, refine, device=device)
    check = None if check_run is None else predictor.with_gnn(check_run, device)
    return _Models(predictor, fp, str(gnn_run), str(axis_run), check,
                   "" if check_run is None else str(check_run))


def _link_or_copy(src: Path, dst: Path, mode: str) -> None:
    """Put ``src`` at ``dst`` (a new path in a fresh staging folder) by ``mode``
    (:class:`PseudoLabelConfig`); a link that cannot be made becomes a copy."""
    try:
        if mode == "symlink":
            os.symlink(src.resolve(), dst)
            return
        if mode == "hardlink":
            os.link(src.resolve(), dst)
            return
    except OSError as e:
        logger.debug("cannot link %s (%s): copying it", src, e.strerror or e)
    shutil.copyfile(src, dst)


def _write_folder(
    stage: Path, shape, hierarchy_file: Path, links, records: list[dict[str, Any]],
    config: PseudoLabelConfig, models: _Models,
    meshes: Callable[[], Mapping[str, tuple[np.ndarray, np.ndarray]]] | None = None,
) -> None:
    """Assemble the PartNet-Mobility folder of a kept shape in ``stage`` (``meshes``: the
    shape's meshes by name, read once by :func:`pseudo_label_shape`)."""

    stage.mkdir(parents=True)
    shutil.copyfile(hierarchy_file, stage / "result.json")
    merged = shape.path / "result_after_merging.json"
    if merged.is_file() and merged.resolve() != hierarchy_file.resolve():
        shutil.copyfile(merged, stage / "result_after_merging.json")
    if (shape.path / "meta.json").is_file():
        shutil.copyfile(shape.path / "meta.json", stage / "meta.json")
    else:
        write_json(stage / "meta.json", {"model_cat": shape.category, "anno_id": shape.id})
    tex = stage / "textured_objs"
    tex.mkdir()
    names = {m for nid in shape.hierarchy.nodes for m in shape.hierarchy.nodes[nid].objs}
    for name in sorted(names):
        _link_or_copy(shape.mesh_path(name), tex / f"{name}.obj", config.link)
    export(shape, stage, ["mobility_v2"], links=links, name=shape.id, meshes=meshes)
    # the folder as kinmo reads it (validates the round trip)
    out_shape = read_shape(stage, external_links=config.link == "symlink")
    export(out_shape, stage, [f for f in config.formats if f != "mobility_v2"], name=shape.id,
           progress=False, collision=config.collision, meshes=meshes)  # same files, same names  # one bar: the dataset's
    write_json(stage / "scores.json", {
        "shape_id": shape.id,
        "category": shape.category,
        "source": str(shape.path),
        "threshold": config.threshold,
        "min_score": min(r["score"] for r in records),
        "joints": records,
        "models": {"gnn": models.gnn_path, "axis": models.axis_path,
                   **({"check": models.check_path} if models.check_path else {})},
        "options": config.model_dump(mode="json"),
        "frame": "mesh (y-up)",
    })


def _place(stage: Path, final: Path) -> None:
    """Move a staged folder onto ``final``, replacing an older one."""
    old = None
    if final.exists() or final.is_symlink():
        old = final.parent / ".staging" / f"old-{final.name}-{uuid.uuid4().hex[:8]}"
        os.replace(final, old)
    os.replace(stage, final)
    if old is not None:
        shutil.rmtree(old, ignore_errors=True)


def score_graph(predictor: Any, graph: PartGraph, config: PseudoLabelConfig, meshes: Any = None,
                check: Any = None) -> tuple[list[Any], list[dict[str, Any]]]:
    """Predict, refine and score one part graph as :func:`pseudo_label_shape` does.

    Parameters
    ----------
    predictor : kinmo.inference.predictor.Predictor
    graph : PartGraph
    config : PseudoLabelConfig
        ``consistent``, ``hinge_limit`` and ``slider_fraction`` shape the prediction;
        ``score`` and ``sign`` the scores (:func:`score_joints`).
    meshes : callable, ShapeMeshes or None
        The graph's leaf meshes for the refinement
        (:meth:`~kinmo.inference.predictor.Predictor.refine_with_details`); None: read from
        the graph's source folder.
    check : kinmo.inference.predictor.Predictor or None
        The second model (:class:`PseudoLabelConfig` ``agree_prob``): predicted and refined
        the same way, then compared joint by joint (:func:`score_joints`).

    Returns
    -------
    (links, joints)
        As :func:`score_joints`.
    """
    options = TreeOptions(tuple(config.hinge_limit), config.slider_fraction)
    gnn = predictor.gnn_predictions([graph], options, consistent=config.consistent)[0]
    sp, refined = predictor.refine_with_details(gnn, meshes=meshes, options=options)
    second = None
    if check is not None:
        g2 = check.gnn_predictions([graph], options, consistent=config.consistent)[0]
        second = check.refine_with_details(g2, meshes=meshes, options=options)[0]
    return score_joints(graph, sp, refined, config, second)


def score_joints(graph: PartGraph, sp: Any, refined: Any, config: PseudoLabelConfig,
                 second: Any = None) -> tuple[list[Any], list[dict[str, Any]]]:
    """Every predicted moving joint of a refined shape with its pseudo-label score.

    Parameters
    ----------
    graph : PartGraph
    sp : kinmo.mobility_tree.ShapePrediction
        The refined prediction (:meth:`kinmo.inference.predictor.Predictor.refine_with_details`).
    refined : kinmo.refine.refine.RefinedPredictions
        Its per-edge details.
    config : PseudoLabelConfig
        ``score``, ``sign``, ``agree_prob`` and ``agree_deg`` are used.
    second : kinmo.mobility_tree.ShapePrediction or None
        A second model's refined prediction of the same graph. Each joint then gets
        ``check_prob`` (that model's probability of the joint's motion ``R``/``P``/``PR``),
        ``check_axis_deg`` (the sign-free angle between the two refined axes of its sibling
        edge) and ``check_agrees`` (both within :class:`PseudoLabelConfig`'s bounds), which
        :func:`judge` requires.

    Returns
    -------
    links : list of Link
        The tree's links (axes turned to the feasible direction with ``sign="feasibility"``).
    joints : list of dict
        One per moving link, in link order, as written to the shape's record (``"link"``:
        the link id; its sibling edge is ``sp.tree.link_edge[link]``).
    """
    tree, tree_pred, type_names = sp.tree, sp.edges, refined.type_names
    links = list(tree.links)
    joints: list[dict[str, Any]] = []
    for n, lk in enumerate(links):
        if not lk.joint.is_moving:
            continue
        k = tree.link_edge[lk.id]
        det = refined.details.get(int(k))
        if det is None or det.scores.best < 0:  # not refined, or no candidate: score 0
            score, terms = 0.0, {}
        else:
            b = det.scores.best
            score = float(det.confidence)
            terms = {"feasibility": float(det.scores.feasibility[b]),
                     "direction_agreement": float(det.scores.direction[b]),
                     "position_agreement": float(det.scores.position[b]),
                     "candidate": det.kind, "n_candidates": len(det.candidates)}
            if config.sign == "feasibility":
                lim = lk.joint.limit
                if lim is not None and float(np.dot(det.direction, lk.joint.direction)) < 0:
                    lim = (-lim[1], -lim[0])  # the range follows the axis' sign
                links[n] = replace(lk, joint=replace(lk.joint, direction=det.direction.copy(), limit=lim))
        i, j = (int(x) for x in graph.sibling_edges[k])
        type_prob = float(np.max(tree_pred.probs[k]))
        ftype = type_names[int(np.argmax(tree_pred.probs[k]))]
        if second is not None:
            motion = COARSE_INDEX[ftype.split("_")[0]]
            check_prob = float(second.edges.coarse()[k, motion])
            check_deg = float(axis_angle_deg(links[n].joint.direction, second.edges.direction[k]))
            terms["check_prob"], terms["check_axis_deg"] = check_prob, check_deg
            terms["check_agrees"] = bool(check_prob >= config.agree_prob and check_deg <= config.agree_deg)
        joints.append({
            "link": lk.id, "name": lk.name, "joint": lk.joint.type.value,
            "rotates": bool(lk.joint.rotates),
            "type": ftype,
            "type_prob": type_prob,
            "moving_node": int(graph.node_ids[i]), "reference_node": int(graph.node_ids[j]),
            "line_confidence": score,
            "score": score * type_prob if config.score == "joint" else score, **terms,
        })
    return links, joints


def judge(joints: Sequence[dict[str, Any]], threshold: float) -> tuple[str, str]:
    """The pseudo-label decision for a shape's scored joints (:func:`score_joints`).

    Returns
    -------
    (status, reason)
        ``("kept", "")`` when every joint scores ``>= threshold`` and no joint has
        ``check_agrees`` False (a second model disagreeing, :func:`score_joints`);
        ``no_moving_joint``, ``below_threshold`` or ``disagreement`` with a one-line reason
        otherwise.
    """
    if not joints:
        return "no_moving_joint", "no moving joint predicted"
    low = [j for j in joints if not j["score"] >= threshold]
    if low:
        worst = min(low, key=lambda j: j["score"])
        return "below_threshold", (f"{len(low)} of {len(joints)} joints below {threshold:g} "
                                   f"(lowest: link {worst['link']} {worst['name']!r} {worst['score']:.3f})")
    off = [j for j in joints if j.get("check_agrees") is False]
    if not off:
        return "kept", ""
    j = off[0]
    return "disagreement", (f"{len(off)} of {len(joints)} joints not confirmed by the second model "
                            f"(link {j['link']} {j['name']!r}: its motion's probability "
                            f"{j['check_prob']:.2f}, axes {j['check_axis_deg']:.0f}° apart)")


def pseudo_label_shape(
    folder: str | Path,
    out: str | Path,
    models: _Models,
    config: PseudoLabelConfig,
    cache: str | Path | None = None,
    root: str | Path | None = None,
) -> ShapeRecord:
    """Predict, refine, judge and (if kept) write one shape (module docstring).

    Parameters
    ----------
    folder : str or Path
        A PartNet (or PartNet-Mobility) shape folder.
    out : str or Path
        The output root: the shape becomes ``out/<id>/``.
    models : _Models
        Loaded networks (:func:`pseudo_label_dataset` loads them).
    config : PseudoLabelConfig
    cache : str or Path, optional
        A ``kinmo prepare`` cache of ``root`` to read the part graph from.
    root : str or Path, optional
        The dataset root (for cache keys).

    Returns
    -------
    ShapeRecord
        Bad input gives status ``failed`` with the reason; nothing is raised for it.
    """

    t0 = time.perf_counter()
    folder = Path(folder)
    out = Path(out)
    rec = ShapeRecord(id=folder.name, category="unknown", status="failed", source=str(folder))
    try:
        rec.fingerprint = _fingerprint(source_fingerprint(folder), models.models_fp, config)
        shape = read_shape(folder)
        rec.id, rec.category = shape.id, shape.category
        # the shape's meshes: read once, when first needed (part graph, the selector's
        # sweep, the exporters), and passed down
        named = MeshesOnce(shape)

        graph = None
        if cache is not None:
            graph = cached_graph(cache, cache_key(folder, root or folder.parent), folder)
        if graph is None:
            if cache is not None:
                logger.debug("%s: not in the cache %s, building its part graph", folder, cache)
            graph = build_graph(shape, meshes=named())
        links, joints = score_graph(models.predictor, graph, config,
                                    meshes=lambda g: graph_meshes(g, shape.hierarchy, named()),
                                    check=models.check)
        rec.joints = joints
        rec.n_moving = len(joints)
        rec.status, rec.reason = judge(joints, config.threshold)
        if joints:
            rec.min_score = min(j["score"] for j in joints)
        if rec.status == "kept":
            hfile = next((shape.path / h for h in HIERARCHY_FILES
                          if (shape.path / h).is_file()), None)
            if hfile is None:
                raise KinmoDataError(shape.path, "no hierarchy file")
            stage = out / ".staging" / f"{shape.id}-{uuid.uuid4().hex[:8]}"
            try:
                _write_folder(stage, shape, hfile, links, joints, config, models, named)
                _place(stage, out / shape.id)
            finally:
                if stage.exists():
                    shutil.rmtree(stage, ignore_errors=True)
    except (KinmoError, OSError, ValueError) as e:
        rec.status, rec.reason = "failed", one_line(e)
    except Exception as e:  # keep a long batch going; the reason names the error type
        rec.status, rec.reason = "failed", one_line(f"internal error: {type(e).__name__}: {e}")
    rec.seconds = time.perf_counter() - t0
    if rec.status != "kept" and (out / rec.id).is_dir() and rec.fingerprint:
        logger.info("%s: no longer kept (%s), removing its folder of an earlier run",
                    rec.id, rec.status)
        shutil.rmtree(out / rec.id, ignore_errors=True)
    write_json(out / ".records" / f"{rec.id}.json", _record_json(rec))
    return rec


def _record_json(rec: ShapeRecord) -> dict[str, Any]:
    d = asdict(rec)
    d["min_score"] = None if not np.isfinite(rec.min_score) else rec.min_score
    return d


def _record_from_json(d: dict[str, Any]) -> ShapeRecord:
    d = dict(d)
    d["min_score"] = float("nan") if d.get("min_score") is None else float(d["min_score"])
    return ShapeRecord(**d)


def _worker_init(gnn_run: str, axis_run: str, device: str, refine_json: dict | None = None,
                 check_run: str | None = None) -> None:
    single_threaded_worker()
    global _WORKER_MODELS
    from kinmo.refine.config import RefineConfig

    _WORKER_MODELS = _load_models(Path(gnn_run), Path(axis_run), device,
                                  None if refine_json is None else RefineConfig(**refine_json),
                                  None if check_run is None else Path(check_run))


def _worker_run(folder: str | Path, out: str, config_json: dict, cache: str | None, root: str
                ) -> ShapeRecord:
    assert _WORKER_MODELS is not None
    return pseudo_label_shape(folder, out, _WORKER_MODELS, PseudoLabelConfig(**config_json),
                              cache, root)


def _worker_failed(folder: Path, e: Exception) -> ShapeRecord:
    # the worker raised or died (e.g. killed for memory)
    return ShapeRecord(id=folder.name, category="unknown", status="failed", source=str(folder),
                       reason=stages.worker_error(folder, e))


# ----------------------------------------------------------------------------- the dataset


def _current_record(out: Path, folder: Path, models_fp: str, config: PseudoLabelConfig
                    ) -> ShapeRecord | None:
    p = out / ".records" / f"{folder.name}.json"
    if not p.is_file():
        return None
    try:
        rec = _record_from_json(json.loads(p.read_text()))
        fp = _fingerprint(source_fingerprint(folder), models_fp, config)
    except (OSError, ValueError, TypeError, KinmoError):
        return None
    if rec.fingerprint != fp:
        return None
    if rec.status == "kept" and not (out / rec.id / "scores.json").is_file():
        return None
    return rec


def summary_rows(records: Sequence[ShapeRecord]) -> list[dict[str, Any]]:
    """Per-category counts of each status, plus a final ``all`` row.

    Returns
    -------
    list of dict
        Keys :data:`SUMMARY_COLUMNS`, categories sorted.
    """
    cats: dict[str, dict[str, Any]] = {}
    for r in records:
        row = cats.setdefault(r.category, {"category": r.category, "shapes": 0,
                                           **{s: 0 for s in STATUSES}})
        row["shapes"] += 1
        row[r.status] += 1
    rows = [cats[c] for c in sorted(cats)]
    total = {"category": "all", "shapes": len(records),
             **{s: sum(r.status == s for r in records) for s in STATUSES}}
    return rows + [total]


def _csv(columns: Sequence[str], rows: Sequence[dict[str, Any]]) -> str:
    buf = io.StringIO()
    w = csv.DictWriter(buf, fieldnames=list(columns), lineterminator="\n", extrasaction="ignore")
    w.writeheader()
    for r in rows:
        w.writerow({k: (f"{v:.4g}" if isinstance(v, float) else v) for k, v in r.items()})
    return buf.getvalue()


def _write_tables(out: Path, records: Sequence[ShapeRecord]) -> None:
    # the table's columns only (no deep copy of every record's joints: this runs as
    # records arrive)
    rows = [{**{c: getattr(r, c) for c in SHAPE_COLUMNS if c != "min_score"},
             "min_score": r.min_score if np.isfinite(r.min_score) else ""}
            for r in sorted(records, key=lambda r: r.id)]
    write_text(out / "shapes.csv", _csv(SHAPE_COLUMNS, rows))
    write_text(out / "summary.csv", _csv(SUMMARY_COLUMNS, summary_rows(records)))


def pseudo_label_dataset(
    data: str | Path,
    gnn_run: str | Path,
    axis_run: str | Path,
    out: str | Path,
    config: PseudoLabelConfig | None = None,
    workers: int = 1,
    cache: str | Path | None = None,
    force: bool = False,
    progress: bool = True,
    on_record: Callable[[ShapeRecord], None] | None = None,
    executor: str = "local",
    check_run: str | Path | None = None,
) -> PseudoLabelResult:
    """Pseudo-label every shape folder below ``data`` (module docstring).

    Parameters
    ----------
    data : str or Path
        A PartNet dataset folder (or one shape folder).
    gnn_run : str or Path
        Run folder (or ``model.pt``) of ``kinmo train gnn``.
    axis_run : str or Path
        Run folder (or ``model.pt``) of ``kinmo train axis``; with the learned selector
        (``config.refine.selector == "ranker"``) a folder holding only ``ranker.json`` will
        do (the ranker then needs no network).
    out : str or Path
        Output folder.
    config : PseudoLabelConfig, optional
    workers : int
        Worker processes (1: in this process; 0: one per CPU).
    cache : str or Path, optional
        A ``kinmo prepare`` cache of ``data`` (part graphs are built when missing).
    force : bool
        Redo shapes whose record is current.
    progress : bool
        Show a rich progress bar.
    on_record : callable, optional
        Called with every finished shape's record.
    executor : str
        ``local``, ``ray``, ``ray:auto`` or ``ray:ADDRESS`` (:mod:`kinmo.executor`).
    check_run : str or Path, optional
        Run folder (or ``model.pt``) of a second motion GNN (``kinmo train all``: its
        coarse-type GNN) that must agree on every joint of a kept shape
        (:class:`PseudoLabelConfig` ``agree_prob``, ``agree_deg``); None: no second model.

    Returns
    -------
    PseudoLabelResult

    Raises
    ------
    KinmoDataError
        ``data`` holds no shape folder, or a checkpoint is missing or unreadable.
    KinmoError
        Another ``kinmo pseudo-label`` is writing ``out``.
    KinmoUsageError
        ``out`` is, lies inside or holds an input (``data``, the model folders, ``cache``):
        outputs never overwrite inputs (:func:`kinmo.io.check_outputs_apart`).
    """
    config = config or PseudoLabelConfig()
    t0 = time.perf_counter()
    data, out, gnn_run, axis_run = Path(data), Path(out), Path(gnn_run), Path(axis_run)
    check = None if check_run is None else Path(check_run)
    folders = [f for f, _ in stages.shape_jobs(data)]
    check_outputs_apart(out, [data, gnn_run, axis_run, *([cache] if cache is not None else []),
                              *([check] if check is not None else [])])
    models_fp = _models_fingerprint(gnn_run, axis_run, check, config.refine)  # raises for a missing checkpoint
    out.mkdir(parents=True, exist_ok=True)
    stage: ShapeStage[ShapeRecord] = ShapeStage(
        out, "kinmo pseudo-label", len(folders), save=lambda recs, _: _write_tables(out, recs),
        title="pseudo-label", description="shapes", counters={"kept": "green", "failed": "red"},
        progress=progress, on_result=on_record, scratch=(".staging",), save_at_start=False)
    with stage:
        todo = stage.resume(folders, None if force else
                            (lambda f: _current_record(out, f, models_fp, config)))
        if todo:
            # 0: one per CPU; a negative count runs in this process
            workers = resolve_workers(workers, len(todo)) if workers >= 0 else 1
            in_process = workers == 1 and parse_executor(executor).kind == "local"
            if in_process:
                # in this process: map_unordered calls fn directly, no initializer
                models = _load_models(gnn_run, axis_run, config.device, config.refine, check)
                fn = partial(pseudo_label_shape, out=out, models=models, config=config,
                             cache=cache, root=data)
            else:  # each worker loads the models once (_worker_init)
                fn = partial(_worker_run, out=str(out), config_json=config.model_dump(mode="json"),
                             cache=None if cache is None else str(cache), root=str(data))
            # one torch thread in this process too, as in every worker (_worker_init): torch's
            # reductions then add in the same order, and -j 1 writes the bytes -j N writes
            with torch_threads(1 if in_process else 0):
                stage.map(fn, todo, workers, _worker_failed, initializer=_worker_init,
                          initargs=(str(gnn_run), str(axis_run), config.device,
                                    config.refine.model_dump(mode="json"),
                                    None if check is None else str(check)), executor=executor)
    return PseudoLabelResult(out, sorted(stage.results, key=lambda r: r.id), stage.n_skipped,
                             time.perf_counter() - t0)
