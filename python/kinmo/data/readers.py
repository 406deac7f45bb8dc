"""Readers of PartNet and PartNet-Mobility shape folders.

Two on-disk formats are recognised (:func:`detect_format`):

- **PartNet** (Mo et al. CVPR 2019): ``result.json`` (or ``result_after_merging.json``),
  ``meta.json`` and ``objs/<name>.obj``. No motion.
- **PartNet-Mobility** (Xiang et al. CVPR 2020): the same hierarchy plus ``mobility_v2.json``
  (kinematic links and joints) and the meshes in ``textured_objs/<name>.obj``.

:func:`read_shape` parses a folder into a :class:`~kinmo.data.model.Shape` and validates it
without loading any mesh (only the existence of every referenced ``.obj`` file is checked;
vertex contents are checked when meshes are loaded, :mod:`kinmo.data.build`).
:func:`find_shapes` lists every shape folder below a dataset root.

Decisions (documented contract):

- Hierarchy file: ``result.json``; ``result_after_merging.json`` only when ``result.json`` is
  absent. With ``hierarchy="merged"`` PartNet shapes use ``result_after_merging.json`` when
  present; PartNet-Mobility objects always use ``result.json`` when present, because the
  link ``parts`` of ``mobility_v2.json`` refer to its node ids (the merged file renumbers
  nodes in 44 of the 50 real objects that have one).
- A missing ``meta.json`` gives category ``"unknown"`` (PartNet-Mobility's joints and the
  hierarchy do not need it); a ``meta.json`` without ``model_cat`` too. A malformed one is an
  error.
- Inner nodes that list ``objs`` have them ignored: a node's geometry is the union of its
  leaves' meshes.
- Joint axes are normalised to unit length; the file's origin is kept. Limits are sorted into
  ``(lower, upper)``: degrees for hinges, mesh units for sliders, ``None`` with ``noLimit``.
  A ``slider`` whose ``limit.rotates`` is true is cylindrical (``Joint.rotates``), its
  rotation range in degrees (``None`` with ``noRotationLimit``). ``free``/``heavy``/
  ``static``/``junk`` joints carry no axis (their placeholder zero axes are not errors).

Every problem raises :class:`~kinmo.errors.KinmoDataError` naming the offending file and the
problem in one line: malformed JSON (with line and column), empty hierarchy, duplicate node
ids, a leaf without meshes, a missing ``.obj`` (its path), an unknown joint type, a
zero-length or non-finite axis of a hinge/slider, link ``parts`` naming unknown nodes, a leaf
claimed by two links, unknown or cyclic parent links.

Untrusted names (:mod:`kinmo.data.names`): a mesh name is a file name, never a path (``..``,
separators, absolute paths, NUL and control characters are refused with the file and the
name), and a mesh file that resolves outside the shape folder (a symbolic link leaving it) is
refused, so that no reader or writer downstream is led outside an object folder. The shape
folder itself may be a symbolic link (kinmo's pipeline links dataset folders).

Frames: mesh frame of the OBJ files, y-up.

Length: over 500 lines, about 35 % of them docstrings: one topic, reading and validating the
two on-disk formats; most of the code is the validation that gives every malformed field a one-
line error naming its file.
"""

from __future__ import annotations

import json
import math
import os
from collections.abc import Iterator
from pathlib import Path
from typing import Any, Literal

import numpy as np

from kinmo.data.model import (
    Joint,
    JointType,
    Link,
    PartHierarchy,
    PartNode,
    Shape,
    ShapeFormat,
)
from kinmo.data.names import check_mesh_name, inside
from kinmo import limits
from kinmo.errors import KinmoDataError

__all__ = [
    "HIERARCHY_FILES",
    "HierarchyChoice",
    "detect_format",
    "find_shapes",
    "iter_shapes",
    "read_hierarchy",
    "read_json",
    "read_links",
    "read_meta",
    "read_shape",
]

#: Hierarchy file names, in order of preference by default.
HIERARCHY_FILES: tuple[str, str] = ("result.json", "result_after_merging.json")
MOBILITY_FILE = "mobility_v2.json"
META_FILE = "meta.json"
#: Files whose presence makes a folder a shape folder for :func:`find_shapes`.
_MARKERS = (*HIERARCHY_FILES, MOBILITY_FILE)

HierarchyChoice = Literal["result", "merged"]


# --------------------------------------------------------------------------------------- JSON


def read_json(path: str | Path) -> Any:
    """Parse a JSON file, turning every failure into a one-line :class:`KinmoDataError`.

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    Any
        The parsed document.

    Raises
    ------
    KinmoDataError
        The file is missing or unreadable, not UTF-8, or not valid JSON (the message gives
        the line and column of the error).
    """
    path = Path(path)
    limits.check_file(path)
    try:
        text = path.read_text(encoding="utf-8")
    except FileNotFoundError:
        raise KinmoDataError(path, "file is missing") from None
    except UnicodeDecodeError as e:
        raise KinmoDataError(path, f"not UTF-8 text (byte {e.start})") from None
    except OSError as e:
        raise KinmoDataError(path, f"cannot read: {e.strerror or e}") from None
    try:
        return json.loads(text)
    except json.JSONDecodeError as e:
        raise KinmoDataError(
            path, f"malformed JSON at line {e.lineno} column {e.colno}: {e.msg}"
        ) from None
    except RecursionError:
        raise KinmoDataError(path, "JSON nested too deeply") from None


# ------------------------------------------------------------------------------------ formats


def _hierarchy_file(folder: Path, fmt: ShapeFormat, hierarchy: HierarchyChoice) -> Path:
    result, merged = (folder / n for n in HIERARCHY_FILES)
    if hierarchy == "merged" and fmt is ShapeFormat.PARTNET and merged.is_file():
        return merged
    if result.is_file():
        return result
    if merged.is_file():
        return merged
    raise KinmoDataError(folder / HIERARCHY_FILES[0], "file is missing (no result.json or "
                         "result_after_merging.json in the shape folder)")


def detect_format(path: str | Path) -> ShapeFormat:
    """Tell the on-disk format of a shape folder.

    Parameters
    ----------
    path : str or Path
        A shape folder.

    Returns
    -------
    ShapeFormat
        ``PARTNET_MOBILITY`` when ``mobility_v2.json`` is present (it then needs
        ``textured_objs/``), else ``PARTNET`` (it needs ``objs/``).

    Raises
    ------
    KinmoDataError
        Not a folder, no hierarchy file, or the mesh folder of the format is missing.
    """
    folder = Path(path)
    if not folder.is_dir():
        raise KinmoDataError(folder, "not a folder")
    if not any((folder / n).is_file() for n in HIERARCHY_FILES):
        raise KinmoDataError(
            folder / HIERARCHY_FILES[0],
            "file is missing (a shape folder needs result.json or result_after_merging.json)",
        )
    if (folder / MOBILITY_FILE).is_file():
        if not (folder / "textured_objs").is_dir():
            raise KinmoDataError(
                folder / "textured_objs",
                "folder is missing (a PartNet-Mobility object keeps its meshes there)",
            )
        return ShapeFormat.PARTNET_MOBILITY
    if (folder / "objs").is_dir():
        return ShapeFormat.PARTNET
    if (folder / "textured_objs").is_dir():
        raise KinmoDataError(
            folder / MOBILITY_FILE,
            "file is missing (textured_objs/ present: a PartNet-Mobility object needs it)",
        )
    raise KinmoDataError(folder / "objs", "folder is missing (a PartNet shape keeps its meshes "
                         "there)")


def _is_shape_folder(folder: Path) -> bool:
    return any((folder / n).is_file() for n in _MARKERS)


def find_shapes(root: str | Path) -> list[Path]:
    """Every shape folder at or below ``root``, sorted.

    A shape folder is one holding ``result.json``, ``result_after_merging.json`` or
    ``mobility_v2.json`` (so that a broken shape is still found, and reported by
    :func:`read_shape`). Shape folders are not searched further; hidden folders are skipped;
    a symbolic link is found when it points to a shape folder, but other linked folders are
    not searched.

    Parameters
    ----------
    root : str or Path
        A dataset folder (e.g. ``partnet-mobility/``, possibly nested by category) or a single
        shape folder.

    Returns
    -------
    list of Path
        Sorted by path; ``[root]`` when ``root`` is itself a shape folder.

    Raises
    ------
    KinmoDataError
        ``root`` is not a folder.
    """
    root = Path(root)
    if not root.is_dir():
        raise KinmoDataError(root, "not a folder")
    if _is_shape_folder(root):
        return [root]
    found: list[Path] = []
    for dirpath, dirnames, _ in os.walk(root):
        here = Path(dirpath)
        keep = []
        for d in sorted(dirnames):
            if d.startswith("."):
                continue
            sub = here / d
            if _is_shape_folder(sub):
                found.append(sub)
            else:
                keep.append(d)
        dirnames[:] = keep
    return sorted(found)


# --------------------------------------------------------------------------------- hierarchy


def _int(value: Any, path: Path, what: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise KinmoDataError(path, f"{what} must be an integer, got {value!r:.40}")
    if isinstance(value, float):
        if not value.is_integer():
            raise KinmoDataError(path, f"{what} must be an integer, got {value!r}")
        value = int(value)
    return int(value)


def read_hierarchy(path: str | Path) -> PartHierarchy:
    """Parse a PartNet hierarchy file (``result.json`` / ``result_after_merging.json``).

    The file holds a list with one root node (a bare root object is accepted too); nodes have
    ``id`` (int), ``name``, ``text``, optional ``children``, and leaves ``objs`` (mesh names).

    Parameters
    ----------
    path : str or Path

    Returns
    -------
    PartHierarchy
        With ``order`` the depth-first pre-order of node ids (children in file order).

    Raises
    ------
    KinmoDataError
        Malformed JSON, no root / several roots, a node that is not an object, a missing or
        non-integer ``id``, a duplicate id, a leaf without ``objs``, a mesh name that is not
        a plain file name (:func:`kinmo.data.names.check_mesh_name`: ``..``, a separator, a
        control character ...).
    """
    path = Path(path)
    doc = read_json(path)
    if isinstance(doc, dict):
        doc = [doc]
    if not isinstance(doc, list):
        raise KinmoDataError(path, f"expected a list with the root node, got {type(doc).__name__}")
    if not doc:
        raise KinmoDataError(path, "empty hierarchy (no root node)")
    if len(doc) > 1:
        raise KinmoDataError(path, f"expected one root node, found {len(doc)}")

    nodes: dict[int, PartNode] = {}
    order: list[int] = []
    # Iterative pre-order walk: (raw node, parent id, position string for messages).
    stack: list[tuple[Any, int | None, str]] = [(doc[0], None, "root")]
    while stack:
        raw, parent, where = stack.pop()
        if not isinstance(raw, dict):
            raise KinmoDataError(path, f"node at {where} is not an object")
        if "id" not in raw:
            raise KinmoDataError(path, f"node at {where} has no 'id'")
        nid = _int(raw["id"], path, f"'id' of the node at {where}")
        if nid in nodes:
            raise KinmoDataError(path, f"duplicate node id {nid}")
        children_raw = raw.get("children") or []
        if not isinstance(children_raw, list):
            raise KinmoDataError(path, f"'children' of node {nid} is not a list")
        name = str(raw.get("name", ""))
        text = str(raw.get("text", name))
        objs: tuple[str, ...] = ()
        if not children_raw:
            objs_raw = raw.get("objs")
            if not objs_raw:
                raise KinmoDataError(path, f"leaf node {nid} ({name!r}) has no meshes ('objs')")
            if not isinstance(objs_raw, list):
                raise KinmoDataError(path, f"'objs' of node {nid} must be a list of mesh names")
            for o in objs_raw:
                check_mesh_name(o, path, f"leaf node {nid}")
            objs = tuple(dict.fromkeys(objs_raw))  # keep order, drop repeats
        child_ids: list[int] = []
        for k, c in enumerate(children_raw):
            if not isinstance(c, dict) or "id" not in c:
                raise KinmoDataError(path, f"child #{k} of node {nid} is not a node with an 'id'")
            child_ids.append(_int(c["id"], path, f"'id' of child #{k} of node {nid}"))
        nodes[nid] = PartNode(nid, name, text, tuple(child_ids), objs, parent)
        order.append(nid)
        for k in range(len(children_raw) - 1, -1, -1):
            stack.append((children_raw[k], nid, f"node {nid} child #{k}"))
    root = order[0]
    return PartHierarchy(nodes=nodes, root=root, order=order)


# ---------------------------------------------------------------------------------- mobility


def _vec3(value: Any, path: Path, what: str) -> np.ndarray:
    try:
        v = np.asarray(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise KinmoDataError(path, f"{what} must be 3 numbers, got {value!r:.60}") from None
    if v.shape != (3,):
        raise KinmoDataError(path, f"{what} must be 3 numbers, got {value!r:.60}")
    if not np.isfinite(v).all():
        raise KinmoDataError(path, f"{what} is not finite: {v.tolist()}")
    return v


def _number(value: Any, path: Path, what: str) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or not math.isfinite(value):
        raise KinmoDataError(path, f"{what} must be a finite number, got {value!r:.40}")
    return float(value)


def _joint(raw: dict, jtype: JointType, path: Path, lid: int) -> Joint:
    if jtype not in (JointType.HINGE, JointType.SLIDER):
        return Joint(type=jtype)
    data = raw.get("jointData")
    if not isinstance(data, dict) or not isinstance(data.get("axis"), dict):
        raise KinmoDataError(path, f"link {lid} ({jtype.value}) has no jointData.axis")
    axis = data["axis"]
    origin = _vec3(axis.get("origin"), path, f"axis origin of link {lid}")
    direction = _vec3(axis.get("direction"), path, f"axis direction of link {lid}")
    norm = float(np.linalg.norm(direction))
    if not norm > 1e-12:
        raise KinmoDataError(path, f"link {lid} ({jtype.value}) has a zero-length axis direction")
    direction = direction / norm
    limit_raw = data.get("limit")
    limit: tuple[float, float] | None = None
    rotates = False
    rotation_limit: float | None = None
    if isinstance(limit_raw, dict):
        if not limit_raw.get("noLimit", False):
            a = _number(limit_raw.get("a"), path, f"limit.a of link {lid}")
            b = _number(limit_raw.get("b"), path, f"limit.b of link {lid}")
            limit = (min(a, b), max(a, b))
        if jtype is JointType.SLIDER and limit_raw.get("rotates", False):
            rotates = True
            if not limit_raw.get("noRotationLimit", False):
                rotation_limit = _number(
                    limit_raw.get("rotationLimit"), path, f"limit.rotationLimit of link {lid}"
                )
    elif limit_raw is not None:
        raise KinmoDataError(path, f"limit of link {lid} is not an object")
    origin.setflags(write=False)
    direction.setflags(write=False)
    return Joint(jtype, origin, direction, limit, rotates, rotation_limit)


def read_links(path: str | Path, hierarchy: PartHierarchy) -> list[Link]:
    """Parse ``mobility_v2.json`` into links, validated against the hierarchy.

    Parameters
    ----------
    path : str or Path
        The ``mobility_v2.json`` file.
    hierarchy : PartHierarchy
        The object's hierarchy (link ``parts`` must name its nodes).

    Returns
    -------
    list of Link
        In file order. Axis directions are unit length; see the module docstring for limits.

    Raises
    ------
    KinmoDataError
        Malformed JSON, a link without integer ``id``/``parent``, a duplicate link id, an
        unknown joint type, a hinge/slider without axis or with a zero-length or non-finite
        one, ``parts`` naming unknown node ids, a leaf in two links, an unknown parent link,
        a cycle of parents.
    """
    path = Path(path)
    doc = read_json(path)
    if not isinstance(doc, list):
        raise KinmoDataError(path, f"expected a list of links, got {type(doc).__name__}")
    if not doc:
        raise KinmoDataError(path, "no links")
    valid_types = {t.value: t for t in JointType}
    links: list[Link] = []
    seen: set[int] = set()
    for k, raw in enumerate(doc):
        if not isinstance(raw, dict) or "id" not in raw:
            raise KinmoDataError(path, f"link #{k} is not an object with an 'id'")
        lid = _int(raw["id"], path, f"'id' of link #{k}")
        if lid in seen:
            raise KinmoDataError(path, f"duplicate link id {lid}")
        seen.add(lid)
        parent = _int(raw.get("parent", -1), path, f"'parent' of link {lid}")
        jname = raw.get("joint")
        if jname not in valid_types:
            raise KinmoDataError(
                path,
                f"link {lid} has unknown joint type {jname!r} "
                f"(expected one of {', '.join(valid_types)})",
            )
        jtype = valid_types[jname]
        parts_raw = raw.get("parts") or []
        if not isinstance(parts_raw, list):
            raise KinmoDataError(path, f"'parts' of link {lid} is not a list")
        parts: list[int] = []
        for p in parts_raw:
            pid = p.get("id") if isinstance(p, dict) else p
            pid = _int(pid, path, f"a part id of link {lid}")
            if pid not in hierarchy.nodes:
                raise KinmoDataError(
                    path, f"link {lid} references node id {pid}, which is not in the hierarchy"
                )
            parts.append(pid)
        joint = _joint(raw, jtype, path, lid)
        links.append(Link(lid, parent, str(raw.get("name", "")), tuple(parts), joint))

    by_id = {lk.id: lk for lk in links}
    for lk in links:
        if lk.parent != -1 and lk.parent not in by_id:
            raise KinmoDataError(path, f"link {lk.id} has unknown parent link {lk.parent}")
        seen_up = {lk.id}
        p = lk.parent
        while p != -1:
            if p in seen_up:
                raise KinmoDataError(path, f"link {lk.id} is in a cycle of parent links")
            seen_up.add(p)
            p = by_id[p].parent
    owner: dict[int, int] = {}
    for lk in links:
        for part in lk.parts:
            for leaf in hierarchy.leaves(part):
                if owner.get(leaf, lk.id) != lk.id:
                    raise KinmoDataError(
                        path, f"leaf node {leaf} belongs to links {owner[leaf]} and {lk.id}"
                    )
                owner[leaf] = lk.id
    return links


# ------------------------------------------------------------------------------------- shape


def read_meta(folder: str | Path) -> tuple[str, dict]:
    """Category and contents of a shape folder's ``meta.json``.

    Parameters
    ----------
    folder : str or Path
        The shape folder.

    Returns
    -------
    category : str
        ``model_cat``, or ``"unknown"`` when ``meta.json`` or the field is missing.
    meta : dict
        The file as read (empty when missing).

    Raises
    ------
    KinmoDataError
        ``meta.json`` is malformed or not a JSON object.
    """
    path = Path(folder) / META_FILE
    if not path.is_file():
        return "unknown", {}
    meta = read_json(path)
    if not isinstance(meta, dict):
        raise KinmoDataError(path, f"expected an object, got {type(meta).__name__}")
    cat = meta.get("model_cat")
    return (str(cat) if cat else "unknown"), meta


_read_meta = read_meta  # former private name, used by other modules


def read_shape(path: str | Path, hierarchy: HierarchyChoice = "result", *,
               external_links: bool = False) -> Shape:
    """Read and validate one shape folder (either format), without loading meshes.

    Parameters
    ----------
    path : str or Path
        The shape folder.
    hierarchy : {"result", "merged"}
        Which hierarchy file to prefer (see the module docstring): ``"result"`` (default)
        reads ``result.json``, ``"merged"`` reads ``result_after_merging.json`` for PartNet
        shapes that have it. Either falls back to the other file when absent.
    external_links : bool
        Accept meshes that resolve outside the shape folder (symbolic links leaving it).
        Default False: refused (module docstring). Only for folders kinmo wrote itself
        with links to a source dataset (``kinmo pseudo-label --link symlink``).

    Returns
    -------
    Shape
        ``id`` is the folder name; ``category`` is ``meta.json``'s ``model_cat`` or
        ``"unknown"``; ``links`` is set for PartNet-Mobility objects.

    Raises
    ------
    KinmoDataError
        Any problem listed in the module docstring; a referenced ``.obj`` that does not
        exist is named by its own path.
    """
    if hierarchy not in ("result", "merged"):
        raise ValueError(f"hierarchy must be 'result' or 'merged', got {hierarchy!r}")
    folder = Path(path)
    fmt = detect_format(folder)
    hfile = _hierarchy_file(folder, fmt, hierarchy)
    tree = read_hierarchy(hfile)
    mesh_dir = folder / ("textured_objs" if fmt is ShapeFormat.PARTNET_MOBILITY else "objs")
    # a mesh name is a file name (kinmo.data.names): its file resolves inside the folder
    # unless the mesh folder or the file itself is a link that leaves it
    dir_inside = external_links or inside(mesh_dir, folder)
    for nid in tree.order:
        node = tree.nodes[nid]
        for name in node.objs:
            obj = mesh_dir / f"{name}.obj"
            if not obj.is_file():
                raise KinmoDataError(
                    obj, f"mesh file is missing (named by leaf node {nid} of {hfile.name})"
                )
            if not external_links and not (dir_inside and not obj.is_symlink()) \
                    and not inside(obj, folder):
                raise KinmoDataError(
                    obj, "is a symbolic link that leaves the shape folder (named by leaf node "
                    f"{nid} of {hfile.name}); kinmo reads only meshes inside the folder"
                )
    category, meta = read_meta(folder)
    links = read_links(folder / MOBILITY_FILE, tree) if fmt is ShapeFormat.PARTNET_MOBILITY else None
    shape = Shape(
        id=folder.name,
        category=category,
        format=fmt,
        path=folder,
        mesh_dir=mesh_dir,
        hierarchy=tree,
        links=links,
        meta=meta,
    )
    return shape


def iter_shapes(root: str | Path, hierarchy: HierarchyChoice = "result") -> Iterator[Shape]:
    """Read every shape under ``root`` (:func:`find_shapes` order); errors propagate."""
    for folder in find_shapes(root):
        yield read_shape(folder, hierarchy)
