"""Evaluation on foreign assets: articulated MuJoCo models with true joints (issue 36).

A foreign asset is an MJCF model (``model.xml``, root ``<mujoco>``) or a URDF
(``model.urdf``) from outside PartNet-Mobility, its hinge and slide joints (URDF: revolute,
continuous, prismatic) the truth (``bench/foreign_assets.py`` builds a set from public
robot-learning repositories). Each is given to kinmo two ways, as a user would (issue 36,
"Done when"):

- ``file``: the file itself, read by :mod:`kinmo.assets.mjcf` (a part per body with
  geometry) or :mod:`kinmo.assets.urdf` (a part per link with geometry), the joints ignored
  (so a URDF counts as one with every joint made fixed), z-up as both formats declare;
- ``glb``: the same parts as a GLB scene (:func:`~kinmo.evaluate.user_format.write_parts_glb`),
  one node per part named ``part_<k>``, turned y-up (glTF's convention); with ``turn`` /
  ``write_up``, also turned quarter turns about its up axis through its box centre and / or
  written z-up (:func:`~kinmo.evaluate.user_format.input_rotation`: issue 36's rotation and
  up-axis checks), read without ``--up`` and turned back before scoring.

Both go through what ``kinmo predict FILE`` does (:func:`kinmo.user_input.asset_frame`
without ``--up``, :func:`kinmo.user_input.stage_partnet`, then
:func:`kinmo.predict.predict_dataset`), and the predictions are scored as
:mod:`kinmo.evaluate.user_format` scores user GLBs: a joint **moves** the parts of its body
and every body below it; a predicted moving link matches a true joint when their moved part
sets have IoU ``>= 0.5`` (greedy, one to one); **fully right** = matched, right type and
axis within 10 degrees, over all true joints; **false movers** = predicted moving links
matched to no true joint, per object (:func:`~kinmo.evaluate.user_format.score`). Joint
ranges are scored for URDF assets only, against each joint's ``<limit>`` (degrees; the file's
units for prismatic joints; continuous joints by continuous-or-not), with
:func:`kinmo.metrics.motion_range.score_range`, as ``kinmo eval user-format`` scores them.
MJCF ``range`` attributes are often control ranges rather than the physical travel, so MJCF
joints carry no range. An object kinmo cannot read counts its joints as missed, with its error.

Truth: MJCF (:func:`mjcf_true_joints`) in MuJoCo's world frame at ``qpos0``
(``mj_kinematics``: ``xaxis`` of each hinge / slide joint); URDF (:func:`urdf_true_joints`)
at the rest pose (:func:`kinmo.assets.urdf.link_poses`), each axis turned by its child
link's pose. Both are the frames the readers give the parts in.
"""

from __future__ import annotations

import math
import shutil
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from kinmo.assets import Part, read_parts
from kinmo.assets.mjcf import compile_mjcf
from kinmo.data.model import Joint, JointType, Link
from kinmo.data.readers import read_shape
from kinmo.errors import KinmoDataError, KinmoError
from kinmo.evaluate.cells import cell
from kinmo.evaluate.user_format import (TrueJoint, input_rotation, links_back, score, score_prediction,
                                        write_parts_glb)
from kinmo.io import write_json, write_text
from kinmo.predict import predict_dataset
from kinmo.user_input import asset_frame, stage_partnet

if TYPE_CHECKING:
    from kinmo.inference.predictor import Predictor

__all__ = ["FOREIGN_VARIANTS", "ForeignObject", "mjcf_true_joints", "urdf_true_joints", "true_joints_of",
           "find_foreign", "evaluate_foreign", "foreign_markdown"]

#: The ways each asset is given (module docs).
FOREIGN_VARIANTS = ("file", "glb")

# z-up -> y-up, (x, y, z) -> (x, z, -y): the GLB variant's turn (kinmo.data.frames' rule;
# both MJCF and URDF are z-up)
_Z_TO_Y = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


@dataclass
class ForeignObject:
    """One foreign asset: its id (folder name) and model file."""

    id: str
    model: Path


def find_foreign(folder: str | Path) -> list[ForeignObject]:
    """The assets of a foreign-asset folder: every ``<id>/model.xml`` or ``<id>/model.urdf``
    below it, sorted by id.

    Raises
    ------
    KinmoDataError
        None found.
    """
    folder = Path(folder)
    found = sorted((p.parent.name, p) for pattern in ("*/model.xml", "*/model.urdf")
                   for p in folder.glob(pattern) if p.is_file())
    if not found:
        raise KinmoDataError(folder, "no foreign assets here (expected <id>/model.xml or model.urdf, as "
                             "bench/foreign_assets.py writes them)")
    return [ForeignObject(i, p) for i, p in found]


def mjcf_true_joints(model: str | Path, parts: Sequence[Part] | None) -> list[TrueJoint]:
    """The hinge and slide joints of an MJCF model, with the parts they move.

    Parameters
    ----------
    model : str or Path
        The MJCF file.
    parts : sequence of Part, optional
        Its parts as :func:`kinmo.assets.read_parts` read them (named after their bodies);
        None when they could not be read: the joints then move no part (each counts as a
        true joint, never matched).

    Returns
    -------
    list of TrueJoint
        In MuJoCo's joint order: ``link`` the joint id, ``type`` ``"hinge"`` / ``"slider"``,
        ``direction`` the unit axis ``(3,) float64`` in the world frame at ``qpos0``,
        ``moved`` the indices into ``parts`` of its body and every body below it. Joints
        moving no part with geometry are left out when ``parts`` is given.

    Raises
    ------
    KinmoDataError
        A file reference refused, or MuJoCo cannot load the model
        (:func:`kinmo.assets.mjcf.compile_mjcf`).
    """
    import mujoco

    m = compile_mjcf(model)  # as kinmo's reader opens it: references checked, no textures
    d = mujoco.MjData(m)
    mujoco.mj_kinematics(m, d)
    index = {name: k for k, (name, _, _) in enumerate(parts or [])}
    names = ["world" if b == 0 else (m.body(b).name or f"body_{b}") for b in range(m.nbody)]
    parent = [int(p) for p in m.body_parentid]
    types = {int(mujoco.mjtJoint.mjJNT_HINGE): JointType.HINGE.value,
             int(mujoco.mjtJoint.mjJNT_SLIDE): JointType.SLIDER.value}
    out = []
    for j in range(m.njnt):
        kind = types.get(int(m.jnt_type[j]))
        if kind is None:
            continue
        body = int(m.jnt_bodyid[j])
        below = [b for b in range(m.nbody) if _descends(b, body, parent)]
        moved = frozenset(index[names[b]] for b in below if names[b] in index)
        if parts is not None and not moved:
            continue
        axis = np.asarray(d.xaxis[j], dtype=np.float64)
        out.append(TrueJoint(j, kind, axis / np.linalg.norm(axis), moved))
    return out


def urdf_true_joints(model: str | Path, parts: Sequence[Part] | None) -> list[TrueJoint]:
    """The revolute, continuous and prismatic joints of a URDF, with the parts they move.

    As :func:`mjcf_true_joints`: ``link`` the joint's index in the file, ``type`` ``"hinge"``
    (revolute, continuous) / ``"slider"``, ``direction`` the unit ``<axis>`` (default
    ``1 0 0``, in the joint frame, which is the child link's) turned into the URDF's world frame
    at the rest pose, ``moved`` the indices into ``parts`` (named after their links) of the
    child link and every link below it, ``joint`` its range (``<limit>``: degrees for
    revolute joints, the file's units for prismatic ones; none for continuous joints).

    Raises
    ------
    KinmoDataError
        The file is not a readable URDF (:func:`kinmo.assets.read_xml`), or a bad ``<origin>``
        / ``<axis>`` / ``<limit>``.
    """
    from kinmo.assets import read_xml
    from kinmo.assets.urdf import link_poses, numbers

    model = Path(model)
    robot = read_xml(model, "robot", "URDF")
    poses = link_poses(robot, model)
    index = {name: k for k, (name, _, _) in enumerate(parts or [])}
    children: dict[str, list[str]] = {}
    joints = robot.findall("joint")
    for j in joints:
        p, c = j.find("parent"), j.find("child")
        if p is not None and c is not None:
            children.setdefault(p.get("link", ""), []).append(c.get("link", ""))
    kinds = {"revolute": JointType.HINGE.value, "continuous": JointType.HINGE.value,
             "prismatic": JointType.SLIDER.value}
    out = []
    for k, j in enumerate(joints):
        kind, c = kinds.get(j.get("type", "")), j.find("child")
        if kind is None or c is None:
            continue
        child = c.get("link", "")
        below, todo = [], [child]
        while todo:
            below.append(todo.pop())
            todo.extend(children.get(below[-1], []))
        moved = frozenset(index[n] for n in below if n in index)
        if parts is not None and not moved:
            continue
        where = f"joint {j.get('name', '')!r}"
        ax = j.find("axis")
        axis = np.array([1.0, 0.0, 0.0]) if ax is None else numbers(ax, "xyz", 3, "1 0 0", model, where)
        world = poses.get(child, np.eye(4))[:3, :3] @ axis
        world = world / np.linalg.norm(world)
        lim = j.find("limit")  # lower / upper default to 0, as URDF's
        ends = (None if j.get("type") == "continuous" or lim is None else
                tuple(float(numbers(lim, a, 1, "0", model, where)[0]) for a in ("lower", "upper")))
        out.append(TrueJoint(k, kind, world, moved, _urdf_joint(kind, world, ends)))
    return out


def _urdf_joint(kind: str, direction: np.ndarray, ends: tuple[float, ...] | None) -> Joint:
    """A URDF joint's range as a :class:`~kinmo.data.model.Joint` along ``direction`` (its
    world axis): ``ends``, its ``<limit>``'s ``(lower, upper)`` in radians (revolute) or the
    file's units (prismatic), in degrees or those units; ``None`` (a continuous joint, one
    without ``<limit>``) or limits that are not ordered give no range."""
    limit = None
    if ends is not None and ends[0] < ends[1]:
        lo, hi = ends
        limit = (math.degrees(lo), math.degrees(hi)) if kind == JointType.HINGE.value else (lo, hi)
    return Joint(JointType(kind), None, direction, limit)


def true_joints_of(model: str | Path, parts: Sequence[Part] | None) -> list[TrueJoint]:
    """:func:`urdf_true_joints` for a ``.urdf`` file, else :func:`mjcf_true_joints`."""
    if Path(model).suffix.lower() == ".urdf":
        return urdf_true_joints(model, parts)
    return mjcf_true_joints(model, parts)


def _descends(b: int, ancestor: int, parent: Sequence[int]) -> bool:
    while True:
        if b == ancestor:
            return True
        if b == 0:
            return False
        b = parent[b]


def evaluate_foreign(
    folder: str | Path,
    predictor: Predictor,
    out: str | Path,
    variants: Sequence[str] = FOREIGN_VARIANTS,
    progress: bool = True,
    turn: int = 0,
    write_up: str = "y",
) -> dict[str, dict[str, Any]]:
    """Score a predictor on the foreign assets of ``folder`` (module docs).

    Parameters
    ----------
    folder : str or Path
        A foreign-asset folder (:func:`find_foreign`). An asset kinmo cannot read counts as
        failed, with its error in its row; its true joints count (all missed) when they can
        still be found, and are unknown (none) when the file is refused before MuJoCo opens
        it (a file reference, a limit: :func:`kinmo.assets.mjcf.compile_mjcf`).
    predictor : Predictor
        A loaded :class:`~kinmo.inference.predictor.Predictor` (the bundle, refined as it says).
    out : str or Path
        Work and result folder (must not be ``folder``): ``glb/<id>.glb``,
        ``stage/<variant>/``, ``pred/<variant>/<id>/``, ``foreign.json`` (scores and
        per-object rows), ``foreign.md``.
    variants : sequence of str
        Of :data:`FOREIGN_VARIANTS`.
    progress : bool
    turn, write_up
        The GLBs turned ``turn`` quarter turns about their up axis and written ``write_up``-up
        (module docs); the ``file`` variant is left out when either is set.

    Returns
    -------
    dict of str to dict
        Per variant: :func:`~kinmo.evaluate.user_format.score`'s fields.

    Raises
    ------
    ValueError
        An unknown variant, or ``out`` is ``folder``.
    KinmoDataError
        No asset in ``folder``.
    """
    for v in variants:
        if v not in FOREIGN_VARIANTS:
            raise ValueError(f"variant must be one of {', '.join(FOREIGN_VARIANTS)}, got {v!r}")
    rot = input_rotation(turn, write_up)
    if not np.array_equal(rot, np.eye(3)):
        variants = [v for v in variants if v != "file"]
    folder, out = Path(folder), Path(out)
    if out.resolve() == folder.resolve():
        raise ValueError(f"the output folder {out} is the asset folder: give another one")
    objects = find_foreign(folder)
    parts: dict[str, list[Part] | None] = {}
    errors: dict[str, str] = {}
    truth: dict[str, list[TrueJoint]] = {}
    for o in objects:
        try:
            parts[o.id] = read_parts(o.model)
        except KinmoError as e:
            parts[o.id], errors[o.id] = None, " ".join(str(e).split())
        try:
            truth[o.id] = true_joints_of(o.model, parts[o.id])
        except KinmoError:
            if parts[o.id] is not None:
                raise
            # refused before MuJoCo opened it (a file reference, a limit): its joints are
            # unknown, so it counts as a failed object with no true joint
            truth[o.id] = []
    results: dict[str, dict[str, Any]] = {}
    all_rows: dict[str, list[dict[str, Any]]] = {}
    for variant in variants:
        stage, pred = out / "stage" / variant, out / "pred" / variant
        for d in (stage, pred):
            if d.exists():
                shutil.rmtree(d)
        stage.mkdir(parents=True)
        backs: dict[str, Callable[[list[Link]], list[Link]]] = {}
        node_leaves: dict[str, list[list[int]]] = {}
        for o in objects:
            ps = parts[o.id]
            if ps is None:
                continue
            if variant == "file":
                src, read, back = o.model, ps, np.eye(3)
            else:  # y-up, then turned about the box centre
                src = write_parts_glb([(f"part_{k}", v @ _Z_TO_Y.T, f) for k, (_, v, f) in enumerate(ps)],
                                      out / "glb" / f"{o.id}.glb", rot)
                read, back = read_parts(src), rot @ _Z_TO_Y
            frame = asset_frame(src, read)
            stage_partnet(src, stage / o.id, category="unknown", parts=read, frame=frame,
                          vocab=predictor.run.vocab)
            backs[o.id] = links_back(frame, back)
            # staged leaf k + 1 is the k-th part read; a GLB's parts are named part_<input index>
            leaves: list[list[int]] = [[] for _ in ps]
            for k, (name, _, _) in enumerate(read):
                leaves[k if variant == "file" else int(name.rsplit("_", 1)[1])].append(k + 1)
            node_leaves[o.id] = leaves
        if backs:
            predict_dataset(stage, predictor, pred, progress=progress, formats=["mobility_v2"])
        rows = []
        for o in objects:
            if o.id not in backs:
                row = {"id": o.id, "n_true": len(truth[o.id]), "n_pred": 0, "angles": [], "type_ok": [],
                       "ranges": [], "error": errors[o.id]}
            else:
                hierarchy = read_shape(stage / o.id).hierarchy
                row = score_prediction(o.id, truth[o.id], pred / o.id, hierarchy, node_leaves[o.id],
                                       backs[o.id])
            row["true_types"] = [t.type for t in truth[o.id]]
            rows.append(row)
        results[variant] = score(rows)
        all_rows[variant] = rows
    write_json(out / "foreign.json", {"assets": str(folder), "turn": int(turn) % 4, "write_up": write_up,
                                      "scores": results, "rows": all_rows})
    write_text(out / "foreign.md", foreign_markdown(results))
    return results


def foreign_markdown(results: dict[str, dict[str, Any]]) -> str:
    """A Markdown table of :func:`evaluate_foreign`'s scores, one row per variant (``file``:
    the MJCF or URDF as given)."""
    head = ("| input | objects | true joints | found | right type (of found) | axis, mean | "
            "fully right | false movers / object | unreadable | hinge range IoU | IoU >= 0.5 "
            "| slider range IoU | IoU >= 0.5 |\n|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n")
    rows = []
    for v, s in results.items():
        ranges = " | ".join(cell(s.get(k)) for k in ("range_iou_hinge", "range_ok_hinge",
                                                       "range_iou_slider", "range_ok_slider"))
        rows.append(f"| {v} | {s['objects']} | {s['true_joints']} | {cell(s['recall'])} | "
                    f"{cell(s['type_accuracy'])} | {cell(s['mean_angle'], 1, '°')} | "
                    f"**{cell(s['fully_right'])}** | {cell(s['false_movers_per_object'])} | "
                    f"{s['failed']} | {ranges} |")
    return head + "\n".join(rows) + "\n"

