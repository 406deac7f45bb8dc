"""Evaluation on labelled objects given as a user would give them (issue 22, part 1).

Each test object of a PartNet-Mobility split is exported as a **user GLB**: a glTF scene in the
object's own frame (y-up, mesh units) with one node per input part and no hierarchy. Variants:

- ``generic``: a node per mobility link (every leaf of the link merged), named ``part_<k>``;
- ``semantic``: the same nodes named after their link (``door_3``: unique, the number goes in
  :class:`kinmo.features.SemanticVocab`);
- ``leaf``: a node per PartNet leaf (finer than a link, as a part segmenter's output), named
  ``part_<k>``;
- ``partnet``: the object in PartNet format (its hierarchy and names), scored on the nodes of
  ``generic`` (a node per link).

Each GLB goes through what ``kinmo predict FILE`` does (its frame read by
:func:`kinmo.user_input.asset_frame`, no ``--up`` given; :func:`kinmo.user_input.stage_partnet`
with category ``"unknown"``, then :func:`kinmo.predict.predict_dataset`), and the written
``mobility_v2.json`` is scored in the GLB's frame. ``--turn K`` and ``--write-up z`` give the
GLBs turned about their up axis or written z-up (:func:`input_rotation`, issue 36: facing and
up-axis invariance), their predictions turned back before scoring.

**Metric** (issue 22, "Done when"): a joint *moves* a set of input nodes (its link and every
link below it; a node counts when most of its PartNet leaves are in those links). A predicted
moving link (hinge or slider) matches a true moving joint when their moved sets have IoU
``>= 0.5`` (greedy one-to-one by IoU). **Recall** = matched / true moving joints; **angle** =
mean over matched joints of the acute angle between the axis directions (degrees); **type
accuracy** = share of matched joints with the right joint type (hinge / slider).

glTF note: trimesh loads a scene's nodes in reverse order and merges nodes of equal names, so
every node has a unique name and predictions are mapped back by name, never by order.
"""

from __future__ import annotations

import dataclasses
import math
import re
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np

from kinmo.assets import read_parts
from kinmo.data.augment import flat_groups
from kinmo.data.frames import AssetFrame
from kinmo.data.model import Joint, JointType, Link, PartHierarchy, Shape
from kinmo.data.build import load_shape_meshes
from kinmo.data.labels import link_subtree
from kinmo.data.readers import find_shapes, read_links, read_shape
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.evaluate.cells import cell
from kinmo.features import quarter_turn
from kinmo.metrics.motion_range import RangeScore, score_range, summarise_ranges
from kinmo.inference.predictor import Predictor
from kinmo.io import atomic_path, write_json, write_text
from kinmo.predict import predict_dataset
from kinmo.user_input import asset_frame, stage_partnet

__all__ = ["VARIANTS", "WRITE_UPS", "input_rotation", "TrueJoint", "PredJoint", "UserNodes", "user_nodes", "write_user_glb",
           "true_joints", "moved_nodes", "match_joints", "acute_angle", "score", "score_prediction",
           "write_parts_glb", "links_back", "evaluate_user_format",
           "results_markdown"]

#: The input variants (module docstring).
VARIANTS = ("generic", "semantic", "leaf", "partnet")
_MOVING = (JointType.HINGE, JointType.SLIDER)


@dataclass
class UserNodes:
    """The input nodes of one object in one variant.

    Attributes
    ----------
    names : list of str
        Unique node names (``[A-Za-z0-9_]``), as written into the GLB.
    leaves : list of list of int
        PartNet leaf ids of each node.
    """

    names: list[str]
    leaves: list[list[int]]


@dataclass
class TrueJoint:
    """A true moving joint: its link, type, unit axis direction (mesh frame), moved nodes and
    the joint itself (its range)."""

    link: int
    type: str
    direction: np.ndarray
    moved: frozenset[int]
    joint: Joint | None = None


@dataclass
class PredJoint:
    """A predicted moving link: id, type, unit axis direction, the input nodes it moves and the
    joint itself (its range)."""

    link: int
    type: str
    direction: np.ndarray
    moved: frozenset[int]
    joint: Joint | None = None


def _clean(name: str) -> str:
    return re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_") or "part"


def user_nodes(shape: Shape, variant: str) -> UserNodes:
    """The nodes of ``shape`` as a user's asset of ``variant`` has them (module docstring).

    ``partnet`` uses the nodes of ``generic`` (its scoring nodes).

    Raises
    ------
    ValueError
        Unknown variant, or a shape without links.
    """
    if variant not in VARIANTS:
        raise ValueError(f"variant must be one of {', '.join(VARIANTS)}, got {variant!r}")
    groups = flat_groups(shape, "leaf" if variant == "leaf" else "link")
    if variant == "semantic":
        names = [f"{_clean(n)}_{k}" for k, (n, _) in enumerate(groups)]
    else:
        names = [f"part_{k}" for k in range(len(groups))]
    return UserNodes(names, [list(g) for _, g in groups])


def write_user_glb(shape: Shape, nodes: UserNodes, path: str | Path,
                   transform: np.ndarray | None = None) -> Path:
    """Write the user GLB of ``shape``: one scene node per entry of ``nodes``, mesh frame.

    Parameters
    ----------
    shape : Shape
    nodes : UserNodes
        From :func:`user_nodes`.
    path : str or Path
        The ``.glb`` file (written atomically).
    transform : (3, 3) float64, optional
        A proper rotation ``T`` applied about the shape's bounding-box centre ``c``
        (``v -> T (v - c) + c``; :func:`input_rotation`); default: the mesh frame as is.

    Returns
    -------
    Path

    Raises
    ------
    KinmoDataError
        A mesh cannot be loaded.
    """
    h = shape.hierarchy
    groups = []
    for name, leaves in zip(nodes.names, nodes.leaves):
        objs = list(dict.fromkeys(o for leaf in leaves for o in h.nodes[leaf].objs))
        meshes = load_shape_meshes([shape.mesh_path(o) for o in objs])
        vs, fs, n = [], [], 0
        for v, f in meshes:
            vs.append(np.asarray(v, dtype=np.float64))
            fs.append(np.asarray(f, dtype=np.int64) + n)
            n += len(v)
        groups.append((name, np.concatenate(vs), np.concatenate(fs)))
    return write_parts_glb(groups, path, transform)


def write_parts_glb(parts: Sequence[tuple[str, np.ndarray, np.ndarray]], path: str | Path,
                    transform: np.ndarray | None = None) -> Path:
    """Write ``parts`` (``(name, (V, 3) float64, (F, 3) int64)``, unique names) as a GLB scene
    with one node per part, no hierarchy (glTF: y-up); atomically.

    ``transform`` ``(3, 3) float64``, a proper rotation ``T``, is applied about the parts'
    bounding-box centre ``c`` (``v -> T (v - c) + c``; :func:`input_rotation`); default: the
    coordinates as given.
    """
    import trimesh  # optional heavy dependency, as in kinmo.assets.mesh

    if transform is not None:
        lo = np.min([v.min(0) for _, v, _ in parts], axis=0)
        hi = np.max([v.max(0) for _, v, _ in parts], axis=0)
        c = (lo + hi) / 2.0
        t = np.asarray(transform, dtype=np.float64)
        parts = [(name, (v - c) @ t.T + c, f) for name, v, f in parts]
    scene = trimesh.Scene()
    for name, v, f in parts:
        mesh = trimesh.Trimesh(v, f, process=False)
        scene.add_geometry(mesh, node_name=name, geom_name=name)
    path = Path(path)
    with atomic_path(path) as tmp:
        Path(tmp).write_bytes(scene.export(file_type="glb"))
    return path


#: The frames :func:`input_rotation` writes a GLB in: its up axis.
WRITE_UPS = ("y", "z")


def input_rotation(turn: int = 0, up: str = "y") -> np.ndarray:
    """The rotation ``T`` a test object is given with (``kinmo eval user-format --turn/--write-up``).

    ``turn`` quarter turns about the object's up axis (PartNet's +y; counter-clockwise seen
    from above), then, with ``up="z"``, the y-up object written z-up (``(x, y, z) -> (x, -z,
    y)``, the object's +y becomes the file's +z). Predicted directions are brought back with
    ``T^T`` before they are scored, so the scores compare with the untouched input's.

    Returns
    -------
    (3, 3) float64
        A proper rotation (exact: entries 0 and +-1).

    Raises
    ------
    ValueError
        ``up`` is not one of :data:`WRITE_UPS`.
    """
    if up not in WRITE_UPS:
        raise ValueError(f"the written up axis must be one of {', '.join(WRITE_UPS)}, not {up!r}")
    write = np.eye(3) if up == "y" else np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]])
    return write @ quarter_turn(turn)


def _subtree_leaves(links: Sequence[Link], hierarchy: PartHierarchy, link: int) -> set[int]:
    by_id = {lk.id: lk for lk in links}
    ids = link_subtree({lk.id: lk.parent for lk in links}, link)
    return {leaf for i in ids for part in by_id[i].parts for leaf in hierarchy.leaves(part)}

def moved_nodes(node_leaves: Sequence[Sequence[int]], moved_leaves: set[int]) -> frozenset[int]:
    """Input nodes moved by a joint: those with more than half of their leaves moved.

    Parameters
    ----------
    node_leaves : sequence of sequence of int
        Leaf ids of each input node.
    moved_leaves : set of int
        Leaf ids moved by the joint.

    Returns
    -------
    frozenset of int
        Node indices.
    """
    return frozenset(k for k, ls in enumerate(node_leaves)
                     if ls and 2 * sum(1 for x in ls if x in moved_leaves) > len(ls))


def true_joints(shape: Shape, nodes: UserNodes) -> list[TrueJoint]:
    """The true moving joints (hinge, slider) of a labelled shape, with the nodes they move."""
    assert shape.links is not None
    out = []
    for lk in shape.links:
        if lk.joint.type not in _MOVING or lk.joint.direction is None:
            continue
        moved = moved_nodes(nodes.leaves, _subtree_leaves(shape.links, shape.hierarchy, lk.id))
        out.append(TrueJoint(lk.id, lk.joint.type.value, np.asarray(lk.joint.direction, float), moved,
                             lk.joint))
    return out


def _pred_joints(links: Sequence[Link], hierarchy: PartHierarchy,
                 node_leaves: Sequence[Sequence[int]]) -> list[PredJoint]:
    out = []
    for lk in links:
        if lk.joint.type not in _MOVING or lk.joint.direction is None:
            continue
        moved = moved_nodes(node_leaves, _subtree_leaves(links, hierarchy, lk.id))
        out.append(PredJoint(lk.id, lk.joint.type.value, np.asarray(lk.joint.direction, float), moved,
                             lk.joint))
    return out


def _iou(a: frozenset[int], b: frozenset[int]) -> float:
    u = len(a | b)
    return len(a & b) / u if u else 0.0


def match_joints(true: Sequence[TrueJoint], pred: Sequence[PredJoint],
                 min_iou: float = 0.5) -> list[tuple[int, int, float]]:
    """Greedy one-to-one matching of true and predicted joints by moved-node IoU.

    Ties in IoU arise when two true joints move the same parts (a compound joint written as a
    slide and a hinge on one body, as some MJCF and URDF assets do): a predicted joint is then
    matched to the one it agrees with, of the same type first, then the smaller axis angle.

    Returns
    -------
    list of (true index, predicted index, IoU)
        Pairs with IoU ``>= min_iou``, highest IoU first (ties: same type first, then the
        smaller acute axis angle, then lower indices).
    """
    cand = sorted(((-_iou(t.moved, p.moved), t.type != p.type, acute_angle(t.direction, p.direction), i, j)
                   for i, t in enumerate(true) for j, p in enumerate(pred)))
    used_t: set[int] = set()
    used_p: set[int] = set()
    out = []
    for neg, _, _, i, j in cand:
        if -neg < min_iou:
            break
        if i in used_t or j in used_p:
            continue
        used_t.add(i)
        used_p.add(j)
        out.append((i, j, -neg))
    return out


def acute_angle(a: np.ndarray, b: np.ndarray) -> float:
    """Acute angle between two axis directions, degrees in ``[0, 90]``."""
    c = abs(float(np.dot(a, b)) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(min(1.0, c)))


def score(rows: Sequence[dict[str, Any]]) -> dict[str, Any]:
    """Recall, mean angle and type accuracy pooled over per-object rows (:func:`_score_one`)."""
    n_true = sum(r["n_true"] for r in rows)
    angles = [a for r in rows for a in r["angles"]]
    types = [t for r in rows for t in r["type_ok"]]
    return {
        "objects": len(rows),
        "failed": sum(1 for r in rows if r.get("error")),
        "true_joints": n_true,
        "matched": len(angles),
        "predicted_moving": sum(r["n_pred"] for r in rows),
        "recall": len(angles) / n_true if n_true else float("nan"),
        "mean_angle": float(np.mean(angles)) if angles else float("nan"),
        "median_angle": float(np.median(angles)) if angles else float("nan"),
        "within_5deg": float(np.mean(np.asarray(angles) <= 5.0)) if angles else float("nan"),
        "flips_over_45deg": int(np.sum(np.asarray(angles) > 45.0)) if angles else 0,
        "type_accuracy": float(np.mean(types)) if types else float("nan"),
        # issue 36: found, right type and axis within 10 degrees, of all true joints; and
        # predicted moving joints matched to no true one, per object
        "fully_right": (sum(1 for r in rows for a, ok in zip(r["angles"], r["type_ok"]) if ok and a <= 10.0)
                        / n_true if n_true else float("nan")),
        "false_movers_per_object": ((sum(r["n_pred"] for r in rows) - len(angles)) / len(rows)
                                    if rows else float("nan")),
        **summarise_ranges(RangeScore(**s) for r in rows for s in r.get("ranges", [])),
    }


def _score_one(sid: str, true: list[TrueJoint], pred: list[PredJoint]) -> dict[str, Any]:
    m = match_joints(true, pred)
    return {"id": sid, "n_true": len(true), "n_pred": len(pred),
            "angles": [acute_angle(true[i].direction, pred[j].direction) for i, j, _ in m],
            "type_ok": [true[i].type == pred[j].type for i, j, _ in m],
            "ranges": [dataclasses.asdict(x) for i, j, _ in m if pred[j].joint is not None
                       and true[i].joint is not None
                       and (x := score_range(pred[j].joint, true[i].joint)) is not None], "error": ""}


@dataclass
class _Obj:
    shape: Shape


def evaluate_user_format(
    data: str | Path,
    run: str | Path | Predictor,
    ids: Sequence[str],
    out: str | Path,
    variants: Sequence[str] = VARIANTS,
    axis_model: str | Path | None = None,
    refine_config: Any = None,
    device: str = "auto",
    progress: bool = True,
    turn: int = 0,
    write_up: str = "y",
) -> dict[str, dict[str, Any]]:
    """Score a motion GNN on the objects ``ids`` of ``data`` in the user formats (module docs).

    Parameters
    ----------
    data : str or Path
        PartNet-Mobility dataset folder.
    run : str, Path or Predictor
        A loaded :class:`~kinmo.inference.predictor.Predictor` (then ``axis_model``,
        ``refine_config`` and ``device`` are ignored), or a run folder of ``kinmo train gnn``
        refined as those say (:meth:`~kinmo.inference.predictor.Predictor.from_parts`).
    ids : sequence of str
        Object ids to evaluate (the test split); ids not in ``data`` are skipped.
    out : str or Path
        Work and result folder: ``glb/<variant>/<id>.glb``, ``pred/<variant>/<id>/``,
        ``user_format.json`` (scores and per-object rows), ``user_format.md``.
    variants : sequence of str
        Of :data:`VARIANTS`.
    axis_model, refine_config, device
        With a run folder: :meth:`~kinmo.inference.predictor.Predictor.from_parts`.
    progress : bool
    turn, write_up
        Give each GLB turned ``turn`` quarter turns about its up axis and written ``write_up``-up
        (:func:`input_rotation`); every GLB is read as ``kinmo predict FILE`` reads it, without
        ``--up`` (:func:`kinmo.user_input.asset_frame`), and the predictions are brought back
        before they are scored. The ``partnet`` variant is PartNet's own frame: it is left out
        when either is set.

    Returns
    -------
    dict of str to dict
        Per variant: :func:`score`'s fields.

    Raises
    ------
    ValueError
        An unknown variant.
    KinmoDataError
        No object of ``ids`` in ``data``; the run cannot be loaded.
    """
    for v in variants:
        if v not in VARIANTS:
            raise ValueError(f"variant must be one of {', '.join(VARIANTS)}, got {v!r}")
    rot = input_rotation(turn, write_up)
    moved_input = not np.array_equal(rot, np.eye(3))
    if moved_input:
        variants = [v for v in variants if v != "partnet"]
    data, out = Path(data), Path(out)
    want = set(ids)
    objs: dict[str, _Obj] = {}
    for folder in find_shapes(data):
        if folder.name in want:
            s = read_shape(folder)
            if s.links is not None:
                objs[s.id] = _Obj(s)
    if not objs:
        raise KinmoDataError(data, "none of the objects to evaluate is a labelled object here")
    r = run if isinstance(run, Predictor) else Predictor.from_parts(run, axis_model, refine_config, device=device)
    kw = dict(progress=progress, formats=["mobility_v2"])
    results: dict[str, dict[str, Any]] = {}
    all_rows: dict[str, list[dict[str, Any]]] = {}
    for variant in variants:
        rows: list[dict[str, Any]] = []
        pred_dir = out / "pred" / variant
        if pred_dir.exists():
            shutil.rmtree(pred_dir)
        if variant == "partnet":
            stage = out / "stage" / variant
            if stage.exists():
                shutil.rmtree(stage)
            stage.mkdir(parents=True)
            for sid, o in objs.items():
                (stage / sid).symlink_to(o.shape.path.resolve(), target_is_directory=True)
            predict_dataset(stage, r, pred_dir, **kw)
            for sid, o in sorted(objs.items()):
                nodes = user_nodes(o.shape, "generic")
                rows.append(score_prediction(sid, true_joints(o.shape, nodes), pred_dir / sid, o.shape.hierarchy,
                                 nodes.leaves))
        else:
            stage = out / "stage" / variant
            if stage.exists():
                shutil.rmtree(stage)
            stage.mkdir(parents=True)
            node_sets: dict[str, UserNodes] = {}
            frames: dict[str, AssetFrame] = {}
            for sid, o in sorted(objs.items()):
                nodes = user_nodes(o.shape, variant)
                node_sets[sid] = nodes
                glb = write_user_glb(o.shape, nodes, out / "glb" / variant / f"{sid}.glb",
                                     transform=rot if moved_input else None)
                parts = read_parts(glb)
                frames[sid] = asset_frame(glb, parts)
                stage_partnet(glb, stage / sid, category="unknown", parts=parts, frame=frames[sid],
                              vocab=r.run.vocab)
            predict_dataset(stage, r, pred_dir, **kw)
            for sid, o in sorted(objs.items()):
                nodes = node_sets[sid]
                staged = read_shape(stage / sid)
                # staged leaf id -> input node index, by the name as read (never by order; the
                # staged name is part_<k> when the model does not know the names)
                index = {n: k for k, n in enumerate(nodes.names)}
                sh = staged.hierarchy
                node_leaves = [[] for _ in nodes.names]
                for nid in sh.order:
                    nd = sh.nodes[nid]
                    if nd.is_leaf and nd.text in index:
                        node_leaves[index[nd.text]].append(nid)
                rows.append(score_prediction(sid, true_joints(o.shape, nodes), pred_dir / sid, sh, node_leaves,
                                 links_back(frames[sid], rot)))
        results[variant] = score(rows)
        all_rows[variant] = rows
    # the model as a folder, not a Predictor's repr (a page of modules, with memory addresses)
    write_json(out / "user_format.json", {"run": str(run.source if isinstance(run, Predictor) else run),
                                          "axis_model": None if axis_model is None
                                          else str(axis_model), "turn": int(turn) % 4, "write_up": write_up,
                                          "scores": results, "rows": all_rows})
    write_text(out / "user_format.md", results_markdown(results))
    return results


def links_back(frame: AssetFrame, rot: np.ndarray) -> Callable[[list[Link]], list[Link]]:
    """Predicted links (kinmo's frame of a staged file) -> the source object's frame: into the
    file's frame and units (``frame``), then the rotation ``rot`` the object was written with
    (source frame -> file frame) undone (directions only: the scores compare directions,
    moved nodes and ranges)."""
    def back(links: list[Link]) -> list[Link]:
        out = []
        for lk in frame.links_to_asset(links):
            d = lk.joint.direction
            if d is not None:
                lk = dataclasses.replace(lk, joint=dataclasses.replace(lk.joint, direction=np.asarray(d) @ rot))
            out.append(lk)
        return out
    return back


def score_prediction(sid: str, true: list[TrueJoint], pred_folder: Path, hierarchy: PartHierarchy,
         node_leaves: Sequence[Sequence[int]],
         links_back: Callable[[list[Link]], list[Link]] | None = None) -> dict[str, Any]:
    """One object's row for :func:`score`: its prediction (``pred_folder/mobility_v2.json``,
    read on ``hierarchy``, mapped by ``links_back``) against ``true``, the input node of each
    staged leaf given by ``node_leaves``; an unreadable prediction scores as no prediction,
    with its ``error``."""
    f = pred_folder / "mobility_v2.json"
    try:
        links = read_links(f, hierarchy)
    except KinmoError as e:
        row = _score_one(sid, true, [])
        row["error"] = " ".join(str(e).split())
        return row
    if links_back is not None:
        links = links_back(list(links))
    return _score_one(sid, true, _pred_joints(links, hierarchy, node_leaves))


def results_markdown(results: dict[str, dict[str, Any]]) -> str:
    """A Markdown table of :func:`evaluate_user_format`'s scores."""
    lines = ["| input | objects | true joints | recall | mean angle (deg) | median | within 5 deg "
             "| > 45 deg | type acc. | fully right | false movers / object | hinge range IoU "
             "| IoU >= 0.5 | slider range IoU | IoU >= 0.5 | continuous acc. |",
             "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
    for v, s in results.items():
        r = [s.get(k) for k in ("range_iou_hinge", "range_ok_hinge", "range_iou_slider",
                                "range_ok_slider", "range_cont_acc")]
        lines.append(f"| {v} | {s['objects']} | {s['true_joints']} | {cell(s['recall'])} | "
                     f"{cell(s['mean_angle'], 1)} | {cell(s['median_angle'], 1)} | "
                     f"{cell(s['within_5deg'])} | {s['flips_over_45deg']} | {cell(s['type_accuracy'])} | "
                     f"{cell(s.get('fully_right'))} | {cell(s.get('false_movers_per_object'))} | "
                     + " | ".join(cell(x) for x in r) + " |")
    return "\n".join(lines) + "\n"
