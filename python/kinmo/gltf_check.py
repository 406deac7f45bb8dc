"""Checks of a glTF / GLB file's JSON before a mesh library reads it (issue 21, findings 4, 7).

trimesh follows a glTF scene graph as given: a node cycle makes it loop until "Iteration
limit exceeded", an external ``uri`` makes it open any file the name points to, and accessor
counts decide how much it allocates. :func:`check_gltf` reads only the JSON chunk and refuses,
with one line naming the file:

- more nodes than the ``nodes`` limit, or more triangles in one mesh than ``triangles``
  (:mod:`kinmo.limits`), the file larger than ``file_bytes``;
- a node that is its own ancestor (a cycle) or the child of two nodes, or a child index out of
  range;
- an external ``uri`` (buffer or image) that is not a plain file name beside the file
  (:func:`kinmo.data.names.name_problem`: no separators, no ``..``, no absolute path, no
  control characters); ``data:`` URIs are embedded and pass.

The glTF 2.0 specification, Sec. 3.5 (nodes form disjoint strict trees) and 3.6 (URIs).
"""

from __future__ import annotations

import json
import struct
from pathlib import Path
from typing import Any

from kinmo import limits
from kinmo.data.names import name_problem
from kinmo.errors import KinmoDataError

__all__ = ["check_gltf", "gltf_json"]

_GLB_MAGIC = b"glTF"
_JSON_CHUNK = 0x4E4F534A


def gltf_json(path: str | Path) -> dict[str, Any]:
    """The JSON document of a ``.glb`` (its first chunk) or ``.gltf`` file.

    Raises
    ------
    KinmoDataError
        Unreadable, over the ``file_bytes`` limit, not a GLB/glTF, or its JSON does not parse.
    """
    path = Path(path)
    limits.check_file(path)
    try:
        with open(path, "rb") as f:
            head = f.read(20)
            if head[:4] == _GLB_MAGIC:
                if len(head) < 20:
                    raise KinmoDataError(path, "truncated GLB header")
                _, _, total, length, kind = struct.unpack("<4sIIII", head)
                if kind != _JSON_CHUNK or length > total:
                    raise KinmoDataError(path, "GLB: the first chunk is not JSON")
                raw = f.read(length)
            else:
                raw = head + f.read()
        doc = json.loads(raw.decode("utf-8"))
    except OSError as e:
        raise KinmoDataError(path, f"cannot read: {e.strerror}") from None
    except (UnicodeDecodeError, ValueError) as e:
        raise KinmoDataError(path, f"not a glTF file: {' '.join(str(e).split())}") from None
    if not isinstance(doc, dict):
        raise KinmoDataError(path, "not a glTF file: the JSON is not an object")
    return doc


def _list(doc: dict[str, Any], key: str, path: Path) -> list[Any]:
    v = doc.get(key, [])
    if not isinstance(v, list):
        raise KinmoDataError(path, f"glTF {key!r} is not a list")
    return v


def check_gltf(path: str | Path) -> dict[str, Any]:
    """Check a ``.glb`` / ``.gltf`` file (module rules) and return its JSON document.

    Raises
    ------
    KinmoDataError
        The first problem found, naming the file: over a limit, a node cycle or a node with two
        parents, a bad child index, an external URI that is not a plain name.
    """
    path = Path(path)
    doc = gltf_json(path)
    nodes = _list(doc, "nodes", path)
    limits.check("nodes", len(nodes), path)
    parent: dict[int, int] = {}
    for i, node in enumerate(nodes):
        children = node.get("children", []) if isinstance(node, dict) else []
        if not isinstance(children, list):
            raise KinmoDataError(path, f"glTF node {i}: 'children' is not a list")
        for c in children:
            if not isinstance(c, int) or isinstance(c, bool) or not 0 <= c < len(nodes):
                raise KinmoDataError(path, f"glTF node {i}: child {c!r} is not a node index")
            if c in parent:
                raise KinmoDataError(path, f"glTF node {c} is a child of nodes {parent[c]} and {i} "
                                           "(the nodes must form trees)")
            parent[c] = i
    for start in parent:  # every chain of parents must end within len(nodes) steps
        v, steps = start, 0
        while v in parent:
            v = parent[v]
            steps += 1
            if v == start or steps > len(nodes):
                raise KinmoDataError(path, f"glTF node {start} is its own ancestor (the nodes form "
                                           "a cycle)")
    for key in ("buffers", "images"):
        for i, item in enumerate(_list(doc, key, path)):
            uri = item.get("uri") if isinstance(item, dict) else None
            if uri is None or (isinstance(uri, str) and uri.startswith("data:")):
                continue
            problem = name_problem(uri) if isinstance(uri, str) else "not a string"
            if problem:
                raise KinmoDataError(path, f"glTF {key[:-1]} {i}: uri {uri!r} refused ({problem}); "
                                           "external files must lie beside the glTF file")
    accessors = _list(doc, "accessors", path)
    for m, mesh in enumerate(_list(doc, "meshes", path)):
        tri = 0
        for prim in (mesh.get("primitives", []) if isinstance(mesh, dict) else []):
            if not isinstance(prim, dict):
                continue
            a = prim.get("indices", (prim.get("attributes") or {}).get("POSITION"))
            if isinstance(a, int) and 0 <= a < len(accessors) and isinstance(accessors[a], dict):
                count = accessors[a].get("count", 0)
                tri += count // 3 if isinstance(count, int) else 0
        limits.check("triangles", tri, f"{path} (mesh {m})")
    return doc
