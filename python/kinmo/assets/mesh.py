"""Mesh files read with trimesh: GLB / glTF scenes, OBJ with groups, STL, PLY, OFF.

A glTF scene gives one part per node with a mesh (node transforms applied); an OBJ gives one
part per ``o`` object / ``g`` group (trimesh's ``split_objects`` and ``split_groups``, named
``<object>_<group>`` in trimesh's order). glTF JSON is checked before trimesh follows it
(:func:`kinmo.gltf_check.check_gltf`: node cycles, external URIs, counts); other files are
bounded by the ``file_bytes`` limit, every mesh by ``triangles`` (:mod:`kinmo.limits`).
The up axis is y (:func:`kinmo.data.frames.default_up`).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import trimesh

from kinmo import limits
from kinmo.assets import Part, ReadOptions, register
from kinmo.data.frames import default_up
from kinmo.errors import KinmoDataError
from kinmo.gltf_check import check_gltf

__all__ = ["MESH_SUFFIXES", "mesh_parts"]

#: Mesh files read as assets, and taken as parts from a folder.
MESH_SUFFIXES: tuple[str, ...] = (".obj", ".stl", ".ply", ".off", ".glb", ".gltf")


def _why(e: Exception, path: Path) -> str:
    text = " ".join(str(e).split()) or type(e).__name__
    if path.suffix.lower() == ".dae":
        text += " (COLLADA .dae needs the pycollada package: pip install pycollada, or convert " \
                "the mesh to .obj, .stl or .glb)"
    return text


def mesh_parts(path: Path, **kw) -> list[Part]:
    """One part per mesh node of the file ``path`` (trimesh scene; transforms applied).

    Parameters
    ----------
    path : Path
        Any file trimesh reads (``.dae`` only with pycollada installed).
    **kw
        Passed to ``trimesh.load`` (``split_objects`` ...).

    Returns
    -------
    list of Part
        ``(node name, vertices (V, 3) float64, faces (F, 3) int64)``, file units; nodes
        without triangles are skipped.

    Raises
    ------
    KinmoDataError
        Unreadable file (trimesh's reason in one line), or over a limit.
    """
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
        raise KinmoDataError(path, f"cannot read the mesh: {_why(e, path)}") from None
    return parts


def _accepts(path: Path) -> bool:
    return path.is_file() and path.suffix.lower() in MESH_SUFFIXES


@register("mesh", "a GLB/glTF scene (a node per part), an OBJ (an o/g group per part), "
                  "STL, PLY or OFF", _accepts, lambda p: default_up(p.suffix))
def read_mesh(path: Path, options: ReadOptions) -> list[Part]:
    """The parts of a mesh file (module docs); ``options`` are unused."""
    if path.suffix.lower() == ".obj":
        return mesh_parts(path, split_objects=True, split_groups=True, group_material=False)
    return mesh_parts(path)
