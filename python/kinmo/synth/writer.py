"""Write a :class:`~kinmo.synth.assembly.SynthObject` as a PartNet-Mobility or PartNet folder.

Formats reproduce the real datasets (see ``/work/shared/data/README.md``):

PartNet-Mobility folder ``<id>/``
    ``meta.json`` (``model_id``, ``anno_id``, ``user_id``, ``time_in_sec``, ``version``,
    ``model_cat``, string values), ``result.json`` (a list with one root node; nodes carry
    ``text``, ``children`` or ``objs``, ``id``, ``name``; ids assigned breadth-first from 0
    as PartNet does), ``textured_objs/original-<k>.obj`` (one closed mesh per file, k from 1
    in leaf pre-order), ``mobility_v2.json`` (moving links ``0..n-2`` then the base link
    ``n-1``; ``parts`` list the PartNet leaf ids ``{id, name, children: []}``; hinge limits
    in degrees, slider limits in mesh units, sliders also carry ``rotates``,
    ``noRotationLimit``, ``rotationLimit``), ``semantics.txt`` (``link_<i> <joint>
    <label>``, ``slider+`` for rotating sliders).

PartNet folder ``<id>/``
    ``meta.json``, ``result.json``, ``objs/original-<k>.obj``; no motion.

Numbers are written rounded (vertices and origins to 1e-6, directions to 1e-9, hinge limits
to 1e-4 degrees, slider limits to 1e-6) so output bytes do not depend on the last bits of
floating point arithmetic. Each object folder is assembled in a hidden temporary folder next
to it and renamed into place, so a reader never sees a half-written object.
"""

from __future__ import annotations

import hashlib
import json
import os
import shutil
import tempfile
from collections import deque
from pathlib import Path

import numpy as np
import trimesh

from kinmo.synth.assembly import Node, SynthObject

#: ``user_id`` written to ``meta.json`` of every generated object.
USER_ID = "kinmo-synth"


def _num(x: float, nd: int) -> float | int:
    """Round for JSON: no negative zero, integers written without a fraction."""
    v = round(float(x), nd) + 0.0
    return int(v) if v == int(v) and abs(v) < 1e15 else v


def _vec(v: np.ndarray, nd: int) -> list[float | int]:
    return [_num(x, nd) for x in v]


def obj_text(mesh: trimesh.Trimesh, name: str) -> str:
    """Wavefront OBJ text of a triangle mesh (``v`` with 6 decimals, 1-based ``f``).

    Parameters
    ----------
    mesh : trimesh.Trimesh
    name : str
        Object name written after ``o``.

    Returns
    -------
    str
    """
    v = np.round(np.asarray(mesh.vertices, dtype=np.float64), 6) + 0.0
    f = np.asarray(mesh.faces, dtype=np.int64) + 1
    lines = [f"# kinmo synth\no {name}"]
    lines += [f"v {a:.6f} {b:.6f} {c:.6f}" for a, b, c in v]
    lines += [f"f {a} {b} {c}" for a, b, c in f]
    return "\n".join(lines) + "\n"


def assign_ids(root: Node) -> tuple[dict[int, int], dict[int, list[str]]]:
    """PartNet node ids (breadth-first from 0) and mesh names (leaf pre-order from 1).

    Parameters
    ----------
    root : Node

    Returns
    -------
    ids : dict
        ``id(node) -> PartNet id``.
    names : dict
        ``id(leaf) -> ["original-<k>", ...]``, one name per mesh.
    """
    ids: dict[int, int] = {}
    queue = deque([root])
    while queue:
        n = queue.popleft()
        ids[id(n)] = len(ids)
        queue.extend(n.children)
    names: dict[int, list[str]] = {}
    k = 1
    for leaf in root.leaves():
        names[id(leaf)] = [f"original-{k + i}" for i in range(len(leaf.meshes))]
        k += len(leaf.meshes)
    return ids, names


def result_json(root: Node, ids: dict[int, int], names: dict[int, list[str]]) -> list[dict]:
    """The ``result.json`` content: a list holding the root node dict."""

    def node(n: Node) -> dict:
        d: dict = {"text": n.text}
        if n.children:
            d["children"] = [node(c) for c in n.children]
        else:
            d["objs"] = names[id(n)]
        d["id"] = ids[id(n)]
        d["name"] = n.name
        return d

    return [node(root)]


def mobility_json(obj: SynthObject, ids: dict[int, int]) -> tuple[list[dict], list[str]]:
    """``mobility_v2.json`` entries and ``semantics.txt`` lines of ``obj``.

    Parameters
    ----------
    obj : SynthObject
        Normalised object.
    ids : dict
        PartNet ids from :func:`assign_ids`.

    Returns
    -------
    links : list of dict
    semantics : list of str
    """
    base_id = len(obj.links)
    out: list[dict] = []
    sem: list[str] = []
    for i, link in enumerate(obj.links):
        mo = link.motion
        if mo.kind == "hinge":
            limit = {
                "a": _num(mo.limit[0], 4) if mo.limit else 0,
                "b": _num(mo.limit[1], 4) if mo.limit else 0,
                "noLimit": mo.limit is None,
            }
        else:
            assert mo.limit is not None
            limit = {
                "a": _num(mo.limit[0], 6),
                "b": _num(mo.limit[1], 6),
                "noLimit": False,
                "rotates": bool(mo.rotates),
                "noRotationLimit": bool(mo.rotates and mo.rotation_limit is None),
                "rotationLimit": _num(mo.rotation_limit, 4) if mo.rotation_limit is not None else 0,
            }
        out.append(
            {
                "id": i,
                "parent": base_id if link.parent is None else link.parent,
                "joint": mo.kind,
                "name": link.name,
                "parts": [
                    {"id": ids[id(leaf)], "name": leaf.name, "children": []}
                    for leaf in link.leaves()
                ],
                "jointData": {
                    "axis": {"origin": _vec(mo.origin, 6), "direction": _vec(mo.direction, 9)},
                    "limit": limit,
                },
            }
        )
        joint = "slider+" if mo.kind == "slider" and mo.rotates else mo.kind
        sem.append(f"link_{i} {joint} {link.semantic}")
    base = obj.base_leaves()
    out.append(
        {
            "id": base_id,
            "parent": -1,
            "joint": obj.base_joint,
            "name": base[0].name,
            "parts": [{"id": ids[id(leaf)], "name": leaf.name, "children": []} for leaf in base],
            "jointData": {},
        }
    )
    sem.append(f"link_{base_id} {obj.base_joint} {obj.base_semantic}")
    return out, sem


def model_id(anno_id: str) -> str:
    """A deterministic 32-hex-digit ``model_id`` (ShapeNet-style) for a synthetic id."""
    return hashlib.sha1(f"kinmo-synth:{anno_id}".encode()).hexdigest()[:32]


def meta_json(obj: SynthObject, anno_id: str) -> dict:
    """``meta.json`` content with the real key order and string values."""
    return {
        "model_id": model_id(anno_id),
        "anno_id": anno_id,
        "user_id": USER_ID,
        "time_in_sec": "0",
        "version": "1",
        "model_cat": obj.category,
    }


def _write(path: Path, text: str) -> None:
    with open(path, "w", encoding="utf-8", newline="\n") as f:
        f.write(text)


def write_object(obj: SynthObject, folder: str | Path, anno_id: str, partnet: bool = False) -> Path:
    """Write ``obj`` as a dataset folder, replacing ``folder`` as a whole.

    Parameters
    ----------
    obj : SynthObject
        A normalised object (see :func:`kinmo.synth.assembly.normalize`).
    folder : str or Path
        Destination ``<root>/<anno_id>``; an existing folder is replaced.
    anno_id : str
        The object's id (``meta.json`` ``anno_id``).
    partnet : bool
        Write the PartNet format (``objs/``, no motion) instead of PartNet-Mobility.

    Returns
    -------
    Path
        ``folder``.

    Raises
    ------
    ValueError
        ``obj`` is structurally invalid (see :meth:`SynthObject.check`).
    OSError
        The folder cannot be written.
    """
    obj.check()
    folder = Path(folder)
    folder.parent.mkdir(parents=True, exist_ok=True)
    tmp = Path(tempfile.mkdtemp(prefix=f".{folder.name}.", suffix=".tmp", dir=folder.parent))
    try:
        ids, names = assign_ids(obj.root)
        mesh_dir = tmp / ("objs" if partnet else "textured_objs")
        mesh_dir.mkdir()
        for leaf in obj.root.leaves():
            for mesh, name in zip(leaf.meshes, names[id(leaf)], strict=True):
                _write(mesh_dir / f"{name}.obj", obj_text(mesh, name))
        _write(tmp / "meta.json", json.dumps(meta_json(obj, anno_id)) + "\n")
        _write(tmp / "result.json", json.dumps(result_json(obj.root, ids, names)) + "\n")
        if not partnet:
            links, sem = mobility_json(obj, ids)
            _write(tmp / "mobility_v2.json", json.dumps(links, separators=(",", ":")) + "\n")
            _write(tmp / "semantics.txt", "\n".join(sem) + "\n")
        for p in sorted(tmp.rglob("*")):
            if p.is_file():
                os.chmod(p, 0o644)
        os.chmod(tmp, 0o755)
        old = None
        if folder.exists():
            old = folder.parent / f".{folder.name}.old"
            if old.exists():
                shutil.rmtree(old)
            os.replace(folder, old)
        os.replace(tmp, folder)
        if old is not None:
            shutil.rmtree(old)
    except BaseException:
        shutil.rmtree(tmp, ignore_errors=True)
        raise
    return folder
