"""Prediction on a user's own part-segmented mesh (``kinmo predict FILE``).

kinmo predicts motion over a *part hierarchy* (Liu et al. 2023, Sec. 3.1: the GNN runs on the
parts of a PartNet shape). A user's asset gives the parts in one of four ways; each becomes a
PartNet folder (``result.json``, ``meta.json``, ``objs/part_<k>.obj``) that the unchanged
prediction path (:func:`kinmo.predict.predict_dataset`: part graph, motion GNN, optional
axis refinement) reads like any PartNet shape:

==============================  ===========================================================
input                           parts
==============================  ===========================================================
``.glb`` / ``.gltf`` scene      one part per scene node with a mesh (node transforms applied)
``.obj`` with ``o`` / ``g``     one part per object / group (``trimesh``'s ``split_objects``
                                and ``split_groups``; named ``<object>_<group>``, in
                                trimesh's order)
a folder of mesh files          one part per file (``.obj``, ``.stl``, ``.ply``, ``.off``,
                                ``.glb``; each file merged into one part)
``.urdf``                       one part per link with visual meshes, placed at the link's
                                rest pose (joint origins, visual origins and ``scale``
                                applied): re-labels an existing asset
==============================  ===========================================================

**Hierarchy rule.** A root node named after the file (its stem), with one leaf per part in
input order (scene nodes, sorted file names, URDF link order), named after the node / group / file / link (``part_<k>`` when nameless; names
sanitised to ``[A-Za-z0-9_]``). PartNet's own hierarchies are deeper; a flat one is what a
user's segmentation tells, and the GNN's sibling edges then relate every pair of parts.

Frames and units (issue 22; :mod:`kinmo.data.frames`): the asset's up axis is ``--up``, by
default its format's (:func:`asset_up`: glTF and OBJ y-up, URDF z-up by ROS convention, a
URDF kinmo wrote y-up); a warning is logged when its support faces suggest the other axis.
The parts are staged in kinmo's frame (y-up, centred, bounding-box diagonal 2, whatever the
units), and every output is mapped back: ``textured_objs/`` holds the meshes as given,
``mobility_v2.json`` and the exports carry the joints in the asset's frame and units, and
``frame.json`` records the map (``edges.json`` stays in kinmo's frame).

Output (:func:`predict_user_input`): ``OUT/<stem>/`` becomes a complete PartNet-Mobility
folder: ``result.json``, ``meta.json``, ``textured_objs/part_<k>.obj``, ``mobility_v2.json``,
``edges.json``, ``frame.json``, ``view.html`` (:func:`kinmo.view.view_folder`) and the chosen
export formats (:mod:`kinmo.export`), the staged PartNet folder
(``OUT/.staging/<stem>``) is removed afterwards. An unsegmented input (fewer than two parts)
raises :class:`~kinmo.errors.KinmoDataError` saying what kinmo needs.
"""

from __future__ import annotations

import logging
import math
import re
import shutil
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from kinmo import limits
from kinmo.data.frames import AssetFrame, UpAxis, default_up, guess_up
from kinmo.data.names import inside, name_problem
from kinmo.data.readers import find_shapes, read_shape
from kinmo.data.writers import write_mobility_v2
from kinmo.errors import KinmoDataError
from kinmo.export import DEFAULT_FORMATS, export
from kinmo.export.collision import DEFAULT_COLLISION
from kinmo.export.kinematics import write_obj
from kinmo.gltf_check import check_gltf
from kinmo.io import check_outputs_apart, parse_xml, staged_folder, write_json, write_text
from kinmo.predict import predict_dataset
from kinmo.progress import plain
from kinmo.view import view_folder

__all__ = [
    "MESH_SUFFIXES",
    "Part",
    "asset_up",
    "is_user_input",
    "predict_user_input",
    "read_parts",
    "stage_partnet",
]

#: Mesh files taken as parts from a folder.
MESH_SUFFIXES: tuple[str, ...] = (".obj", ".stl", ".ply", ".off", ".glb", ".gltf")
_NEEDS = ("kinmo needs the object split into its parts (at least 2): a GLB/glTF scene with "
          "one node per part, an OBJ with one 'o'/'g' group per part, a folder with one mesh "
          "file per part, or a URDF with one link per part")

Part = tuple[str, np.ndarray, np.ndarray]

logger = logging.getLogger(__name__)
"""A part: ``(name, vertices (V, 3) float64, faces (F, 3) int64)`` in the mesh frame."""


def is_user_input(path: str | Path) -> bool:
    """True for a mesh/URDF file, or a folder of mesh files that holds no shape folder."""

    path = Path(path)
    if path.is_file():
        return path.suffix.lower() in MESH_SUFFIXES + (".urdf",)
    if not path.is_dir():
        return False
    if find_shapes(path):
        return False
    return any(p.suffix.lower() in MESH_SUFFIXES for p in path.iterdir() if p.is_file())


def _clean(name: str, k: int) -> str:
    s = re.sub(r"[^A-Za-z0-9_]+", "_", name).strip("_")
    return s or f"part_{k}"


def _trimesh_parts(path: Path, **kw) -> list[Part]:
    import trimesh

    if path.suffix.lower() in (".glb", ".gltf"):
        check_gltf(path)  # cycles, external URIs, limits: before trimesh follows them
    else:
        limits.check_file(path)
    try:
        loaded = trimesh.load(path, force="scene", process=False, **kw)
        parts: list[Part] = []
        for node in loaded.graph.nodes_geometry:
            T, gname = loaded.graph[node]
            g = loaded.geometry[gname]
            if not isinstance(g, trimesh.Trimesh) or len(g.faces) == 0:
                continue
            limits.check("triangles", len(g.faces), path)
            v = np.asarray(g.vertices, dtype=np.float64) @ T[:3, :3].T + T[:3, 3]
            parts.append((str(node), v, np.asarray(g.faces, dtype=np.int64)))
            limits.check("parts", len(parts), path)
    except KinmoDataError:
        raise
    except Exception as e:  # trimesh raises many types on bad files
        raise KinmoDataError(path, f"cannot read the mesh: {' '.join(str(e).split())}") from None
    return parts


def _urdf_mesh(path: Path, link: str, filename: str) -> Path:
    """The mesh file a URDF ``<mesh filename>`` names: a relative path inside the URDF's
    folder (``package://`` and ``file://`` prefixes dropped); absolute paths, ``..`` and
    links leaving the folder are refused (issue 21, the rule for names from input files)."""
    fname = re.sub(r"^(package|file)://", "", filename)
    pieces = fname.replace("\\", "/").split("/")
    if (not fname or Path(fname).is_absolute() or fname.startswith(("/", "\\")) or ".." in pieces
            or any(name_problem(p) for p in pieces if p not in ("", "."))):
        raise KinmoDataError(path, f"link {link!r}: mesh filename {filename!r} refused (it must be "
                                   "a relative path inside the URDF's folder)")
    mesh_path = path.parent / fname
    if not inside(mesh_path, path.parent):
        raise KinmoDataError(path, f"link {link!r}: mesh {filename!r} leads outside the URDF's "
                                   "folder (a symbolic link)")
    return mesh_path


def _merge(parts: list[Part], name: str) -> Part:
    vs, fs, n = [], [], 0
    for _, v, f in parts:
        vs.append(v)
        fs.append(f + n)
        n += len(v)
    return name, np.concatenate(vs), np.concatenate(fs)


def _rpy(rpy: np.ndarray) -> np.ndarray:
    from scipy.spatial.transform import Rotation

    return Rotation.from_euler("xyz", rpy).as_matrix()  # URDF: fixed-axis roll, pitch, yaw


def _origin(el: ET.Element | None, where: Path) -> np.ndarray:
    T = np.eye(4)
    if el is None:
        return T
    try:
        xyz = np.array([float(x) for x in el.get("xyz", "0 0 0").split()])
        rpy = np.array([float(x) for x in el.get("rpy", "0 0 0").split()])
    except ValueError:
        raise KinmoDataError(where, f"bad <origin> {el.attrib}") from None
    if xyz.shape != (3,) or rpy.shape != (3,):
        raise KinmoDataError(where, f"bad <origin> {el.attrib}")
    T[:3, :3] = _rpy(rpy)
    T[:3, 3] = xyz
    return T


def _urdf_parts(path: Path) -> list[Part]:
    try:
        root = parse_xml(path).getroot()
    except KinmoDataError as e:
        raise KinmoDataError(path, f"not a readable URDF: {e.problem}") from None
    joints = {}
    for j in root.findall("joint"):
        c, p = j.find("child"), j.find("parent")
        if c is not None and p is not None:
            joints[c.get("link")] = (p.get("link"), _origin(j.find("origin"), path))
    pose: dict[str, np.ndarray] = {}

    def world(name: str, depth: int = 0) -> np.ndarray:
        if name not in pose:
            if depth > len(joints) or name not in joints:
                pose[name] = np.eye(4)
            else:
                parent, T = joints[name]
                pose[name] = world(parent, depth + 1) @ T
        return pose[name]

    parts: list[Part] = []
    for link in root.findall("link"):
        name = link.get("name", "")
        pieces: list[Part] = []
        for vis in link.findall("visual"):
            m = vis.find("geometry/mesh")
            if m is None:
                continue
            fname = m.get("filename", "")
            mesh_path = _urdf_mesh(path, name, fname)
            if not mesh_path.is_file():
                raise KinmoDataError(path, f"link {name!r}: mesh {fname!r} not found")
            T = world(name) @ _origin(vis.find("origin"), path)
            scale = np.array([float(s) for s in m.get("scale", "1 1 1").split()])
            for _, v, f in _trimesh_parts(mesh_path):
                pieces.append((name, (v * scale) @ T[:3, :3].T + T[:3, 3], f))
        if pieces:
            parts.append(_merge(pieces, name))
    return parts


def read_parts(path: str | Path) -> list[Part]:
    """The parts of a user's asset (module docs: which input gives which parts).

    Parameters
    ----------
    path : str or Path
        ``.glb``/``.gltf``, ``.obj``, ``.urdf``, or a folder of mesh files.

    Returns
    -------
    list of Part
        In input order, vertices in the mesh frame (transforms applied).

    Raises
    ------
    KinmoDataError
        Unknown kind, unreadable file, a missing URDF mesh, or fewer than two parts (the
        message says what kinmo needs).
    """
    path = Path(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        files = sorted(p for p in path.iterdir()
                       if p.is_file() and p.suffix.lower() in MESH_SUFFIXES and inside(p, path))
        parts = [_merge(ps, f.stem) for f in files if (ps := _trimesh_parts(f))]
    elif suffix == ".urdf":
        parts = _urdf_parts(path)
    elif suffix == ".obj":
        parts = _trimesh_parts(path, split_objects=True, split_groups=True, group_material=False)
    elif suffix in MESH_SUFFIXES:
        parts = _trimesh_parts(path)
    else:
        raise KinmoDataError(path, f"unknown input kind {suffix or '(folder)'!r}; {_NEEDS}")
    limits.check("parts", len(parts), path)
    if len(parts) < 2:
        raise KinmoDataError(path, f"found {len(parts)} part(s): an unsegmented mesh; {_NEEDS}")
    return parts


def asset_up(path: str | Path) -> UpAxis:
    """The up axis ``path`` declares by its format (:func:`kinmo.data.frames.default_up`:
    glTF y-up by its specification, URDF z-up by ROS REP 103), except a URDF that kinmo
    wrote (its joints carry ``<mobility_v2>`` elements): kinmo's URDFs are y-up
    (:mod:`kinmo.urdf`)."""
    path = Path(path)
    if path.suffix.lower() == ".urdf" and path.is_file():
        try:
            if parse_xml(path).getroot().find("joint/mobility_v2") is not None:
                return "y"
        except KinmoDataError:
            pass  # read_parts names the problem
    return default_up("" if path.is_dir() else path.suffix)


def stage_partnet(path: str | Path, folder: str | Path, category: str = "unknown",
                  parts: Sequence[Part] | None = None, frame: AssetFrame | None = None) -> Path:
    """Write the parts of ``path`` as a PartNet shape folder (module docs: hierarchy rule).

    Parameters
    ----------
    path : str or Path
        The user's asset (:func:`read_parts`).
    folder : str or Path
        The shape folder to create (replaced if present).
    category : str
        ``model_cat`` written to ``meta.json`` (used only as the GNN's semantic context).
    parts : sequence of Part, optional
        The parts when the caller has read them (else :func:`read_parts` of ``path``).
    frame : AssetFrame, optional
        Map the parts into kinmo's frame (y-up, diagonal 2) before writing them
        (:meth:`kinmo.data.frames.AssetFrame.to_kinmo`); default: written as given.

    Returns
    -------
    Path
        ``folder``, readable by :func:`kinmo.data.readers.read_shape`.

    Raises
    ------
    KinmoDataError
        As :func:`read_parts`.
    """

    path, folder = Path(path), Path(folder)
    parts = read_parts(path) if parts is None else parts
    if folder.exists():
        shutil.rmtree(folder)
    (folder / "objs").mkdir(parents=True)
    leaves = []
    for k, (name, v, f) in enumerate(parts):
        write_obj(folder / "objs" / f"part_{k}.obj", v if frame is None else frame.to_kinmo(v), f)
        pname = _clean(name, k)
        leaves.append({"id": k + 1, "name": pname, "text": name or pname, "objs": [f"part_{k}"]})
    stem = _clean(path.stem, 0)
    write_json(folder / "result.json", [{"id": 0, "name": stem, "text": path.name,
                                          "children": leaves}])
    write_json(folder / "meta.json", {"model_cat": category, "anno_id": stem,
                                      "source": str(path)})
    return folder


def predict_user_input(path: str | Path, run, out: str | Path, formats: Sequence[str] | None = None,
                       category: str = "unknown", up: str | None = None, **predict_kw):
    """Predict the motion of a user's asset; write ``OUT/<stem>/`` (module docs).

    Parameters
    ----------
    path : str or Path
        ``.glb``/``.gltf``, ``.obj`` with groups, ``.urdf`` or a folder of part meshes.
    run : str, Path or Run
        Motion GNN run folder (``kinmo train gnn``).
    out : str or Path
        Output folder.
    formats : sequence of str, optional
        Export formats (default :data:`kinmo.export.DEFAULT_FORMATS`); ``mobility_v2`` is
        always written.
    category : str
        Category name given to the GNN.
    up : {"y", "z"}, optional
        The asset's up axis (default :func:`asset_up`: by its format). A warning is logged
        when the geometry suggests the other one (:func:`kinmo.data.frames.guess_up`).
    **predict_kw
        Passed to :func:`kinmo.predict.predict_dataset` (``axis_model``, ``options``,
        ``device``, ``progress`` ...).

    Returns
    -------
    list of PredictRow
        One row (the asset), ``outputs`` naming every file written.

    Raises
    ------
    KinmoDataError
        As :func:`read_parts`, or the run cannot be loaded.
    KinmoUsageError
        ``out`` would overwrite ``path`` (:func:`kinmo.io.check_outputs_apart`).
    """

    path, out = Path(path), Path(out)
    stem = _clean(path.stem, 0)
    check_outputs_apart(out, [path], written=[stem, ".staging", "predictions.csv"])
    staging = out / ".staging"
    parts = read_parts(path)
    up = up if up is not None else asset_up(path)
    suggested = guess_up([(v, f) for _, v, f in parts], up)
    if suggested is not None:
        logger.warning("%s: read as %s-up, but it stands on faces that say %s-up (give --up %s if so)",
                       plain(path), up, suggested, suggested)
    frame = AssetFrame.fit([v for _, v, _ in parts], up)
    shutil.rmtree(staging, ignore_errors=True)  # a killed run's leftovers
    shape_dir = stage_partnet(path, staging / "shapes" / stem, category, parts=parts, frame=frame)
    fmts = list(dict.fromkeys(["mobility_v2", *(DEFAULT_FORMATS if formats is None else formats)]))
    try:
        pred_out = staging / "pred"
        rows = predict_dataset(staging / "shapes", run, pred_out, formats=["mobility_v2"], **predict_kw)
        for row in rows:
            if row.status != "ok":
                continue
            # OUT/<stem> is built in a temporary sibling and renamed into place whole (issue
            # 21, finding 12), in the asset's own frame and units: its meshes as given, the
            # predicted joints mapped back (edges.json stays in kinmo's frame)
            with staged_folder(out / stem) as final:
                for entry in (pred_out / stem).iterdir():
                    shutil.move(str(entry), str(final / entry.name))
                tex = final / "textured_objs"  # kinmo-frame copies of the staged meshes: replaced
                shutil.rmtree(tex, ignore_errors=True)
                tex.mkdir()
                for k, (_, v, f) in enumerate(parts):
                    write_obj(tex / f"part_{k}.obj", v, f)
                for name in ("result.json", "meta.json"):
                    shutil.copyfile(shape_dir / name, final / name)
                predicted = read_shape(final)
                if predicted.links is not None and not frame.is_identity:
                    write_mobility_v2(frame.links_to_asset(predicted.links), final / "mobility_v2.json",
                                      predicted.hierarchy)
                write_json(final / "frame.json", frame.to_json())
                files = export(read_shape(final), final, fmts, name=stem,
                               progress=predict_kw.get("progress", True),
                               collision=predict_kw.get("collision", DEFAULT_COLLISION))
                written = {f: w[0] for f, w in files.items()}
                written["view"] = view_folder(final)  # view.html: a slider per joint
                written.update({k: v for k, v in row.outputs.items() if k not in written})
            row.outputs = {k: out / stem / Path(v).name for k, v in written.items()}
        write_text(out / "predictions.csv", (pred_out / "predictions.csv").read_text())
    finally:
        shutil.rmtree(staging, ignore_errors=True)
    return rows
